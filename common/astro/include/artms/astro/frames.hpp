// Reference frames. Matrices are named R_<to>_from_<from>: v_to = R * v_from.
// Quaternions (Eigen::Quaterniond) are named the same way, q_<to>_from_<from>,
// and satisfy q.toRotationMatrix() == R_<to>_from_<from> (docs/conventions.md).
#pragma once

#include <array>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "artms/astro/time.hpp"

namespace artms::astro {

using Vec3 = Eigen::Vector3d;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat3 = Eigen::Matrix3d;
using Mat6 = Eigen::Matrix<double, 6, 6>;

// Cartesian state (position, velocity) in one frame, SI units.
struct StateVector {
  Vec3 r_m = Vec3::Zero();
  Vec3 v_mps = Vec3::Zero();
  [[nodiscard]] Vec6 stacked() const {
    Vec6 x;
    x << r_m, v_mps;
    return x;
  }
  static StateVector from_stacked(const Vec6& x) { return {x.head<3>(), x.tail<3>()}; }
};

// Coordinate (passive) rotations about axis 1, 2, 3 by angle a: the matrix
// that maps components in the old frame to components in a frame rotated by
// +a about that axis (Vallado's ROT1/ROT2/ROT3).
Mat3 rot1(double a_rad);
Mat3 rot2(double a_rad);
Mat3 rot3(double a_rad);

// IAU 1976 precession, J2000 -> mean equator and equinox of date
// (Vallado 2013 eq. 3-88 with Lieske's angles, eq. 3-89).
Mat3 R_mod_from_eci(TimeTT t);

// ECI (J2000) -> ECEF: R3(GMST_1982) * P_1976. Nutation (< 20 arcsec) and
// polar motion (< 0.5 arcsec) are neglected; see docs/conventions.md.
Mat3 R_ecef_from_eci(TimeTT t, double dut1_s = 0.0);
// Angular velocity of ECEF relative to ECI, in ECEF components (rad/s).
Vec3 omega_earth_ecef_radps();
StateVector ecef_from_eci(const StateVector& x_eci, TimeTT t, double dut1_s = 0.0);
StateVector eci_from_ecef(const StateVector& x_ecef, TimeTT t, double dut1_s = 0.0);

// RTN frame R of a spacecraft (paper, "Measurement Model"): x along r,
// z along h = r x v, y = z x x. Throws std::invalid_argument if r and v are
// parallel or zero.
Mat3 R_rtn_from_eci(const StateVector& x_eci);
// Velocity-aligned frame W: y along v, z = z_R, x = y x z.
Mat3 R_w_from_eci(const StateVector& x_eci);

// Camera frame V with boresight z_V along +y_W (kPlusVelocity) or -y_W
// (kMinusVelocity, "anti-velocity"). x_V = x_W in both cases, y_V = z_V x x_V:
// +v: V = [x_W, -z_W, +y_W];  -v: V = [x_W, +z_W, -y_W] (rows of R_v_from_w).
enum class Boresight { kPlusVelocity, kMinusVelocity };
Mat3 R_v_from_w(Boresight boresight);
Mat3 R_v_from_eci(const StateVector& x_eci, Boresight boresight);

// Quaternion text/wire form: [w, x, y, z], scalar first. Eigen's coeffs() is
// [x, y, z, w], so always go through these two.
std::array<double, 4> wxyz_from_quaternion(const Eigen::Quaterniond& q);
Eigen::Quaterniond quaternion_from_wxyz(const std::array<double, 4>& wxyz);

}  // namespace artms::astro
