// Truth propagation: Cowell's method in ECI integrated with SUNDIALS CVODE
// (Adams-Moulton, fixed-point iteration), one integrator per spacecraft.
// States at arbitrary epochs come from CVODE's dense output (CVodeGetDky)
// without restarting the integrator; maneuvers stop the integrator exactly at
// their epoch (CVodeSetStopTime), apply the delta-v and re-initialise.
// Only the truth service and evaluation tools link this library.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "artms/astro/frames.hpp"
#include "artms/astro/time.hpp"
#include "artms/dynamics/forces.hpp"

namespace artms::truth {

using astro::StateVector;
using astro::TimeTT;
using dynamics::ForceModel;
using dynamics::ImpulsiveManeuver;
using dynamics::SpacecraftProperties;

struct CowellOptions {
  // CVODE tolerances. Position components get abs_tol_m, velocity components
  // abs_tol_m / 1000 s; the relative tolerance dominates for orbits. The
  // corrector of the Adams method (fixed-point iteration) is converged much
  // tighter than CVODE's default (0.1): with the default, CVODE's global
  // error is erratic and ~100x larger at equal cost. docs/dynamics.md has the
  // study behind these values (two-body, 30 days: energy to ~1e-11).
  double rel_tol = 1e-14;
  double abs_tol_m = 1e-9;
  double nonlinear_convergence_coefficient = 1e-3;
  int max_nonlinear_iterations = 10;
  double max_step_s = 300.0;
  long max_steps_between_outputs = 100000;
  void validate() const;  // throws std::invalid_argument naming the field
};

// Counters from CVODE, for diagnostics and benchmarks.
struct CowellStats {
  long steps = 0;
  long rhs_evaluations = 0;
  long reinitialisations = 0;
};

class CowellPropagator {
 public:
  // forces must outlive the propagator. Maneuvers may be in any order; those
  // at or before t0 are rejected (std::invalid_argument).
  CowellPropagator(const ForceModel& forces, const SpacecraftProperties& sc, TimeTT t0,
                   const StateVector& x0_eci, std::vector<ImpulsiveManeuver> maneuvers = {},
                   CowellOptions options = {});
  ~CowellPropagator();
  CowellPropagator(const CowellPropagator&) = delete;
  CowellPropagator& operator=(const CowellPropagator&) = delete;
  CowellPropagator(CowellPropagator&&) noexcept;
  CowellPropagator& operator=(CowellPropagator&&) noexcept;

  // State at t (t >= the last maneuver already applied; t may go back inside
  // the last integration step). Interpolates CVODE's dense output. Throws
  // std::runtime_error with CVODE's flag on an integration failure.
  StateVector state_at(TimeTT t);

  [[nodiscard]] TimeTT epoch() const;
  [[nodiscard]] CowellStats stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace artms::truth
