#include "artms/astro/frames.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "artms/astro/constants.hpp"
#include "artms/testing/testing.hpp"

namespace artms::astro {
namespace {

using artms::testing::IsNearMatrix;

constexpr double kOrthoTol = 1e-14;

void expect_rotation(const Mat3& R) {
  EXPECT_THAT(Mat3(R * R.transpose()), IsNearMatrix(Mat3::Identity(), kOrthoTol));
  EXPECT_NEAR(R.determinant(), 1.0, kOrthoTol);
}

TEST(Frames, PassiveRotationsMapComponentsIntoRotatedFrame) {
  // Frame rotated +90 deg about z: the old x axis has components (0, -1, 0).
  EXPECT_THAT(Vec3(rot3(kPi / 2) * Vec3::UnitX()), IsNearMatrix(Vec3(0, -1, 0), 1e-15));
  EXPECT_THAT(Vec3(rot1(kPi / 2) * Vec3::UnitY()), IsNearMatrix(Vec3(0, 0, -1), 1e-15));
  EXPECT_THAT(Vec3(rot2(kPi / 2) * Vec3::UnitZ()), IsNearMatrix(Vec3(-1, 0, 0), 1e-15));
}

TEST(Frames, PrecessionMatchesVallado315) {
  // Vallado (2013) Example 3-15, 2004-04-06 07:51:28.386009 UTC: J2000 -> MOD.
  const TimeTT t = tt_from_utc_string("2004-04-06T07:51:28.386009Z");
  const Vec3 r_j2000_km(5102.5096, 6123.01152, 6378.1363);
  const Vec3 r_mod_km(5094.0283745, 6127.8708164, 6380.2485164);
  // The book's J2000 vector is rounded to 0.1 m - 1 m; 2 m covers it.
  EXPECT_LT((R_mod_from_eci(t) * r_j2000_km - r_mod_km).norm(), 2e-3);
}

TEST(Frames, EcefRoundTripAndEarthFixedPoint) {
  const TimeTT t = tt_from_utc_string("2024-05-08T00:00:00Z");
  const StateVector x{Vec3(6.9e6, -1.2e6, 0.4e6), Vec3(100.0, 7400.0, 1200.0)};
  const StateVector back = eci_from_ecef(ecef_from_eci(x, t), t);
  EXPECT_LT((back.r_m - x.r_m).norm(), 1e-8);
  EXPECT_LT((back.v_mps - x.v_mps).norm(), 1e-11);
  expect_rotation(R_ecef_from_eci(t));

  // A point at rest on the equator moves at omega * R in ECI.
  const StateVector ground{Vec3(kRadiusEarth_m, 0, 0), Vec3::Zero()};
  const StateVector g_eci = eci_from_ecef(ground, t);
  EXPECT_NEAR(g_eci.v_mps.norm(), kEarthRotation_radps * kRadiusEarth_m, 1e-9);
  EXPECT_NEAR(g_eci.v_mps.dot(g_eci.r_m), 0.0, 1e-3);
}

TEST(Frames, EcefRotatesAtSiderealRate) {
  const TimeTT t0 = tt_from_utc_string("2024-02-05T00:00:00Z");
  const TimeTT t1 = t0.plus_seconds(3600.0);
  const Mat3 dR = R_ecef_from_eci(t1) * R_ecef_from_eci(t0).transpose();
  const double angle = std::atan2(dR(0, 1), dR(0, 0));
  // One hour: 15.041 deg (GMST rate incl. precession in right ascension).
  EXPECT_NEAR(angle, kEarthRotation_radps * 3600.0, 2e-7);
}

TEST(Frames, RtnWAndCameraFrames) {
  // Circular, equatorial, prograde at r = x: RTN = W = identity.
  const StateVector circ{Vec3(7e6, 0, 0), Vec3(0, 7546.0, 0)};
  EXPECT_THAT(R_rtn_from_eci(circ), IsNearMatrix(Mat3::Identity(), 1e-15));
  EXPECT_THAT(R_w_from_eci(circ), IsNearMatrix(Mat3::Identity(), 1e-15));

  std::mt19937 rng(3);
  std::normal_distribution<double> n(0, 1);
  for (int k = 0; k < 100; ++k) {
    const StateVector x{7e6 * Vec3(n(rng), n(rng), n(rng)).normalized(),
                        7.5e3 * Vec3(n(rng), n(rng), n(rng)).normalized()};
    const Mat3 R = R_rtn_from_eci(x);
    expect_rotation(R);
    EXPECT_NEAR((R * x.r_m).x(), x.r_m.norm(), 1e-6);
    EXPECT_NEAR((R * x.r_m).tail<2>().norm(), 0.0, 1e-6);
    EXPECT_NEAR((R * x.v_mps).z(), 0.0, 1e-9);
    const Mat3 W = R_w_from_eci(x);
    expect_rotation(W);
    EXPECT_NEAR((W * x.v_mps).y(), x.v_mps.norm(), 1e-9);
    for (Boresight b : {Boresight::kPlusVelocity, Boresight::kMinusVelocity}) {
      const Mat3 V = R_v_from_eci(x, b);
      expect_rotation(V);
      const double sign = b == Boresight::kPlusVelocity ? 1.0 : -1.0;
      EXPECT_NEAR((V * x.v_mps.normalized()).z(), sign, 1e-12);
    }
  }
  EXPECT_THROW(R_rtn_from_eci(StateVector{Vec3(7e6, 0, 0), Vec3(10, 0, 0)}),
               std::invalid_argument);
}

}  // namespace
}  // namespace artms::astro
