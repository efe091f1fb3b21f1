// Physical constants used across the project. SI units throughout.
#pragma once

#include <numbers>

namespace artms::astro {

inline constexpr double kPi = std::numbers::pi;
inline constexpr double kTwoPi = 2.0 * std::numbers::pi;
inline constexpr double kDegToRad = std::numbers::pi / 180.0;
inline constexpr double kRadToDeg = 180.0 / std::numbers::pi;
inline constexpr double kArcsecToRad = kDegToRad / 3600.0;

// GGM01S (Tapley et al. 2004), the gravity model ARTMS flies: GM and reference
// radius from the model's header (data/gravity/GGM01S.gfc).
inline constexpr double kGmEarth_m3ps2 = 398600.4415e9;
inline constexpr double kRadiusEarth_m = 6378136.3;
// J2 = -sqrt(5) * C20 (fully normalised C20 = -4.8416485210e-4 from the
// coefficient line of GGM01S.gfc; the header's value differs, see data/README).
inline constexpr double kJ2Earth = 1.082625521611732e-3;

// IERS nominal mean angular velocity of the Earth (rad/s).
inline constexpr double kEarthRotation_radps = 7.292115e-5;

inline constexpr double kSecondsPerDay = 86400.0;
inline constexpr double kDaysPerJulianCentury = 36525.0;

}  // namespace artms::astro
