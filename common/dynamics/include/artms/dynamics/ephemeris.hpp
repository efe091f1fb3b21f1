// Low-precision analytical Sun and Moon ephemerides (Montenbruck & Gill 2000,
// Satellite Orbits, section 3.3.2), geocentric, ECI J2000, meters.
// Accuracy: Sun ~0.1 deg / 0.1 %, Moon ~ several arcmin / 500 km (M&G);
// measured figures below each function.
#pragma once

#include "artms/astro/frames.hpp"
#include "artms/astro/time.hpp"

namespace artms::dynamics {

using astro::TimeTT;
using astro::Vec3;

inline constexpr double kGmSun_m3ps2 = 1.32712440018e20;   // DE405 / IERS
inline constexpr double kGmMoon_m3ps2 = 4.9028e12;         // DE405 / IERS
inline constexpr double kAstronomicalUnit_m = 149597870700.0;
inline constexpr double kRadiusSun_m = 696000e3;
inline constexpr double kRadiusMoon_m = 1738e3;

// Geocentric position of the Sun, ECI J2000 components (M&G eq. 3.43-3.46).
// M&G's longitude is referred to the J2000 equinox, so their optional
// +1.3972 deg/century term (which would refer it to the equinox of date) is
// not applied. Against astropy 5.2 (ERFA epv00) the direction error is
// < 0.005 deg + 0.33 deg per century from J2000 (0.10 deg in 2030) and the
// distance error < 1e-4 relative (ephemeris_test.cpp).
Vec3 sun_position_eci_m(TimeTT t);
// Geocentric position of the Moon, ECI J2000 components (M&G eq. 3.47-3.49).
// Against astropy 5.2 (ERFA moon98), 2000-2030: < 0.08 deg in direction, < 450 km in distance.
Vec3 moon_position_eci_m(TimeTT t);
// Velocity of the Earth's centre relative to the solar-system barycentre,
// ECI J2000 components (m/s): minus the rate of sun_position_eci_m (central
// difference over +-600 s). It leaves out the Sun's own motion about the
// barycentre (<= 13 m/s) and the Earth's about the Earth-Moon barycentre
// (12.6 m/s) and the perihelion's motion: against ERFA epv00, 1990-2040,
// within 100 m/s (0.07" of
// aberration; tests/oracle/dynamics_oracle_test.cpp). For stellar
// aberration (astro/aberration.hpp): the observer's velocity is this plus
// its geocentric velocity.
Vec3 earth_velocity_bcrs_mps(TimeTT t);

// Third-body perturbing acceleration on a satellite at r_sat of a body of
// gravitational parameter gm at r_body (both geocentric), M&G eq. 3.37:
// a = gm ((s - r)/|s - r|^3 - s/|s|^3).
Vec3 third_body_acceleration_mps2(const Vec3& r_sat_m, const Vec3& r_body_m, double gm_m3ps2);

}  // namespace artms::dynamics
