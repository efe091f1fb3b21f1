#include "artms/astro/bearing.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "artms/astro/roe.hpp"

namespace artms::astro {

Bearing bearing_from_los(const Vec3& los) {
  const double rho = los.norm();
  if (!(rho > 0.0)) throw std::invalid_argument("bearing_from_los: zero line of sight");
  return {std::asin(std::clamp(los.y() / rho, -1.0, 1.0)), std::atan2(los.x(), los.z())};
}

Vec3 unit_los_from_bearing(const Bearing& b) {
  // Inverse of eq. (2): y = sin(az); (x, z) = cos(az) (sin el, cos el).
  const double ca = std::cos(b.az_rad);
  return {ca * std::sin(b.el_rad), std::sin(b.az_rad), ca * std::cos(b.el_rad)};
}

Mat23 bearing_jacobian_los(const Vec3& los) {
  const double x = los.x(), y = los.y(), z = los.z();
  const double s2 = x * x + z * z;
  if (!(s2 > 0.0)) throw std::domain_error("bearing_jacobian_los: los along the y axis");
  const double s = std::sqrt(s2);
  const double rho2 = s2 + y * y;
  Mat23 J;
  // d asin(y/rho) = (rho/s) d(y/rho);  d atan2(x, z) = (z dx - x dz) / s^2.
  J << -x * y / (s * rho2), s / rho2, -z * y / (s * rho2),  //
      z / s2, 0.0, -x / s2;
  return J;
}

Bearing bearing_from_eci(const Vec3& r_o, const Vec3& r_t, const Mat3& R_v_from_eci) {
  return bearing_from_los(R_v_from_eci * (r_t - r_o));
}

Mat23 bearing_jacobian_target_eci(const Vec3& r_o, const Vec3& r_t, const Mat3& R_v_from_eci) {
  return bearing_jacobian_los(R_v_from_eci * (r_t - r_o)) * R_v_from_eci;
}

Mat26 bearing_jacobian_roe_linear(const Vec6& roe, double a, double u, const Mat3& R_v_from_rtn) {
  const Mat6 J_map = rtn_from_roe_linear_jacobian(a, u);
  const Vec3 r_rtn = J_map.topRows<3>() * roe;
  return bearing_jacobian_los(R_v_from_rtn * r_rtn) * R_v_from_rtn * J_map.topRows<3>();
}

}  // namespace artms::astro
