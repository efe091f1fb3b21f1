// Relative orbit elements (paper eq. 4), their exact inverse, the linear
// ROE -> RTN map (paper eq. 8, D'Amico 2010) and curvilinear <-> rectilinear
// relative positions (paper eq. 7).
#pragma once

#include "artms/astro/elements.hpp"

namespace artms::astro {

// Quasi-nonsingular ROE [da, dlambda, dex, dey, dix, diy], dimensionless
// (dlambda, dix, diy in radians). a_o * ROE is "a*droe" in meters.
struct Roe {
  double da = 0.0;
  double dlambda = 0.0;
  double dex = 0.0;
  double dey = 0.0;
  double dix = 0.0;
  double diy = 0.0;
  [[nodiscard]] Vec6 as_vector() const;
  static Roe from_vector(const Vec6& v);
  // From meters (a*droe) given the observer's semi-major axis.
  static Roe from_scaled_m(const Vec6& a_droe_m, double a_observer_m);
};

// Paper eq. (4): ROE of target t relative to observer o. Angle differences
// are wrapped to (-pi, pi]. Throws std::invalid_argument if a_o <= 0.
Roe roe_from_qns(const QnsElements& observer, const QnsElements& target);
// Exact inverse of eq. (4): the target's elements from the observer's and the
// ROE. Needs sin(i_o) != 0 (throws std::invalid_argument when |sin i_o| < 1e-9).
QnsElements qns_from_roe(const QnsElements& observer, const Roe& roe);

// Linear map from ROE to the relative state in the observer's RTN frame for a
// near-circular observer orbit (D'Amico 2010; Sullivan et al. 2020):
//   r_R = a (da - dex cos u - dey sin u)
//   r_T = a (dlambda + 2 dex sin u - 2 dey cos u)
//   r_N = a (dix sin u - diy cos u)
//   v_R = a n (dex sin u - dey cos u)
//   v_T = a n (-1.5 da + 2 dex cos u + 2 dey sin u)
//   v_N = a n (dix cos u + diy sin u)
// with u the observer's mean argument of latitude. The position it returns is
// the curvilinear position (dr, a*Theta, a*Phi) of the paper. The paper's
// printed eq. (8) differs (no -dey sin u in R, a -1.5 da term in T): see
// docs/conventions.md for why and the test that decides it.
StateVector rtn_from_roe_linear(const Roe& roe, double a_observer_m, double u_observer_rad,
                                double gm_m3ps2 = kGmEarth_m3ps2);
// 6x6 Jacobian of the map above: d[r_rtn; v_rtn] / d[roe].
Mat6 rtn_from_roe_linear_jacobian(double a_observer_m, double u_observer_rad,
                                  double gm_m3ps2 = kGmEarth_m3ps2);

// Curvilinear relative position (dr, r_o*Theta, r_o*Phi) <-> rectilinear RTN
// position (paper eq. 7), with r_o the observer's orbit radius (a_o in the
// paper, which assumes a circular orbit).
Vec3 rectilinear_from_curvilinear(const Vec3& curv_m, double r_observer_m);
Vec3 curvilinear_from_rectilinear(const Vec3& rect_m, double r_observer_m);

// Exact relative position of the target in the observer's RTN frame from two
// ECI states, rectilinear and curvilinear.
Vec3 relative_rtn_rectilinear(const StateVector& observer_eci, const StateVector& target_eci);
Vec3 relative_rtn_curvilinear(const StateVector& observer_eci, const StateVector& target_eci);

}  // namespace artms::astro
