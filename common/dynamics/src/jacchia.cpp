#include "artms/dynamics/jacchia.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "artms/astro/constants.hpp"

namespace artms::dynamics {

namespace {

using astro::kDegToRad;
using astro::kTwoPi;

// J71 diurnal and latitudinal variation of T_inf (Vallado 2013, B.1).
constexpr double kR = 0.3;
constexpr double kM = 2.2;
constexpr double kN = 3.0;
constexpr double kBeta_rad = -37.0 * kDegToRad;
constexpr double kP_rad = 6.0 * kDegToRad;
constexpr double kGamma_rad = 43.0 * kDegToRad;

// Scale-height law: atomic oxygen above J71's fixed boundary at 120 km.
constexpr double kBoltzmann_JpK = 1.380649e-23;
constexpr double kAtomicMassUnit_kg = 1.66053906660e-27;
constexpr double kOxygenMass_kg = 15.999 * kAtomicMassUnit_kg;
constexpr double kLowerBoundary_m = 120e3;

double wrap_pi(double a) {
  return std::remainder(a, kTwoPi);  // [-pi, pi]
}

void check_positive(double v, const std::string& field) {
  if (!(v > 0.0) || !std::isfinite(v)) {
    throw std::invalid_argument("space weather " + field + " must be a positive finite number, got " +
                                std::to_string(v));
  }
}

void check_kp(double v, const std::string& field) {
  if (!(v >= 0.0 && v <= 9.0)) {
    throw std::invalid_argument("space weather " + field + " must lie in [0, 9], got " + std::to_string(v));
  }
}

void check_sigma(double v, const std::string& field) {
  if (!(v >= 0.0) || !std::isfinite(v)) {
    throw std::invalid_argument("space weather " + field + " must be a finite number >= 0, got " +
                                std::to_string(v));
  }
}

// SplitMix64 (Steele, Lea & Flood 2014): a stateless hash of (seed, day).
std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

// Uniform in (0, 1) from 53 bits.
double unit_open(std::uint64_t bits) {
  return (static_cast<double>(bits >> 11) + 0.5) * 0x1.0p-53;
}

// Standard normal (Box-Muller) for one (seed, day, stream).
double day_normal(std::uint64_t seed, std::int64_t day, std::uint64_t stream) {
  const std::uint64_t base =
      splitmix64(splitmix64(seed ^ 0x5350414345574541ULL) + static_cast<std::uint64_t>(day) * 2 + stream);
  const double u1 = unit_open(splitmix64(base));
  const double u2 = unit_open(splitmix64(base ^ 0xD1B54A32D192ED03ULL));
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(kTwoPi * u2);
}

}  // namespace

void SpaceWeather::validate() const {
  check_positive(f107_sfu, "f107_sfu");
  check_positive(f107_81day_sfu, "f107_81day_sfu");
  check_kp(kp, "kp");
  for (std::size_t k = 0; k < daily.size(); ++k) {
    const std::string at = "daily[" + std::to_string(k) + "].";
    check_positive(daily[k].f107_sfu, at + "f107_sfu");
    check_kp(daily[k].kp, at + "kp");
  }
  check_sigma(f107_daily_sigma_sfu, "f107_daily_sigma_sfu");
  check_sigma(kp_daily_sigma, "kp_daily_sigma");
  check_sigma(density_error_sigma, "density_error_sigma");
  if (!(density_error_time_s > 0.0) || !std::isfinite(density_error_time_s)) {
    throw std::invalid_argument("space weather density_error_time_s must be a positive finite number, got " +
                                std::to_string(density_error_time_s));
  }
}

std::vector<SpaceWeather::DensityErrorTerm> SpaceWeather::density_error_terms() const {
  std::vector<DensityErrorTerm> out;
  if (!(density_error_sigma > 0.0)) return out;
  // Streams 0 and 1 of day_normal are the days' F10.7 and Kp (hashed at
  // 2 day + stream); the terms are hashed 2^40 further on.
  constexpr std::uint64_t kStream = std::uint64_t{1} << 40;
  for (int k = 0; k < kDensityErrorTerms; ++k) {
    const double w = day_normal(seed, k, kStream) / density_error_time_s;
    const double z = day_normal(seed, k, kStream + 1);
    // A uniform phase from a normal draw: its CDF, through erfc.
    const double u = 0.5 * std::erfc(-z / std::sqrt(2.0));
    out.push_back({w, kTwoPi * u});
  }
  return out;
}

SpaceWeather::Day SpaceWeather::at(astro::TimeTT t) const {
  const double day_f = std::floor(astro::seconds_between(start, t) / astro::kSecondsPerDay);
  const auto day = static_cast<std::int64_t>(day_f);
  if (day >= 0 && static_cast<std::size_t>(day) < daily.size()) {
    return daily[static_cast<std::size_t>(day)];
  }
  Day d{f107_sfu, kp};
  if (f107_daily_sigma_sfu > 0.0) {
    d.f107_sfu = std::max(0.3 * f107_sfu, f107_sfu + f107_daily_sigma_sfu * day_normal(seed, day, 0));
  }
  if (kp_daily_sigma > 0.0) d.kp = std::clamp(kp + kp_daily_sigma * day_normal(seed, day, 1), 0.0, 9.0);
  return d;
}

double jacchia71_exospheric_temperature_K(double lat_rad, double sun_dec_rad, double hour_angle_rad,
                                          double f107_sfu, double f107_81day_sfu, double kp) {
  // Nighttime minimum of the global exospheric temperature.
  const double t_c = 379.0 + 3.24 * f107_81day_sfu + 1.3 * (f107_sfu - f107_81day_sfu);
  // Diurnal and latitudinal variation.
  const double eta = 0.5 * std::abs(lat_rad - sun_dec_rad);
  const double theta = 0.5 * std::abs(lat_rad + sun_dec_rad);
  const double tau = wrap_pi(hour_angle_rad + kBeta_rad + kP_rad * std::sin(hour_angle_rad + kGamma_rad));
  const double s = std::pow(std::sin(theta), kM);
  const double c = std::pow(std::cos(eta), kM);
  const double t_l = t_c * (1.0 + kR * (s + (c - s) * std::pow(std::abs(std::cos(0.5 * tau)), kN)));
  // Geomagnetic activity (J71's temperature form, above ~200 km).
  return t_l + 28.0 * kp + 0.03 * std::exp(kp);
}

double jacchia71_semiannual_factor(astro::TimeTT t, double height_m) {
  // Phi: tropical years since 1958 January 1.0.
  const double z_km = std::max(height_m * 1e-3, 90.0);
  const double phi = (astro::julian_date_tt(t) - 2436204.5) / 365.2422;
  const double tau =
      phi + 0.09544 * (std::pow(0.5 + 0.5 * std::sin(kTwoPi * phi + 6.035), 1.65) - 0.5);
  const double f = (5.876e-7 * std::pow(z_km, 2.331) + 0.06328) * std::exp(-0.002868 * z_km);
  // g(t) without its constant 0.02835 (the annual mean).
  const double g = (0.3817 + 0.17829 * std::sin(kTwoPi * tau + 4.137)) * std::sin(2.0 * kTwoPi * tau + 4.259);
  return std::pow(10.0, f * g);
}

JacchiaScaledHarrisPriester::JacchiaScaledHarrisPriester(HarrisPriester table, SpaceWeather weather,
                                                         JacchiaOptions options)
    : table_(std::move(table)), weather_(std::move(weather)), options_(options) {
  weather_.validate();
  density_error_ = weather_.density_error_terms();
  if (!density_error_.empty()) {
    density_error_amplitude_ =
        weather_.density_error_sigma * std::sqrt(2.0 / static_cast<double>(density_error_.size()));
  }
  if (!(options_.reference_temperature_K > 0.0) || !std::isfinite(options_.reference_temperature_K)) {
    throw std::invalid_argument("Jacchia reference_temperature_K must be a positive finite number");
  }
}

double JacchiaScaledHarrisPriester::exospheric_temperature_K(astro::TimeTT t, const Vec3& r_eci_m,
                                                             const Vec3& r_sun_eci_m) const {
  const double lat = std::atan2(r_eci_m.z(), r_eci_m.head<2>().norm());
  const double dec_sun = std::atan2(r_sun_eci_m.z(), r_sun_eci_m.head<2>().norm());
  // Hour angle of the point from the Sun's meridian, positive in the afternoon.
  const double h = wrap_pi(std::atan2(r_eci_m.y(), r_eci_m.x()) - std::atan2(r_sun_eci_m.y(), r_sun_eci_m.x()));
  const SpaceWeather::Day d = weather_.at(t);
  return jacchia71_exospheric_temperature_K(lat, dec_sun, h, d.f107_sfu, weather_.f107_81day_sfu, d.kp);
}

double JacchiaScaledHarrisPriester::temperature_ratio(double t_inf_K, double height_m) const {
  // Isothermal diffusive equilibrium above h0: ln rho = const - m dPhi / (k T).
  const double r0 = astro::kRadiusEarth_m + kLowerBoundary_m;
  const double r = astro::kRadiusEarth_m + std::max(height_m, kLowerBoundary_m);
  const double dphi = astro::kGmEarth_m3ps2 * (1.0 / r0 - 1.0 / r);
  const double a = kOxygenMass_kg * dphi / kBoltzmann_JpK;  // K
  return std::exp(-a * (1.0 / t_inf_K - 1.0 / options_.reference_temperature_K));
}

double JacchiaScaledHarrisPriester::density_kgpm3(astro::TimeTT t, const Vec3& r_eci_m, const Vec3& r_ecef_m,
                                                  const Vec3& r_sun_eci_m) const {
  const double h = geodetic_height_m(r_ecef_m);
  const HarrisPriester::Densities d = table_.table_densities(h);
  if (d.min_kgpm3 == 0.0) return 0.0;
  double rho = d.min_kgpm3 * temperature_ratio(exospheric_temperature_K(t, r_eci_m, r_sun_eci_m), h);
  if (options_.semiannual) rho *= jacchia71_semiannual_factor(t, h);
  return rho * density_error_factor(t);
}

double JacchiaScaledHarrisPriester::density_error_factor(astro::TimeTT t) const {
  if (density_error_.empty()) return 1.0;
  const double dt = astro::seconds_between(weather_.start, t);
  double sum = 0.0;
  for (const auto& term : density_error_) sum += std::cos(term.w_rad_per_s * dt + term.phase_rad);
  return std::exp(density_error_amplitude_ * sum);
}

}  // namespace artms::dynamics
