#include "artms/truth_propagator/cowell.hpp"

#include <cvode/cvode.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunnonlinsol/sunnonlinsol_fixedpoint.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace artms::truth {

void CowellOptions::validate() const {
  const auto positive = [](double v, const char* name) {
    if (!(v > 0.0) || !std::isfinite(v)) {
      throw std::invalid_argument(std::string("CowellOptions.") + name + " must be positive");
    }
  };
  positive(rel_tol, "rel_tol");
  positive(abs_tol_m, "abs_tol_m");
  positive(max_step_s, "max_step_s");
  positive(nonlinear_convergence_coefficient, "nonlinear_convergence_coefficient");
  if (max_nonlinear_iterations < 1) {
    throw std::invalid_argument("CowellOptions.max_nonlinear_iterations must be >= 1");
  }
  if (max_steps_between_outputs <= 0) {
    throw std::invalid_argument("CowellOptions.max_steps_between_outputs must be positive");
  }
}

struct CowellPropagator::Impl {
  const ForceModel* forces;
  SpacecraftProperties sc;
  TimeTT epoch;          // t = 0 of the integrator
  CowellOptions options;
  std::vector<ImpulsiveManeuver> maneuvers;  // pending, sorted by time
  std::size_t next_maneuver = 0;
  SUNContext ctx = nullptr;
  N_Vector y = nullptr;
  N_Vector abstol = nullptr;
  N_Vector dky = nullptr;
  SUNNonlinearSolver nls = nullptr;
  void* cvode = nullptr;
  double t_segment_start = 0.0;  // seconds since epoch of the last (re)init
  CowellStats stats;

  ~Impl() {
    if (cvode) CVodeFree(&cvode);
    if (nls) SUNNonlinSolFree(nls);
    if (y) N_VDestroy(y);
    if (abstol) N_VDestroy(abstol);
    if (dky) N_VDestroy(dky);
    if (ctx) SUNContext_Free(&ctx);
  }

  static int rhs(double t_s, N_Vector yv, N_Vector ydot, void* user) {
    auto* self = static_cast<Impl*>(user);
    const double* s = N_VGetArrayPointer(yv);
    double* d = N_VGetArrayPointer(ydot);
    StateVector x{astro::Vec3(s[0], s[1], s[2]), astro::Vec3(s[3], s[4], s[5])};
    if (!x.r_m.allFinite() || !x.v_mps.allFinite()) return 1;  // recoverable: CVODE retries
    astro::Vec3 a;
    try {
      a = self->forces->acceleration_eci(self->epoch.plus_seconds(t_s), x, self->sc);
    } catch (const std::exception&) {
      return -1;  // unrecoverable (e.g. below the atmosphere table: decayed)
    }
    for (int k = 0; k < 3; ++k) {
      d[k] = s[3 + k];
      d[3 + k] = a[k];
    }
    return 0;
  }

  void check(int flag, const char* what) const {
    if (flag < 0) {
      throw std::runtime_error(std::string("CVODE ") + what + " failed: " +
                               CVodeGetReturnFlagName(flag));
    }
  }

  void init(double t0_s) {
    t_segment_start = t0_s;
    if (!cvode) {
      cvode = CVodeCreate(CV_ADAMS, ctx);
      if (!cvode) throw std::runtime_error("CVodeCreate failed");
      check(CVodeInit(cvode, rhs, t0_s, y), "CVodeInit");
      check(CVodeSetUserData(cvode, this), "CVodeSetUserData");
      check(CVodeSVtolerances(cvode, options.rel_tol, abstol), "CVodeSVtolerances");
      nls = SUNNonlinSol_FixedPoint(y, 0, ctx);
      check(CVodeSetNonlinearSolver(cvode, nls), "CVodeSetNonlinearSolver");
      check(CVodeSetMaxStep(cvode, options.max_step_s), "CVodeSetMaxStep");
      check(CVodeSetNonlinConvCoef(cvode, options.nonlinear_convergence_coefficient),
            "CVodeSetNonlinConvCoef");
      check(CVodeSetMaxNonlinIters(cvode, options.max_nonlinear_iterations),
            "CVodeSetMaxNonlinIters");
      check(CVodeSetMaxNumSteps(cvode, options.max_steps_between_outputs), "CVodeSetMaxNumSteps");
    } else {
      check(CVodeReInit(cvode, t0_s, y), "CVodeReInit");
      ++stats.reinitialisations;
    }
    set_stop_time();
  }

  void set_stop_time() {
    if (next_maneuver < maneuvers.size()) {
      check(CVodeSetStopTime(cvode, seconds(maneuvers[next_maneuver].t)), "CVodeSetStopTime");
    }
    // CVODE forgets a stop time once it has returned there (CV_TSTOP_RETURN),
    // so after the last maneuver nothing needs clearing.
  }

  double seconds(TimeTT t) const { return astro::seconds_between(epoch, t); }

  double current_time() const {
    double tcur = 0.0;
    CVodeGetCurrentTime(cvode, &tcur);
    return tcur;
  }
};

CowellPropagator::CowellPropagator(const ForceModel& forces, const SpacecraftProperties& sc,
                                   TimeTT t0, const StateVector& x0,
                                   std::vector<ImpulsiveManeuver> maneuvers, CowellOptions options)
    : impl_(std::make_unique<Impl>()) {
  options.validate();
  sc.validate();
  if (!x0.r_m.allFinite() || !x0.v_mps.allFinite()) {
    throw std::invalid_argument("CowellPropagator: initial state is not finite");
  }
  std::sort(maneuvers.begin(), maneuvers.end(),
            [](const auto& a, const auto& b) { return a.t < b.t; });
  for (const auto& m : maneuvers) {
    if (m.t <= t0) {
      throw std::invalid_argument("CowellPropagator: maneuver at " + astro::utc_string(m.t) +
                                  " is not after the initial epoch " + astro::utc_string(t0));
    }
  }
  Impl& s = *impl_;
  s.forces = &forces;
  s.sc = sc;
  s.epoch = t0;
  s.options = options;
  s.maneuvers = std::move(maneuvers);
  if (SUNContext_Create(nullptr, &s.ctx) != 0) throw std::runtime_error("SUNContext_Create failed");
  s.y = N_VNew_Serial(6, s.ctx);
  s.abstol = N_VNew_Serial(6, s.ctx);
  s.dky = N_VNew_Serial(6, s.ctx);
  double* y = N_VGetArrayPointer(s.y);
  double* tol = N_VGetArrayPointer(s.abstol);
  for (int k = 0; k < 3; ++k) {
    y[k] = x0.r_m[k];
    y[3 + k] = x0.v_mps[k];
    tol[k] = options.abs_tol_m;
    tol[3 + k] = options.abs_tol_m * 1e-3;
  }
  s.init(0.0);
}

CowellPropagator::~CowellPropagator() = default;
CowellPropagator::CowellPropagator(CowellPropagator&&) noexcept = default;
CowellPropagator& CowellPropagator::operator=(CowellPropagator&&) noexcept = default;

TimeTT CowellPropagator::epoch() const { return impl_->epoch; }

CowellStats CowellPropagator::stats() const {
  CowellStats st = impl_->stats;
  long nst = 0, nfe = 0;
  CVodeGetNumSteps(impl_->cvode, &nst);
  CVodeGetNumRhsEvals(impl_->cvode, &nfe);
  st.steps += nst;
  st.rhs_evaluations += nfe;
  return st;
}

StateVector CowellPropagator::state_at(TimeTT t) {
  Impl& s = *impl_;
  const double target = s.seconds(t);
  if (target < s.t_segment_start) {
    throw std::invalid_argument("CowellPropagator::state_at: " + astro::utc_string(t) +
                                " is before the current integration segment (states are "
                                "requested in increasing time)");
  }
  // Apply every maneuver at or before t (stop exactly on each, then restart).
  while (s.next_maneuver < s.maneuvers.size() && s.seconds(s.maneuvers[s.next_maneuver].t) <= target) {
    const double tm = s.seconds(s.maneuvers[s.next_maneuver].t);
    // Single steps until CVODE lands on the stop time: it then returns y(tm)
    // with CV_TSTOP_RETURN and forgets the stop time (SUNDIALS 6.4). A
    // CV_NORMAL call with tout == tstop would interpolate instead and leave
    // the stop time armed, which makes the next segment fail.
    while (s.current_time() < tm) {
      double tret = 0.0;
      s.check(CVode(s.cvode, tm, s.y, &tret, CV_ONE_STEP), "CVode");
    }
    double* y = N_VGetArrayPointer(s.y);
    StateVector x{astro::Vec3(y[0], y[1], y[2]), astro::Vec3(y[3], y[4], y[5])};
    x = dynamics::apply_maneuver(x, s.maneuvers[s.next_maneuver].dv_rtn_mps);
    for (int k = 0; k < 3; ++k) {
      y[k] = x.r_m[k];
      y[3 + k] = x.v_mps[k];
    }
    const CowellStats before = stats();
    s.stats.steps = before.steps;
    s.stats.rhs_evaluations = before.rhs_evaluations;
    ++s.next_maneuver;
    s.init(tm);
  }
  // Step until the integrator has passed t, then interpolate.
  double tcur = s.current_time();
  while (tcur < target) {
    double tret = 0.0;
    s.check(CVode(s.cvode, target, s.y, &tret, CV_ONE_STEP), "CVode");
    tcur = s.current_time();
  }
  if (target == s.t_segment_start) {
    const double* y = N_VGetArrayPointer(s.y);
    // Right after (re)initialisation the dense output is the initial state.
    if (tcur == target) {
      return {astro::Vec3(y[0], y[1], y[2]), astro::Vec3(y[3], y[4], y[5])};
    }
  }
  s.check(CVodeGetDky(s.cvode, target, 0, s.dky), "CVodeGetDky");
  const double* d = N_VGetArrayPointer(s.dky);
  return {astro::Vec3(d[0], d[1], d[2]), astro::Vec3(d[3], d[4], d[5])};
}

}  // namespace artms::truth
