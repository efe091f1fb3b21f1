#include "artms/imaging/photometry.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "artms/astro/constants.hpp"
#include "artms/dynamics/ephemeris.hpp"
#include "artms/dynamics/shadow.hpp"

namespace artms::imaging {

namespace {

using astro::kPi;

constexpr double kInf = std::numeric_limits<double>::infinity();

}  // namespace

double phase_angle_rad(const Vec3& r_target_eci_m, const Vec3& r_observer_eci_m,
                       const Vec3& r_sun_eci_m) {
  const Vec3 to_sun = r_sun_eci_m - r_target_eci_m;
  const Vec3 to_observer = r_observer_eci_m - r_target_eci_m;
  if (to_sun.norm() == 0.0 || to_observer.norm() == 0.0) {
    throw std::invalid_argument("phase_angle_rad: target coincides with the observer or the Sun");
  }
  // atan2(|a x b|, a.b) is accurate near 0 and pi, unlike acos.
  return std::atan2(to_sun.cross(to_observer).norm(), to_sun.dot(to_observer));
}

double lambert_phase(double alpha_rad) {
  const double a = std::clamp(alpha_rad, 0.0, kPi);
  // sin(pi - a) == sin(a), but exactly 0 at a = pi (sin(kPi) is 1.2e-16).
  const double b = kPi - a;
  return std::max(0.0, (b * std::cos(a) + std::sin(b)) / kPi);
}

double diffuse_sphere_vmag(double radius_m, double geometric_albedo, double range_m,
                           double alpha_rad, double sun_distance_m) {
  if (!(radius_m > 0.0) || !(range_m > 0.0) || !(sun_distance_m > 0.0) ||
      !(geometric_albedo >= 0.0)) {
    throw std::invalid_argument(
        "diffuse_sphere_vmag: radius, range and Sun distance must be > 0, albedo >= 0");
  }
  const double size = radius_m / range_m;
  const double sun = dynamics::kAstronomicalUnit_m / sun_distance_m;
  const double flux_ratio = geometric_albedo * size * size * lambert_phase(alpha_rad) * sun * sun;
  if (!(flux_ratio > 0.0)) return kInf;
  return kSunVmagAt1Au - 2.5 * std::log10(flux_ratio);
}

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

double hashed_uniform(std::uint64_t seed, std::uint64_t index, std::uint64_t stream) {
  // Chain the three words through the mixer so that neighbouring seeds,
  // indices and streams give unrelated outputs.
  const std::uint64_t h = splitmix64(splitmix64(splitmix64(seed) ^ stream) ^ index);
  return static_cast<double>(h >> 11) * 0x1.0p-53;
}

double hashed_normal(std::uint64_t seed, std::uint64_t index, std::uint64_t stream) {
  // Box-Muller with two uniforms from sub-streams; u1 in (0, 1] avoids log(0).
  const double u1 = 1.0 - hashed_uniform(seed, index, splitmix64(stream));
  const double u2 = hashed_uniform(seed, index, splitmix64(stream + 1));
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(astro::kTwoPi * u2);
}

TargetBrightness target_brightness(const Vec3& r_target_eci_m, const Vec3& r_observer_eci_m,
                                   const Vec3& r_sun_eci_m, const TargetOptics& optics,
                                   const TargetProfile& profile, std::uint64_t seed,
                                   std::uint64_t frame_index) {
  TargetBrightness b;
  b.range_m = (r_target_eci_m - r_observer_eci_m).norm();
  b.phase_angle_rad = phase_angle_rad(r_target_eci_m, r_observer_eci_m, r_sun_eci_m);
  // The same shadow function (conical, M&G 3.4.2) as the dynamics' SRP.
  b.sunlit_fraction =
      dynamics::sunlit_fraction(r_target_eci_m, r_sun_eci_m, dynamics::ShadowModel::kConical);
  b.lit = b.sunlit_fraction > 0.0;
  if (!b.lit) {
    b.vmag = kInf;
    return b;
  }
  double m = diffuse_sphere_vmag(optics.radius_m, optics.geometric_albedo, b.range_m,
                                 b.phase_angle_rad, (r_sun_eci_m - r_target_eci_m).norm());
  m -= 2.5 * std::log10(b.sunlit_fraction);
  m += profile.loss_mag;
  if (profile.scintillation_sigma_mag > 0.0) {
    m += profile.scintillation_sigma_mag * hashed_normal(seed, frame_index, kStreamScintillation);
  }
  b.vmag = m;
  return b;
}

double target_vmag(const Vec3& r_target_eci_m, const Vec3& r_observer_eci_m,
                   const Vec3& r_sun_eci_m, const TargetOptics& optics,
                   const TargetProfile& profile, std::uint64_t seed, std::uint64_t frame_index) {
  return target_brightness(r_target_eci_m, r_observer_eci_m, r_sun_eci_m, optics, profile, seed,
                           frame_index)
      .vmag;
}

}  // namespace artms::imaging
