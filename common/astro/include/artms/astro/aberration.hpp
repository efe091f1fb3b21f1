// Stellar aberration: the direction from which an observer moving with
// velocity v (relative to the solar-system barycentre) sees light that
// arrives from unit direction u in the barycentric frame. Special
// relativity's boost of the photon's momentum (Lorentz transformation of a
// null vector; e.g. Kaplan, USNO Circular 179, eq. 7.40 to first order):
//   u' = [u + (gamma - 1)(u . b_hat) b_hat + gamma b] / [gamma (1 + u . b)],
//   b = v / c,
// to first order u' = u + b - (u . b) u. For Starling (about 30 km/s about
// the Sun plus 7.6 km/s in orbit) the shift reaches 26". A nearby target's
// light time cancels all but the difference of the two velocities, which
// for spacecraft 50-150 km apart on one orbit is 57-164 m/s, 0.04-0.11"
// (neither the renderer nor IMP applies it). So a star tracker whose
// catalog is not aberrated puts its attitude, and every bearing, off by up
// to 26".
#pragma once

#include "artms/astro/frames.hpp"

namespace artms::astro {

inline constexpr double kSpeedOfLight_mps = 299792458.0;  // exact (SI)

// Apparent unit direction of a source at unit direction u for an observer
// moving at v_mps (same frame as u). Throws std::invalid_argument for
// |v| >= c or a zero u.
Vec3 aberrated_direction(const Vec3& u, const Vec3& v_mps);

}  // namespace artms::astro
