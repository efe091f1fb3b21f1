// Pins every convention of docs/conventions.md: if one of these fails, a
// convention changed and every consumer must be checked.
#include <gtest/gtest.h>

#include "artms/astro/bearing.hpp"
#include "artms/astro/elements.hpp"
#include "artms/astro/frames.hpp"
#include "artms/astro/roe.hpp"
#include "artms/astro/time.hpp"
#include "artms/testing/testing.hpp"

namespace artms::astro {
namespace {

using artms::testing::IsNearMatrix;
using artms::testing::IsNearQuaternion;

// Quaternions: q_b_from_a is an Eigen::Quaterniond with
// q.toRotationMatrix() == R_b_from_a, so v_b = q * v_a. Text and wire carry
// [w, x, y, z] (scalar first). Eigen's coeffs() is [x, y, z, w]: never
// serialise it directly.
TEST(Conventions, QuaternionScalarFirstMapsAIntoB) {
  // Frame b = frame a rotated +90 deg about z: x_a has b-components (0, -1, 0).
  const Mat3 R_b_from_a = rot3(kPi / 2);
  const Eigen::Quaterniond q_b_from_a(R_b_from_a);
  EXPECT_THAT(Mat3(q_b_from_a.toRotationMatrix()), IsNearMatrix(R_b_from_a, 1e-15));
  EXPECT_THAT(Vec3(q_b_from_a * Vec3::UnitX()), IsNearMatrix(Vec3(0, -1, 0), 1e-15));
  const auto wxyz = wxyz_from_quaternion(q_b_from_a);
  EXPECT_NEAR(wxyz[0], std::cos(kPi / 4), 1e-15);   // scalar first
  EXPECT_NEAR(wxyz[3], -std::sin(kPi / 4), 1e-15);  // frame rotation +90 deg = vector rotation -90
  EXPECT_THAT(quaternion_from_wxyz(wxyz), IsNearQuaternion(q_b_from_a, 1e-15));
  // Composition: q_c_from_a = q_c_from_b * q_b_from_a.
  const Eigen::Quaterniond q_c_from_b(rot1(0.3));
  EXPECT_THAT(Mat3((q_c_from_b * q_b_from_a).toRotationMatrix()),
              IsNearMatrix(Mat3(rot1(0.3) * R_b_from_a), 1e-15));
}

TEST(Conventions, TimeIsTtNanosecondsSinceJ2000) {
  EXPECT_EQ(tt_from_utc_string("2000-01-01T11:58:55.816Z").ns_since_j2000, 0);
}

TEST(Conventions, RtnAndCameraAxes) {
  // Circular equatorial prograde orbit at r = +x: R = T = N = identity,
  // W = RTN; anti-velocity camera looks along -y_ECI with x_V = x_ECI.
  const StateVector x{Vec3(7e6, 0, 0), Vec3(0, 7.5e3, 0)};
  const Mat3 V = R_v_from_eci(x, Boresight::kMinusVelocity);
  EXPECT_THAT(Vec3(V.row(2).transpose()), IsNearMatrix(Vec3(0, -1, 0), 1e-15));
  EXPECT_THAT(Vec3(V.row(0).transpose()), IsNearMatrix(Vec3(1, 0, 0), 1e-15));
  EXPECT_THAT(Vec3(V.row(1).transpose()), IsNearMatrix(Vec3(0, 0, 1), 1e-15));
  const Mat3 Vp = R_v_from_eci(x, Boresight::kPlusVelocity);
  EXPECT_THAT(Vec3(Vp.row(2).transpose()), IsNearMatrix(Vec3(0, 1, 0), 1e-15));
  EXPECT_THAT(Vec3(Vp.row(1).transpose()), IsNearMatrix(Vec3(0, 0, -1), 1e-15));
}

TEST(Conventions, QnsElementsAndRoeDefinitions) {
  const KeplerElements k{7e6, 0.01, 1.0, 0.5, 0.3, 0.2};
  const QnsElements q = qns_from_kepler(k);
  EXPECT_DOUBLE_EQ(q.ex, 0.01 * std::cos(0.3));
  EXPECT_DOUBLE_EQ(q.ey, 0.01 * std::sin(0.3));
  EXPECT_DOUBLE_EQ(q.u_rad, 0.5);  // argp + M
  // A target 1 km ahead along-track, same orbit otherwise: dlambda = 1000 / a > 0.
  QnsElements t = q;
  t.u_rad += 1000.0 / q.a_m;
  EXPECT_NEAR(roe_from_qns(q, t).dlambda * q.a_m, 1000.0, 1e-9);
}

TEST(Conventions, BearingAnglesEquation2) {
  // Azimuth from the y_V component, elevation from x_V over z_V.
  const Bearing b = bearing_from_los(Vec3(0.1, 0.2, 1.0));
  EXPECT_DOUBLE_EQ(b.az_rad, std::asin(0.2 / Vec3(0.1, 0.2, 1.0).norm()));
  EXPECT_DOUBLE_EQ(b.el_rad, std::atan(0.1 / 1.0));
}

}  // namespace
}  // namespace artms::astro
