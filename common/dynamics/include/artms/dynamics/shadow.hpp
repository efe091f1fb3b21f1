// Earth shadow (eclipse) function. The same function decides eclipse for the
// solar radiation pressure and, later, whether a camera target is lit.
#pragma once

#include "artms/astro/frames.hpp"

namespace artms::dynamics {

using astro::Vec3;

enum class ShadowModel { kCylindrical, kConical };

// Fraction of the solar disc visible from r_sat (0 = umbra, 1 = full sun),
// given geocentric Sun position r_sun (both ECI, meters). Conical model:
// Montenbruck & Gill section 3.4.2 (eqs. 3.79-3.87), with the Earth's
// equatorial radius and the Sun's radius; cylindrical: 0 or 1.
double sunlit_fraction(const Vec3& r_sat_m, const Vec3& r_sun_m,
                       ShadowModel model = ShadowModel::kConical);

// Cannonball solar radiation pressure (M&G eq. 3.75), with the shadow
// fraction: a = -nu P_sun Cr (A/m) (AU^2 / |s - r|^2) (s - r)/|s - r|,
// P_sun = 4.56e-6 N/m^2 at 1 AU.
inline constexpr double kSolarPressureAt1Au_Npm2 = 4.56e-6;
Vec3 srp_acceleration_mps2(const Vec3& r_sat_m, const Vec3& r_sun_m, double cr,
                           double area_to_mass_m2pkg, ShadowModel model = ShadowModel::kConical);

}  // namespace artms::dynamics
