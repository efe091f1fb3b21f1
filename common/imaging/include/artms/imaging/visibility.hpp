// Target visibility (is a swarm member in this frame, and if not, why),
// camera exclusion (Sun / Moon / bright Earth in or near the field of view)
// and frame faults (drop-outs, time-tag offset and drift). The paper's
// lessons modelled here: eclipses interrupt tracking, targets beyond ~100 km
// are often too faint, sun intrusion into the FOV was not modelled before
// flight, and star-tracker time tags drifted against the GPS clock
// (docs/imaging_targets.md).
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "artms/astro/constants.hpp"
#include "artms/astro/frames.hpp"
#include "artms/astro/time.hpp"
#include "artms/imaging/photometry.hpp"

namespace artms::imaging {

using astro::Mat3;
using astro::TimeTT;

// ---------------------------------------------------------------- visibility

// Reasons (the truth sidecar's `reason` strings, DESIGN.md section 7).
inline constexpr const char* kReasonVisible = "visible";
inline constexpr const char* kReasonEclipse = "eclipse";
inline constexpr const char* kReasonOcculted = "occulted by Earth";
inline constexpr const char* kReasonOutsideFov = "outside field of view";
inline constexpr const char* kReasonTooFaint = "too faint";

// Height above the Earth's equatorial radius below which a line of sight is
// treated as blocked: ~100 km (the Karman line) is where the atmosphere
// becomes optically significant for grazing rays (refraction, extinction,
// airglow layer at 85-100 km), so a target seen through it is not detectable.
// The same sphere, R_E + 100 km, is the "bright Earth" of the limb exclusion.
inline constexpr double kAtmosphereMargin_m = 100e3;

// Line of sight in ECI (observer -> target, any length) -> is it inside the
// sensor's field of view. Empty function: no field-of-view check.
using InFov = std::function<bool(const Vec3& los_eci)>;

// Circular field of view of half-angle half_angle_rad about boresight_eci.
InFov conical_fov(const Vec3& boresight_eci, double half_angle_rad);
// Rectangular pinhole field of view: camera frame z = boresight (conventions:
// x along +column, y along +row); inside if Z > 0, |X/Z| <= tan(half_x) and
// |Y/Z| <= tan(half_y). NST: half angles 6 x 5 deg (paper Table 1).
InFov rectangular_fov(const Mat3& R_cam_from_eci, double half_x_rad, double half_y_rad);

struct VisibilityOptions {
  // "eclipse" when the conical sunlit fraction of the target is below this.
  // 0.5 (half the solar disc hidden) puts the boundary mid-penumbra; above it
  // the -2.5 log10(nu) dimming (< 0.75 mag) is left to the "too faint" check.
  double min_sunlit_fraction = 0.5;
  double atmosphere_margin_m = kAtmosphereMargin_m;
  // "too faint" when vmag > limiting_vmag (+inf disables the check).
  double limiting_vmag = kNstLikeLimitingVmag;
  TargetOptics optics{};
  TargetProfile profile = TargetProfile::nominal();
};

struct TargetVisibility {
  bool visible = false;
  std::string reason;            // one of the kReason* strings
  double sunlit_fraction = 0.0;  // conical model (dynamics::sunlit_fraction)
  double vmag = 0.0;             // always computed; +inf when unlit
  double range_m = 0.0;
  double phase_angle_rad = 0.0;
};

// True if the segment observer -> target passes within radius_m of the
// Earth's centre (closest point of the segment, not of the infinite line, so
// a target in front of the Earth is not occulted by the Earth behind it).
bool line_of_sight_blocked(const Vec3& r_observer_eci_m, const Vec3& r_target_eci_m,
                           double radius_m = astro::kRadiusEarth_m + kAtmosphereMargin_m);

// Visibility of one target in one frame. The reason is the first failing
// check in this order: eclipse, occulted by Earth, outside field of view,
// too faint; "visible" otherwise. vmag includes the profile's per-frame
// fluctuation drawn from (seed, frame_index).
TargetVisibility target_visibility(const Vec3& r_target_eci_m, const Vec3& r_observer_eci_m,
                                   const Vec3& r_sun_eci_m, const InFov& in_fov,
                                   const VisibilityOptions& options = {}, std::uint64_t seed = 0,
                                   std::uint64_t frame_index = 0);

// ----------------------------------------------------------------- exclusion

// Exclusion half-angles measured from the boresight. Assumptions typical of
// small star trackers with a standard baffle, not NST datasheet values:
// - Sun 45 deg: baffled star trackers quote 30-45 deg; the larger value
//   because the paper found sun intrusion worse than modelled.
// - Moon 15 deg: the Moon is ~1e-6 of the Sun's brightness, so a few degrees
//   beyond the NST's 7.8 deg half-diagonal.
// - Earth limb 15 deg: from Starling's a = 6943 km the limb of the R_E + 100 km
//   sphere lies 90 - asin(6478/6943) = 21.1 deg below the horizontal, and
//   StarFOX imaged along +-velocity (horizontal) routinely, so the NST's
//   effective Earth exclusion must be below ~21 deg; nano trackers quote
//   ~25-30 deg for full stray-light rejection (APST: 27 deg, Muruganandan et
//   al. 2017, Trans. JSASS 60(6)), which would forbid the flight geometry.
struct ExclusionAngles {
  double sun_rad = 45.0 * astro::kDegToRad;
  double moon_rad = 15.0 * astro::kDegToRad;
  double earth_limb_rad = 15.0 * astro::kDegToRad;
  double atmosphere_margin_m = kAtmosphereMargin_m;
};

inline constexpr const char* kExclusionNone = "none";
inline constexpr const char* kExclusionSun = "sun exclusion";
inline constexpr const char* kExclusionMoon = "moon exclusion";
inline constexpr const char* kExclusionEarthLimb = "earth limb exclusion";

struct ExclusionResult {
  bool excluded = false;
  std::string reason;  // one of the kExclusion* strings
};

// Angular radius of the Earth (sphere of radius R_E + margin) seen from
// r_observer: asin(R / |r|).
double earth_angular_radius_rad(const Vec3& r_observer_eci_m,
                                double atmosphere_margin_m = kAtmosphereMargin_m);

// Is the camera blinded? boresight_eci: unit (or any non-zero) vector of the
// camera boresight in ECI; positions geocentric ECI in meters. First match in
// the order Sun, Moon, Earth limb:
// - Sun: angle(boresight, Sun seen from the observer) < sun_rad, unless the
//   Sun is hidden by the Earth (observer's conical sunlit fraction is 0).
// - Moon: angle(boresight, Moon) < moon_rad, unless the Earth sphere blocks
//   the line of sight to the Moon's centre.
// - Earth limb: angle(boresight, nadir) < earth angular radius + earth_limb_rad,
//   i.e. the boresight is within earth_limb_rad of the limb or on the disc.
//   Applied whether or not the Earth below is sunlit: the night side still
//   has airglow, city lights and a twilight limb, and the simplification is
//   conservative (it only removes frames).
ExclusionResult camera_exclusion(const Vec3& boresight_eci, const Vec3& r_observer_eci_m,
                                 const Vec3& r_sun_eci_m, const Vec3& r_moon_eci_m,
                                 const ExclusionAngles& angles = {});

// -------------------------------------------------------------- frame faults

// Per-observer faults (scenario `faults[]`, config/swarms/SCHEMA.md).
struct FrameFaults {
  double dropout_probability = 0.0;  // per frame, 0 <= p < 1
  double time_tag_offset_s = 0.0;    // paper: -0.4 s correction, varying per spacecraft
  double time_tag_drift_ppm = 0.0;   // paper: time tags "appeared to drift over time"
};

// Deterministic drop-out: hashed_uniform(seed, frame_index, kStreamFrameDropout) < p.
// The same (seed, frame_index, p) always gives the same answer, whatever the
// order of the calls. p <= 0: never; p >= 1: always.
bool frame_dropped(std::uint64_t seed, std::uint64_t frame_index, double p);

// Time tag written on a frame taken at true_t:
// true_t + offset + drift_ppm * 1e-6 * (true_t - epoch), rounded to the
// nanosecond. epoch is when the camera clock was last synchronised (the
// scenario epoch).
TimeTT time_tag(TimeTT true_t, TimeTT epoch, const FrameFaults& faults);

}  // namespace artms::imaging
