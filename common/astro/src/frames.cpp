#include "artms/astro/frames.hpp"

#include <cmath>
#include <stdexcept>

#include "artms/astro/constants.hpp"

namespace artms::astro {

Mat3 rot1(double a) {
  const double c = std::cos(a), s = std::sin(a);
  Mat3 m;
  m << 1, 0, 0, 0, c, s, 0, -s, c;
  return m;
}

Mat3 rot2(double a) {
  const double c = std::cos(a), s = std::sin(a);
  Mat3 m;
  m << c, 0, -s, 0, 1, 0, s, 0, c;
  return m;
}

Mat3 rot3(double a) {
  const double c = std::cos(a), s = std::sin(a);
  Mat3 m;
  m << c, s, 0, -s, c, 0, 0, 0, 1;
  return m;
}

Mat3 R_mod_from_eci(TimeTT t) {
  const double T = t.julian_centuries();
  // Lieske et al. (1977) precession angles in arcsec (Vallado 2013 eq. 3-89).
  const double zeta = (2306.2181 * T + 0.30188 * T * T + 0.017998 * T * T * T) * kArcsecToRad;
  const double theta = (2004.3109 * T - 0.42665 * T * T - 0.041833 * T * T * T) * kArcsecToRad;
  const double z = (2306.2181 * T + 1.09468 * T * T + 0.018203 * T * T * T) * kArcsecToRad;
  return rot3(-z) * rot2(theta) * rot3(-zeta);
}

Mat3 R_ecef_from_eci(TimeTT t, double dut1_s) {
  return rot3(gmst_rad(t, dut1_s)) * R_mod_from_eci(t);
}

Vec3 omega_earth_ecef_radps() { return {0.0, 0.0, kEarthRotation_radps}; }

StateVector ecef_from_eci(const StateVector& x, TimeTT t, double dut1_s) {
  const Mat3 R = R_ecef_from_eci(t, dut1_s);
  StateVector out;
  out.r_m = R * x.r_m;
  // Transport theorem: v_ecef = R v_eci - omega x r_ecef.
  out.v_mps = R * x.v_mps - omega_earth_ecef_radps().cross(out.r_m);
  return out;
}

StateVector eci_from_ecef(const StateVector& x, TimeTT t, double dut1_s) {
  const Mat3 R = R_ecef_from_eci(t, dut1_s);
  StateVector out;
  out.r_m = R.transpose() * x.r_m;
  out.v_mps = R.transpose() * (x.v_mps + omega_earth_ecef_radps().cross(x.r_m));
  return out;
}

Mat3 R_rtn_from_eci(const StateVector& x) {
  const Vec3 h = x.r_m.cross(x.v_mps);
  const double rn = x.r_m.norm(), hn = h.norm();
  if (!(rn > 0.0) || !(hn > 1e-12 * rn * x.v_mps.norm())) {
    throw std::invalid_argument("R_rtn_from_eci: position and velocity are zero or parallel");
  }
  const Vec3 xr = x.r_m / rn;
  const Vec3 zr = h / hn;
  const Vec3 yr = zr.cross(xr);
  Mat3 R;
  R.row(0) = xr.transpose();
  R.row(1) = yr.transpose();
  R.row(2) = zr.transpose();
  return R;
}

Mat3 R_w_from_eci(const StateVector& x) {
  const Mat3 R_rtn = R_rtn_from_eci(x);  // validates the state
  const Vec3 yw = x.v_mps.normalized();
  const Vec3 zw = R_rtn.row(2).transpose();
  const Vec3 xw = yw.cross(zw);
  Mat3 R;
  R.row(0) = xw.transpose();
  R.row(1) = yw.transpose();
  R.row(2) = zw.transpose();
  return R;
}

Mat3 R_v_from_w(Boresight boresight) {
  Mat3 R;
  if (boresight == Boresight::kPlusVelocity) {
    R << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  } else {
    R << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  }
  return R;
}

Mat3 R_v_from_eci(const StateVector& x, Boresight boresight) {
  return R_v_from_w(boresight) * R_w_from_eci(x);
}

std::array<double, 4> wxyz_from_quaternion(const Eigen::Quaterniond& q) {
  return {q.w(), q.x(), q.y(), q.z()};
}

Eigen::Quaterniond quaternion_from_wxyz(const std::array<double, 4>& wxyz) {
  return Eigen::Quaterniond(wxyz[0], wxyz[1], wxyz[2], wxyz[3]);
}

}  // namespace artms::astro
