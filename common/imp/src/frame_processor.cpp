#include "artms/imp/frame_processor.hpp"

#include "artms/astro/aberration.hpp"
#include "artms/imp/qmethod.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <stdexcept>

namespace artms::imp {

void PersistenceOptions::validate() const {
  auto bad = [](const char* f) { throw std::invalid_argument(std::string("PersistenceOptions.") + f + " out of range"); };
  if (!(hot_pixel_tolerance_px > 0.0)) bad("hot_pixel_tolerance_px");
  if (hot_pixel_min_repeats < 1) bad("hot_pixel_min_repeats");
  if (!(hot_pixel_min_age_s >= 0.0)) bad("hot_pixel_min_age_s");
  if (!(star_tolerance_rad > 0.0)) bad("star_tolerance_rad");
  if (hot_map_min_frames < 1) bad("hot_map_min_frames");
  if (!(hot_map_radius_px >= 0.0)) bad("hot_map_radius_px");
  if (history_frames < 1) bad("history_frames");
  if (!(history_max_age_s > 0.0)) bad("history_max_age_s");
}

namespace {

// A centroid's 1-sigma (pixels) with blend_sigma_px added when it is a blend
// (FrameProcessorOptions).
double blend_sigma_px(double sigma_px, bool blended, const FrameProcessorOptions& o) {
  return blended ? std::hypot(sigma_px, o.blend_sigma_px) : sigma_px;
}

}  // namespace

void FrameProcessorOptions::validate() const {
  star_id.validate();
  persistence.validate();
  if (!(tracking_tolerance_rad > 0.0)) throw std::invalid_argument("FrameProcessorOptions.tracking_tolerance_rad out of range");
  if (!(prior_max_age_s >= 0.0)) throw std::invalid_argument("FrameProcessorOptions.prior_max_age_s out of range");
  if (!(blend_radius_px >= 0.0)) throw std::invalid_argument("FrameProcessorOptions.blend_radius_px out of range");
  if (!(blend_sigma_px >= 0.0)) throw std::invalid_argument("FrameProcessorOptions.blend_sigma_px out of range");
  if (!(blend_chi2_z > 0.0)) throw std::invalid_argument("FrameProcessorOptions.blend_chi2_z out of range");
  if (!(focal_search_fraction >= 0.0 && focal_search_fraction < 0.5)) {
    throw std::invalid_argument("FrameProcessorOptions.focal_search_fraction out of range [0, 0.5)");
  }
}

FrameProcessor::FrameProcessor(Intrinsics intrinsics, const StarIdCatalog& catalog, FrameProcessorOptions options)
    : K_(intrinsics), K_nominal_(intrinsics), catalog_(catalog), opt_(std::move(options)) {
  K_.validate();
  opt_.validate();
}

FrameSummary FrameProcessor::process(std::span<const std::uint16_t> pixels, astro::TimeTT t,
                                     const std::optional<Eigen::Vector3d>& observer_velocity_mps) {
  const double t_s = t.seconds_since_j2000();
  // A catalog direction as this observer sees it (aberrated when its
  // velocity is given).
  const auto apparent = [&](const Eigen::Vector3d& u_eci) -> Eigen::Vector3d {
    return observer_velocity_mps ? astro::aberrated_direction(u_eci, *observer_velocity_mps) : u_eci;
  };
  FrameSummary out;
  out.psf_sigma_px = opt_.detection.psf_sigma_px;
  const DetectionResult det = detect(pixels, K_.width, K_.height, opt_.detection);
  out.detections = static_cast<int>(det.centroids.size());
  if (last_.attitude_usable && keep_recent_ > 0) {
    recent_.push_front(std::move(last_));
    while (recent_.size() > keep_recent_) recent_.pop_back();
  }
  last_ = Last{};
  last_.t_s = t_s;
  last_.noise_dn = det.noise_dn;
  for (const auto& c : det.centroids) last_.detections_px.emplace_back(c.x_px, c.y_px);
  for (const std::size_t k : det.hot_suspects) {
    const Eigen::Vector2d px(static_cast<double>(k % static_cast<std::size_t>(K_.width)),
                             static_cast<double>(k / static_cast<std::size_t>(K_.width)));
    last_.hot_px.push_back(px);
    if (++hot_counts_[k] == opt_.persistence.hot_map_min_frames) hot_known_px_.push_back(px);
  }
  // Brightest first (Pyramid uses the first max_stars).
  std::vector<std::size_t> order(det.centroids.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](auto a, auto b) { return det.centroids[a].flux_dn > det.centroids[b].flux_dn; });
  std::vector<Eigen::Vector3d> dirs;
  dirs.reserve(order.size());
  for (auto i : order) dirs.push_back(K_.unproject({det.centroids[i].x_px, det.centroids[i].y_px}));
  if (prior_ && std::abs(t_s - prior_t_s_) > opt_.prior_max_age_s) prior_.reset();
  StarIdResult id;
  bool found_by_search = false;
  // Centroid pixels in identification order (the focal-length search and
  // its refinement re-project them).
  std::vector<Eigen::Vector2d> px;
  if (opt_.focal_search_fraction > 0.0) {
    px.reserve(order.size());
    for (auto i : order) px.emplace_back(det.centroids[i].x_px, det.centroids[i].y_px);
  }
  if (det.usable && dirs.size() >= 3) {
    if (prior_) {
      id = identify_with_prior(dirs, catalog_, *prior_, opt_.tracking_tolerance_rad, opt_.star_id);
      out.used_prior = id.usable;
    }
    if (!id.usable) id = identify_lost_in_space(dirs, catalog_, opt_.star_id);
    if (!id.usable && opt_.focal_search_fraction > 0.0) {
      const StarIdResult nominal = id;
      if (search_focal_length(px, dirs, id)) {
        found_by_search = true;
      } else {
        id = nominal;
        id.why += "; also with the focal length scaled within +-" +
                  std::to_string(static_cast<int>(std::lround(100.0 * opt_.focal_search_fraction))) + " %";
      }
    }
  }
  if (id.usable && opt_.focal_search_fraction > 0.0 && !found_by_search && focal_scale_ != 1.0) {
    // The camera file's focal length failed on an earlier frame: every frame
    // identified since gets its own scale (tetra3 fits a field of view per
    // image); a camera file that identifies is trusted as it is.
    const double s_frame = refine_focal_scale(px, id, focal_scale_);
    if (std::abs(s_frame - 1.0) <= opt_.focal_search_fraction) {
      use_focal_scale(s_frame);
      dirs = directions_at(px, s_frame);
    }
  }
  out.focal_scale = focal_scale_;
  if (id.usable && opt_.focal_search_fraction > 0.0 && focal_scale_ != 1.0 && id.matches.size() >= 3) {
    // Half the second difference of N rms^2 over +-1e-4 of scale (the loss
    // is quadratic in the scale this near its minimum).
    const double h = 1e-4, n = static_cast<double>(id.matches.size());
    const auto loss = [&](double s) {
      const double r = scale_residual_rad(px, id, s);
      return n * r * r;
    };
    const double info = 0.5 * (loss(focal_scale_ + h) - 2.0 * loss(focal_scale_) + loss(focal_scale_ - h)) / (h * h);
    out.focal_scale_information = std::isfinite(info) && info > 0.0 ? info : 0.0;
  }
  out.status = !det.usable || dirs.size() < 3 ? "no_detections" : (id.usable ? "ok" : "not_identified");
  if (!det.usable) {
    out.why = det.why;
  } else if (dirs.size() < 3) {
    out.why = std::to_string(dirs.size()) + " detections (3 needed for identification)";
  } else if (!id.usable) {
    out.why = id.why;
  }
  if (!id.usable) {
    prior_.reset();
    return out;
  }
  // Attitude by Davenport's q-method from the identified stars, each
  // weighted by its centroid's 1/sigma^2 (the identification's own Kabsch
  // solution is the fallback should the q-method be unusable).
  std::vector<WeightedPair> pairs;
  for (const auto& [idx, cat_id] : id.matches) {
    const auto& c = det.centroids[order[static_cast<std::size_t>(idx)]];
    // A star whose single-PSF fit shows a neighbour (an uncatalogued star
    // beside it) is weighted as a blend, like a candidate below.
    const double s = std::max(blend_sigma_px(c.sigma_px, c.psf_chi2_z > opt_.blend_chi2_z, opt_), 0.01) / K_.fx;
    pairs.push_back({dirs[static_cast<std::size_t>(idx)],
                     apparent(catalog_.stars()[static_cast<std::size_t>(catalog_.index_of(cat_id))].u_eci),
                     1.0 / (s * s)});
  }
  AttitudeSolution q = q_method(pairs);
  // Stars that scatter far more than their centroid sigmas say (a real
  // camera: seeing, optics, catalog; eq. below) are re-weighted with a
  // common systematic term s added to every sigma, s such that
  //   sum_i |b_i - A r_i|^2 / (sigma_i^2 + s^2) = 2N - 3
  // (variance component estimation); otherwise the brightest star's photon
  // bound outweighs all others. Frames whose stars fit their sigmas
  // (chi^2 / dof <= 2) keep the photon weights.
  if (q.usable && pairs.size() >= 3) {
    const double dof = 2.0 * static_cast<double>(pairs.size()) - 3.0;
    const Eigen::Matrix3d A = q.q_body_from_ref.toRotationMatrix();
    std::vector<double> r2(pairs.size()), s2(pairs.size());
    double chi2 = 0.0;
    for (std::size_t i = 0; i < pairs.size(); ++i) {
      r2[i] = (pairs[i].body - A * pairs[i].reference).squaredNorm();
      s2[i] = 1.0 / pairs[i].weight;
      chi2 += r2[i] / s2[i];
    }
    if (chi2 > 2.0 * dof) {
      const auto excess = [&](double sys2) {
        double c = 0.0;
        for (std::size_t i = 0; i < pairs.size(); ++i) c += r2[i] / (s2[i] + sys2);
        return c - dof;
      };
      double lo = 0.0, hi = *std::max_element(r2.begin(), r2.end());
      for (int it = 0; it < 60 && excess(hi) > 0.0; ++it) hi *= 2.0;
      for (int it = 0; it < 60; ++it) {
        const double mid = 0.5 * (lo + hi);
        (excess(mid) > 0.0 ? lo : hi) = mid;
      }
      for (std::size_t i = 0; i < pairs.size(); ++i) pairs[i].weight = 1.0 / (s2[i] + hi);
      const AttitudeSolution again = q_method(pairs);
      if (again.usable) q = again;
    }
  }
  out.attitude_usable = true;
  out.stars_matched = static_cast<int>(id.matches.size());
  if (q.usable) {
    out.q_cam_from_eci = q.q_body_from_ref;
    out.residual_rms_rad = q.residual_rms_rad;
    // Per-axis attitude 1-sigma across the boresight: the q-method
    // covariance, scaled by the a-posteriori variance of unit weight when the
    // stars scatter more than their centroid sigmas say (uncatalogued stars
    // beside catalog ones, catalog errors): 2 loss = sum w |b - A r|^2 has
    // expectation 2N - 3 (two angles per star, three fitted).
    const double dof = 2.0 * static_cast<double>(pairs.size()) - 3.0;
    const double unit_variance = dof > 0.0 ? std::max(1.0, 2.0 * q.loss / dof) : 1.0;
    out.attitude_sigma_rad =
        std::sqrt(0.5 * (q.covariance_rad2(0, 0) + q.covariance_rad2(1, 1)) * unit_variance);
  } else {
    out.q_cam_from_eci = id.q_cam_from_eci;
    out.residual_rms_rad = id.residual_rms_rad;
    out.attitude_sigma_rad = id.residual_rms_rad;
  }
  prior_ = out.q_cam_from_eci;
  prior_t_s_ = t_s;
  if (opt_.learn_psf) {
    std::vector<double> w;
    for (const auto& [idx, cat_id] : id.matches) {
      const auto& c = det.centroids[order[static_cast<std::size_t>(idx)]];
      if (!c.saturated && c.moment_sigma_px > 0.0 && c.peak_dn > 20.0 * det.noise_dn) {
        w.push_back(c.moment_sigma_px);
      }
    }
    if (w.size() >= 3) {
      std::nth_element(w.begin(), w.begin() + static_cast<long>(w.size() / 2), w.end());
      psf_widths_.push_back(w[w.size() / 2]);
      if (psf_widths_.size() > 10) psf_widths_.pop_front();
      std::vector<double> m(psf_widths_.begin(), psf_widths_.end());
      std::nth_element(m.begin(), m.begin() + static_cast<long>(m.size() / 2), m.end());
      opt_.detection.psf_sigma_px = std::clamp(m[m.size() / 2], 0.3, 5.0);
    }
  }
  {
    const Eigen::Matrix3d R_cam_from_eci = out.q_cam_from_eci.toRotationMatrix();
    for (const auto& [idx, cat_id] : id.matches) {
      const auto& c = det.centroids[order[static_cast<std::size_t>(idx)]];
      const Eigen::Vector3d u_cat =
          R_cam_from_eci * apparent(catalog_.stars()[static_cast<std::size_t>(catalog_.index_of(cat_id))].u_eci);
      const Eigen::Vector3d& u_meas = dirs[static_cast<std::size_t>(idx)];
      out.stars.push_back({c.x_px, c.y_px, cat_id, std::atan2(u_meas.cross(u_cat).norm(), u_meas.dot(u_cat)),
                           c.saturated, blend_sigma_px(c.sigma_px, c.psf_chi2_z > opt_.blend_chi2_z, opt_)});
    }
  }

  std::vector<bool> is_star(order.size(), false);
  for (const auto& [idx, cat] : id.matches) is_star[static_cast<std::size_t>(idx)] = true;
  const Eigen::Matrix3d R_eci_from_cam = out.q_cam_from_eci.toRotationMatrix().transpose();
  last_.attitude_usable = true;
  last_.attitude_sigma_rad = out.attitude_sigma_rad;
  last_.R_eci_from_cam = R_eci_from_cam;
  if (keep_recent_ > 0) last_.pixels.assign(pixels.begin(), pixels.end());
  // Forget frames beyond the history window.
  while (!history_.empty() && (static_cast<int>(history_.size()) >= opt_.persistence.history_frames ||
                               t_s - history_.front().t_s > opt_.persistence.history_max_age_s)) {
    history_.pop_front();
  }
  // Catalogued stars on the sensor at this attitude (set_blend_stars): a
  // target spot on one (closer than blend_radius_px, often too close to be
  // detected on its own: a V 6.53 star 1.1 px from a V 5.3 target moved the
  // centroid 0.43 px, 15", in starling_pse_flight at 11:35) is a blend.
  std::vector<Eigen::Vector2d> catalog_px;
  {
    const double cos_fov = std::cos(K_.half_diagonal_fov_rad());
    const Eigen::Vector3d boresight_eci = R_eci_from_cam.col(2);
    const auto add = [&](const Eigen::Vector3d& u_eci) {
      if (u_eci.dot(boresight_eci) < cos_fov) return;
      if (const auto star_px = K_.project(R_eci_from_cam.transpose() * apparent(u_eci))) catalog_px.push_back(*star_px);
    };
    if (blend_stars_.empty()) {
      for (const auto& cs : catalog_.stars()) add(cs.u_eci);
    } else {
      for (const auto& u : blend_stars_) add(u);
    }
  }
  last_.catalog_px = catalog_px;
  const auto& P = opt_.persistence;
  const double cos_star = std::cos(P.star_tolerance_rad);
  Seen now{t_s, {}, {}};
  for (std::size_t n = 0; n < order.size(); ++n) {
    if (is_star[n]) continue;
    const auto& c = det.centroids[order[n]];
    Candidate cand;
    cand.x_px = c.x_px;
    cand.y_px = c.y_px;
    cand.flux_dn = c.flux_dn;
    cand.u_cam = dirs[n];
    cand.u_eci = (R_eci_from_cam * dirs[n]).normalized();
    cand.psf_chi2_z = c.psf_chi2_z;
    cand.blended = c.psf_chi2_z > opt_.blend_chi2_z;
    for (const auto& o : det.centroids) {
      const double d = std::hypot(o.x_px - c.x_px, o.y_px - c.y_px);
      if (d > 0.0 && d < opt_.blend_radius_px) cand.blended = true;
    }
    for (const auto& sp : catalog_px) {
      if ((sp - Eigen::Vector2d(c.x_px, c.y_px)).norm() < opt_.blend_radius_px) {
        cand.blended = true;
        cand.on_catalog_star = true;
      }
    }
    cand.sigma_rad = std::hypot(blend_sigma_px(c.sigma_px, cand.blended, opt_) / K_.fx, out.attitude_sigma_rad);
    cand.signal_dn = c.signal_dn;
    cand.signal_variance_dn2 = window_signal_variance_dn2(opt_.detection, c.signal_dn, c.noise_dn);
    cand.noise_dn = c.noise_dn;
    cand.psf_width_px = c.psf_width_px;
    cand.weight_width_px = c.weight_width_px;
    cand.saturated = c.saturated;
    cand.attitude_sigma_rad = out.attitude_sigma_rad;
    now.px.emplace_back(c.x_px, c.y_px);
    now.u_eci.push_back(cand.u_eci);
    // Uncatalogued star: same inertial direction as an object of an earlier frame.
    bool star = false;
    int repeats = 0;
    bool old_enough = false;
    for (const auto& h : history_) {
      for (const auto& u : h.u_eci) {
        if (u.dot(cand.u_eci) > cos_star) star = true;
      }
      for (const auto& p : h.px) {
        if ((p - Eigen::Vector2d(c.x_px, c.y_px)).norm() < P.hot_pixel_tolerance_px) {
          ++repeats;
          if (t_s - h.t_s >= P.hot_pixel_min_age_s) old_enough = true;
          break;
        }
      }
    }
    if (star) {
      ++out.uncatalogued_stars_removed;
      continue;
    }
    const Eigen::Vector2d cp(c.x_px, c.y_px);
    if (std::any_of(hot_known_px_.begin(), hot_known_px_.end(),
                    [&](const Eigen::Vector2d& h) { return (h - cp).norm() < P.hot_map_radius_px; })) {
      ++out.hot_pixels_removed;
      continue;
    }
    if (repeats >= P.hot_pixel_min_repeats && old_enough) {
      ++out.hot_pixels_removed;
      continue;
    }
    out.candidates.push_back(cand);
  }
  history_.push_back(std::move(now));
  return out;
}

std::optional<bool> FrameProcessor::source_at(std::span<const std::uint16_t> pixels, const Eigen::Vector3d& u_eci,
                                              const AidedDetectionOptions& options, double tolerance_px) const {
  return source_in(last_, pixels, u_eci, options, tolerance_px);
}

std::optional<bool> FrameProcessor::source_before(const Eigen::Vector3d& u_eci, const AidedDetectionOptions& options,
                                                  double tolerance_px) const {
  for (const Last& frame : recent_) {
    if (const auto r = source_in(frame, frame.pixels, u_eci, options, tolerance_px)) return r;
  }
  return std::nullopt;
}

std::optional<FrameProcessor::StackedSky> FrameProcessor::stacked_sky(std::span<const std::uint16_t> pixels,
                                                                       const Eigen::Vector3d& u_eci,
                                                                       const Eigen::Vector2d& detection_px,
                                                                       const AidedDetectionOptions& options,
                                                                       double ring_px,
                                                                       double neighbour_false_alarms) const {
  const int R = static_cast<int>(std::floor(ring_px));
  constexpr double kInner = 1.5;
  // Offsets in the stack; the star field between frames a minute apart
  // moves by a translation (the camera turns about an axis across its
  // boresight), so whole-pixel offsets carry over.
  std::vector<Eigen::Vector2d> offsets;
  for (int dy = -R; dy <= R; ++dy)
    for (int dx = -R; dx <= R; ++dx)
      if (std::hypot(dx, dy) <= ring_px) offsets.emplace_back(dx, dy);
  // Per offset: the sum of nu over the frames that see it clear of hot
  // pixels (fixed on the sensor, not in the sky: this frame's lone sharp
  // pixels and the learned map) anywhere under the kernel (half-width
  // ceil(3 s)), and their count.
  std::vector<double> sum(offsets.size(), 0.0);
  std::vector<int> count(offsets.size(), 0);
  int frames = 0;
  const double r_kernel = std::ceil(3.0 * options.psf_sigma_px) + 0.5;
  const auto add = [&](const Last& frame, std::span<const std::uint16_t> px) {
    if (!frame.attitude_usable || !(frame.noise_dn > 0.0)) return;
    if (px.size() != static_cast<std::size_t>(K_.width) * static_cast<std::size_t>(K_.height)) return;
    const auto p = K_.project(frame.R_eci_from_cam.transpose() * u_eci);
    if (!p || (*p - detection_px).norm() < ring_px + 4.0) return;
    std::vector<Eigen::Vector2d> hot;
    for (const auto& h : hot_pixels(frame))
      if ((h - *p).norm() < ring_px + 2.0 * r_kernel) hot.push_back(h);
    std::vector<std::optional<double>> nu(offsets.size());
    for (std::size_t i = 0; i < offsets.size(); ++i) {
      const Eigen::Vector2d q = *p + offsets[i];
      const auto v = imp::forced_snr(px, K_.width, K_.height, q, frame.noise_dn, options.psf_sigma_px);
      if (!v) return;  // too close to the edge
      if (std::none_of(hot.begin(), hot.end(),
                       [&](const Eigen::Vector2d& h) { return (h - q).cwiseAbs().maxCoeff() <= r_kernel; }))
        nu[i] = *v;
    }
    for (std::size_t i = 0; i < offsets.size(); ++i) {
      if (!nu[i]) continue;
      sum[i] += *nu[i];
      ++count[i];
    }
    ++frames;
  };
  add(last_, pixels);
  for (const Last& frame : recent_) add(frame, frame.pixels);
  if (frames == 0) return std::nullopt;
  StackedSky out;
  out.frames = frames;
  for (std::size_t i = 0; i < offsets.size(); ++i) {
    if (count[i] == 0) continue;
    const double nu = sum[i] / std::sqrt(static_cast<double>(count[i])), d = offsets[i].norm();
    if (d == 0.0) out.snr_at = nu;
    if (d >= kInner && nu > out.neighbour_snr) {
      out.neighbour_snr = nu;
      out.neighbour_offset_px = offsets[i];
    }
  }
  const SearchRegion annulus{std::numbers::pi * (ring_px * ring_px - kInner * kInner),
                             2.0 * std::numbers::pi * (ring_px + kInner)};
  out.neighbour_threshold = false_alarm_threshold_snr(neighbour_false_alarms, annulus, options.psf_sigma_px);
  return out;
}

void FrameProcessor::keep_recent_frames(int n) {
  keep_recent_ = static_cast<std::size_t>(std::max(0, n));
  while (recent_.size() > keep_recent_) recent_.pop_back();
}

std::vector<Eigen::Vector2d> FrameProcessor::hot_pixels(const Last& frame) const {
  std::vector<Eigen::Vector2d> hot = frame.hot_px;
  hot.insert(hot.end(), hot_known_px_.begin(), hot_known_px_.end());
  return hot;
}

std::optional<bool> FrameProcessor::source_in(const Last& frame, std::span<const std::uint16_t> pixels,
                                              const Eigen::Vector3d& u_eci, const AidedDetectionOptions& options,
                                              double tolerance_px) const {
  if (!frame.attitude_usable) return std::nullopt;
  if (pixels.size() != static_cast<std::size_t>(K_.width) * static_cast<std::size_t>(K_.height)) return std::nullopt;
  const auto px = K_.project(frame.R_eci_from_cam.transpose() * u_eci);
  if (!px || px->x() < 8.0 || px->y() < 8.0 || px->x() > K_.width - 9.0 || px->y() > K_.height - 9.0)
    return std::nullopt;
  const std::vector<Eigen::Vector2d> hot = hot_pixels(frame);  // not sources
  const double r_hot = opt_.persistence.hot_map_radius_px;
  const auto near_hot = [&](const Eigen::Vector2d& p) {
    return std::any_of(hot.begin(), hot.end(), [&](const Eigen::Vector2d& h) { return (h - p).norm() < r_hot; });
  };
  for (const auto& d : frame.detections_px) {
    if ((d - *px).norm() <= tolerance_px + 1.0 && !near_hot(d)) return true;
  }
  AidedDetectionOptions o = options;
  o.min_separation_px = r_hot;
  const auto a = detect_near_prediction(pixels, K_.width, K_.height, *px,
                                        tolerance_px * tolerance_px * Eigen::Matrix2d::Identity(), frame.noise_dn, hot, o);
  return a.found || a.peaks > 1;
}

double FrameProcessor::sigma_rad_for_signal(const Candidate& c, double signal_dn, double signal_variance_dn2) const {
  const double sigma_px = centroid_sigma_px(opt_.detection, signal_dn, c.noise_dn, c.psf_width_px,
                                            c.weight_width_px, c.saturated, signal_variance_dn2);
  return std::hypot(blend_sigma_px(sigma_px, c.blended, opt_) / K_.fx, c.attitude_sigma_rad);
}

std::optional<double> FrameProcessor::forced_snr(std::span<const std::uint16_t> pixels, const Eigen::Vector2d& px,
                                                 const AidedDetectionOptions& options) const {
  if (!(last_.noise_dn > 0.0)) return std::nullopt;
  return imp::forced_snr(pixels, K_.width, K_.height, px, last_.noise_dn, options.psf_sigma_px);
}

Candidate FrameProcessor::aided_candidate_at(const AidedDetection& a, const Eigen::Vector2d& px,
                                             double sigma_px, bool blended_before) const {
  Candidate cand;
  cand.x_px = px.x();
  cand.y_px = px.y();
  cand.flux_dn = a.centroid.flux_dn;
  cand.u_cam = K_.unproject(px);
  cand.u_eci = (last_.R_eci_from_cam * cand.u_cam).normalized();
  // The blend rules of process()'s candidates: a poor single-PSF fit, a
  // detection or a catalogued star within blend_radius_px.
  const auto within = [&](const std::vector<Eigen::Vector2d>& pts) {
    return std::any_of(pts.begin(), pts.end(),
                       [&](const Eigen::Vector2d& q) { return (q - px).norm() < opt_.blend_radius_px; });
  };
  cand.psf_chi2_z = a.psf_chi2_z;
  cand.on_catalog_star = within(last_.catalog_px);
  cand.blended =
      a.psf_chi2_z > opt_.blend_chi2_z || within(last_.detections_px) || cand.on_catalog_star || blended_before;
  cand.sigma_rad = std::hypot(blend_sigma_px(sigma_px, cand.blended, opt_) / K_.fx, last_.attitude_sigma_rad);
  cand.attitude_sigma_rad = last_.attitude_sigma_rad;
  cand.aided = true;
  return cand;
}

std::optional<Candidate> FrameProcessor::aided_candidate(std::span<const std::uint16_t> pixels,
                                                        const Eigen::Vector2d& predicted_px,
                                                        const Eigen::Matrix2d& cov_px2,
                                                        const AidedDetectionOptions& options, std::string* why,
                                                        std::optional<SnrPrior> expected_snr) {
  auto refuse = [&](const std::string& reason) -> std::optional<Candidate> {
    if (why) *why = reason;
    return std::nullopt;
  };
  if (!last_.attitude_usable) return refuse("no attitude");
  // Stars and hot pixels are not the target.
  std::vector<Eigen::Vector2d> avoid = last_.detections_px;
  const std::vector<Eigen::Vector2d> hot = hot_pixels(last_);
  avoid.insert(avoid.end(), hot.begin(), hot.end());
  const AidedDetection a = detect_near_prediction(pixels, K_.width, K_.height, predicted_px, cov_px2, last_.noise_dn,
                                                  avoid, options);
  if (!a.found) return refuse(a.why);
  double sigma_px = a.centroid.sigma_px;
  if (expected_snr) {
    sigma_px = aided_centroid_sigma_px(snr_for_sigma(a.snr, *expected_snr), a.centroid.flux_dn, options,
                                       snr_posterior_variance(*expected_snr));
  }
  Candidate cand = aided_candidate_at(a, {a.centroid.x_px, a.centroid.y_px}, sigma_px);
  const auto& P = opt_.persistence;
  while (!aided_seen_.empty() && last_.t_s - aided_seen_.front().first > P.history_max_age_s) aided_seen_.pop_front();
  const double cos_star = std::cos(P.star_tolerance_rad);
  bool star = false;
  for (const auto& [t, u] : aided_seen_) {
    if (t < last_.t_s && u.dot(cand.u_eci) > cos_star) star = true;
  }
  aided_seen_.emplace_back(last_.t_s, cand.u_eci);
  if (star) return refuse("a faint star (same inertial direction as an earlier aided detection)");
  if (why) why->clear();
  return cand;
}

std::optional<Candidate> FrameProcessor::stacked_aided_candidate(std::span<const std::uint16_t> pixels,
                                                                const std::vector<StackedPrediction>& predictions,
                                                                const Eigen::Matrix2d& cov_px2,
                                                                const AidedDetectionOptions& options,
                                                                std::string* why) {
  auto refuse = [&](const std::string& reason) -> std::optional<Candidate> {
    if (why) *why = reason;
    return std::nullopt;
  };
  const std::size_t n = predictions.size();
  if (!last_.attitude_usable) return refuse("no attitude");
  if (n < 2) return refuse("fewer than 2 frames");
  if (pixels.size() != static_cast<std::size_t>(K_.width) * static_cast<std::size_t>(K_.height)) {
    return refuse("frame size");
  }
  // The frames: the last one, then the kept ones, each with its prediction.
  std::vector<const Last*> frames{&last_};
  std::vector<std::span<const std::uint16_t>> px{pixels};
  for (std::size_t k = 1; k < n; ++k) {
    if (k - 1 >= recent_.size()) return refuse("frames not kept");
    const Last& f = recent_[k - 1];
    if (std::abs(f.t_s - predictions[k].t_s) > 1e-6 || f.pixels.size() != pixels.size()) {
      return refuse("frames not kept");
    }
    frames.push_back(&f);
    px.emplace_back(f.pixels);
  }
  if (std::abs(last_.t_s - predictions[0].t_s) > 1e-6) return refuse("frames not kept");
  for (const auto& p : predictions)
    if (!p.px.allFinite()) return refuse("outside");
  // Whole-pixel shifts onto the last frame's prediction, and their rounding.
  std::vector<Eigen::Vector2i> shift(n);
  Eigen::Vector2d rounding = Eigen::Vector2d::Zero();
  for (std::size_t k = 0; k < n; ++k) {
    const Eigen::Vector2d d = predictions[0].px - predictions[k].px;
    shift[k] = Eigen::Vector2i(static_cast<int>(std::lround(d.x())), static_cast<int>(std::lround(d.y())));
    rounding += shift[k].cast<double>() - d;
  }
  rounding /= static_cast<double>(n);
  // The cutout (last frame's pixels) that detect_near_prediction reads.
  const double s = options.psf_sigma_px;
  const Eigen::Matrix2d S = cov_px2 + s * s * Eigen::Matrix2d::Identity();
  const double reach = std::sqrt(options.gate_chi2 * S.diagonal().maxCoeff());
  if (!std::isfinite(reach) || reach > options.max_half_window_px) return refuse("too wide");
  const int half = static_cast<int>(std::ceil(reach)) + static_cast<int>(std::ceil(3.0 * s)) + 2;
  const int cx = static_cast<int>(std::lround(predictions[0].px.x()));
  const int cy = static_cast<int>(std::lround(predictions[0].px.y()));
  const int ox = cx - half, oy = cy - half, w = 2 * half + 1;
  for (std::size_t k = 0; k < n; ++k) {
    const int x0 = ox - shift[k].x(), y0 = oy - shift[k].y();
    if (x0 < 0 || y0 < 0 || x0 + w > K_.width || y0 + w > K_.height) return refuse("outside");
  }
  std::vector<std::uint16_t> sum(static_cast<std::size_t>(w) * static_cast<std::size_t>(w));
  for (int y = 0; y < w; ++y)
    for (int x = 0; x < w; ++x) {
      std::uint32_t v = 0;
      for (std::size_t k = 0; k < n; ++k) {
        const int fx = ox + x - shift[k].x(), fy = oy + y - shift[k].y();
        v += px[k][static_cast<std::size_t>(fy) * static_cast<std::size_t>(K_.width) + static_cast<std::size_t>(fx)];
      }
      sum[static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x)] =
          static_cast<std::uint16_t>(std::min<std::uint32_t>(v, 65535u));
    }
  // Every frame's detections and hot pixels, where they fall in the stack.
  std::vector<Eigen::Vector2d> avoid;
  double noise2 = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    const Eigen::Vector2d to_stack = shift[k].cast<double>() - Eigen::Vector2d(ox, oy);
    for (const auto& q : frames[k]->detections_px) avoid.push_back(q + to_stack);
    for (const auto& q : hot_pixels(*frames[k])) avoid.push_back(q + to_stack);
    noise2 += frames[k]->noise_dn * frames[k]->noise_dn;
  }
  const Eigen::Vector2d predicted_in_stack = predictions[0].px - Eigen::Vector2d(ox, oy);
  const AidedDetection a =
      detect_near_prediction(sum, w, w, predicted_in_stack, cov_px2, std::sqrt(noise2), avoid, options);
  if (!a.found) return refuse(a.why);
  // The mean offset from the predictions, as the last frame's pixel.
  const Eigen::Vector2d offset =
      Eigen::Vector2d(a.centroid.x_px, a.centroid.y_px) - predicted_in_stack - rounding;
  const Eigen::Vector2d at_last = predictions[0].px + offset;
  // The light spread over the frames as a target's, not one frame's.
  std::vector<double> nu;
  for (std::size_t k = 0; k < n; ++k) {
    const auto v = imp::forced_snr(px[k], K_.width, K_.height, predictions[k].px + offset, frames[k]->noise_dn, s);
    if (!v) return refuse("outside");
    nu.push_back(*v);
  }
  for (std::size_t k = 0; k < n; ++k) {
    double others = 0.0;
    for (std::size_t j = 0; j < n; ++j)
      if (j != k) others += nu[j];
    others /= static_cast<double>(n - 1);
    if (nu[k] - others > kStackOneFrameExcess) return refuse("one frame's source");
  }
  // A detection or a catalogued star within blend_radius_px of the target in
  // any stacked frame is in the sum too: the stack is a blend.
  bool blended_before = false;
  for (std::size_t k = 1; k < n; ++k) {
    const Eigen::Vector2d at_k = predictions[k].px + offset;
    const auto near = [&](const std::vector<Eigen::Vector2d>& pts) {
      return std::any_of(pts.begin(), pts.end(),
                         [&](const Eigen::Vector2d& q) { return (q - at_k).norm() < opt_.blend_radius_px; });
    };
    blended_before = blended_before || near(frames[k]->detections_px) || near(frames[k]->catalog_px);
  }
  // At the stack's own nu, averaged over its unit noise (detect_near_prediction):
  // the frames' forced photometry would over-state it, the stack being made of
  // frames where the target was not found.
  Candidate cand = aided_candidate_at(a, at_last, a.centroid.sigma_px, blended_before);
  cand.stacked_frames = static_cast<int>(n);
  if (why) why->clear();
  return cand;
}

void FrameProcessor::use_focal_scale(double scale) {
  focal_scale_ = scale;
  K_ = K_nominal_;
  K_.fx *= scale;
  K_.fy *= scale;
}

std::vector<Eigen::Vector3d> FrameProcessor::directions_at(const std::vector<Eigen::Vector2d>& px, double scale) const {
  Intrinsics K = K_nominal_;
  K.fx *= scale;
  K.fy *= scale;
  std::vector<Eigen::Vector3d> d;
  d.reserve(px.size());
  for (const auto& p : px) d.push_back(K.unproject(p));
  return d;
}

double FrameProcessor::scale_residual_rad(const std::vector<Eigen::Vector2d>& px, const StarIdResult& r,
                                          double scale) const {
  const std::vector<Eigen::Vector3d> ds = directions_at(px, scale);
  std::vector<WeightedPair> pairs;
  for (const auto& [idx, cat_id] : r.matches) {
    pairs.push_back({ds[static_cast<std::size_t>(idx)],
                     catalog_.stars()[static_cast<std::size_t>(catalog_.index_of(cat_id))].u_eci, 1.0});
  }
  const AttitudeSolution q = q_method(pairs);
  return q.usable ? q.residual_rms_rad : 1e9;
}

double FrameProcessor::refine_focal_scale(const std::vector<Eigen::Vector2d>& px, StarIdResult& r, double scale) const {
  const auto dirs_at = [&](double sc) { return directions_at(px, sc); };
  // Refine (three rounds): the scale that makes the identified stars'
  // separations match the catalog's (least squares over the pairs,
  // separations being inversely proportional to the focal length), then
  // the minimum of the q-method residual within +-0.1 %, then every star
  // identified again at that scale from the attitude found.
  const auto q_residual = [&](double s, const StarIdResult& res) { return scale_residual_rad(px, res, s); };
  double best = scale;
  for (int round = 0; round < 3; ++round) {
    const std::vector<Eigen::Vector3d> ds = dirs_at(best);
    double num = 0.0, den = 0.0;
    for (std::size_t i = 0; i < r.matches.size(); ++i) {
      for (std::size_t j = i + 1; j < r.matches.size(); ++j) {
        const auto& ui = ds[static_cast<std::size_t>(r.matches[i].first)];
        const auto& uj = ds[static_cast<std::size_t>(r.matches[j].first)];
        const auto& ci = catalog_.stars()[static_cast<std::size_t>(catalog_.index_of(r.matches[i].second))].u_eci;
        const auto& cj = catalog_.stars()[static_cast<std::size_t>(catalog_.index_of(r.matches[j].second))].u_eci;
        const double am = std::atan2(ui.cross(uj).norm(), ui.dot(uj));
        const double ac = std::atan2(ci.cross(cj).norm(), ci.dot(cj));
        num += am * ac;
        den += ac * ac;
      }
    }
    if (den > 0.0) best *= num / den;
    double lo = best * 0.999, hi = best * 1.001;
    const double g = 0.5 * (std::sqrt(5.0) - 1.0);
    double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo), f1 = q_residual(x1, r), f2 = q_residual(x2, r);
    for (int it = 0; it < 30; ++it) {
      if (f1 < f2) {
        hi = x2;
        x2 = x1;
        f2 = f1;
        x1 = hi - g * (hi - lo);
        f1 = q_residual(x1, r);
      } else {
        lo = x1;
        x1 = x2;
        f1 = f2;
        x2 = lo + g * (hi - lo);
        f2 = q_residual(x2, r);
      }
    }
    best = 0.5 * (lo + hi);
    StarIdResult again =
        identify_with_prior(dirs_at(best), catalog_, r.q_cam_from_eci, opt_.tracking_tolerance_rad, opt_.star_id);
    if (again.usable && again.matches.size() >= r.matches.size()) r = std::move(again);
  }
  return best;
}

bool FrameProcessor::search_focal_length(const std::vector<Eigen::Vector2d>& px, std::vector<Eigen::Vector3d>& dirs,
                                         StarIdResult& id) {
  const auto dirs_at = [&](double scale) { return directions_at(px, scale); };
  // A separation of up to the sensor diagonal moves by step * separation:
  // at most half the match tolerance.
  const double step = 0.5 * opt_.star_id.match_tolerance_rad / (2.0 * K_nominal_.half_diagonal_fov_rad());
  const int n = static_cast<int>(std::ceil(opt_.focal_search_fraction / step));
  const double base = focal_scale_;
  for (int k = 1; k <= n; ++k) {
    for (const double sign : {1.0, -1.0}) {
      const double scale = base * (1.0 + sign * k * step);
      if (std::abs(scale - 1.0) > opt_.focal_search_fraction) continue;
      std::vector<Eigen::Vector3d> d = dirs_at(scale);
      StarIdResult r = identify_lost_in_space(d, catalog_, opt_.star_id);
      if (!r.usable) continue;
      const double best = refine_focal_scale(px, r, scale);
      if (std::abs(best - 1.0) > opt_.focal_search_fraction) continue;
      // More freedom, more chance matches: a scale found by the search must
      // fit at least 5 stars to a third of the match tolerance (chance
      // matches sit near the tolerance: a mirrored frame matched 5 stars at
      // 52" with a 60" tolerance; the real frames fit 8-28 stars at 4-11").
      if (r.matches.size() < 5 || scale_residual_rad(px, r, best) > opt_.star_id.match_tolerance_rad / 3.0) continue;
      use_focal_scale(best);
      dirs = dirs_at(best);
      id = std::move(r);
      return true;
    }
  }
  return false;
}

}  // namespace artms::imp
