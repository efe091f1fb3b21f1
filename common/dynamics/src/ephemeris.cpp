#include "artms/dynamics/ephemeris.hpp"

#include <cmath>

#include "artms/astro/constants.hpp"

namespace artms::dynamics {

namespace {

using astro::kArcsecToRad;
using astro::kDegToRad;

// Obliquity of the ecliptic at J2000 (M&G section 3.3.2).
constexpr double kObliquityJ2000_rad = 23.43929111 * kDegToRad;

// Equatorial (ECI J2000) components of a point at ecliptic longitude lambda,
// latitude beta and distance r: R_x(-eps) * (ecliptic Cartesian vector).
Vec3 equatorial_from_ecliptic(double r, double lambda, double beta) {
  const Vec3 ecliptic(r * std::cos(lambda) * std::cos(beta), r * std::sin(lambda) * std::cos(beta),
                      r * std::sin(beta));
  return astro::rot1(-kObliquityJ2000_rad) * ecliptic;
}

}  // namespace

Vec3 sun_position_eci_m(TimeTT t) {
  const double T = t.julian_centuries();
  // M&G eq. 3.43-3.46: mean anomaly M, longitude of perigee Omega + omega =
  // 282.9400 deg, ecliptic longitude and distance. The longitude is referred
  // to the mean equinox and ecliptic of J2000 as it stands; M&G's optional
  // +1.3972 deg T (general precession) would refer it to the equinox of date
  // and is therefore NOT added for ECI J2000 output (against astropy it
  // triples the error: 0.33 deg instead of 0.10 deg in 2030). The remaining
  // error grows as ~0.33 deg per century (the perihelion's motion is absent
  // from the model), see ephemeris_test.cpp.
  const double M = (357.5256 + 35999.049 * T) * kDegToRad;
  const double lambda =
      282.9400 * kDegToRad + M + (6892.0 * std::sin(M) + 72.0 * std::sin(2.0 * M)) * kArcsecToRad;
  const double r_m = (149.619 - 2.499 * std::cos(M) - 0.021 * std::cos(2.0 * M)) * 1e9;
  return equatorial_from_ecliptic(r_m, lambda, 0.0);
}

Vec3 earth_velocity_bcrs_mps(TimeTT t) {
  constexpr double h_s = 600.0;
  return -(sun_position_eci_m(t.plus_seconds(h_s)) - sun_position_eci_m(t.plus_seconds(-h_s))) / (2.0 * h_s);
}

Vec3 moon_position_eci_m(TimeTT t) {
  const double T = t.julian_centuries();
  // M&G eq. 3.47-3.49 (fundamental arguments, longitude, latitude, distance).
  // L0 includes -1.3972 deg T (general precession) so that the mean longitude
  // is measured from the fixed equinox of J2000.
  const double L0 = (218.31617 + 481267.88088 * T - 1.3972 * T) * kDegToRad;  // mean longitude
  const double l = (134.96292 + 477198.86753 * T) * kDegToRad;                // Moon's mean anomaly
  const double lp = (357.52543 + 35999.04944 * T) * kDegToRad;                // Sun's mean anomaly
  const double F = (93.27283 + 483202.01873 * T) * kDegToRad;   // mean argument of latitude
  const double D = (297.85027 + 445267.11135 * T) * kDegToRad;  // mean elongation from the Sun

  // Ecliptic longitude perturbations (arcsec).
  const double dL =
      22640.0 * std::sin(l) + 769.0 * std::sin(2.0 * l) - 4586.0 * std::sin(l - 2.0 * D) +
      2370.0 * std::sin(2.0 * D) - 668.0 * std::sin(lp) - 412.0 * std::sin(2.0 * F) -
      212.0 * std::sin(2.0 * l - 2.0 * D) - 206.0 * std::sin(l + lp - 2.0 * D) +
      192.0 * std::sin(l + 2.0 * D) - 165.0 * std::sin(lp - 2.0 * D) + 148.0 * std::sin(l - lp) -
      125.0 * std::sin(D) - 110.0 * std::sin(l + lp) - 55.0 * std::sin(2.0 * F - 2.0 * D);
  const double lambda = L0 + dL * kArcsecToRad;

  // Ecliptic latitude; the argument of the main term is
  // F + lambda - L0 + 412" sin 2F + 541" sin l'.
  const double beta =
      (18520.0 *
           std::sin(F + (dL + 412.0 * std::sin(2.0 * F) + 541.0 * std::sin(lp)) * kArcsecToRad) -
       526.0 * std::sin(F - 2.0 * D) + 44.0 * std::sin(l + F - 2.0 * D) -
       31.0 * std::sin(-l + F - 2.0 * D) - 25.0 * std::sin(-2.0 * l + F) -
       23.0 * std::sin(lp + F - 2.0 * D) + 21.0 * std::sin(-l + F) +
       11.0 * std::sin(-lp + F - 2.0 * D)) *
      kArcsecToRad;

  // Distance (km).
  const double r_km = 385000.0 - 20905.0 * std::cos(l) - 3699.0 * std::cos(2.0 * D - l) -
                      2956.0 * std::cos(2.0 * D) - 570.0 * std::cos(2.0 * l) +
                      246.0 * std::cos(2.0 * l - 2.0 * D) - 205.0 * std::cos(lp - 2.0 * D) -
                      171.0 * std::cos(l + 2.0 * D) - 152.0 * std::cos(l + lp - 2.0 * D);

  return equatorial_from_ecliptic(r_km * 1e3, lambda, beta);
}

Vec3 third_body_acceleration_mps2(const Vec3& r_sat_m, const Vec3& r_body_m, double gm_m3ps2) {
  // M&G eq. 3.37: direct attraction on the satellite minus that on the Earth.
  const Vec3 d = r_body_m - r_sat_m;
  const double d3 = std::pow(d.norm(), 3);
  const double s3 = std::pow(r_body_m.norm(), 3);
  return gm_m3ps2 * (d / d3 - r_body_m / s3);
}

}  // namespace artms::dynamics
