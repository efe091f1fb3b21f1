#include "artms/imaging/visibility.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "artms/astro/constants.hpp"
#include "artms/dynamics/ephemeris.hpp"

namespace artms::imaging {
namespace {

using astro::kDegToRad;
using astro::kPi;
using astro::kRadiusEarth_m;

// Starling-like orbit radius (scenario example: a = 6943 km).
constexpr double kLeoRadius_m = 6943e3;
constexpr double kMoonDistance_m = 384400e3;

Vec3 rotate_in_plane(const Vec3& e, const Vec3& f, double a) {
  return std::cos(a) * e + std::sin(a) * f;
}

struct Geometry {
  Vec3 sun;
  Vec3 e_sun;
  Vec3 e_perp;    // perpendicular to the Sun line
  Vec3 e_normal;  // perpendicular to both
};

Geometry geometry() {
  Geometry g;
  g.sun = dynamics::sun_position_eci_m(astro::tt_from_utc_string("2024-05-08T00:00:00Z"));
  g.e_sun = g.sun.normalized();
  g.e_perp = g.e_sun.cross(Vec3::UnitZ()).normalized();
  g.e_normal = g.e_sun.cross(g.e_perp);
  return g;
}

// Magnitude change from the Sun's actual distance relative to 1 AU.
double sun_distance_term(const Vec3& r, const Vec3& sun) {
  return 5.0 * std::log10((sun - r).norm() / dynamics::kAstronomicalUnit_m);
}

// ------------------------------------------------------------- visibility

TEST(Visibility, VisibleOnTheDaySide) {
  const Geometry g = geometry();
  const Vec3 obs = kLeoRadius_m * (g.e_sun + g.e_perp).normalized();
  const Vec3 target = obs + 50e3 * g.e_normal;  // horizontal, phase ~90 deg
  const TargetVisibility v =
      target_visibility(target, obs, g.sun, conical_fov(g.e_normal, 5 * kDegToRad));
  EXPECT_TRUE(v.visible);
  EXPECT_EQ(v.reason, kReasonVisible);
  EXPECT_EQ(v.sunlit_fraction, 1.0);
  EXPECT_NEAR(v.range_m, 50e3, 1e-6);
  EXPECT_NEAR(v.phase_angle_rad, kPi / 2.0, 1e-3);
  // docs/imaging_targets.md table (50 km, 90 deg, 1 AU): 4.14, plus the
  // Sun's distance in May (1.009 AU): 5 log10(r_sun / 1 AU) = +0.02.
  EXPECT_NEAR(v.vmag, 4.14 + sun_distance_term(target, g.sun), 0.01);
}

TEST(Visibility, EclipseBehindTheEarth) {
  const Geometry g = geometry();
  const Vec3 obs = -kLeoRadius_m * g.e_sun;  // anti-Sun point: deep umbra
  const Vec3 target = obs + 50e3 * g.e_perp;
  const TargetVisibility v =
      target_visibility(target, obs, g.sun, conical_fov(g.e_perp, 5 * kDegToRad));
  EXPECT_FALSE(v.visible);
  EXPECT_EQ(v.reason, kReasonEclipse);
  EXPECT_EQ(v.sunlit_fraction, 0.0);
  EXPECT_EQ(v.vmag, std::numeric_limits<double>::infinity());
  // Eclipse is reported before the field-of-view check.
  EXPECT_EQ(target_visibility(target, obs, g.sun, conical_fov(-g.e_perp, 5 * kDegToRad)).reason,
            kReasonEclipse);
}

TEST(Visibility, OccultedWhenTheEarthIsBetween) {
  const Geometry g = geometry();
  // Both on the terminator plane (lit), on opposite sides of the Earth.
  const Vec3 obs = kLeoRadius_m * g.e_perp;
  const Vec3 target = -kLeoRadius_m * g.e_perp;
  const TargetVisibility v = target_visibility(target, obs, g.sun, {});
  EXPECT_EQ(v.sunlit_fraction, 1.0);
  EXPECT_FALSE(v.visible);
  EXPECT_EQ(v.reason, kReasonOcculted);
}

TEST(Visibility, LineOfSightGrazingTheAtmosphere) {
  // Chord whose closest point to the Earth's centre is at altitude h.
  auto chord = [](double h, Vec3& obs, Vec3& target) {
    const double rm = kRadiusEarth_m + h;
    const double half = std::sqrt(kLeoRadius_m * kLeoRadius_m - rm * rm);
    obs = Vec3(half, rm, 0.0);
    target = Vec3(-half, rm, 0.0);
  };
  Vec3 obs;
  Vec3 target;
  chord(50e3, obs, target);
  EXPECT_TRUE(line_of_sight_blocked(obs, target));                   // through the 100 km margin
  EXPECT_FALSE(line_of_sight_blocked(obs, target, kRadiusEarth_m));  // not the solid Earth
  chord(150e3, obs, target);
  EXPECT_FALSE(line_of_sight_blocked(obs, target));
  // Looking down at a lower target: the Earth behind it does not occult it.
  const Vec3 o(0.0, kLeoRadius_m, 0.0);
  EXPECT_FALSE(line_of_sight_blocked(o, o - Vec3(0.0, 50e3, 0.0)));
}

TEST(Visibility, OutsideFieldOfView) {
  const Geometry g = geometry();
  const Vec3 obs = kLeoRadius_m * (g.e_sun + g.e_perp).normalized();
  const Vec3 target = obs + 50e3 * g.e_normal;
  EXPECT_EQ(target_visibility(target, obs, g.sun, conical_fov(-g.e_normal, 5 * kDegToRad)).reason,
            kReasonOutsideFov);
  // 4.9 deg off the boresight is inside a 5 deg cone, 5.1 deg is not.
  const Vec3 side = g.e_normal.cross(g.e_sun).normalized();
  const InFov cone = conical_fov(g.e_normal, 5 * kDegToRad);
  EXPECT_TRUE(cone(rotate_in_plane(g.e_normal, side, 4.9 * kDegToRad)));
  EXPECT_FALSE(cone(rotate_in_plane(g.e_normal, side, 5.1 * kDegToRad)));
}

TEST(Visibility, RectangularFieldOfViewOfTheNst) {
  // NST: 12 x 10 deg (paper Table 1). Camera frame = ECI here.
  const InFov fov = rectangular_fov(astro::Mat3::Identity(), 6 * kDegToRad, 5 * kDegToRad);
  EXPECT_TRUE(fov(Vec3(std::tan(5.9 * kDegToRad), 0.0, 1.0)));
  EXPECT_FALSE(fov(Vec3(std::tan(6.1 * kDegToRad), 0.0, 1.0)));
  EXPECT_TRUE(fov(Vec3(0.0, -std::tan(4.9 * kDegToRad), 1.0)));
  EXPECT_FALSE(fov(Vec3(0.0, -std::tan(5.1 * kDegToRad), 1.0)));
  // The corner (6, 5) is in; behind the camera is out.
  EXPECT_TRUE(fov(Vec3(std::tan(5.9 * kDegToRad), std::tan(4.9 * kDegToRad), 1.0)));
  EXPECT_FALSE(fov(Vec3(0.0, 0.0, -1.0)));
  // A rotated camera: boresight along ECI +x (R_cam_from_eci maps x_eci -> z_cam).
  astro::Mat3 R;
  R << 0, 1, 0,  //
      0, 0, 1,   //
      1, 0, 0;
  EXPECT_TRUE(rectangular_fov(R, 6 * kDegToRad, 5 * kDegToRad)(Vec3::UnitX()));
  EXPECT_FALSE(rectangular_fov(R, 6 * kDegToRad, 5 * kDegToRad)(Vec3::UnitZ()));
}

TEST(Visibility, TooFaintBeyondTheDetectionLimit) {
  const Geometry g = geometry();
  const Vec3 obs = kLeoRadius_m * (g.e_sun + g.e_perp).normalized();
  VisibilityOptions opt;
  opt.profile = TargetProfile{TargetProfile::Kind::kFlightLike, 1.5, 0.0};
  // 150 km at 90 deg phase, flight-like: V = 8.03 > 6.5.
  const TargetVisibility far = target_visibility(obs + 150e3 * g.e_normal, obs, g.sun, {}, opt);
  EXPECT_EQ(far.reason, kReasonTooFaint);
  EXPECT_NEAR(far.vmag, 8.03 + sun_distance_term(obs, g.sun), 0.01);
  // 50 km, same profile: V = 5.64, visible.
  EXPECT_EQ(target_visibility(obs + 50e3 * g.e_normal, obs, g.sun, {}, opt).reason, kReasonVisible);
  // No magnitude limit: visible at any range.
  opt.limiting_vmag = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(target_visibility(obs + 150e3 * g.e_normal, obs, g.sun, {}, opt).visible);
}

// ------------------------------------------------------------- exclusion

TEST(Visibility, SunExclusionNearTheSun) {
  const Geometry g = geometry();
  const Vec3 obs = kLeoRadius_m * g.e_perp;      // lit, zenith = e_perp
  const Vec3 moon = -kMoonDistance_m * g.e_sun;  // far from every boresight below
  const Vec3 s_hat = (g.sun - obs).normalized();
  const Vec3 up = (g.e_perp - g.e_perp.dot(s_hat) * s_hat).normalized();
  const ExclusionResult at_sun = camera_exclusion(s_hat, obs, g.sun, moon);
  EXPECT_TRUE(at_sun.excluded);
  EXPECT_EQ(at_sun.reason, kExclusionSun);
  // 44 deg from the Sun (tilted towards the zenith): excluded; 46 deg: not.
  EXPECT_EQ(camera_exclusion(rotate_in_plane(s_hat, up, 44 * kDegToRad), obs, g.sun, moon).reason,
            kExclusionSun);
  const ExclusionResult clear =
      camera_exclusion(rotate_in_plane(s_hat, up, 46 * kDegToRad), obs, g.sun, moon);
  EXPECT_FALSE(clear.excluded);
  EXPECT_EQ(clear.reason, kExclusionNone);
}

TEST(Visibility, SunBehindTheEarthDoesNotBlindTheCamera) {
  const Geometry g = geometry();
  const Vec3 obs = -kLeoRadius_m * g.e_sun;  // umbra: the Sun is behind the Earth
  const Vec3 moon = kMoonDistance_m * g.e_perp;
  const ExclusionResult r = camera_exclusion(g.e_sun, obs, g.sun, moon);
  EXPECT_TRUE(r.excluded);
  EXPECT_EQ(r.reason, kExclusionEarthLimb);  // it looks at the (night) Earth instead
}

TEST(Visibility, MoonExclusionUnlessTheEarthHidesIt) {
  const Geometry g = geometry();
  const Vec3 obs = kLeoRadius_m * g.e_perp;
  // Moon at the zenith, Sun 90 deg away: moon exclusion.
  const ExclusionResult r = camera_exclusion(g.e_perp, obs, g.sun, kMoonDistance_m * g.e_perp);
  EXPECT_EQ(r.reason, kExclusionMoon);
  // 16 deg away from the Moon: clear (towards the normal, away from the Sun and the Earth).
  EXPECT_FALSE(camera_exclusion(rotate_in_plane(g.e_perp, g.e_normal, 16 * kDegToRad), obs, g.sun,
                                kMoonDistance_m * g.e_perp)
                   .excluded);
  // Moon at the nadir, behind the Earth: the limb, not the Moon.
  EXPECT_EQ(camera_exclusion(-g.e_perp, obs, g.sun, -kMoonDistance_m * g.e_perp).reason,
            kExclusionEarthLimb);
}

TEST(Visibility, EarthLimbExclusion) {
  const Geometry g = geometry();
  const Vec3 obs = kLeoRadius_m * g.e_perp;  // zenith e_perp, horizontal plane {e_sun, e_normal}
  const Vec3 moon = kMoonDistance_m * g.e_perp;
  ExclusionAngles no_moon;
  no_moon.moon_rad = 0.0;
  const double rho = earth_angular_radius_rad(obs);
  EXPECT_NEAR(rho, std::asin((kRadiusEarth_m + 100e3) / kLeoRadius_m), 1e-15);
  EXPECT_NEAR(rho / kDegToRad, 68.91, 0.01);
  // Nadir pointing: excluded.
  const ExclusionResult nadir = camera_exclusion(-g.e_perp, obs, g.sun, moon, no_moon);
  EXPECT_TRUE(nadir.excluded);
  EXPECT_EQ(nadir.reason, kExclusionEarthLimb);
  // Horizontal pointing (the +-velocity boresight of StarFOX), away from the
  // Sun: not excluded, the limb is 21.1 deg below (> 15 deg).
  EXPECT_FALSE(camera_exclusion(g.e_normal, obs, g.sun, moon, no_moon).excluded);
  // Tilted towards the Earth: excluded once within 15 deg of the limb.
  const double limb_elev = rho - kPi / 2.0;  // -21.1 deg
  const double just_out = limb_elev + 15.1 * kDegToRad;
  const double just_in = limb_elev + 14.9 * kDegToRad;
  EXPECT_FALSE(
      camera_exclusion(rotate_in_plane(g.e_normal, g.e_perp, just_out), obs, g.sun, moon, no_moon)
          .excluded);
  EXPECT_EQ(
      camera_exclusion(rotate_in_plane(g.e_normal, g.e_perp, just_in), obs, g.sun, moon, no_moon)
          .reason,
      kExclusionEarthLimb);
}

// ---------------------------------------------------------- frame faults

TEST(Visibility, FrameDropoutFrequencyAndDeterminism) {
  const int n = 10000;
  for (const double p : {0.02, 0.1, 0.5}) {
    int dropped = 0;
    for (int k = 0; k < n; ++k) {
      if (frame_dropped(2024, static_cast<std::uint64_t>(k), p)) ++dropped;
    }
    const double sigma = std::sqrt(n * p * (1.0 - p));
    EXPECT_NEAR(dropped, n * p, 3.0 * sigma) << "p = " << p;
  }
  // Deterministic for a seed, whatever the call order; another seed differs.
  int same = 0;
  int differ = 0;
  for (int k = n - 1; k >= 0; --k) {
    const auto i = static_cast<std::uint64_t>(k);
    if (frame_dropped(7, i, 0.3) == frame_dropped(7, i, 0.3)) ++same;
    if (frame_dropped(7, i, 0.3) != frame_dropped(8, i, 0.3)) ++differ;
  }
  EXPECT_EQ(same, n);
  EXPECT_GT(differ, n / 4);  // expected 2 p (1 - p) n = 4200
  for (std::uint64_t k = 0; k < 100; ++k) {
    EXPECT_FALSE(frame_dropped(7, k, 0.0));
    EXPECT_TRUE(frame_dropped(7, k, 1.0));
  }
}

TEST(Visibility, TimeTagOffsetAndDrift) {
  const TimeTT epoch = astro::tt_from_utc_string("2024-03-24T00:00:00Z");
  const TimeTT t = epoch.plus_seconds(3600.0);
  // No faults: the true time.
  EXPECT_EQ(time_tag(t, epoch, FrameFaults{}), t);
  // Paper: -0.4 s offset. Plus 100 ppm drift over 3600 s = +0.36 s.
  const FrameFaults f{0.0, -0.4, 100.0};
  EXPECT_EQ(time_tag(t, epoch, f).ns_since_j2000 - t.ns_since_j2000, -40'000'000);
  EXPECT_EQ(time_tag(epoch, epoch, f).ns_since_j2000 - epoch.ns_since_j2000, -400'000'000);
  // Before the epoch the drift changes sign.
  const TimeTT before = epoch.plus_seconds(-3600.0);
  EXPECT_EQ(time_tag(before, epoch, f).ns_since_j2000 - before.ns_since_j2000, -760'000'000);
  // Pure drift over one day, -2.5 ppm: -216 ms.
  const FrameFaults drift{0.0, 0.0, -2.5};
  const TimeTT day = epoch.plus_seconds(86400.0);
  EXPECT_EQ(time_tag(day, epoch, drift).ns_since_j2000 - day.ns_since_j2000, -216'000'000);
}

}  // namespace
}  // namespace artms::imaging
