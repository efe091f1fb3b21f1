// Bearing-angle measurement model, paper eq. (2), with analytic Jacobians.
// los_v = line of sight observer -> target in camera frame V components.
//   azimuth   alpha   = asin(los_y / |los|)
//   elevation epsilon = atan(los_x / los_z)   (atan2(los_x, los_z) here)
#pragma once

#include <Eigen/Core>

#include "artms/astro/frames.hpp"

namespace artms::astro {

using Vec2 = Eigen::Vector2d;
using Mat23 = Eigen::Matrix<double, 2, 3>;
using Mat26 = Eigen::Matrix<double, 2, 6>;

struct Bearing {
  double az_rad = 0.0;
  double el_rad = 0.0;
  [[nodiscard]] Vec2 as_vector() const { return {az_rad, el_rad}; }
};

// Eq. (2). Throws std::invalid_argument for a zero line of sight.
Bearing bearing_from_los(const Vec3& los_v);
// Unit line of sight in V from bearing angles (inverse of eq. 2).
Vec3 unit_los_from_bearing(const Bearing& b);

// d[az, el] / d[los_v] (2x3). Singular when los_x = los_z = 0 (target at
// 90 deg azimuth); throws std::domain_error there.
Mat23 bearing_jacobian_los(const Vec3& los_v);

// Chained to absolute ECI positions, attitude held fixed:
// los_v = R_v_from_eci (r_target - r_observer).
Bearing bearing_from_eci(const Vec3& r_observer_eci_m, const Vec3& r_target_eci_m,
                         const Mat3& R_v_from_eci);
// d[az, el] / d[r_target_eci]; the derivative w.r.t. r_observer_eci is minus it.
Mat23 bearing_jacobian_target_eci(const Vec3& r_observer_eci_m, const Vec3& r_target_eci_m,
                                  const Mat3& R_v_from_eci);

// Chained to the relative orbit through the linear ROE map (roe.hpp):
// los_v = R_v_from_rtn * rtn_from_roe_linear(roe).position.
// Returns d[az, el] / d[roe] (2x6, per unit ROE).
Mat26 bearing_jacobian_roe_linear(const Vec6& roe, double a_observer_m, double u_observer_rad,
                                  const Mat3& R_v_from_rtn);

}  // namespace artms::astro
