#include "artms/bod/bod.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <limits>
#include <optional>
#include <stdexcept>

#include "artms/astro/bearing.hpp"
#include "artms/astro/constants.hpp"
#include "artms/dynamics/gve.hpp"

namespace artms::bod {

namespace {

using Vec7 = BatchModel::Vec7;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;
// The estimated components of x (all but a0 dlambda, index 2).
constexpr int kFree[6] = {0, 1, 3, 4, 5, 6};

astro::QnsElements qns(const Vec6& v) { return astro::QnsElements::from_vector(v); }

// Element differences with RAAN and u wrapped.
Vec6 element_difference(const Vec6& a, const Vec6& b) {
  Vec6 d = a - b;
  d[4] = astro::wrap_pi(d[4]);
  d[5] = astro::wrap_pi(d[5]);
  return d;
}

Vec6 osculating(const astro::QnsElements& mean, const dynamics::J2Constants& j2) {
  return dynamics::osculating_from_mean(mean, j2).as_vector();
}

astro::Vec3 position(const Vec6& elements, const dynamics::J2Constants& j2) {
  return astro::cartesian_from_qns(qns(elements), j2.gm_m3ps2).r_m;
}

Eigen::Vector2d angles(const astro::Mat3& R_v, const astro::Vec3& los_eci) {
  return astro::bearing_from_los(R_v * los_eci).as_vector();
}

Eigen::Vector2d angle_residual(const Eigen::Vector2d& meas, const Eigen::Vector2d& model) {
  return {meas[0] - model[0], astro::wrap_pi(meas[1] - model[1])};
}

// Exact inverse of paper eq. (4) as a linear map: element differences
// [da_m, dex, dey, di, dRAAN, du] of the target from its ROE, at observer a, i.
Mat6 element_difference_from_roe(double a_m, double i_rad) {
  Mat6 E = Mat6::Zero();
  const double s = std::sin(i_rad), c = std::cos(i_rad);
  E(0, 0) = a_m;        // a_t - a_o = a_o da
  E(1, 2) = 1.0;        // ex
  E(2, 3) = 1.0;        // ey
  E(3, 4) = 1.0;        // i
  E(4, 5) = 1.0 / s;    // RAAN: diy = dRAAN sin i
  E(5, 1) = 1.0;        // u: dlambda = du + dRAAN cos i
  E(5, 5) = -c / s;
  return E;
}

const double kElementStep[6] = {1.0, 1e-7, 1e-7, 1e-7, 1e-7, 1e-7};

}  // namespace

const char* to_string(Verdict v) {
  switch (v) {
    case Verdict::kUsable: return "usable";
    case Verdict::kTooFewMeasurements: return "too few measurements";
    case Verdict::kBadInput: return "bad input";
    case Verdict::kNotConverged: return "not converged";
    case Verdict::kMinimumAtEdge: return "minimum at the edge of the samples";
    case Verdict::kFlatResidualCurve: return "residual curve flat";
    case Verdict::kOutsideTolerances: return "outside tolerances";
  }
  return "?";
}

void Options::validate() const {
  auto fail = [](const std::string& field, const std::string& why) {
    throw std::invalid_argument("bod options: " + field + " " + why);
  };
  if (!(range_min_m > 0.0)) fail("range_min_m", "must be > 0");
  if (!(range_max_m > range_min_m) || !std::isfinite(range_max_m)) fail("range_max_m", "must be finite and > range_min_m");
  if (samples < 5) fail("samples", "must be >= 5");
  if (max_iterations < 1) fail("max_iterations", "must be >= 1");
  if (!(convergence_m > 0.0)) fail("convergence_m", "must be > 0");
  if (min_measurements < 7) fail("min_measurements", "must be >= 7 (six unknowns)");
  if (max_measurements < min_measurements) fail("max_measurements", "must be >= min_measurements");
  if (!(min_curve_rise_chi2 >= 0.0)) fail("min_curve_rise_chi2", "must be >= 0");
  if (!(max_residual_rms_rad > 0.0)) fail("max_residual_rms_rad", "must be > 0");
  if (!(max_a_da_m > 0.0)) fail("max_a_da_m", "must be > 0");
  if (!(max_sigma_range_fraction > 0.0)) fail("max_sigma_range_fraction", "must be > 0");
  if (!(max_sigma_a_da_m > 0.0)) fail("max_sigma_a_da_m", "must be > 0");
  if (!(correction_window > 1.0) || !std::isfinite(correction_window)) fail("correction_window", "must be finite and > 1");
  if (!(model_sigma_m >= 0.0) || !std::isfinite(model_sigma_m)) fail("model_sigma_m", "must be finite and >= 0");
  if (!(model_sigma_range_fraction >= 0.0) || !(model_sigma_range_fraction < 1.0)) {
    fail("model_sigma_range_fraction", "must be in [0, 1)");
  }
}

std::string Result::brief() const {
  char buf[320];
  if (usable()) {
    // Short: the navigator appends its decision, and event texts are bounded (bus::kEventTextChars).
    std::snprintf(buf, sizeof buf,
                  "BOD usable: %d bearings, range %.2f +- %.2f km, a*dlambda %.1f m, a*da %.1f m, RMS %.1f\" "
                  "(inflation %.1f), %d iterations",
                  measurements, range_m / 1e3, sigma_range_m / 1e3, roe_mean.dlambda * a_observer_m,
                  roe_mean.da * a_observer_m, residual_rms_rad / astro::kArcsecToRad, correlation_inflation, iterations);
    if (model_correction_rms_rad > 0.0) {
      char more[160];
      std::snprintf(more, sizeof more, "; model-corrected (%.2f\" RMS, range %.2f km before)",
                    model_correction_rms_rad / astro::kArcsecToRad, uncorrected_range_m / 1e3);
      return std::string(buf) + more;
    }
  } else {
    std::snprintf(buf, sizeof buf, "BOD not usable (%s): %s", to_string(verdict), why.c_str());
  }
  return buf;
}

BatchModel::BatchModel(std::vector<Measurement> batch, const ObserverPrior& prior, const dynamics::J2Constants& j2)
    : prior_(prior), j2_(j2) {
  const astro::QnsElements& mean0 = prior.mean;
  for (const Measurement& me : batch) {
    Precomputed p;
    p.dt_s = astro::seconds_between(prior.t_est, me.t);
    p.u_eci = me.u_eci.normalized();
    p.R_v = me.R_v_from_eci;
    p.z = angles(p.R_v, p.u_eci);
    const astro::QnsElements mean_j = dynamics::propagate_mean_j2(mean0, p.dt_s, j2);
    p.chief_osc = osculating(mean_j, j2);
    p.r_o = position(p.chief_osc, j2);
    // The observer's trajectory in its a (1 m central differences).
    astro::QnsElements mp = mean0, mm = mean0;
    mp.a_m += 1.0;
    mm.a_m -= 1.0;
    const Vec6 op = osculating(dynamics::propagate_mean_j2(mp, p.dt_s, j2), j2);
    const Vec6 om = osculating(dynamics::propagate_mean_j2(mm, p.dt_s, j2), j2);
    p.dosc_da = element_difference(op, om) / 2.0;
    p.dro_da = (position(op, j2) - position(om, j2)) / 2.0;
    // d osc / d mean at the observer (central differences) and its change
    // along the orbit.
    auto jacobian_osc = [&](const Vec6& mean) {
      Mat6 D;
      for (int k = 0; k < 6; ++k) {
        Vec6 a = mean, b = mean;
        a[k] += kElementStep[k];
        b[k] -= kElementStep[k];
        D.col(k) = element_difference(osculating(qns(a), j2), osculating(qns(b), j2)) / (2.0 * kElementStep[k]);
      }
      return D;
    };
    constexpr double kDu = 1e-3;
    Vec6 up = mean_j.as_vector(), um = up;
    up[5] += kDu;
    um[5] -= kDu;
    p.D = jacobian_osc(mean_j.as_vector());
    p.dD_du = (jacobian_osc(up) - jacobian_osc(um)) / (2.0 * kDu);
    p.EPhi = element_difference_from_roe(mean0.a_m, mean_j.i_rad) * dynamics::roe_stm_j2(mean0, p.dt_s, j2);
    auto jacobian_r = [&](const Vec6& osc) {
      Eigen::Matrix<double, 3, 6> Jr;
      for (int k = 0; k < 6; ++k) {
        Vec6 a = osc, b = osc;
        a[k] += kElementStep[k];
        b[k] -= kElementStep[k];
        Jr.col(k) = (position(a, j2) - position(b, j2)) / (2.0 * kElementStep[k]);
      }
      return Jr;
    };
    Vec6 op_u = p.chief_osc, om_u = p.chief_osc;
    op_u[5] += kDu;
    om_u[5] -= kDu;
    p.Jr = jacobian_r(p.chief_osc);
    p.dJr_du = (jacobian_r(op_u) - jacobian_r(om_u)) / (2.0 * kDu);
    p.DEPhi = p.D * p.EPhi;
    const astro::StateVector xc = astro::cartesian_from_qns(qns(p.chief_osc), j2.gm_m3ps2);
    p.t_hat = xc.r_m.cross(xc.v_mps).normalized().cross(xc.r_m.normalized());
    m_.push_back(p);
  }
}

Eigen::Vector2d BatchModel::modelled(int j, const Vec7& x, Eigen::Matrix<double, 2, 7>* S) const {
  const Precomputed& p = m_[static_cast<std::size_t>(j)];
  const double a0 = prior_.mean.a_m;
  const double da_obs = x[0] - a0;
  const Vec6 roe = x.tail<6>() / a0;
  const Vec6 dmean = p.EPhi * roe;
  const Vec6 dosc = (p.D + 0.5 * dmean[5] * p.dD_du) * dmean;
  const Vec6 el_t = p.chief_osc + p.dosc_da * da_obs + dosc;
  const astro::Vec3 los = position(el_t, j2_) - (p.r_o + p.dro_da * da_obs);
  const astro::Vec3 los_v = p.R_v * los;
  if (S) {
    const astro::Mat23 Jb = astro::bearing_jacobian_los(los_v) * p.R_v;
    // The target's position derivatives at its own phase (first order in
    // the phase difference): this keeps the curvature that makes the range
    // observable. a moves both spacecraft's elements by dosc_da.
    const Eigen::Matrix<double, 3, 6> Jr_t = p.Jr + dosc[5] * p.dJr_du;
    S->col(0) = Jb * (dosc[5] * p.dJr_du * p.dosc_da);
    S->rightCols<6>() = Jb * (Jr_t * p.DEPhi) / a0;
  }
  return astro::bearing_from_los(los_v).as_vector();
}

Eigen::Vector2d BatchModel::modelled_exact(int j, const Vec7& x, const Eigen::Matrix<double, 5, 1>& d_prior) const {
  const Precomputed& p = m_[static_cast<std::size_t>(j)];
  astro::QnsElements mean0 = prior_.mean;
  mean0.a_m = x[0];
  mean0.ex += d_prior[0];
  mean0.ey += d_prior[1];
  mean0.i_rad += d_prior[2];
  mean0.raan_rad += d_prior[3];
  mean0.u_rad += d_prior[4];
  const Vec6 roe0 = x.tail<6>() / prior_.mean.a_m;
  const astro::QnsElements chief = dynamics::propagate_mean_j2(mean0, p.dt_s, j2_);
  const Vec6 roe_j = dynamics::roe_stm_j2(mean0, p.dt_s, j2_) * roe0;
  const astro::QnsElements deputy = astro::qns_from_roe(chief, astro::Roe::from_vector(roe_j));
  const astro::Vec3 los = position(osculating(deputy, j2_), j2_) - position(osculating(chief, j2_), j2_);
  return angles(p.R_v, los);
}

namespace {

struct Fit {
  Vec7 x = Vec7::Zero();
  int iterations = 0;
  bool converged = false;
  double ss_az = 0.0, ss_el = 0.0;  // sums of squared residuals per angle
};

// Gauss-Newton on the six free components with a0 dlambda = x[2] fixed.
Fit refine_unguarded(const BatchModel& model, Vec7 x, const Options& opt) {
  Fit f;
  const int n = model.size();
  Eigen::Matrix<double, 2, 7> S;
  for (int it = 1; it <= opt.max_iterations; ++it) {
    Mat6 A = Mat6::Zero();
    Vec6 b = Vec6::Zero();
    for (int j = 0; j < n; ++j) {
      const Eigen::Vector2d dz = angle_residual(model.measured(j), model.modelled(j, x, &S));
      Eigen::Matrix<double, 2, 6> Sf;
      for (int k = 0; k < 6; ++k) Sf.col(k) = S.col(kFree[k]);
      A.noalias() += Sf.transpose() * Sf;
      b.noalias() += Sf.transpose() * dz;
    }
    const Vec6 dx = A.ldlt().solve(b);
    if (!dx.allFinite()) break;
    for (int k = 0; k < 6; ++k) x[kFree[k]] += dx[k];
    f.iterations = it;
    if (dx.cwiseAbs().maxCoeff() < opt.convergence_m) {
      f.converged = true;
      break;
    }
  }
  f.x = x;
  for (int j = 0; j < n; ++j) {
    const Eigen::Vector2d dz = angle_residual(model.measured(j), model.modelled(j, x));
    f.ss_az += dz[0] * dz[0];
    f.ss_el += dz[1] * dz[1];
  }
  if (!std::isfinite(f.ss_az + f.ss_el)) f.converged = false;
  return f;
}

// The same, with a diverged iterate (an orbit the element conversions
// refuse) reported as not converged.
Fit refine(const BatchModel& model, const Vec7& x, const Options& opt) {
  try {
    return refine_unguarded(model, x, opt);
  } catch (const std::exception&) {
    Fit f;
    f.x = x;
    f.ss_az = f.ss_el = std::numeric_limits<double>::infinity();
    return f;
  }
}

Result fail(Result r, Verdict v, std::string why) {
  r.verdict = v;
  r.why = std::move(why);
  return r;
}

}  // namespace

static Result solve_unguarded(const std::vector<Measurement>& batch_in, const ObserverPrior& prior, const Options& opt) {
  Result r;
  r.t_est = prior.t_est;
  std::vector<Measurement> batch;
  for (const auto& m : batch_in) {
    if (m.u_eci.allFinite() && m.u_eci.norm() > 0.5 && m.R_v_from_eci.allFinite()) batch.push_back(m);
  }
  std::stable_sort(batch.begin(), batch.end(), [](const auto& a, const auto& b) { return a.t < b.t; });
  r.measurements = static_cast<int>(batch.size());
  if (r.measurements < opt.min_measurements) {
    return fail(r, Verdict::kTooFewMeasurements,
                "fewer than " + std::to_string(opt.min_measurements) + " bearings (" + std::to_string(r.measurements) +
                    (batch.size() != batch_in.size() ? ", non-finite ones left out)" : ")"));
  }
  if (static_cast<int>(batch.size()) > opt.max_measurements) {
    std::vector<Measurement> thin;
    const double step = static_cast<double>(batch.size() - 1) / (opt.max_measurements - 1);
    for (int k = 0; k < opt.max_measurements; ++k) thin.push_back(batch[static_cast<std::size_t>(std::lround(k * step))]);
    batch = std::move(thin);
    r.measurements = opt.max_measurements;
  }
  if (!prior.mean.as_vector().allFinite() || !(prior.mean.a_m > 0.0) || !prior.P_prior.allFinite()) {
    return fail(r, Verdict::kBadInput, "the observer's prior elements or covariance are not finite");
  }
  std::optional<BatchModel> model_storage;
  try {
    model_storage.emplace(batch, prior, opt.j2);
  } catch (const std::exception& ex) {
    return fail(r, Verdict::kBadInput, std::string("the mean J2 model refuses the observer's orbit: ") + ex.what());
  }
  const BatchModel& model = *model_storage;
  const int n = model.size();
  const double a0 = model.a0_m();

  // dlambda's sign: ahead of the observer (+) or behind (-), from the
  // measured lines of sight.
  double along = 0.0;
  for (int j = 0; j < n; ++j) along += model.measured_los(j).dot(model.along_track(j));
  const double sign = along >= 0.0 ? 1.0 : -1.0;

  const int ns = opt.samples;
  std::vector<Fit> fits(static_cast<std::size_t>(ns));
  r.curve.resize(static_cast<std::size_t>(ns));
  const double ratio = std::pow(opt.range_max_m / opt.range_min_m, 1.0 / (ns - 1));
  for (int s = 0; s < ns; ++s) {
    const double range = opt.range_min_m * std::pow(ratio, s);
    Vec7 x0 = Vec7::Zero();
    x0[0] = a0;
    if (s > 0 && fits[static_cast<std::size_t>(s - 1)].converged) {
      // The previous solution scaled to this range: bearings depend on the
      // ROE's direction, so the scaled orbit is close to this sample's.
      x0 = fits[static_cast<std::size_t>(s - 1)].x;
      x0.tail<6>() *= ratio;
    }
    x0[2] = sign * range;
    fits[static_cast<std::size_t>(s)] = refine(model, x0, opt);
    if (!fits[static_cast<std::size_t>(s)].converged) {
      Vec7 cold = Vec7::Zero();
      cold[0] = a0;
      cold[2] = sign * range;
      const Fit again = refine(model, cold, opt);
      if (again.converged) fits[static_cast<std::size_t>(s)] = again;
    }
    const Fit& f = fits[static_cast<std::size_t>(s)];
    Sample& c = r.curve[static_cast<std::size_t>(s)];
    c.a_dlambda_m = sign * range;
    c.iterations = f.iterations;
    c.converged = f.converged;
    c.residual_rms_rad = std::sqrt((f.ss_az + f.ss_el) / (2.0 * n));
  }
  int best = -1;
  for (int s = 0; s < ns; ++s) {
    const auto& c = r.curve[static_cast<std::size_t>(s)];
    if (c.converged && (best < 0 || c.residual_rms_rad < r.curve[static_cast<std::size_t>(best)].residual_rms_rad)) best = s;
  }
  r.best_sample = best;
  if (best < 0) return fail(r, Verdict::kNotConverged, "no dlambda sample converged");
  // R_vbs from the winner's post-fit residuals (2n angles, 6 unknowns).
  const Fit& fb = fits[static_cast<std::size_t>(best)];
  const double dof = std::max(1.0, n - 3.0);
  const double floor2 = std::pow(1e-3 * astro::kArcsecToRad, 2);
  r.R_vbs = Eigen::Vector2d(std::max(fb.ss_az / dof, floor2), std::max(fb.ss_el / dof, floor2)).asDiagonal();
  for (int s = 0; s < ns; ++s) {
    const Fit& f = fits[static_cast<std::size_t>(s)];
    r.curve[static_cast<std::size_t>(s)].chi2 = f.ss_az / r.R_vbs(0, 0) + f.ss_el / r.R_vbs(1, 1);
  }
  char buf[240];
  if (best == 0 || best == ns - 1) {
    std::snprintf(buf, sizeof buf, "the smallest residual is at the %s sample (%.1f km): the range is outside [%.1f, %.1f] km",
                  best == 0 ? "nearest" : "farthest", std::abs(r.curve[static_cast<std::size_t>(best)].a_dlambda_m) / 1e3,
                  opt.range_min_m / 1e3, opt.range_max_m / 1e3);
    return fail(r, Verdict::kMinimumAtEdge, buf);
  }
  auto chi2 = [&](int s) { return r.curve[static_cast<std::size_t>(s)].chi2; };
  double rise_lo = 0.0, rise_hi = 0.0;
  for (int s = 0; s < best; ++s) rise_lo = std::max(rise_lo, chi2(s) - chi2(best));
  for (int s = best + 1; s < ns; ++s) rise_hi = std::max(rise_hi, chi2(s) - chi2(best));
  // Parabola through the minimum and its neighbours: y = A x^2 + B x + C.
  const double x1 = r.curve[static_cast<std::size_t>(best - 1)].a_dlambda_m, x2 = r.curve[static_cast<std::size_t>(best)].a_dlambda_m,
               x3 = r.curve[static_cast<std::size_t>(best + 1)].a_dlambda_m;
  const double y1 = chi2(best - 1), y2 = chi2(best), y3 = chi2(best + 1);
  const double A = ((y3 - y2) / (x3 - x2) - (y2 - y1) / (x2 - x1)) / (x3 - x1);
  if (std::min(rise_lo, rise_hi) < opt.min_curve_rise_chi2 || !(A > 0.0)) {
    std::snprintf(buf, sizeof buf, "residual curve flat: range unobservable (chi2 rises by %.2f and %.2f either side, need %.1f)",
                  rise_lo, rise_hi, opt.min_curve_rise_chi2);
    return fail(r, Verdict::kFlatResidualCurve, buf);
  }
  const double B = (y2 - y1) / (x2 - x1) - A * (x1 + x2);
  const double x_star = std::clamp(-B / (2.0 * A), std::min(x1, x3), std::max(x1, x3));
  const double var_dlambda_m2 = 1.0 / A;  // chi2 rises by 1 at one sigma
  Vec7 xs = fb.x;
  xs.tail<6>() *= x_star / x2;
  xs[2] = x_star;
  Fit fin = refine(model, xs, opt);
  if (!fin.converged) fin = fb;
  r.iterations = fin.iterations;
  r.residual_rms_rad = std::sqrt((fin.ss_az + fin.ss_el) / (2.0 * n));

  // Covariance of all seven (dlambda included, linearised at the solution):
  //   P = A^-1 (Omega + S^T Y_prior P_prior Y_prior^T S) A^-1,  A = S^T S,
  // which is the paper's P_est = Y* (N R_vbs + Y_prior P_prior Y_prior^T) Y*^T
  // (Y* = A^-1 S^T) with N R_vbs, the white post-fit residuals, generalised
  // to residuals correlated in time, as the mean model's misfit of the world
  // (gravity beyond J2, drag) is: Omega is the Newey-West estimate
  //   Omega = sum_j g_j g_j^T + sum_{k=1..L} (1 - k/(L+1)) sum_j (g_j g_{j-k}^T + g_{j-k} g_j^T),
  //   g_j = S_j^T dz_j, L = n/4 bearings (Bartlett weights, time order),
  // which is S^T R S for white residuals.
  std::vector<Vec7> gj(static_cast<std::size_t>(n));
  Mat7 A7 = Mat7::Zero(), white = Mat7::Zero();
  Eigen::Matrix<double, 7, 5> SY = Eigen::Matrix<double, 7, 5>::Zero();
  Eigen::Matrix<double, 2, 7> S;
  const Eigen::Matrix<double, 5, 1> zero5 = Eigen::Matrix<double, 5, 1>::Zero();
  constexpr double kPriorStep = 1e-7;
  for (int j = 0; j < n; ++j) {
    const Eigen::Vector2d dz = angle_residual(model.measured(j), model.modelled(j, fin.x, &S));
    A7 += S.transpose() * S;
    white += S.transpose() * r.R_vbs * S;
    gj[static_cast<std::size_t>(j)] = S.transpose() * dz;
    const Eigen::Vector2d z0 = model.modelled_exact(j, fin.x, zero5);
    Eigen::Matrix<double, 2, 5> Yp;
    for (int k = 0; k < 5; ++k) {
      Eigen::Matrix<double, 5, 1> d = zero5;
      d[k] = kPriorStep;
      Yp.col(k) = angle_residual(model.modelled_exact(j, fin.x, d), z0) / kPriorStep;
    }
    SY += S.transpose() * Yp;
  }
  Mat7 Omega = Mat7::Zero();
  const int L = std::max(1, n / 4);
  for (int j = 0; j < n; ++j) Omega += gj[static_cast<std::size_t>(j)] * gj[static_cast<std::size_t>(j)].transpose();
  for (int k = 1; k <= L; ++k) {
    const double w = 1.0 - static_cast<double>(k) / (L + 1);
    for (int j = k; j < n; ++j) {
      const Mat7 c = gj[static_cast<std::size_t>(j)] * gj[static_cast<std::size_t>(j - k)].transpose();
      Omega += w * (c + c.transpose());
    }
  }
  Omega *= (2.0 * n) / (2.0 * n - 7.0);  // 2n angles, 7 parameters
  // dlambda's variance: the profile likelihood's (the residual curve's
  // curvature; the linearised normal matrix misses the range's nonlinearity),
  // times the ratio of the correlated to the white linearised variance.
  // The other six: their covariance at fixed dlambda plus dlambda's variance
  // carried along the slope of the solution family.
  const Mat7 A7inv = A7.ldlt().solve(Mat7::Identity());
  const Mat7 prior_part = SY * prior.P_prior * SY.transpose();
  const double var7 = (A7inv * (Omega + prior_part) * A7inv)(2, 2);
  const double var7_white = (A7inv * (white + prior_part) * A7inv)(2, 2);
  r.correlation_inflation = var7_white > 0.0 ? std::max(1.0, var7 / var7_white) : 1.0;
  const double var_dlambda = var_dlambda_m2 * r.correlation_inflation +
                             std::pow(opt.model_sigma_range_fraction * x_star, 2);
  Mat6 A6, Om6, Pr6;
  for (int p = 0; p < 6; ++p) {
    for (int q = 0; q < 6; ++q) {
      A6(p, q) = A7(kFree[p], kFree[q]);
      Om6(p, q) = Omega(kFree[p], kFree[q]);
      Pr6(p, q) = prior_part(kFree[p], kFree[q]);
    }
  }
  const Mat6 A6inv = A6.ldlt().solve(Mat6::Identity());
  const Mat6 P_est = A6inv * (Om6 + Pr6) * A6inv;
  const Fit& lo = fits[static_cast<std::size_t>(best - 1)];
  const Fit& hi = fits[static_cast<std::size_t>(best + 1)];
  Vec6 g;
  for (int k = 0; k < 6; ++k) g[k] = (hi.x[kFree[k]] - lo.x[kFree[k]]) / (x3 - x1);
  Mat7 P7 = Mat7::Zero();
  for (int p = 0; p < 6; ++p) {
    for (int q = 0; q < 6; ++q) P7(kFree[p], kFree[q]) = P_est(p, q) + g[p] * g[q] * var_dlambda;
    P7(kFree[p], 2) = P7(2, kFree[p]) = g[p] * var_dlambda;
  }
  P7(2, 2) = var_dlambda;
  for (int k : {1, 3, 4, 5, 6}) P7(k, k) += opt.model_sigma_m * opt.model_sigma_m;
  P7 = 0.5 * (P7 + P7.transpose()).eval();
  if (!(P7.diagonal().minCoeff() > 0.0) || !P7.allFinite()) {
    return fail(r, Verdict::kFlatResidualCurve, "residual curve flat: range unobservable (covariance not positive)");
  }
  r.a_observer_m = fin.x[0];
  r.sigma_a_observer_m = std::sqrt(std::max(0.0, P7(0, 0)));
  r.roe_mean = astro::Roe::from_vector(fin.x.tail<6>() / a0);
  r.P_roe_mean = P7.bottomRightCorner<6, 6>() / (a0 * a0);
  r.range_m = std::abs(fin.x[2]);
  r.sigma_range_m = std::sqrt(P7(2, 2));

  const double a_da = fin.x[1], sigma_a_da = std::sqrt(std::max(0.0, P7(1, 1)));
  if (!(r.residual_rms_rad <= opt.max_residual_rms_rad)) {
    std::snprintf(buf, sizeof buf, "outside the state or uncertainty tolerances: post-fit RMS %.1f arcsec > %.1f",
                  r.residual_rms_rad / astro::kArcsecToRad, opt.max_residual_rms_rad / astro::kArcsecToRad);
    return fail(r, Verdict::kOutsideTolerances, buf);
  }
  if (!(std::abs(a_da) <= opt.max_a_da_m)) {
    std::snprintf(buf, sizeof buf, "outside the state or uncertainty tolerances: |a da| %.0f m > %.0f", std::abs(a_da),
                  opt.max_a_da_m);
    return fail(r, Verdict::kOutsideTolerances, buf);
  }
  if (!(r.sigma_range_m <= opt.max_sigma_range_fraction * r.range_m)) {
    std::snprintf(buf, sizeof buf, "outside the state or uncertainty tolerances: range 1-sigma %.1f %% of range > %.1f %%",
                  100.0 * r.sigma_range_m / r.range_m, 100.0 * opt.max_sigma_range_fraction);
    return fail(r, Verdict::kOutsideTolerances, buf);
  }
  if (!(sigma_a_da <= opt.max_sigma_a_da_m)) {
    std::snprintf(buf, sizeof buf, "outside the state or uncertainty tolerances: sigma(a da) %.1f m > %.1f", sigma_a_da,
                  opt.max_sigma_a_da_m);
    return fail(r, Verdict::kOutsideTolerances, buf);
  }
  r.verdict = Verdict::kUsable;
  r.why.clear();
  return r;
}

// The onboard numerical model's bearings minus the mean J2 theory's, for the
// solution r, at every measurement (both spacecraft from the solution's
// osculating states at t_est: the difference is what the mean theory misses
// of the onboard model along the batch).
static std::vector<Eigen::Vector2d> model_bearing_differences(const std::vector<Measurement>& batch, const ObserverPrior& prior,
                                                       const Result& r, const Options& opt) {
  astro::QnsElements chief = prior.mean;
  chief.a_m = r.a_observer_m;
  const astro::QnsElements deputy = astro::qns_from_roe(chief, r.roe_mean);
  const dynamics::GveRk4Propagator prop(*opt.onboard_forces, opt.onboard_properties);
  const dynamics::GveRk4Propagator prop_target(*opt.onboard_forces,
                                               opt.target_properties.value_or(opt.onboard_properties));
  const astro::QnsElements o0 = dynamics::osculating_from_mean(chief, opt.j2);
  const astro::QnsElements d0 = dynamics::osculating_from_mean(deputy, opt.j2);
  std::vector<std::size_t> order(batch.size());
  for (std::size_t j = 0; j < order.size(); ++j) order[j] = j;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return batch[a].t < batch[b].t; });
  std::vector<Eigen::Vector2d> dz(batch.size(), Eigen::Vector2d::Zero());
  // Outward from t_est: backward over the earlier bearings, forward over the later ones.
  auto sweep = [&](auto begin, auto end) {
    astro::QnsElements o = o0, d = d0;
    astro::TimeTT tc = prior.t_est;
    for (auto it = begin; it != end; ++it) {
      const Measurement& m = batch[*it];
      o = prop.propagate(o, tc, m.t);
      d = prop_target.propagate(d, tc, m.t);
      tc = m.t;
      const astro::Vec3 los_num = astro::cartesian_from_qns(d, opt.j2.gm_m3ps2).r_m - astro::cartesian_from_qns(o, opt.j2.gm_m3ps2).r_m;
      const double dt = astro::seconds_between(prior.t_est, m.t);
      const astro::QnsElements cj = dynamics::propagate_mean_j2(chief, dt, opt.j2);
      const Vec6 roe_j = dynamics::roe_stm_j2(chief, dt, opt.j2) * r.roe_mean.as_vector();
      const astro::QnsElements dj = astro::qns_from_roe(cj, astro::Roe::from_vector(roe_j));
      const astro::Vec3 los_j2 = position(osculating(dj, opt.j2), opt.j2) - position(osculating(cj, opt.j2), opt.j2);
      dz[*it] = angle_residual(angles(m.R_v_from_eci, los_num), angles(m.R_v_from_eci, los_j2));
    }
  };
  const auto split = std::partition_point(order.begin(), order.end(), [&](std::size_t j) { return batch[j].t < prior.t_est; });
  sweep(std::make_reverse_iterator(split), order.rend());
  sweep(split, order.end());
  return dz;
}

// Model correction (Options::onboard_forces): the measured bearings less what
// the mean theory misses of the onboard model at the usable solution r,
// solved again near r's range. r itself when the second solution is not
// usable or the correction fails.
static Result corrected_solution(const std::vector<Measurement>& batch, const ObserverPrior& prior, Result r,
                                 const Options& opt) {
  try {
    const std::vector<Eigen::Vector2d> dz = model_bearing_differences(batch, prior, r, opt);
    std::vector<Measurement> corrected = batch;
    double ss = 0.0;
    std::size_t used = 0;
    for (std::size_t j = 0; j < batch.size(); ++j) {
      const Measurement& m = batch[j];
      if (!(m.u_eci.allFinite() && m.u_eci.norm() > 0.5 && m.R_v_from_eci.allFinite() && dz[j].allFinite())) continue;
      const Eigen::Vector2d z = angles(m.R_v_from_eci, m.u_eci.normalized()) - dz[j];
      corrected[j].u_eci = m.R_v_from_eci.transpose() * astro::unit_los_from_bearing(astro::Bearing{z[0], z[1]});
      ss += dz[j].squaredNorm();
      ++used;
    }
    Options second = opt;
    const double ratio = std::pow(opt.range_max_m / opt.range_min_m, 1.0 / (opt.samples - 1));
    second.range_min_m = std::max(opt.range_min_m, r.range_m / opt.correction_window);
    second.range_max_m = std::min(opt.range_max_m, r.range_m * opt.correction_window);
    second.samples =
        std::max(5, static_cast<int>(std::ceil(std::log(second.range_max_m / second.range_min_m) / std::log(ratio))) + 1);
    Result c = solve_unguarded(corrected, prior, second);
    if (!c.usable()) return r;
    c.curve = std::move(r.curve);
    c.best_sample = r.best_sample;
    c.uncorrected_range_m = r.range_m;
    c.model_correction_rms_rad = std::sqrt(ss / (2.0 * static_cast<double>(std::max<std::size_t>(1, used))));
    return c;
  } catch (const std::exception&) {
    return r;
  }
}

Result solve(const std::vector<Measurement>& batch, const ObserverPrior& prior, const Options& opt) {
  opt.validate();
  try {
    Result r = solve_unguarded(batch, prior, opt);
    r.uncorrected_range_m = r.range_m;
    if (opt.onboard_forces == nullptr || !r.usable()) return r;
    return corrected_solution(batch, prior, std::move(r), opt);
  } catch (const std::exception& ex) {
    Result r;
    r.t_est = prior.t_est;
    r.measurements = static_cast<int>(batch.size());
    r.verdict = Verdict::kNotConverged;
    r.why = std::string("the iteration left the orbits the model can convert: ") + ex.what();
    return r;
  }
}

}  // namespace artms::bod
