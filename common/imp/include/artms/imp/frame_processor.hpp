// IMP first phase (paper, "Image Processing"): one frame -> attitude and
// measurement candidates. detect() -> unit vectors through the calibrated
// sensor model -> Pyramid star identification (tracking mode with the
// previous attitude, lost in space otherwise) -> attitude (q-method on the
// identified stars) -> the detections that are not identified stars, minus
//  * hot pixels: objects at an unchanging pixel position across frames, and
//  * uncatalogued stars: objects at an unchanging inertial direction across
//    frames,
// which is what remains for SAMUS: "the remaining minimalistic set of
// inertial unit vectors ... likely corresponds to known targets or other
// unknown objects in the FOV".
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <deque>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "artms/imp/detection.hpp"
#include "artms/imp/star_id.hpp"

namespace artms::imp {

struct Candidate {
  double x_px = 0.0;
  double y_px = 0.0;
  double flux_dn = 0.0;
  Eigen::Vector3d u_cam = Eigen::Vector3d::UnitZ();  // unit line of sight, camera components
  Eigen::Vector3d u_eci = Eigen::Vector3d::UnitZ();  // unit line of sight, ECI (J2000) components
  double sigma_rad = 0.0;  // 1-sigma per axis: centroid noise and attitude uncertainty
};

struct PersistenceOptions {
  // Hot pixel: within hot_pixel_tolerance_px of an object seen in at least
  // hot_pixel_min_repeats earlier frames, one of them hot_pixel_min_age_s
  // ago or more (a target drifting slowly across the sensor never stays
  // within a fraction of a pixel that long; a hot pixel does not move).
  double hot_pixel_tolerance_px = 0.3;
  int hot_pixel_min_repeats = 2;
  double hot_pixel_min_age_s = 290.0;
  // Uncatalogued star: within star_tolerance_rad of the inertial direction
  // of an object of an earlier frame (stars do not move inertially; a target
  // in a similar orbit turns with the orbit, ~4 deg/min in LEO).
  double star_tolerance_rad = 30.0 * 4.84813681109536e-6;
  // Frames kept for both tests, and their maximum age.
  int history_frames = 12;
  double history_max_age_s = 1800.0;
  void validate() const;
};

struct FrameProcessorOptions {
  DetectionOptions detection;
  StarIdOptions star_id;
  // Tracking-mode tolerance (attitude change between frames).
  double tracking_tolerance_rad = 0.2 * 0.017453292519943295;
  // Forget the previous attitude when the frame is older than this.
  double prior_max_age_s = 600.0;
  PersistenceOptions persistence;
  // Blends: a candidate with another detection (star or not) closer than
  // blend_radius_px has blend_sigma_px added in quadrature to its centroid
  // sigma: the Cramer-Rao sigma of detect() assumes an isolated source, and
  // the wing of a neighbour a few pixels away biases the weighted centroid by
  // a good fraction of a pixel (two targets 5 px apart in the IT formation).
  double blend_radius_px = 6.0;
  double blend_sigma_px = 0.5;
  void validate() const;
};

struct FrameSummary {
  bool attitude_usable = false;
  std::string status;  // "ok", "no_detections", "not_identified"
  Eigen::Quaterniond q_cam_from_eci = Eigen::Quaterniond::Identity();
  int stars_matched = 0;
  double residual_rms_rad = 0.0;   // RMS angle, identified stars vs rotated catalog
  double attitude_sigma_rad = 0.0; // per-axis 1-sigma across the boresight
  bool used_prior = false;
  int detections = 0;
  int hot_pixels_removed = 0;
  int uncatalogued_stars_removed = 0;
  std::vector<Candidate> candidates;  // empty unless attitude_usable
};

// Stateful: keeps the previous attitude (tracking mode) and the objects of
// recent frames (persistence tests). Frames must come in time order.
class FrameProcessor {
 public:
  FrameProcessor(Intrinsics intrinsics, const StarIdCatalog& catalog, FrameProcessorOptions options = {});
  // pixels: row-major width x height of the intrinsics. t_s: frame time tag
  // (any epoch, seconds), used for the history ages only.
  FrameSummary process(std::span<const std::uint16_t> pixels, double t_s);
  [[nodiscard]] const Intrinsics& intrinsics() const { return K_; }

 private:
  struct Seen {
    double t_s;
    std::vector<Eigen::Vector2d> px;
    std::vector<Eigen::Vector3d> u_eci;
  };
  Intrinsics K_;
  const StarIdCatalog& catalog_;
  FrameProcessorOptions opt_;
  std::optional<Eigen::Quaterniond> prior_;
  double prior_t_s_ = 0.0;
  std::deque<Seen> history_;
};

}  // namespace artms::imp
