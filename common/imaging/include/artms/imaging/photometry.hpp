// Target photometry: apparent visual magnitude of a swarm CubeSat seen by a
// star tracker, as a diffuse (Lambertian) sphere lit by the Sun.
//
// Model (Hejduk 2011, "Specular and diffuse components in spherical satellite
// photometric modeling", AMOS; McCue, Williams & Morford 1971, "Optical
// characteristics of artificial satellites"): a Lambertian sphere of radius R
// and geometric albedo p, at range d from the observer and r_s from the Sun,
// seen at solar phase angle alpha (Sun-target-observer), has
//
//   m = m_sun - 2.5 log10( p (R/d)^2 Phi(alpha) (1 AU / r_s)^2 )
//   Phi(alpha) = ((pi - alpha) cos alpha + sin alpha) / pi,  Phi(0) = 1,
//
// with m_sun = -26.74 (apparent V magnitude of the Sun at 1 AU). Phi is
// normalised to 1 at full phase, so p is the geometric albedo; its phase
// integral q = 2 int_0^pi Phi(a) sin a da = 3/2, hence the Bond albedo (the
// Lambertian surface reflectance rho) is A = p q = 1.5 p. Hejduk writes the
// same thing with the reflectance: (2/3) rho (R/d)^2 Phi(alpha).
//
// The model is "nominal": it is what a pre-flight analysis predicts. StarFOX
// found the swarm "significantly dimmer than expected in orbit" and lost
// targets beyond ~100 km (paper, "Navigation Mode 1" and "Lessons Learned");
// TargetProfile::flight_like() models that finding (see below).
#pragma once

#include <cstdint>

#include "artms/astro/frames.hpp"

namespace artms::imaging {

using astro::Vec3;

// Apparent V magnitude of the Sun at 1 AU (Willmer 2018, ApJS 236:47: -26.76;
// the value -26.74 is the one used by Hejduk 2011 and most of the
// space-object photometry literature, kept here for comparability).
inline constexpr double kSunVmagAt1Au = -26.74;

// Limiting V magnitude assumed for an NST-like star tracker detecting a point
// target against the noise of a single 12-bit frame. An assumption, not a
// datasheet value: star trackers of this class track stars to V ~ 6-7; 6.5 is
// the bright end, matching the paper's finding that SNR was lower than
// expected (hot pixels). With flight_like() it puts the default CubeSat's
// detection horizon near 100 km (docs/imaging_targets.md).
inline constexpr double kNstLikeLimitingVmag = 6.5;

// Optical properties of a target, modelled as a diffuse sphere.
struct TargetOptics {
  // Effective radius: a 6U CubeSat body of ~0.1 x 0.2 x 0.3 m has surface
  // area S = 0.22 m^2; a convex body's projected area averaged over all
  // orientations is S / 4 (Cauchy) = 0.055 m^2, i.e. the sphere of equal mean
  // cross-section has R = sqrt(0.055 / pi) = 0.132 m. (Solar arrays mostly
  // face the Sun and reflect specularly away from the observer; not counted.)
  double radius_m = 0.132;
  // Geometric albedo p (Bond albedo 1.5 p = 0.3): a typical satellite value
  // (diffuse reflectances 0.1-0.3 for MLI, anodised aluminium, solar-cell
  // glass; Hejduk 2011 and ESA MASTER assume 0.1-0.2 for the reflectance of
  // intact objects). It is the optimistic, pre-flight value on purpose.
  double geometric_albedo = 0.2;
};

// Brightness profile: the nominal diffuse-sphere model, or "flight-like" with
// the losses the paper observed added on top.
struct TargetProfile {
  enum class Kind { kNominal, kFlightLike };
  Kind kind = Kind::kNominal;
  // Constant magnitude added to the model (> 0 dims the target).
  double loss_mag = 0.0;
  // 1-sigma of a zero-mean Gaussian per-frame magnitude fluctuation
  // ("scintillation": here not atmospheric, but attitude-dependent glints and
  // dark faces of a box-shaped target), drawn deterministically from the
  // seed and the frame index.
  double scintillation_sigma_mag = 0.0;

  static TargetProfile nominal() { return {}; }
  // Flight-like: +1.5 mag constant loss (attitude-dependent reflectivity of
  // the faces actually seen along (anti-)velocity, and the star tracker's
  // deliberate defocus spreading a point target over more pixels, which
  // lowers its peak SNR like a dimmer source), plus 0.3 mag per-frame
  // fluctuation. These numbers are a model of the paper's qualitative finding
  // ("significantly dimmer than expected", targets beyond ~100 km frequently
  // lost), chosen so that the default CubeSat crosses kNstLikeLimitingVmag
  // near 100 km at moderate phase angles; they are NOT measured values.
  static TargetProfile flight_like() { return {Kind::kFlightLike, 1.5, 0.3}; }
};

// Sun-target-observer angle in [0, pi] (0 = full phase, target lit from
// behind the observer). Positions are geocentric ECI in meters. Throws
// std::invalid_argument if the target coincides with the observer or the Sun.
double phase_angle_rad(const Vec3& r_target_eci_m, const Vec3& r_observer_eci_m,
                       const Vec3& r_sun_eci_m);

// Lambertian-sphere phase function Phi(alpha) above, normalised to Phi(0) = 1
// (Phi(pi/2) = 1/pi, Phi(pi) = 0). alpha is clamped to [0, pi].
double lambert_phase(double alpha_rad);

// Diffuse-sphere apparent V magnitude (formula above). +inf if the phase
// function or any factor is zero. Throws std::invalid_argument for a
// non-positive range, Sun distance or radius, or a negative albedo.
double diffuse_sphere_vmag(double radius_m, double geometric_albedo, double range_m,
                           double alpha_rad, double sun_distance_m);

// Deterministic per-frame random numbers (independent of call order, so any
// process rendering frame k of a seeded run draws the same values).
// splitmix64 (Steele, Lea & Flood 2014, "Fast splittable pseudorandom number
// generators", OOPSLA; the finaliser of Vigna's reference implementation).
std::uint64_t splitmix64(std::uint64_t x);
// Uniform in [0, 1) from (seed, index, stream): 53 high bits of the hash.
// `stream` separates independent uses of the same (seed, index).
double hashed_uniform(std::uint64_t seed, std::uint64_t index, std::uint64_t stream);
// Standard normal from (seed, index, stream) by Box-Muller.
double hashed_normal(std::uint64_t seed, std::uint64_t index, std::uint64_t stream);

// Stream ids used by this library (documented so that no two uses collide).
inline constexpr std::uint64_t kStreamScintillation = 0x5C1A'7111ULL;
inline constexpr std::uint64_t kStreamFrameDropout = 0xD209'0017ULL;

struct TargetBrightness {
  double vmag = 0.0;             // +inf when unlit
  bool lit = false;              // sunlit_fraction > 0
  double sunlit_fraction = 0.0;  // dynamics::sunlit_fraction, conical model
  double phase_angle_rad = 0.0;
  double range_m = 0.0;
};

// Apparent V magnitude of a target: diffuse sphere at the actual Sun distance,
// dimmed by the conical Earth-shadow sunlit fraction nu (-2.5 log10 nu, so
// penumbra fades the target and umbra gives +inf), plus the profile's loss
// and per-frame fluctuation (seed, frame_index). All positions geocentric ECI
// in meters.
TargetBrightness target_brightness(const Vec3& r_target_eci_m, const Vec3& r_observer_eci_m,
                                   const Vec3& r_sun_eci_m, const TargetOptics& optics = {},
                                   const TargetProfile& profile = TargetProfile::nominal(),
                                   std::uint64_t seed = 0, std::uint64_t frame_index = 0);

// Just the magnitude of target_brightness (+inf when unlit).
double target_vmag(const Vec3& r_target_eci_m, const Vec3& r_observer_eci_m,
                   const Vec3& r_sun_eci_m, const TargetOptics& optics = {},
                   const TargetProfile& profile = TargetProfile::nominal(), std::uint64_t seed = 0,
                   std::uint64_t frame_index = 0);

}  // namespace artms::imaging
