// Time scales. On the wire and inside the code the one time scale is TT as
// int64 nanoseconds since J2000.0 (2000-01-01 12:00:00 TT), see
// docs/conventions.md. UTC appears only at the edges (configs, outputs) and is
// converted with the leap-second table below (valid from 1972-01-01 on).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace artms::astro {

inline constexpr std::int64_t kNanosPerSecond = 1'000'000'000;

// An instant in Terrestrial Time, nanoseconds since J2000.0 (TT).
struct TimeTT {
  std::int64_t ns_since_j2000 = 0;

  [[nodiscard]] double seconds_since_j2000() const {
    return static_cast<double>(ns_since_j2000) * 1e-9;
  }
  // TT Julian centuries since J2000.0, for precession and ephemerides.
  [[nodiscard]] double julian_centuries() const;
  [[nodiscard]] TimeTT plus_seconds(double dt_s) const;
  friend auto operator<=>(const TimeTT&, const TimeTT&) = default;
};

// Seconds from a to b (b - a), exact to the nanosecond before rounding to double.
double seconds_between(TimeTT a, TimeTT b);

// A UTC calendar instant. ns_of_minute may reach 60.999999999 s during a
// positive leap second (23:59:60).
struct UtcCalendar {
  int year = 2000;
  int month = 1;
  int day = 1;
  int hour = 0;
  int minute = 0;
  std::int64_t ns_of_minute = 0;
  friend bool operator==(const UtcCalendar&, const UtcCalendar&) = default;
};

// TAI - UTC in whole seconds at a UTC date (leap-second table, 37 s since
// 2017-01-01). Throws std::out_of_range before 1972-01-01.
int tai_minus_utc_s(int year, int month, int day);

// UTC calendar <-> TT. Throws std::invalid_argument on a malformed date and
// std::out_of_range before 1972.
TimeTT tt_from_utc(const UtcCalendar& utc);
UtcCalendar utc_from_tt(TimeTT t);

// ISO 8601 UTC text: "2024-05-08T00:00:00Z", "2024-05-08 00:00:00.25",
// "2024-05-08" (midnight). Throws std::invalid_argument naming the text.
TimeTT tt_from_utc_string(std::string_view iso_utc);
// "YYYY-MM-DDTHH:MM:SS.fffZ" with `decimals` digits of seconds (0..9).
std::string utc_string(TimeTT t, int decimals = 3);

// International Atomic Time and GPS time.
// TT = TAI + 32.184 s exactly; GPS = TAI - 19 s exactly.
inline constexpr std::int64_t kTtMinusTai_ns = 32'184'000'000;
inline constexpr std::int64_t kTaiMinusGps_ns = 19'000'000'000;
struct GpsWeekTime {
  int week = 0;          // weeks since 1980-01-06 00:00:00 UTC (no roll-over)
  double seconds_of_week = 0.0;
};
GpsWeekTime gps_from_tt(TimeTT t);
TimeTT tt_from_gps(const GpsWeekTime& gps);

// Julian dates (as double; for rotation angles and ephemerides only).
double julian_date_tt(TimeTT t);
// UT1 Julian date, with UT1 = UTC + dut1_s (default 0: UT1 ~ UTC to 0.9 s).
double julian_date_ut1(TimeTT t, double dut1_s = 0.0);

// Earth rotation angle (IERS 2010 eq. 5.15), radians in [0, 2pi).
double earth_rotation_angle_rad(TimeTT t, double dut1_s = 0.0);
// Greenwich mean sidereal time, IAU 1982 (Aoki et al.; Vallado eq. 3-47),
// radians in [0, 2pi). Used with IAU 1976 precession for ECI <-> ECEF.
double gmst_rad(TimeTT t, double dut1_s = 0.0);

}  // namespace artms::astro
