#include "artms/imp/frame_processor.hpp"

#include "artms/imp/qmethod.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace artms::imp {

void PersistenceOptions::validate() const {
  auto bad = [](const char* f) { throw std::invalid_argument(std::string("PersistenceOptions.") + f + " out of range"); };
  if (!(hot_pixel_tolerance_px > 0.0)) bad("hot_pixel_tolerance_px");
  if (hot_pixel_min_repeats < 1) bad("hot_pixel_min_repeats");
  if (!(hot_pixel_min_age_s >= 0.0)) bad("hot_pixel_min_age_s");
  if (!(star_tolerance_rad > 0.0)) bad("star_tolerance_rad");
  if (history_frames < 1) bad("history_frames");
  if (!(history_max_age_s > 0.0)) bad("history_max_age_s");
}

void FrameProcessorOptions::validate() const {
  star_id.validate();
  persistence.validate();
  if (!(tracking_tolerance_rad > 0.0)) throw std::invalid_argument("FrameProcessorOptions.tracking_tolerance_rad out of range");
  if (!(prior_max_age_s >= 0.0)) throw std::invalid_argument("FrameProcessorOptions.prior_max_age_s out of range");
  if (!(blend_radius_px >= 0.0)) throw std::invalid_argument("FrameProcessorOptions.blend_radius_px out of range");
  if (!(blend_sigma_px >= 0.0)) throw std::invalid_argument("FrameProcessorOptions.blend_sigma_px out of range");
}

FrameProcessor::FrameProcessor(Intrinsics intrinsics, const StarIdCatalog& catalog, FrameProcessorOptions options)
    : K_(intrinsics), catalog_(catalog), opt_(std::move(options)) {
  K_.validate();
  opt_.validate();
}

FrameSummary FrameProcessor::process(std::span<const std::uint16_t> pixels, double t_s) {
  FrameSummary out;
  const DetectionResult det = detect(pixels, K_.width, K_.height, opt_.detection);
  out.detections = static_cast<int>(det.centroids.size());
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
  if (det.usable && dirs.size() >= 3) {
    if (prior_) {
      id = identify_with_prior(dirs, catalog_, *prior_, opt_.tracking_tolerance_rad, opt_.star_id);
      out.used_prior = id.usable;
    }
    if (!id.usable) id = identify_lost_in_space(dirs, catalog_, opt_.star_id);
  }
  out.status = !det.usable || dirs.size() < 3 ? "no_detections" : (id.usable ? "ok" : "not_identified");
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
    const double s = std::max(c.sigma_px, 0.01) / K_.fx;
    pairs.push_back({dirs[static_cast<std::size_t>(idx)],
                     catalog_.stars()[static_cast<std::size_t>(catalog_.index_of(cat_id))].u_eci, 1.0 / (s * s)});
  }
  const AttitudeSolution q = q_method(pairs);
  out.attitude_usable = true;
  out.stars_matched = static_cast<int>(id.matches.size());
  if (q.usable) {
    out.q_cam_from_eci = q.q_body_from_ref;
    out.residual_rms_rad = q.residual_rms_rad;
    // Per-axis attitude 1-sigma across the boresight: from the q-method
    // covariance, but never below the star residual scatter / sqrt(N)
    // (the centroid sigmas leave out calibration errors).
    out.attitude_sigma_rad =
        std::max(std::sqrt(0.5 * (q.covariance_rad2(0, 0) + q.covariance_rad2(1, 1))),
                 q.residual_rms_rad / std::sqrt(static_cast<double>(pairs.size())));
  } else {
    out.q_cam_from_eci = id.q_cam_from_eci;
    out.residual_rms_rad = id.residual_rms_rad;
    out.attitude_sigma_rad = id.residual_rms_rad;
  }
  prior_ = out.q_cam_from_eci;
  prior_t_s_ = t_s;

  std::vector<bool> is_star(order.size(), false);
  for (const auto& [idx, cat] : id.matches) is_star[static_cast<std::size_t>(idx)] = true;
  const Eigen::Matrix3d R_eci_from_cam = out.q_cam_from_eci.toRotationMatrix().transpose();
  // Forget frames beyond the history window.
  while (!history_.empty() && (static_cast<int>(history_.size()) >= opt_.persistence.history_frames ||
                               t_s - history_.front().t_s > opt_.persistence.history_max_age_s)) {
    history_.pop_front();
  }
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
    double sigma_px = c.sigma_px;
    for (const auto& o : det.centroids) {
      const double d = std::hypot(o.x_px - c.x_px, o.y_px - c.y_px);
      if (d > 0.0 && d < opt_.blend_radius_px) {
        sigma_px = std::hypot(sigma_px, opt_.blend_sigma_px);  // a blend (see FrameProcessorOptions)
        break;
      }
    }
    cand.sigma_rad = std::hypot(sigma_px / K_.fx, out.attitude_sigma_rad);
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
    if (repeats >= P.hot_pixel_min_repeats && old_enough) {
      ++out.hot_pixels_removed;
      continue;
    }
    out.candidates.push_back(cand);
  }
  history_.push_back(std::move(now));
  return out;
}

}  // namespace artms::imp
