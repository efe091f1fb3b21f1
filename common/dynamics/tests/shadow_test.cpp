#include "artms/dynamics/shadow.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "artms/astro/constants.hpp"
#include "artms/dynamics/ephemeris.hpp"
#include "artms/testing/testing.hpp"

namespace artms::dynamics {
namespace {

using artms::testing::IsNearMatrix;
using astro::kDegToRad;
using astro::kRadiusEarth_m;

constexpr double kLeoRadius_m = kRadiusEarth_m + 500e3;

// A realistic Sun: the 2024-05-08 position from the ephemeris.
Vec3 test_sun() {
  return sun_position_eci_m(astro::tt_from_utc_string("2024-05-08T00:00:00Z"));
}

// Orthonormal pair (e_sun, e_perp) spanning a plane through the Sun line.
Vec3 perpendicular_to(const Vec3& e) {
  return e.cross(Vec3::UnitZ()).normalized();
}

TEST(Shadow, FullSunOnTheDaySide) {
  const Vec3 sun = test_sun();
  const Vec3 e_sun = sun.normalized();
  const Vec3 e_perp = perpendicular_to(e_sun);
  for (const Vec3& r : {Vec3(kLeoRadius_m * e_sun), Vec3(kLeoRadius_m * e_perp),
                        Vec3(kLeoRadius_m * (e_sun + e_perp).normalized())}) {
    EXPECT_EQ(sunlit_fraction(r, sun, ShadowModel::kConical), 1.0);
    EXPECT_EQ(sunlit_fraction(r, sun, ShadowModel::kCylindrical), 1.0);
  }
}

TEST(Shadow, UmbraDeepBehindTheEarth) {
  const Vec3 sun = test_sun();
  const Vec3 e_sun = sun.normalized();
  const Vec3 e_perp = perpendicular_to(e_sun);
  for (const Vec3& r :
       {Vec3(-kLeoRadius_m * e_sun), Vec3(kLeoRadius_m * (-e_sun + 0.5 * e_perp).normalized())}) {
    EXPECT_EQ(sunlit_fraction(r, sun, ShadowModel::kConical), 0.0);
    EXPECT_EQ(sunlit_fraction(r, sun, ShadowModel::kCylindrical), 0.0);
  }
}

TEST(Shadow, SunCentreOnTheEarthLimbIsAboutHalfLit) {
  // Satellite placed so that its line of sight to the Sun's centre grazes the
  // Earth: r = R_E n - L d, Sun at r + 1 AU d with n perpendicular to d. The
  // Earth's limb then bisects the solar disc up to the limb's curvature
  // (Sun radius 0.27 deg against an Earth radius of ~65 deg as seen from LEO).
  const Vec3 d = Vec3(1.0, 0.3, -0.2).normalized();
  const Vec3 n = d.cross(Vec3::UnitZ()).normalized();
  const Vec3 r = kRadiusEarth_m * n - 3000e3 * d;
  const Vec3 sun = r + kAstronomicalUnit_m * d;
  const double nu = sunlit_fraction(r, sun, ShadowModel::kConical);
  EXPECT_NEAR(nu, 0.5, 0.01);
}

TEST(Shadow, AnnularOccultationFarBehindTheEarth) {
  // 3 million km down the anti-Sun axis the Earth (0.12 deg) looks smaller
  // than the Sun (0.26 deg) and sits centred on it: nu = 1 - b^2 / a^2.
  const Vec3 sun(kAstronomicalUnit_m, 0, 0);
  const Vec3 r(-3e9, 0, 0);
  const double a = std::asin(kRadiusSun_m / (kAstronomicalUnit_m + 3e9));
  const double b = std::asin(kRadiusEarth_m / 3e9);
  EXPECT_NEAR(sunlit_fraction(r, sun), 1.0 - (b * b) / (a * a), 1e-12);
  EXPECT_EQ(sunlit_fraction(r, sun, ShadowModel::kCylindrical), 0.0);
}

TEST(Shadow, PenumbraIsPartialAndMonotonicAcrossTheBoundary) {
  // Walk a circular LEO orbit lying in a plane that contains the Sun line,
  // from deep shadow (anti-Sun) towards the day side, through the exit
  // boundary of the shadow. The conical fraction must rise monotonically
  // from 0 to 1 with several strictly partial samples in between.
  const Vec3 sun = test_sun();
  const Vec3 e_sun = sun.normalized();
  const Vec3 e_perp = perpendicular_to(e_sun);
  // Cylinder boundary at angle theta_b from the anti-Sun direction.
  const double theta_b = std::asin(kRadiusEarth_m / kLeoRadius_m);
  std::vector<double> nu;
  int partial = 0;
  for (double dtheta = -1.0; dtheta <= 1.0; dtheta += 0.002) {
    const double theta = theta_b + dtheta * kDegToRad;
    const Vec3 r = kLeoRadius_m * (-std::cos(theta) * e_sun + std::sin(theta) * e_perp);
    const double f = sunlit_fraction(r, sun, ShadowModel::kConical);
    ASSERT_GE(f, 0.0);
    ASSERT_LE(f, 1.0);
    if (!nu.empty()) {
      EXPECT_GE(f, nu.back()) << "dtheta " << dtheta << " deg";
    }
    if (f > 0.0 && f < 1.0) ++partial;
    nu.push_back(f);
  }
  EXPECT_EQ(nu.front(), 0.0);
  EXPECT_EQ(nu.back(), 1.0);
  // Penumbra from LEO spans ~0.5 deg of the Sun's diameter over the limb's
  // angular rate: expect tens of samples at 0.002 deg spacing.
  EXPECT_GT(partial, 20);
}

TEST(Shadow, CylindricalAndConicalAgreeAwayFromTheBoundary) {
  const Vec3 sun = test_sun();
  const Vec3 e_sun = sun.normalized();
  std::mt19937_64 rng(42);
  std::normal_distribution<double> gauss;
  std::uniform_real_distribution<double> radius(kRadiusEarth_m + 300e3, kRadiusEarth_m + 1500e3);
  int compared = 0, shadowed = 0;
  for (int k = 0; k < 5000; ++k) {
    const Vec3 r = radius(rng) * Vec3(gauss(rng), gauss(rng), gauss(rng)).normalized();
    const double along = r.dot(e_sun);
    const double perp = (r - along * e_sun).norm();
    // Penumbra and umbra cones depart from the cylinder by the distance
    // behind the terminator (< 4700 km here) times the Sun's apparent radius
    // (0.27 deg), < 25 km; keep 50 km away from the boundary.
    if (along < 0.0 && std::abs(perp - kRadiusEarth_m) < 50e3) continue;
    const double cyl = sunlit_fraction(r, sun, ShadowModel::kCylindrical);
    const double con = sunlit_fraction(r, sun, ShadowModel::kConical);
    EXPECT_EQ(cyl, con) << "r = " << r.transpose();
    ++compared;
    if (cyl == 0.0) ++shadowed;
  }
  EXPECT_GT(compared, 4500);
  EXPECT_GT(shadowed, 500);
}

TEST(Shadow, SrpAtOneAuEqualsPressureTimesCrTimesAreaToMass) {
  const Vec3 d = Vec3(0.3, -0.8, 0.5).normalized();  // satellite -> Sun
  const Vec3 r = 7000e3 * d;                         // day side
  const Vec3 sun = r + kAstronomicalUnit_m * d;      // exactly 1 AU away
  const double cr = 1.3, am = 0.02;
  const Vec3 a = srp_acceleration_mps2(r, sun, cr, am);
  const Vec3 expected = -kSolarPressureAt1Au_Npm2 * cr * am * d;
  EXPECT_THAT(a, IsNearMatrix(expected, 1e-12 * expected.norm()));
  // Inverse square with distance: at 2 AU a quarter.
  const Vec3 a2 = srp_acceleration_mps2(r, r + 2.0 * kAstronomicalUnit_m * d, cr, am);
  EXPECT_NEAR(a2.norm(), 0.25 * expected.norm(), 1e-12 * expected.norm());
}

TEST(Shadow, SrpScalesWithTheSunlitFraction) {
  const Vec3 sun = test_sun();
  const Vec3 e_sun = sun.normalized();
  EXPECT_EQ(srp_acceleration_mps2(-kLeoRadius_m * e_sun, sun, 1.3, 0.02).norm(), 0.0);
  // Halfway into the limb (see SunCentreOnTheEarthLimbIsAboutHalfLit).
  const Vec3 d = Vec3(1.0, 0.3, -0.2).normalized();
  const Vec3 r = kRadiusEarth_m * d.cross(Vec3::UnitZ()).normalized() - 3000e3 * d;
  const Vec3 s = r + kAstronomicalUnit_m * d;
  const double nu = sunlit_fraction(r, s);
  const Vec3 a = srp_acceleration_mps2(r, s, 1.3, 0.02);
  EXPECT_NEAR(a.norm(), nu * kSolarPressureAt1Au_Npm2 * 1.3 * 0.02, 1e-20);
  EXPECT_NEAR(a.normalized().dot(-d), 1.0, 1e-12);
}

}  // namespace
}  // namespace artms::dynamics
