#include "artms/imaging/renderer.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "artms/astro/aberration.hpp"
#include "artms/astro/constants.hpp"
#include "artms/dynamics/ephemeris.hpp"
#include "artms/dynamics/shadow.hpp"

namespace artms::imaging {

std::uint64_t frame_seed(std::uint64_t base, const std::string& observer, std::uint64_t frame_index) {
  std::uint64_t h = splitmix64(base);
  for (const char c : observer) h = splitmix64(h ^ static_cast<unsigned char>(c));
  return splitmix64(h ^ frame_index);
}

FrameRenderer::FrameRenderer(CameraModel camera, StarCatalog catalog, RenderOptions options)
    : former_(std::move(camera)), catalog_(std::move(catalog)), options_(std::move(options)) {}

namespace {
constexpr double kBandDeg = 1.0;  // faint-star sky cells: 1 deg declination bands
constexpr std::uint64_t kStreamFaint = 0xFA1E'57A2ULL;
}  // namespace

std::vector<PointSource> FrameRenderer::faint_star_sources(const Eigen::Quaterniond& q, const Vec3* v_obs_mps,
                                                           std::size_t* count) const {
  std::vector<PointSource> out;
  *count = 0;
  if (!options_.faint_stars) return out;
  const CameraModel& cam = camera();
  const Eigen::Matrix3d R = q.toRotationMatrix();  // R_cam_from_eci
  const Vec3 boresight = R.row(2).transpose();
  const double half_diag = std::atan(std::hypot(cam.width_px / cam.fx_px, cam.height_px / cam.fy_px) / 2.0);
  const double dec0 = std::asin(std::clamp(boresight.z(), -1.0, 1.0)) * astro::kRadToDeg;
  const double ra0 = std::atan2(boresight.y(), boresight.x()) * astro::kRadToDeg;
  const double reach = half_diag * astro::kRadToDeg + kBandDeg;
  // Sky cells: 1 deg bands in declination, each cut into RA cells of ~1 deg
  // on the sky. Cell contents come from hashes of the cell index only.
  const int band_lo = static_cast<int>(std::floor(std::max(-90.0, dec0 - reach)));
  const int band_hi = static_cast<int>(std::floor(std::min(89.999, dec0 + reach)));
  const double mmin = options_.faint_star_min_vmag, mmax = options_.faint_star_max_vmag;
  // N(<m) ~ 10^(0.48 m) (Galactic-average star counts): inverse CDF sampling.
  const double a0 = std::pow(10.0, 0.48 * mmin), a1 = std::pow(10.0, 0.48 * mmax);
  for (int band = band_lo; band <= band_hi; ++band) {
    const double dec_c = (band + 0.5) * kBandDeg * astro::kDegToRad;
    const int n_ra = std::max(1, static_cast<int>(std::round(360.0 * std::cos(dec_c) / kBandDeg)));
    const double cell_ra_deg = 360.0 / n_ra;
    const double cos_dec = std::max(std::cos(dec_c), 1e-3);
    const double ra_reach = std::min(180.0, reach / cos_dec + cell_ra_deg);
    const int c_lo = static_cast<int>(std::floor((ra0 - ra_reach) / cell_ra_deg));
    const int c_hi = static_cast<int>(std::floor((ra0 + ra_reach) / cell_ra_deg));
    for (int c = c_lo; c <= c_hi; ++c) {
      if (c_hi - c_lo + 1 > n_ra && c >= c_lo + n_ra) break;  // whole band already covered
      const int cell = ((c % n_ra) + n_ra) % n_ra;
      const std::uint64_t id = (static_cast<std::uint64_t>(band + 90) << 20) | static_cast<std::uint64_t>(cell);
      // Area of the cell in deg^2, and a Poisson count with that mean.
      const double area = cell_ra_deg * kBandDeg *
                          (std::sin((band + 1) * kBandDeg * astro::kDegToRad) -
                           std::sin(band * kBandDeg * astro::kDegToRad)) /
                          (kBandDeg * astro::kDegToRad);
      const double mean = options_.faint_stars_per_deg2 * area;
      int n = 0;
      double p = std::exp(-mean), cdf = p;
      const double u = hashed_uniform(options_.sky_seed, id, kStreamFaint);
      while (u > cdf && n < 1000) {
        ++n;
        p *= mean / n;
        cdf += p;
      }
      for (int k = 0; k < n; ++k) {
        const std::uint64_t idx = id * 1024 + static_cast<std::uint64_t>(k);
        const double ra = (cell + hashed_uniform(options_.sky_seed, idx, kStreamFaint + 1)) * cell_ra_deg;
        const double s0 = std::sin(band * kBandDeg * astro::kDegToRad);
        const double s1 = std::sin((band + 1) * kBandDeg * astro::kDegToRad);
        const double sdec = s0 + (s1 - s0) * hashed_uniform(options_.sky_seed, idx, kStreamFaint + 2);
        const double cdec = std::sqrt(std::max(0.0, 1.0 - sdec * sdec));
        const double ra_rad = ra * astro::kDegToRad;
        const Vec3 u_cat(cdec * std::cos(ra_rad), cdec * std::sin(ra_rad), sdec);
        const Vec3 u_eci = v_obs_mps ? astro::aberrated_direction(u_cat, *v_obs_mps) : u_cat;
        const auto px = cam.project(R * u_eci, 4.0 * cam.psf_sigma_px);
        if (!px) continue;
        const double w = hashed_uniform(options_.sky_seed, idx, kStreamFaint + 3);
        const double vmag = std::log10(a0 + w * (a1 - a0)) / 0.48;
        // Colour: B-V uniform in [0, 1.5] (the bulk of V 6.5-9 field stars).
        const double bv = 1.5 * hashed_uniform(options_.sky_seed, idx, kStreamFaint + 4);
        out.push_back({px->x(), px->y(), cam.electrons_from_vmag(vmag), bv});
        ++*count;
      }
    }
  }
  return out;
}

RenderedFrame FrameRenderer::render(const RenderRequest& req) const {
  const CameraModel& cam = camera();
  RenderedFrame f;
  f.t_true = req.t;
  f.time_tag = time_tag(req.t, options_.fault_epoch, options_.faults);
  f.width = cam.width_px;
  f.height = cam.height_px;
  const std::uint64_t seed = frame_seed(options_.noise_seed, req.observer, req.frame_index);
  f.dropped = frame_dropped(seed, req.frame_index, options_.faults.dropout_probability);

  const Eigen::Matrix3d R = req.q_cam_from_eci.toRotationMatrix();
  const Vec3 boresight = R.row(2).transpose();
  const Vec3 r_obs = req.observer_eci.r_m;
  const Vec3 r_sun = dynamics::sun_position_eci_m(req.t);
  const Vec3 r_moon = dynamics::moon_position_eci_m(req.t);
  ExclusionAngles angles;
  angles.sun_rad = cam.sun_exclusion_rad;
  angles.moon_rad = cam.moon_exclusion_rad;
  angles.earth_limb_rad = cam.earth_limb_exclusion_rad;
  f.exclusion = camera_exclusion(boresight, r_obs, r_sun, r_moon, angles);

  // Catalog stars, aberrated by the observer's barycentric velocity.
  std::optional<Vec3> v_obs;
  if (options_.stellar_aberration) v_obs = dynamics::earth_velocity_bcrs_mps(req.t) + req.observer_eci.v_mps;
  const Vec3* v_obs_ptr = v_obs ? &*v_obs : nullptr;
  const auto stars = stars_in_frame(catalog_, cam, req.q_cam_from_eci, req.t, 4.0 * cam.psf_sigma_px, v_obs_ptr);
  std::vector<PointSource> sources = point_sources(stars);
  for (const auto& s : stars) {
    if (!cam.on_sensor(Vec2(s.x_px, s.y_px))) continue;
    // RA/Dec at the frame epoch (proper motion applied), as imaged.
    const Vec3 u = v_obs_ptr ? astro::aberrated_direction(s.star->unit_eci_at(req.t), *v_obs_ptr)
                             : s.star->unit_eci_at(req.t);
    f.stars.push_back({s.star->catalog_id, std::atan2(u.y(), u.x()) * astro::kRadToDeg,
                       std::asin(std::clamp(u.z(), -1.0, 1.0)) * astro::kRadToDeg, s.star->vmag,
                       s.x_px, s.y_px});
  }
  // Faint uncatalogued stars.
  auto faint = faint_star_sources(req.q_cam_from_eci, v_obs_ptr, &f.faint_stars);
  sources.insert(sources.end(), faint.begin(), faint.end());

  // Targets.
  VisibilityOptions vis;
  vis.limiting_vmag = options_.limiting_vmag;
  vis.optics = options_.optics;
  vis.profile = options_.profile;
  const InFov in_fov = [&](const Vec3& los_eci) { return cam.in_fov(R * los_eci); };
  for (const auto& t : req.targets) {
    const TargetVisibility v =
        target_visibility(t.r_eci_m, r_obs, r_sun, in_fov, vis, options_.noise_seed, req.frame_index);
    TargetTruth tt;
    tt.id = t.id;
    tt.vmag = v.vmag;
    tt.range_m = v.range_m;
    tt.reason = v.reason;
    const auto px = cam.project_unbounded(R * (t.r_eci_m - r_obs));
    tt.x_px = px ? px->x() : std::numeric_limits<double>::quiet_NaN();
    tt.y_px = px ? px->y() : std::numeric_limits<double>::quiet_NaN();
    // A lit, unoccluded target in the field is drawn whatever its magnitude
    // (faint ones sink into the noise); "visible" says it should be detectable.
    const bool drawable = px && std::isfinite(v.vmag) && v.reason != kReasonOcculted &&
                          v.reason != kReasonEclipse && cam.on_sensor(*px, 4.0 * cam.psf_sigma_px);
    if (drawable) sources.push_back({px->x(), px->y(), cam.electrons_from_vmag(v.vmag)});
    tt.visible = v.visible && !f.exclusion.excluded;
    if (v.visible && f.exclusion.excluded) tt.reason = f.exclusion.reason;
    f.targets.push_back(tt);
  }
  if (f.dropped) return f;
  // Sun in or near the field washes the frame out.
  std::vector<StrayLight> stray;
  const Vec3 sun_cam = R * (r_sun - r_obs).normalized();
  if (f.exclusion.excluded && f.exclusion.reason == kExclusionSun) {
    if (auto s = sun_washout(cam, sun_cam)) stray.push_back(*s);
  }
  // Stray light from the bodies near their exclusion cones (CameraModel::stray_*).
  const bool sun_up = dynamics::sunlit_fraction(r_obs, r_sun, dynamics::ShadowModel::kConical) > 0.0;
  if (sun_up) {
    if (auto s = stray_light_beyond_exclusion(cam, sun_cam, cam.sun_exclusion_rad, cam.stray_sun_edge_e_per_px_per_s)) {
      stray.push_back(*s);
    }
  }
  if (cam.stray_moon_edge_e_per_px_per_s > 0.0 &&
      !line_of_sight_blocked(r_obs, r_moon, astro::kRadiusEarth_m + kAtmosphereMargin_m)) {
    // Illuminated fraction (1 + cos phase) / 2, the phase angle at the Moon
    // between the Sun and the observer.
    const double cos_phase = (r_sun - r_moon).normalized().dot((r_obs - r_moon).normalized());
    if (auto s = stray_light_beyond_exclusion(cam, R * (r_moon - r_obs).normalized(), cam.moon_exclusion_rad,
                                              cam.stray_moon_edge_e_per_px_per_s * 0.5 * (1.0 + cos_phase))) {
      stray.push_back(*s);
    }
  }
  if (cam.stray_earth_edge_e_per_px_per_s > 0.0) {
    // The limb point nearest the boresight: from the observer, the direction
    // at the Earth's angular radius from nadir, in the plane of nadir and
    // the boresight; its local vertical decides how sunlit it is.
    const Vec3 nadir = (-r_obs).normalized();
    const double rho = earth_angular_radius_rad(r_obs);
    Vec3 side = boresight - boresight.dot(nadir) * nadir;
    if (side.norm() < 1e-9) side = nadir.unitOrthogonal();
    side.normalize();
    const Vec3 to_limb = std::cos(rho) * nadir + std::sin(rho) * side;
    const double dist = r_obs.norm() * std::cos(rho);  // tangent length
    const Vec3 limb_point = r_obs + dist * to_limb;
    const double cos_zenith = limb_point.normalized().dot((r_sun - limb_point).normalized());
    if (cos_zenith > 0.0) {
      if (auto s = stray_light_beyond_exclusion(cam, R * to_limb, cam.earth_limb_exclusion_rad,
                                                cam.stray_earth_edge_e_per_px_per_s * cos_zenith)) {
        stray.push_back(*s);
      }
    }
  }
  f.pixels = former_.render(sources, seed, options_.noise, stray);
  // Pixel encoding: DN shifted up as the camera stores them (MSB-aligned).
  if (cam.dn_shift_bits > 0) {
    for (auto& v : f.pixels) v = static_cast<std::uint16_t>(v << cam.dn_shift_bits);
  }
  return f;
}

}  // namespace artms::imaging
