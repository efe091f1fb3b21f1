#include "artms/dynamics/shadow.hpp"

#include <algorithm>
#include <cmath>

#include "artms/astro/constants.hpp"
#include "artms/dynamics/ephemeris.hpp"

namespace artms::dynamics {

namespace {

using astro::kPi;
using astro::kRadiusEarth_m;

double cylindrical_fraction(const Vec3& r_sat_m, const Vec3& r_sun_m) {
  // Shadow is the half-cylinder of radius R_E behind the Earth along -e_sun.
  const Vec3 e_sun = r_sun_m.normalized();
  const double along = r_sat_m.dot(e_sun);
  if (along >= 0.0) return 1.0;
  const double perp = (r_sat_m - along * e_sun).norm();
  return perp < kRadiusEarth_m ? 0.0 : 1.0;
}

double conical_fraction(const Vec3& r_sat_m, const Vec3& r_sun_m) {
  const Vec3 d_sun = r_sun_m - r_sat_m;  // satellite -> Sun
  const double d_sun_norm = d_sun.norm();
  const double r_norm = r_sat_m.norm();
  if (r_norm <= kRadiusEarth_m) return 0.0;  // inside the Earth: no sunlight
  // M&G section 3.4.2 (eqs. 3.79-3.87). Apparent radii of the Sun (a) and the Earth (b), and
  // their apparent separation (c), all seen from the satellite.
  const double a = std::asin(std::min(1.0, kRadiusSun_m / d_sun_norm));
  const double b = std::asin(kRadiusEarth_m / r_norm);
  const double cos_c = std::clamp(-r_sat_m.dot(d_sun) / (r_norm * d_sun_norm), -1.0, 1.0);
  const double c = std::acos(cos_c);

  if (c >= a + b) return 1.0;                      // discs do not overlap: full sun
  if (c <= b - a) return 0.0;                      // Sun disc entirely behind the Earth: umbra
  if (c <= a - b) return 1.0 - (b * b) / (a * a);  // Earth disc inside the Sun's (annular)
  // Partial overlap of the two discs (M&G): occulted area
  // A = a^2 acos(x/a) + b^2 acos((c-x)/b) - c y, x = (c^2+a^2-b^2)/(2c),
  // y = sqrt(a^2 - x^2).
  const double x = (c * c + a * a - b * b) / (2.0 * c);
  const double y = std::sqrt(std::max(0.0, a * a - x * x));
  const double area = a * a * std::acos(std::clamp(x / a, -1.0, 1.0)) +
                      b * b * std::acos(std::clamp((c - x) / b, -1.0, 1.0)) - c * y;
  // Visible fraction nu = 1 - A / (pi a^2).
  return std::clamp(1.0 - area / (kPi * a * a), 0.0, 1.0);
}

}  // namespace

double sunlit_fraction(const Vec3& r_sat_m, const Vec3& r_sun_m, ShadowModel model) {
  switch (model) {
    case ShadowModel::kCylindrical:
      return cylindrical_fraction(r_sat_m, r_sun_m);
    case ShadowModel::kConical:
      break;
  }
  return conical_fraction(r_sat_m, r_sun_m);
}

Vec3 srp_acceleration_mps2(const Vec3& r_sat_m, const Vec3& r_sun_m, double cr,
                           double area_to_mass_m2pkg, ShadowModel model) {
  // M&G eq. 3.75 with the shadow function nu: the pressure scales as
  // (AU / |s - r|)^2 and pushes along -(s - r)/|s - r| (away from the Sun).
  const double nu = sunlit_fraction(r_sat_m, r_sun_m, model);
  if (nu == 0.0) return Vec3::Zero();
  const Vec3 d_sun = r_sun_m - r_sat_m;
  const double d = d_sun.norm();
  const double scale = kAstronomicalUnit_m / d;
  return -nu * kSolarPressureAt1Au_Npm2 * cr * area_to_mass_m2pkg * scale * scale * (d_sun / d);
}

}  // namespace artms::dynamics
