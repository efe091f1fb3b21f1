#include "artms/astro/time.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>

#include "artms/astro/constants.hpp"
#include "artms/astro/elements.hpp"

namespace artms::astro {
namespace {

TEST(Time, J2000EpochIsNoonTT) {
  // 2000-01-01 12:00:00 TT = 11:58:55.816 UTC (TAI-UTC = 32 s, TT-TAI = 32.184 s).
  EXPECT_EQ(tt_from_utc_string("2000-01-01T11:58:55.816Z").ns_since_j2000, 0);
  EXPECT_EQ(utc_string(TimeTT{0}, 3), "2000-01-01T11:58:55.816Z");
}

TEST(Time, LeapSecondTable) {
  EXPECT_EQ(tai_minus_utc_s(1972, 1, 1), 10);
  EXPECT_EQ(tai_minus_utc_s(1999, 1, 1), 32);
  EXPECT_EQ(tai_minus_utc_s(2016, 12, 31), 36);
  EXPECT_EQ(tai_minus_utc_s(2017, 1, 1), 37);
  EXPECT_EQ(tai_minus_utc_s(2024, 5, 8), 37);
  EXPECT_THROW(tai_minus_utc_s(1971, 12, 31), std::out_of_range);
}

TEST(Time, LeapSecondInstantRoundTrips) {
  const TimeTT before = tt_from_utc_string("2016-12-31T23:59:59.5Z");
  const TimeTT leap = tt_from_utc_string("2016-12-31T23:59:60.5Z");
  const TimeTT after = tt_from_utc_string("2017-01-01T00:00:00.5Z");
  EXPECT_EQ(leap.ns_since_j2000 - before.ns_since_j2000, kNanosPerSecond);
  EXPECT_EQ(after.ns_since_j2000 - leap.ns_since_j2000, kNanosPerSecond);
  EXPECT_EQ(utc_string(leap, 1), "2016-12-31T23:59:60.5Z");
  EXPECT_EQ(utc_string(after, 1), "2017-01-01T00:00:00.5Z");
}

TEST(Time, UtcRoundTripIsExactToTheNanosecond) {
  std::mt19937_64 rng(42);
  // 1972-2040 in TT nanoseconds since J2000.
  std::uniform_int_distribution<std::int64_t> dist(-27LL * 365 * 86400 * kNanosPerSecond,
                                                   40LL * 365 * 86400 * kNanosPerSecond);
  for (int k = 0; k < 20000; ++k) {
    const TimeTT t{dist(rng)};
    EXPECT_EQ(tt_from_utc(utc_from_tt(t)).ns_since_j2000, t.ns_since_j2000);
  }
}

TEST(Time, StarlingEpochs) {
  // Table 2 epochs: TT - UTC = 69.184 s in 2024.
  const TimeTT t = tt_from_utc_string("2024-05-08T00:00:00Z");
  const UtcCalendar c = utc_from_tt(t);
  EXPECT_EQ(c, (UtcCalendar{2024, 5, 8, 0, 0, 0}));
  const std::int64_t days = 8894;  // 2000-01-01 -> 2024-05-08
  EXPECT_EQ(t.ns_since_j2000,
            (days * 86400 - 43200 + 69) * kNanosPerSecond + 184'000'000);
}

TEST(Time, ParsesAcceptedForms) {
  const TimeTT a = tt_from_utc_string("2024-02-05T00:00:00Z");
  EXPECT_EQ(tt_from_utc_string("2024-02-05 00:00:00").ns_since_j2000, a.ns_since_j2000);
  EXPECT_EQ(tt_from_utc_string("2024-02-05").ns_since_j2000, a.ns_since_j2000);
  EXPECT_EQ(tt_from_utc_string("2024-02-05T00:00:00.000000001Z").ns_since_j2000,
            a.ns_since_j2000 + 1);
}

TEST(Time, RejectsMalformedText) {
  for (const char* bad : {"2024-13-01T00:00:00Z", "2024-02-30", "2024-05-08T25:00:00Z",
                          "2024-05-08T00:61:00Z", "yesterday", "2024-05-08T00:00:00ZZ",
                          "2024-05-08T00:00:00.Z", ""}) {
    try {
      (void)tt_from_utc_string(bad);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(std::string("'") + bad + "'"), std::string::npos)
          << e.what();
    }
  }
  EXPECT_THROW((void)tt_from_utc_string("1969-07-20T20:17:00Z"), std::out_of_range);
}

TEST(Time, GpsWeekRollover2019) {
  // The second 10-bit GPS week roll-over: week 2048 began 2019-04-07 00:00:00 GPS,
  // which is 2019-04-06T23:59:42 UTC (GPS - UTC = 18 s).
  const GpsWeekTime g = gps_from_tt(tt_from_utc_string("2019-04-07T00:00:00Z"));
  EXPECT_EQ(g.week, 2048);
  EXPECT_DOUBLE_EQ(g.seconds_of_week, 18.0);
  EXPECT_EQ(tt_from_gps(g).ns_since_j2000,
            tt_from_utc_string("2019-04-07T00:00:00Z").ns_since_j2000);
}

TEST(Time, GmstMatchesVallado35) {
  // Vallado (2013) Example 3-5: 1992-08-20 12:14:00 UT1 -> GMST = 152.578787886 deg.
  const TimeTT t = tt_from_utc_string("1992-08-20T12:14:00Z");
  EXPECT_NEAR(gmst_rad(t, 0.0) * kRadToDeg, 152.578787886, 1e-6);
}

TEST(Time, EarthRotationAngleAtJ2000) {
  // ERA(UT1 = J2000.0) = 2 pi * 0.7790572732640 (IERS 2010 eq. 5.15).
  const TimeTT t = tt_from_utc_string("2000-01-01T12:00:00Z");
  EXPECT_NEAR(earth_rotation_angle_rad(t), kTwoPi * 0.7790572732640, 1e-12);
  // One UT1 day later the angle has advanced by 2 pi * 0.00273781191135448.
  const double d = wrap_two_pi(earth_rotation_angle_rad(t.plus_seconds(86400.0)) -
                                        earth_rotation_angle_rad(t));
  EXPECT_NEAR(d, kTwoPi * 0.00273781191135448, 1e-10);
}

}  // namespace
}  // namespace artms::astro
