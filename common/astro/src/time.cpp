#include "artms/astro/time.hpp"

#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "artms/astro/constants.hpp"

namespace artms::astro {
namespace {

constexpr std::int64_t kNanosPerMinute = 60 * kNanosPerSecond;
constexpr std::int64_t kNanosPerDay = 86400 * kNanosPerSecond;

// Days since 1970-01-01 of a proleptic Gregorian date (the classic
// era/year-of-era/day-of-year decomposition of the civil calendar).
constexpr std::int64_t days_from_civil(std::int64_t y, int m, int d) {
  y -= m <= 2 ? 1 : 0;
  const std::int64_t era = (y >= 0 ? y : y - 399) / 400;
  const std::int64_t yoe = y - era * 400;
  const std::int64_t mp = (m + 9) % 12;
  const std::int64_t doy = (153 * mp + 2) / 5 + d - 1;
  const std::int64_t doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + doe - 719468;
}

struct CivilDate {
  std::int64_t year;
  int month;
  int day;
};

constexpr CivilDate civil_from_days(std::int64_t z) {
  z += 719468;
  const std::int64_t era = (z >= 0 ? z : z - 146096) / 146097;
  const std::int64_t doe = z - era * 146097;
  const std::int64_t yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
  const std::int64_t doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
  const std::int64_t mp = (5 * doy + 2) / 153;
  const int d = static_cast<int>(doy - (153 * mp + 2) / 5 + 1);
  const int m = static_cast<int>(mp < 10 ? mp + 3 : mp - 9);
  return {yoe + era * 400 + (m <= 2 ? 1 : 0), m, d};
}

constexpr bool is_leap_year(int y) { return (y % 4 == 0 && y % 100 != 0) || y % 400 == 0; }

int days_in_month(int y, int m) {
  static constexpr std::array<int, 12> kDays{31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  return m == 2 && is_leap_year(y) ? 29 : kDays[static_cast<std::size_t>(m - 1)];
}

// Leap-second table: UTC date from which TAI - UTC takes the given value
// (IERS Bulletin C; no leap second announced after 2017-01-01 as of 2026).
struct LeapEntry {
  int year, month, day, tai_minus_utc_s;
};
constexpr std::array<LeapEntry, 28> kLeapSeconds{{
    {1972, 1, 1, 10}, {1972, 7, 1, 11}, {1973, 1, 1, 12}, {1974, 1, 1, 13},
    {1975, 1, 1, 14}, {1976, 1, 1, 15}, {1977, 1, 1, 16}, {1978, 1, 1, 17},
    {1979, 1, 1, 18}, {1980, 1, 1, 19}, {1981, 7, 1, 20}, {1982, 7, 1, 21},
    {1983, 7, 1, 22}, {1985, 7, 1, 23}, {1988, 1, 1, 24}, {1990, 1, 1, 25},
    {1991, 1, 1, 26}, {1992, 7, 1, 27}, {1993, 7, 1, 28}, {1994, 7, 1, 29},
    {1996, 1, 1, 30}, {1997, 7, 1, 31}, {1999, 1, 1, 32}, {2006, 1, 1, 33},
    {2009, 1, 1, 34}, {2012, 7, 1, 35}, {2015, 7, 1, 36}, {2017, 1, 1, 37},
}};

// Days since 1970 of 2000-01-01; J2000.0 is 12:00 TT of that day.
constexpr std::int64_t kDaysTo2000 = days_from_civil(2000, 1, 1);
constexpr std::int64_t kHalfDay_ns = kNanosPerDay / 2;

// "Uniform UTC" nanoseconds since 2000-01-01T12:00 counting every day as
// 86400 s; adding TAI-UTC and TT-TAI gives TT.
constexpr std::int64_t naive_utc_ns(std::int64_t days_since_1970, std::int64_t ns_of_day) {
  return (days_since_1970 - kDaysTo2000) * kNanosPerDay + ns_of_day - kHalfDay_ns;
}

void check_calendar(const UtcCalendar& c) {
  const bool ok = c.month >= 1 && c.month <= 12 && c.day >= 1 &&
                  c.day <= days_in_month(c.year, c.month) && c.hour >= 0 && c.hour <= 23 &&
                  c.minute >= 0 && c.minute <= 59 && c.ns_of_minute >= 0 &&
                  c.ns_of_minute < 61 * kNanosPerSecond;
  if (!ok) {
    char buf[128];
    std::snprintf(buf, sizeof buf, "invalid UTC calendar date %04d-%02d-%02d %02d:%02d", c.year,
                  c.month, c.day, c.hour, c.minute);
    throw std::invalid_argument(buf);
  }
}

double wrap_two_pi(double angle_rad) {
  double a = std::fmod(angle_rad, kTwoPi);
  return a < 0.0 ? a + kTwoPi : a;
}

}  // namespace

double TimeTT::julian_centuries() const {
  return seconds_since_j2000() / (kSecondsPerDay * kDaysPerJulianCentury);
}

TimeTT TimeTT::plus_seconds(double dt_s) const {
  return TimeTT{ns_since_j2000 + static_cast<std::int64_t>(std::llround(dt_s * 1e9))};
}

double seconds_between(TimeTT a, TimeTT b) {
  return static_cast<double>(b.ns_since_j2000 - a.ns_since_j2000) * 1e-9;
}

// The table's start days (since 1970) and start instants (TAI ns since
// J2000), computed once: the force model asks for UTC at every evaluation.
struct LeapStart {
  std::int64_t day;
  std::int64_t tai_ns;
};
constexpr std::array<LeapStart, kLeapSeconds.size()> leap_starts() {
  std::array<LeapStart, kLeapSeconds.size()> out{};
  for (std::size_t k = 0; k < kLeapSeconds.size(); ++k) {
    const auto& e = kLeapSeconds[k];
    const std::int64_t d = days_from_civil(e.year, e.month, e.day);
    out[k] = {d, naive_utc_ns(d, 0) + e.tai_minus_utc_s * kNanosPerSecond};
  }
  return out;
}
constexpr std::array<LeapStart, kLeapSeconds.size()> kLeapStarts = leap_starts();

int tai_minus_utc_s(int year, int month, int day) {
  const std::int64_t d = days_from_civil(year, month, day);
  if (d < kLeapStarts.front().day) {
    throw std::out_of_range("UTC dates before 1972-01-01 are not supported (leap-second table)");
  }
  for (std::size_t k = kLeapStarts.size(); k-- > 0;) {
    if (d >= kLeapStarts[k].day) return kLeapSeconds[k].tai_minus_utc_s;
  }
  return kLeapSeconds.front().tai_minus_utc_s;
}

TimeTT tt_from_utc(const UtcCalendar& utc) {
  check_calendar(utc);
  const std::int64_t days = days_from_civil(utc.year, utc.month, utc.day);
  const std::int64_t ns_of_day =
      (utc.hour * 60 + utc.minute) * kNanosPerMinute + utc.ns_of_minute;
  const std::int64_t tai_minus_utc =
      tai_minus_utc_s(utc.year, utc.month, utc.day) * kNanosPerSecond;
  return TimeTT{naive_utc_ns(days, ns_of_day) + tai_minus_utc + kTtMinusTai_ns};
}

UtcCalendar utc_from_tt(TimeTT t) {
  const std::int64_t tai = t.ns_since_j2000 - kTtMinusTai_ns;
  // Find the table entry in force: the last whose start instant (in TAI) is <= tai.
  int offset_s = -1;
  bool in_leap_second = false;
  for (std::size_t k = kLeapStarts.size(); k-- > 0;) {
    if (tai < kLeapStarts[k].tai_ns) continue;
    offset_s = kLeapSeconds[k].tai_minus_utc_s;
    // The second just before the next entry is the inserted 23:59:60.
    in_leap_second = k + 1 < kLeapStarts.size() && tai >= kLeapStarts[k + 1].tai_ns - kNanosPerSecond;
    break;
  }
  if (offset_s < 0) {
    throw std::out_of_range("TT instant before 1972-01-01 UTC is not supported");
  }
  std::int64_t naive = tai - offset_s * kNanosPerSecond + kHalfDay_ns;  // since 2000-01-01T00
  if (in_leap_second) naive -= kNanosPerSecond;  // shown as 23:59:60 of the day before
  std::int64_t days = naive / kNanosPerDay;
  std::int64_t ns_of_day = naive % kNanosPerDay;
  if (ns_of_day < 0) {
    ns_of_day += kNanosPerDay;
    days -= 1;
  }
  const CivilDate cd = civil_from_days(days + kDaysTo2000);
  UtcCalendar out;
  out.year = static_cast<int>(cd.year);
  out.month = cd.month;
  out.day = cd.day;
  out.hour = static_cast<int>(ns_of_day / (60 * kNanosPerMinute));
  out.minute = static_cast<int>((ns_of_day / kNanosPerMinute) % 60);
  out.ns_of_minute = ns_of_day % kNanosPerMinute;
  if (in_leap_second) out.ns_of_minute += kNanosPerSecond;
  return out;
}

namespace {

// Parses an unsigned integer of exactly `width` digits at text[pos].
bool parse_fixed(std::string_view text, std::size_t pos, std::size_t width, int& value) {
  if (pos + width > text.size()) return false;
  for (std::size_t k = pos; k < pos + width; ++k) {
    if (text[k] < '0' || text[k] > '9') return false;
  }
  const auto res = std::from_chars(text.data() + pos, text.data() + pos + width, value);
  return res.ec == std::errc{};
}

}  // namespace

TimeTT tt_from_utc_string(std::string_view iso) {
  const auto fail = [&](const char* why) {
    throw std::invalid_argument("invalid UTC time '" + std::string(iso) + "': " + why +
                                " (expected YYYY-MM-DDTHH:MM:SS[.fff][Z])");
  };
  UtcCalendar c;
  if (!parse_fixed(iso, 0, 4, c.year) || iso.size() < 10 || iso[4] != '-' ||
      !parse_fixed(iso, 5, 2, c.month) || iso[7] != '-' || !parse_fixed(iso, 8, 2, c.day)) {
    fail("bad date");
  }
  std::size_t pos = 10;
  if (pos < iso.size() && iso[pos] != 'Z') {
    if (iso[pos] != 'T' && iso[pos] != ' ') fail("date and time must be separated by 'T' or ' '");
    int sec = 0;
    if (!parse_fixed(iso, pos + 1, 2, c.hour) || iso.size() < pos + 9 || iso[pos + 3] != ':' ||
        !parse_fixed(iso, pos + 4, 2, c.minute) || iso[pos + 6] != ':' ||
        !parse_fixed(iso, pos + 7, 2, sec)) {
      fail("bad time of day");
    }
    pos += 9;
    std::int64_t frac_ns = 0;
    if (pos < iso.size() && iso[pos] == '.') {
      ++pos;
      std::int64_t scale = kNanosPerSecond / 10;
      const std::size_t start = pos;
      while (pos < iso.size() && iso[pos] >= '0' && iso[pos] <= '9') {
        frac_ns += (iso[pos] - '0') * scale;
        scale /= 10;
        ++pos;
      }
      if (pos == start) fail("empty fraction of a second");
    }
    c.ns_of_minute = sec * kNanosPerSecond + frac_ns;
  }
  if (pos < iso.size() && iso[pos] == 'Z') ++pos;
  if (pos != iso.size()) fail("trailing characters");
  try {
    return tt_from_utc(c);
  } catch (const std::invalid_argument&) {
    fail("date or time out of range");
  }
  return {};
}

std::string utc_string(TimeTT t, int decimals) {
  if (decimals < 0 || decimals > 9) throw std::invalid_argument("utc_string: decimals must be 0..9");
  const UtcCalendar c = utc_from_tt(t);
  std::int64_t unit = 1;
  for (int k = 0; k < 9 - decimals; ++k) unit *= 10;
  // Truncate (never round up into the next minute).
  const std::int64_t sec = c.ns_of_minute / kNanosPerSecond;
  const std::int64_t frac = (c.ns_of_minute % kNanosPerSecond) / unit;
  char buf[64];
  if (decimals == 0) {
    std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02lldZ", c.year, c.month, c.day,
                  c.hour, c.minute, static_cast<long long>(sec));
  } else {
    std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02lld.%0*lldZ", c.year, c.month,
                  c.day, c.hour, c.minute, static_cast<long long>(sec), decimals,
                  static_cast<long long>(frac));
  }
  return buf;
}

GpsWeekTime gps_from_tt(TimeTT t) {
  // GPS epoch 1980-01-06T00:00:00 UTC, when TAI - UTC = 19 s = TAI - GPS.
  static const std::int64_t kGpsEpochTt = tt_from_utc({1980, 1, 6, 0, 0, 0}).ns_since_j2000;
  const std::int64_t ns = t.ns_since_j2000 - kGpsEpochTt;
  constexpr std::int64_t kWeek = 7 * kNanosPerDay;
  std::int64_t week = ns / kWeek;
  std::int64_t rem = ns % kWeek;
  if (rem < 0) {
    rem += kWeek;
    week -= 1;
  }
  return {static_cast<int>(week), static_cast<double>(rem) * 1e-9};
}

TimeTT tt_from_gps(const GpsWeekTime& gps) {
  static const std::int64_t kGpsEpochTt = tt_from_utc({1980, 1, 6, 0, 0, 0}).ns_since_j2000;
  return TimeTT{kGpsEpochTt + gps.week * 7 * kNanosPerDay +
                static_cast<std::int64_t>(std::llround(gps.seconds_of_week * 1e9))};
}

double julian_date_tt(TimeTT t) { return 2451545.0 + t.seconds_since_j2000() / kSecondsPerDay; }

double julian_date_ut1(TimeTT t, double dut1_s) {
  const UtcCalendar c = utc_from_tt(t);
  const std::int64_t tai_minus_utc = tai_minus_utc_s(c.year, c.month, c.day) * kNanosPerSecond;
  const std::int64_t utc_ns = t.ns_since_j2000 - kTtMinusTai_ns - tai_minus_utc;
  // Split day count and fraction to keep precision in the double.
  const double days = static_cast<double>(utc_ns / kNanosPerDay);
  const double frac = static_cast<double>(utc_ns % kNanosPerDay) * 1e-9 / kSecondsPerDay;
  return 2451545.0 + days + frac + dut1_s / kSecondsPerDay;
}

double earth_rotation_angle_rad(TimeTT t, double dut1_s) {
  const double du = julian_date_ut1(t, dut1_s) - 2451545.0;
  // IERS Conventions 2010, eq. (5.15); the integer part of du drops out.
  const double frac_day = std::fmod(du, 1.0);
  return wrap_two_pi(kTwoPi * (frac_day + 0.7790572732640 + 0.00273781191135448 * du));
}

double gmst_rad(TimeTT t, double dut1_s) {
  const double jd_ut1 = julian_date_ut1(t, dut1_s);
  const double tu = (jd_ut1 - 2451545.0) / kDaysPerJulianCentury;
  // IAU 1982 GMST in seconds of time (Vallado 2013, eq. 3-47).
  const double gmst_s = 67310.54841 + (876600.0 * 3600.0 + 8640184.812866) * tu +
                        0.093104 * tu * tu - 6.2e-6 * tu * tu * tu;
  const double gmst_s_mod = std::fmod(gmst_s, kSecondsPerDay);
  return wrap_two_pi(gmst_s_mod / kSecondsPerDay * kTwoPi);
}

}  // namespace artms::astro
