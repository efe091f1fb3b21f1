#include "artms/astro/aberration.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "artms/astro/constants.hpp"

namespace artms::astro {
namespace {

double angle(const Vec3& a, const Vec3& b) { return std::atan2(a.cross(b).norm(), a.dot(b)); }

TEST(Aberration, NoVelocityNoShift) {
  const Vec3 u = Vec3(0.3, -0.4, 0.8).normalized();
  EXPECT_LT(angle(aberrated_direction(u, Vec3::Zero()), u), 1e-15);
}

TEST(Aberration, AnnualShiftIsVOverCTimesTheSineOfTheAngleToTheApex) {
  // 29.8 km/s (the Earth about the Sun): 20.5" at 90 deg from the apex
  // (the constant of aberration), none towards it, toward the apex always.
  const Vec3 v(29.8e3, 0.0, 0.0);
  for (const double theta_deg : {0.0, 30.0, 90.0, 150.0, 180.0}) {
    const double th = theta_deg * kDegToRad;
    const Vec3 u(std::cos(th), std::sin(th), 0.0);
    const Vec3 app = aberrated_direction(u, v);
    const double expected = v.norm() / kSpeedOfLight_mps * std::sin(th);  // first order
    EXPECT_NEAR(angle(app, u), expected, 5e-3 * kArcsecToRad) << theta_deg;  // second order: (v/c)^2 ~ 0.002"
    if (theta_deg > 0.0 && theta_deg < 180.0) {
      EXPECT_LT(angle(app, v), angle(u, v)) << "towards the apex";
    }
  }
  EXPECT_NEAR(angle(aberrated_direction(Vec3::UnitY(), v), Vec3::UnitY()) / kArcsecToRad, 20.50, 0.01);
}

TEST(Aberration, OppositeBoostUndoesIt) {
  const Vec3 u = Vec3(-0.2, 0.9, 0.1).normalized();
  const Vec3 v(-12e3, 31e3, 7e3);
  const Vec3 back = aberrated_direction(aberrated_direction(u, v), -v);
  EXPECT_LT(angle(back, u), 1e-14);
}

TEST(Aberration, RefusesBadInput) {
  EXPECT_THROW((void)aberrated_direction(Vec3::Zero(), Vec3::Zero()), std::invalid_argument);
  EXPECT_THROW((void)aberrated_direction(Vec3::UnitX(), Vec3(kSpeedOfLight_mps, 0, 0)), std::invalid_argument);
}

}  // namespace
}  // namespace artms::astro
