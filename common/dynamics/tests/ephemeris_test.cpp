#include "artms/dynamics/ephemeris.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>

#include "artms/astro/constants.hpp"
#include "artms/testing/testing.hpp"

namespace artms::dynamics {
namespace {

using astro::kRadToDeg;

// Geometric geocentric Sun and Moon positions (m), ICRS axes (= GCRS axes,
// J2000 within 23 mas), from Debian's astropy 5.2.1 with its built-in
// ephemeris (ERFA epv00 for Sun/Earth, moon98 for the Moon), offline:
//
// /usr/bin/python3 -c "
// from astropy.time import Time
// from astropy.coordinates import get_body_barycentric as b
// J2000 = Time('2000-01-01T12:00:00', scale='tt')
// for iso in ['2000-01-01T12:00:00', '2003-07-19T06:30:00', ...]:  # dates below, TT
//     t = Time(iso, scale='tt'); e = b('earth', t)
//     s = round((t - J2000).to_value('s'))
//     sun = (b('sun', t) - e).xyz.to_value('m'); moon = (b('moon', t) - e).xyz.to_value('m')
//     print(iso, s, *sun, *moon)"
struct AstropyCase {
  const char* iso_tt;
  std::int64_t tt_seconds_since_j2000;
  std::array<double, 3> sun_m;
  std::array<double, 3> moon_m;
};

constexpr std::array<AstropyCase, 9> kAstropyCases{{
    {"2000-01-01T12:00:00",
     0,
     {2.6499029716e+10, -1.3275741763e+11, -5.7556716961e+10},
     {-2.9160546644e+08, -2.6671523322e+08, -7.6099036297e+07}},
    {"2003-07-19T06:30:00",
     111868200,
     {-6.7021649530e+10, 1.2519748970e+11, 5.4278072811e+10},
     {3.9477638540e+08, 3.4431993426e+07, -1.6191416805e+07}},
    {"2007-03-02T18:00:00",
     226130400,
     {1.4074683174e+11, -4.2766728311e+10, -1.8540871608e+10},
     {-3.3885932440e+08, 1.8902631276e+08, 9.4354643138e+07}},
    {"2011-11-11T11:11:00",
     374281860,
     {-9.8061521688e+10, -1.0184337638e+11, -4.4150613626e+10},
     {2.2933148790e+08, 2.9948730740e+08, 1.4282053304e+08}},
    {"2015-06-30T00:00:00",
     488894400,
     {-2.0404953300e+10, 1.3827179465e+11, 5.9943166934e+10},
     {-1.2411680266e+08, -3.4399779008e+08, -1.1571773244e+08}},
    {"2019-02-14T21:45:00",
     603452700,
     {1.2197132093e+11, -7.6484223032e+10, -3.3156494494e+10},
     {6.3456896100e+07, 3.4491177897e+08, 1.2763751462e+08}},
    {"2024-05-08T00:00:00",
     768398400,
     {1.0188003726e+11, 1.0224344773e+11, 4.4320736449e+10},
     {2.5578090534e+08, 2.3331772085e+08, 1.1965167190e+08}},
    {"2026-09-23T15:20:00",
     843448800,
     {-1.5010466603e+11, -6.0255302661e+08, -2.6025159587e+08},
     {3.1476977616e+08, -2.1409577405e+08, -9.6870301809e+07}},
    {"2030-12-31T23:00:00",
     978260400,
     {2.5240525456e+10, -1.3296521342e+11, -5.7636191111e+10},
     {3.7889285718e+08, 7.8164506369e+07, 6.4621313781e+07}},
}};

TimeTT case_time(const AstropyCase& c) {
  return TimeTT{c.tt_seconds_since_j2000 * astro::kNanosPerSecond};
}

Vec3 to_vec(const std::array<double, 3>& a) {
  return {a[0], a[1], a[2]};
}

double angle_deg(const Vec3& a, const Vec3& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * kRadToDeg;
}

TEST(Ephemeris, SunMatchesAstropyWithinLowPrecisionModel) {
  // M&G's Sun keeps the longitude of perigee fixed (282.94 deg), which drifts
  // against the J2000 equinox by ~0.32 deg per century; on top of that the
  // truncated series leaves < 0.005 deg (measured over 300 dates 2000-2030).
  // Distance: the series is good to ~8e-5 relative.
  double max_excess_deg = -1.0, max_angle_deg = 0.0, max_rel_dist = 0.0;
  for (const auto& c : kAstropyCases) {
    SCOPED_TRACE(c.iso_tt);
    const TimeTT t = case_time(c);
    const Vec3 model = sun_position_eci_m(t);
    const Vec3 ref = to_vec(c.sun_m);
    const double T = std::abs(t.julian_centuries());
    const double angle = angle_deg(model, ref);
    const double rel_dist = std::abs(model.norm() - ref.norm()) / ref.norm();
    EXPECT_LT(angle, 0.01 + 0.34 * T);
    EXPECT_LT(rel_dist, 1.5e-4);
    max_angle_deg = std::max(max_angle_deg, angle);
    max_excess_deg = std::max(max_excess_deg, angle - 0.33 * T);
    max_rel_dist = std::max(max_rel_dist, rel_dist);
  }
  EXPECT_LT(max_angle_deg, 0.12);
  std::printf(
      "Sun vs astropy: max angle %.4f deg, max (angle - 0.33 deg T) %.4f deg, "
      "max |dr|/r %.2e\n",
      max_angle_deg, max_excess_deg, max_rel_dist);
}

TEST(Ephemeris, MoonMatchesAstropyWithinLowPrecisionModel) {
  // M&G: "several arcmin" and ~500 km; measured over 200 dates 2000-2030:
  // 0.071 deg and 420 km at worst.
  double max_angle_deg = 0.0, max_dist_m = 0.0;
  for (const auto& c : kAstropyCases) {
    SCOPED_TRACE(c.iso_tt);
    const Vec3 model = moon_position_eci_m(case_time(c));
    const Vec3 ref = to_vec(c.moon_m);
    const double angle = angle_deg(model, ref);
    const double dist = std::abs(model.norm() - ref.norm());
    EXPECT_LT(angle, 0.1);
    EXPECT_LT(dist, 500e3);
    max_angle_deg = std::max(max_angle_deg, angle);
    max_dist_m = std::max(max_dist_m, dist);
  }
  std::printf("Moon vs astropy: max angle %.4f deg, max |dr| %.0f km\n", max_angle_deg,
              max_dist_m * 1e-3);
}

TEST(Ephemeris, SunAndMoonAreSmoothAndBounded) {
  // Over a month the Sun stays within 0.983-1.017 AU and within 23.44 deg of
  // the equator; the Moon stays within 356000-407000 km and 29 deg of it.
  const TimeTT t0 = astro::tt_from_utc_string("2024-05-08T00:00:00Z");
  Vec3 prev_sun = sun_position_eci_m(t0), prev_moon = moon_position_eci_m(t0);
  for (int h = 1; h <= 24 * 30; ++h) {
    const TimeTT t = t0.plus_seconds(3600.0 * h);
    const Vec3 sun = sun_position_eci_m(t), moon = moon_position_eci_m(t);
    EXPECT_GT(sun.norm(), 0.983 * kAstronomicalUnit_m);
    EXPECT_LT(sun.norm(), 1.017 * kAstronomicalUnit_m);
    EXPECT_LT(std::abs(std::asin(sun.z() / sun.norm())) * kRadToDeg, 23.44);
    EXPECT_GT(moon.norm(), 356000e3);
    EXPECT_LT(moon.norm(), 407000e3);
    EXPECT_LT(std::abs(std::asin(moon.z() / moon.norm())) * kRadToDeg, 29.0);
    // Mean motions: Sun ~0.041 deg/h, Moon ~0.55 deg/h (at most ~0.7).
    EXPECT_LT(angle_deg(sun, prev_sun), 0.045);
    EXPECT_LT(angle_deg(moon, prev_moon), 0.7);
    prev_sun = sun;
    prev_moon = moon;
  }
}

TEST(Ephemeris, ThirdBodyExactOnTheLineOfCentres) {
  // Body on +x at distance s, satellite on the same line at x = r: the
  // acceleration is gm (1/(s-r)^2 - 1/s^2) along +x exactly.
  const double s = 384400e3, r = 7000e3;
  const Vec3 a = third_body_acceleration_mps2(Vec3(r, 0, 0), Vec3(s, 0, 0), kGmMoon_m3ps2);
  const double expected = kGmMoon_m3ps2 * (1.0 / ((s - r) * (s - r)) - 1.0 / (s * s));
  EXPECT_NEAR(a.x(), expected, 1e-12 * expected);
  EXPECT_EQ(a.y(), 0.0);
  EXPECT_EQ(a.z(), 0.0);
  // At the geocentre the perturbation vanishes.
  EXPECT_EQ(third_body_acceleration_mps2(Vec3::Zero(), Vec3(s, 0, 0), kGmMoon_m3ps2).norm(), 0.0);
}

TEST(Ephemeris, ThirdBodyApproachesTidalApproximationForFarBody) {
  // For |r| << |s| the perturbation is the tidal term
  // gm/|s|^3 (3 (e_s . r) e_s - r), with a relative error O(|r|/|s|).
  const TimeTT t = astro::tt_from_utc_string("2024-05-08T00:00:00Z");
  const struct {
    Vec3 body;
    double gm;
  } bodies[] = {{sun_position_eci_m(t), kGmSun_m3ps2}, {moon_position_eci_m(t), kGmMoon_m3ps2}};
  const Vec3 sats[] = {Vec3(6878e3, 0, 0), Vec3(-1200e3, 4000e3, 5500e3),
                       Vec3(3000e3, -5000e3, -3500e3)};
  for (const auto& body : bodies) {
    for (const Vec3& r : sats) {
      const Vec3 e_s = body.body.normalized();
      const double s = body.body.norm();
      const Vec3 tidal = body.gm / (s * s * s) * (3.0 * e_s.dot(r) * e_s - r);
      const Vec3 a = third_body_acceleration_mps2(r, body.body, body.gm);
      const double ratio = r.norm() / s;
      EXPECT_LT((a - tidal).norm(), 3.0 * ratio * tidal.norm()) << "ratio " << ratio;
    }
  }
  // Magnitudes in LEO: Sun ~5e-7, Moon ~1e-6 m/s^2 (M&G Fig. 3.1).
  const Vec3 r(6878e3, 0, 0);
  const double a_sun = third_body_acceleration_mps2(r, bodies[0].body, kGmSun_m3ps2).norm();
  const double a_moon = third_body_acceleration_mps2(r, bodies[1].body, kGmMoon_m3ps2).norm();
  EXPECT_GT(a_sun, 2e-7);
  EXPECT_LT(a_sun, 1e-6);
  EXPECT_GT(a_moon, 4e-7);
  EXPECT_LT(a_moon, 3e-6);
}

}  // namespace
}  // namespace artms::dynamics
