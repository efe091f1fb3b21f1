#include "artms/imaging/visibility.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "artms/dynamics/shadow.hpp"

namespace artms::imaging {

namespace {

// Angle between two non-zero vectors, accurate at 0 and pi.
double angle_between(const Vec3& a, const Vec3& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

}  // namespace

InFov conical_fov(const Vec3& boresight_eci, double half_angle_rad) {
  if (boresight_eci.norm() == 0.0) throw std::invalid_argument("conical_fov: zero boresight");
  const Vec3 b = boresight_eci.normalized();
  return [b, half_angle_rad](const Vec3& los_eci) {
    return los_eci.norm() > 0.0 && angle_between(b, los_eci) <= half_angle_rad;
  };
}

InFov rectangular_fov(const Mat3& R_cam_from_eci, double half_x_rad, double half_y_rad) {
  const double tx = std::tan(half_x_rad);
  const double ty = std::tan(half_y_rad);
  return [R_cam_from_eci, tx, ty](const Vec3& los_eci) {
    const Vec3 c = R_cam_from_eci * los_eci;
    return c.z() > 0.0 && std::abs(c.x()) <= tx * c.z() && std::abs(c.y()) <= ty * c.z();
  };
}

bool line_of_sight_blocked(const Vec3& r_observer_eci_m, const Vec3& r_target_eci_m,
                           double radius_m) {
  // Closest point to the Earth's centre on the segment P(s) = o + s d, s in [0, 1].
  const Vec3 d = r_target_eci_m - r_observer_eci_m;
  const double dd = d.squaredNorm();
  const double s = dd > 0.0 ? std::clamp(-r_observer_eci_m.dot(d) / dd, 0.0, 1.0) : 0.0;
  return (r_observer_eci_m + s * d).norm() < radius_m;
}

TargetVisibility target_visibility(const Vec3& r_target_eci_m, const Vec3& r_observer_eci_m,
                                   const Vec3& r_sun_eci_m, const InFov& in_fov,
                                   const VisibilityOptions& options, std::uint64_t seed,
                                   std::uint64_t frame_index) {
  const TargetBrightness b = target_brightness(r_target_eci_m, r_observer_eci_m, r_sun_eci_m,
                                               options.optics, options.profile, seed, frame_index);
  TargetVisibility v;
  v.sunlit_fraction = b.sunlit_fraction;
  v.vmag = b.vmag;
  v.range_m = b.range_m;
  v.phase_angle_rad = b.phase_angle_rad;
  v.visible = false;
  if (b.sunlit_fraction < options.min_sunlit_fraction) {
    v.reason = kReasonEclipse;
  } else if (line_of_sight_blocked(r_observer_eci_m, r_target_eci_m,
                                   astro::kRadiusEarth_m + options.atmosphere_margin_m)) {
    v.reason = kReasonOcculted;
  } else if (in_fov && !in_fov(r_target_eci_m - r_observer_eci_m)) {
    v.reason = kReasonOutsideFov;
  } else if (!(b.vmag <= options.limiting_vmag)) {
    v.reason = kReasonTooFaint;
  } else {
    v.visible = true;
    v.reason = kReasonVisible;
  }
  return v;
}

double earth_angular_radius_rad(const Vec3& r_observer_eci_m, double atmosphere_margin_m) {
  const double r = r_observer_eci_m.norm();
  const double radius = astro::kRadiusEarth_m + atmosphere_margin_m;
  // Inside the sphere the Earth fills (at least) a hemisphere.
  if (r <= radius) return astro::kPi / 2.0;
  return std::asin(radius / r);
}

ExclusionResult camera_exclusion(const Vec3& boresight_eci, const Vec3& r_observer_eci_m,
                                 const Vec3& r_sun_eci_m, const Vec3& r_moon_eci_m,
                                 const ExclusionAngles& angles) {
  if (boresight_eci.norm() == 0.0) throw std::invalid_argument("camera_exclusion: zero boresight");
  const double earth_radius_m = astro::kRadiusEarth_m + angles.atmosphere_margin_m;

  const bool sun_up = dynamics::sunlit_fraction(r_observer_eci_m, r_sun_eci_m,
                                                dynamics::ShadowModel::kConical) > 0.0;
  if (sun_up && angle_between(boresight_eci, r_sun_eci_m - r_observer_eci_m) < angles.sun_rad) {
    return {true, kExclusionSun};
  }
  const bool moon_up = !line_of_sight_blocked(r_observer_eci_m, r_moon_eci_m, earth_radius_m);
  if (moon_up && angle_between(boresight_eci, r_moon_eci_m - r_observer_eci_m) < angles.moon_rad) {
    return {true, kExclusionMoon};
  }
  const double nadir_angle = angle_between(boresight_eci, -r_observer_eci_m);
  if (nadir_angle < earth_angular_radius_rad(r_observer_eci_m, angles.atmosphere_margin_m) +
                        angles.earth_limb_rad) {
    return {true, kExclusionEarthLimb};
  }
  return {false, kExclusionNone};
}

bool frame_dropped(std::uint64_t seed, std::uint64_t frame_index, double p) {
  if (!(p > 0.0)) return false;
  if (p >= 1.0) return true;
  return hashed_uniform(seed, frame_index, kStreamFrameDropout) < p;
}

TimeTT time_tag(TimeTT true_t, TimeTT epoch, const FrameFaults& faults) {
  const double elapsed_ns = static_cast<double>(true_t.ns_since_j2000 - epoch.ns_since_j2000);
  const double error_ns =
      faults.time_tag_offset_s * 1e9 + faults.time_tag_drift_ppm * 1e-6 * elapsed_ns;
  return TimeTT{true_t.ns_since_j2000 + static_cast<std::int64_t>(std::llround(error_ns))};
}

}  // namespace artms::imaging
