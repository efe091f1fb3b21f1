// The onboard propagator ARTMS flies (paper, "Dynamics Model"): Gauss
// variational equations in osculating quasi-nonsingular elements,
// alpha_dot = G(alpha) d_R (+ mean motion in u), integrated by fixed-step
// fourth-order Runge-Kutta (30 s by default) with the shared force model.
#pragma once

#include <vector>

#include "artms/astro/elements.hpp"
#include "artms/dynamics/forces.hpp"

namespace artms::dynamics {

using astro::QnsElements;
using astro::Vec6;
using Mat63 = Eigen::Matrix<double, 6, 3>;

// G(alpha): 6x3 matrix of the GVE for [a, ex, ey, i, RAAN, u] with the
// perturbing acceleration in RTN (m/s^2). Derived from the Keplerian GVE
// (Vallado 2013 eq. 9-24) with the 1/e terms cancelled analytically, so it is
// regular at e = 0 (docs/dynamics.md). Singular at sin i = 0.
Mat63 gve_matrix(const QnsElements& oe, double gm_m3ps2 = astro::kGmEarth_m3ps2);
// d(alpha)/dt = [0 0 0 0 0 n]^T + G(alpha) d_rtn.
Vec6 qns_rates(const QnsElements& oe, const Vec3& d_rtn_mps2,
               double gm_m3ps2 = astro::kGmEarth_m3ps2);

struct GvePropagatorOptions {
  double step_s = 30.0;
  // Throws std::invalid_argument if step_s is not positive and finite.
  void validate() const;
};

class GveRk4Propagator {
 public:
  GveRk4Propagator(const ForceModel& forces, const SpacecraftProperties& sc,
                   GvePropagatorOptions options = {});

  // Propagates osculating elements from t0 to t1 (t1 >= t0 or t1 < t0) in
  // fixed steps, the last one shortened to land exactly on t1. Maneuvers
  // inside (t0, t1] are applied at their epochs (the step is split there).
  // u is kept continuous (not wrapped) during the integration and wrapped to
  // [0, 2 pi) on return.
  [[nodiscard]] QnsElements propagate(const QnsElements& oe, astro::TimeTT t0, astro::TimeTT t1,
                                      const std::vector<ImpulsiveManeuver>& maneuvers = {}) const;
  // One RK4 step of size dt_s from t.
  [[nodiscard]] Vec6 step(const Vec6& alpha, astro::TimeTT t, double dt_s) const;
  // The full state derivative at (t, alpha).
  [[nodiscard]] Vec6 derivative(const Vec6& alpha, astro::TimeTT t) const;

 private:
  const ForceModel& forces_;
  SpacecraftProperties sc_;
  GvePropagatorOptions options_;
};

}  // namespace artms::dynamics
