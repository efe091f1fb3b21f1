// A truth atmosphere whose density follows the solar flux, geomagnetic
// activity, local time, latitude and season: the Harris-Priester table
// rescaled by the exospheric temperature of Jacchia (1971), "Revised static
// models of the thermosphere and exosphere with empirical temperature
// profiles", SAO Special Report 332. Equations and sources: docs/dynamics.md,
// "Truth atmosphere".
#pragma once

#include <cstdint>
#include <vector>

#include "artms/astro/frames.hpp"
#include "artms/astro/time.hpp"
#include "artms/dynamics/atmosphere.hpp"

namespace artms::dynamics {

// Solar and geomagnetic inputs of the model. Defaults: high activity like
// early May 2024 (before the 10 May storm), the Starling experiments'.
struct SpaceWeather {
  struct Day {
    double f107_sfu = 0.0;  // daily F10.7, solar flux units
    double kp = 0.0;        // planetary index, 0 .. 9
    friend bool operator==(const Day&, const Day&) = default;
  };
  double f107_sfu = 170.0;        // daily F10.7 (J71: the previous day's)
  double f107_81day_sfu = 165.0;  // 81-day centred mean of F10.7
  double kp = 3.0;                // 0 .. 9
  // Per day: daily[k] holds for [start + k days, start + (k + 1) days);
  // other days use f107_sfu and kp (varied as below).
  std::vector<Day> daily;
  astro::TimeTT start;
  // Seeded day-to-day variation of the days not in `daily` (0: off): each
  // day's F10.7 and Kp are drawn N(f107_sfu, sigma^2) and N(kp, sigma^2),
  // clamped to F10.7 >= 0.3 f107_sfu and 0 <= Kp <= 9, from a hash of
  // (seed, day): the same seed gives the same days, in any call order.
  double f107_daily_sigma_sfu = 0.0;
  double kp_daily_sigma = 0.0;
  // The empirical model's own error against the real thermosphere, which
  // exact solar and geomagnetic indices leave (about 15 % 1-sigma for
  // Jacchia-class models; Montenbruck & Gill 2000, section 3.5): the
  // density is multiplied by exp(delta(t)), delta a zero-mean stationary
  // Gaussian process of standard deviation density_error_sigma and
  // correlation exp(-dt^2 / (2 density_error_time_s^2)), drawn from the seed
  // (random Fourier features) and common to every spacecraft of the run.
  // 0: off.
  double density_error_sigma = 0.0;
  double density_error_time_s = 5400.0;
  std::uint64_t seed = 1;

  // Throws std::invalid_argument naming the field (e.g. "daily[2].kp") for
  // a non-finite or non-positive flux, Kp outside [0, 9], negative sigmas.
  void validate() const;
  // F10.7 and Kp in force at t (the 81-day mean stays f107_81day_sfu).
  [[nodiscard]] Day at(astro::TimeTT t) const;
  // The draw of delta(t) above: delta(t) = sigma sqrt(2 / N) sum_k
  // cos(w_k (t - start) + phi_k), w_k ~ N(0, 1 / time_s^2), phi_k ~ U(0, 2 pi),
  // N = kDensityErrorTerms (Rahimi & Recht 2007: the features of the
  // squared-exponential kernel). Empty when the error is off.
  static constexpr int kDensityErrorTerms = 64;
  struct DensityErrorTerm {
    double w_rad_per_s = 0.0;
    double phase_rad = 0.0;
  };
  [[nodiscard]] std::vector<DensityErrorTerm> density_error_terms() const;
  friend bool operator==(const SpaceWeather&, const SpaceWeather&) = default;
};

// Jacchia 1971 exospheric temperature (K) at a point, from the geocentric
// latitude phi, the Sun's declination, the hour angle H of the point from
// the Sun (radians, positive to the east of the Sun's meridian, i.e. in the
// afternoon), F10.7, its 81-day mean and Kp:
//   T_c = 379 + 3.24 Fbar + 1.3 (F - Fbar)
//   T_l = T_c (1 + R sin^m(theta) + R (cos^m(eta) - sin^m(theta)) cos^n(tau/2)),
//   eta = |phi - dec|/2, theta = |phi + dec|/2,
//   tau = H + beta + p sin(H + gamma) in [-pi, pi], R 0.3, m 2.2, n 3,
//   beta -37 deg, p 6 deg, gamma 43 deg
//   T_inf = T_l + 28 Kp + 0.03 exp(Kp)  (the form J71 gives above ~200 km)
// (J71; restated in Vallado 2013, appendix B.1, and GTDS, Long et al. 1989).
double jacchia71_exospheric_temperature_K(double lat_rad, double sun_dec_rad, double hour_angle_rad,
                                          double f107_sfu, double f107_81day_sfu, double kp);

// Semi-annual density variation of J71 (Vallado 2013, appendix B.1): the
// factor 10^(f(z) g(t)) with the constant 0.02835 of g (its annual mean)
// left out, so that the table stays an annual mean. height in m.
double jacchia71_semiannual_factor(astro::TimeTT t, double height_m);

struct JacchiaOptions {
  // Exospheric temperature (K) of the state the Harris-Priester table's
  // night-side minimum stands for: the value for which J71's day-night
  // contrast (1 + R) reproduces the table's rho_max / rho_min through the
  // scale-height law below (905-935 K over 400-600 km; docs/dynamics.md).
  double reference_temperature_K = 910.0;
  bool semiannual = true;  // J71's semi-annual variation
};

// rho(h) = rho_HPmin(h) exp(-(m dPhi / k) (1/T_inf - 1/T_ref)) [semi-annual]
// with dPhi = GM (1/(R + h0) - 1/(R + h)), h0 = 120 km (J71's fixed lower
// boundary), m = 16 amu (atomic oxygen, dominant at 300-700 km): the
// isothermal diffusive-equilibrium density of the dominant species above h0.
// The day-night and latitude structure is J71's (through T_inf), not the
// Harris-Priester bulge.
class JacchiaScaledHarrisPriester {
 public:
  // Throws std::invalid_argument (naming the field) for bad space weather or
  // a non-positive reference temperature.
  JacchiaScaledHarrisPriester(HarrisPriester table, SpaceWeather weather, JacchiaOptions options = {});

  // Density (kg/m^3) at t; r_ecef_m gives the WGS84 height, r_eci_m and
  // r_sun_eci_m the latitude, the Sun's declination and the hour angle.
  // 0 above 1000 km; throws std::out_of_range below 100 km (decayed).
  [[nodiscard]] double density_kgpm3(astro::TimeTT t, const Vec3& r_eci_m, const Vec3& r_ecef_m,
                                     const Vec3& r_sun_eci_m) const;
  // T_inf (K) at t over the point r_eci_m.
  [[nodiscard]] double exospheric_temperature_K(astro::TimeTT t, const Vec3& r_eci_m,
                                                const Vec3& r_sun_eci_m) const;
  // The density ratio against the table's night minimum for T_inf at a
  // height (no semi-annual term): 1 when T_inf = T_ref.
  [[nodiscard]] double temperature_ratio(double t_inf_K, double height_m) const;

  // exp(delta(t)) of SpaceWeather's density error; 1 when it is off.
  [[nodiscard]] double density_error_factor(astro::TimeTT t) const;
  [[nodiscard]] const SpaceWeather& weather() const { return weather_; }
  [[nodiscard]] const JacchiaOptions& options() const { return options_; }

 private:
  HarrisPriester table_;
  SpaceWeather weather_;
  JacchiaOptions options_;
  std::vector<SpaceWeather::DensityErrorTerm> density_error_;
  double density_error_amplitude_ = 0.0;  // sigma sqrt(2 / N)
};

}  // namespace artms::dynamics
