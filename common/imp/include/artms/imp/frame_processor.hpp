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
#include <unordered_map>
#include <vector>

#include "artms/astro/time.hpp"
#include "artms/imp/aided_detection.hpp"
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
  double psf_chi2_z = 0.0;  // detect()'s blend statistic (Centroid::psf_chi2_z)
  bool blended = false;     // blend_sigma_px was added (a neighbour, or the PSF fit)
  bool on_catalog_star = false;  // a catalogued star within blend_radius_px (detected or not)
  // What sigma_rad was computed from, so that sigma_rad_for_signal() can
  // compute it again for another signal (the source's expected one,
  // SignalHistory): the centroid's Centroid::signal_dn, noise_dn,
  // psf_width_px, weight_width_px and saturation, the window signal's
  // variance (window_signal_variance_dn2) and the frame's attitude 1-sigma.
  double signal_dn = 0.0;
  double signal_variance_dn2 = 0.0;
  double noise_dn = 0.0;
  double psf_width_px = 0.0;
  double weight_width_px = 0.0;
  bool saturated = false;
  double attitude_sigma_rad = 0.0;
  bool aided = false;  // from aided_candidate(): its 1-sigma comes from the forced photometry instead
  int stacked_frames = 1;  // frames summed (stacked_aided_candidate); 1: one frame
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
  // Learned hot-pixel map: a pixel that looked hot (DetectionResult::
  // hot_suspects: a lone sharp pixel, not part of any source) in at least
  // hot_map_min_frames frames is a known hot pixel; a candidate within
  // hot_map_radius_px of one is removed. A faint target passing next to a
  // hot pixel forms one component with it, the sharpness test no longer
  // recognises the pixel, and the centroid is pulled towards it by up to a
  // pixel and a half with a small sigma.
  int hot_map_min_frames = 3;
  double hot_map_radius_px = 2.5;
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
  // Blends: a candidate with another detection (star or not), or a
  // catalogued star at the frame's attitude (resolved or not), closer than
  // blend_radius_px has blend_sigma_px added in quadrature to its centroid
  // sigma: the Cramer-Rao sigma of detect() assumes an isolated source, and
  // the wing of a neighbour a few pixels away biases the weighted centroid by
  // a good fraction of a pixel (two targets 5 px apart in the IT formation).
  double blend_radius_px = 6.0;
  double blend_sigma_px = 0.5;
  // The same for a candidate whose single-PSF fit is poor
  // (Centroid::psf_chi2_z above blend_chi2_z): a neighbour too faint or too
  // close to be detected on its own, typically an uncatalogued star 2-4 px
  // away. For an isolated source the statistic is about N(0, 1).
  double blend_chi2_z = 5.0;
  // Lost-in-space with an uncertain focal length (a user's camera; 0 = off,
  // the flight camera is calibrated): when identification fails at the
  // nominal focal length, it is tried again with fx and fy scaled by
  // 1 +- k * step up to +-focal_search_fraction, the step such that the
  // largest star separation moves by at most half the match tolerance; the
  // scale that identifies is refined (the identified stars' separations
  // against the catalog's, then the q-method residual's minimum, then every
  // star identified again, three times); the frames that follow start from
  // it and refine their own (FrameSummary::focal_scale). A camera file whose
  // focal length identifies is used as it is.
  double focal_search_fraction = 0.0;
  // Learn the camera's PSF width instead of assuming detection.psf_sigma_px:
  // each solved frame's median width (Centroid::moment_sigma_px) of its
  // identified, unsaturated stars peaking above 20 noise sigma
  // (at least 3), the median of the last 10 such frames replacing
  // detection.psf_sigma_px from the next frame on (the PSF test, the
  // centroid window and sigma follow it). Off: the camera file's value.
  bool learn_psf = false;
  void validate() const;
};

struct FrameSummary {
  bool attitude_usable = false;
  std::string status;  // "ok", "no_detections", "not_identified"
  std::string why;     // the reason when not "ok" (detection's or identification's own)
  // The identified stars: centroid (pixels), catalog id, and the angle
  // between the measured direction and the catalog direction rotated by
  // the solved attitude.
  struct IdentifiedStar {
    double x_px = 0.0, y_px = 0.0;
    int catalog_id = 0;
    double residual_rad = 0.0;
    bool saturated = false;
    double sigma_px = 0.0;  // the centroid 1-sigma the attitude weighted it with
  };
  std::vector<IdentifiedStar> stars;
  // Focal length in use over the nominal one (1 unless focal_search_fraction
  // found another).
  double focal_scale = 1.0;
  // How well this frame's stars fix that scale (when it was refined): half
  // the curvature of sum_i |b_i - A r_i|^2 (rad^2, equal weights, the
  // attitude A re-solved at each scale) at focal_scale, so that the least
  // squares scale common to several frames is sum I_k s_k / sum I_k. 0 when
  // the scale was not refined.
  double focal_scale_information = 0.0;
  // The PSF width detection used on this frame (learned or the option's).
  double psf_sigma_px = 0.0;
  Eigen::Quaterniond q_cam_from_eci = Eigen::Quaterniond::Identity();
  int stars_matched = 0;
  double residual_rms_rad = 0.0;   // RMS angle, identified stars vs rotated catalog
  double attitude_sigma_rad = 0.0; // per-axis 1-sigma across the boresight
  bool used_prior = false;
  int detections = 0;
  int hot_pixels_removed = 0;  // by persistence or the learned hot-pixel map
  int uncatalogued_stars_removed = 0;
  std::vector<Candidate> candidates;  // empty unless attitude_usable
};

// Stateful: keeps the previous attitude (tracking mode) and the objects of
// recent frames (persistence tests). Frames must come in time order.
class FrameProcessor {
 public:
  FrameProcessor(Intrinsics intrinsics, const StarIdCatalog& catalog, FrameProcessorOptions options = {});
  // pixels: row-major width x height of the intrinsics. t: the frame's time
  // tag, used for the history ages only. observer_velocity_mps: the
  // observer's velocity relative to the solar-system barycentre (ECI
  // components; the Earth's plus its orbital velocity): the identified
  // stars' catalog directions are aberrated by it (astro/aberration.hpp)
  // before the attitude is solved, so that the attitude, and the inertial
  // directions of the candidates (targets that move with the observer are
  // not aberrated), are true ones. nullopt: the catalog as it is (an
  // astrometric attitude, off by up to ~26" in flight). Identification
  // itself tolerates the shift (it changes star separations by <= ~5" over
  // the field).
  FrameSummary process(std::span<const std::uint16_t> pixels, astro::TimeTT t,
                       const std::optional<Eigen::Vector3d>& observer_velocity_mps = std::nullopt);
  [[nodiscard]] const Intrinsics& intrinsics() const { return K_; }
  // Directions (ECI unit vectors) of the stars the blend check looks for
  // beside a candidate (FrameProcessorOptions.blend_radius_px): a catalog
  // deeper than the identification one (stars too faint to identify still
  // move a target's centroid). Empty (the default): the identification catalog.
  void set_blend_stars(std::vector<Eigen::Vector3d> u_eci) { blend_stars_ = std::move(u_eci); }
  [[nodiscard]] const FrameProcessorOptions& options() const { return opt_; }
  // A candidate's sigma_rad computed again for signal_dn instead of its own
  // Candidate::signal_dn (the same noise, PSF, blend and attitude terms);
  // equal to sigma_rad for its own signal. signal_variance_dn2: that
  // signal's uncertainty, over which the centroid variance is averaged
  // (centroid_sigma_px).
  [[nodiscard]] double sigma_rad_for_signal(const Candidate& c, double signal_dn,
                                            double signal_variance_dn2 = 0.0) const;
  // SOD-aided detection (aided_detection.hpp) in the frame process() took
  // last, which must have had a usable attitude: a candidate near the
  // predicted pixel, or nullopt with the reason in *why. A source at the
  // inertial direction of an earlier aided detection is a faint star (stars
  // do not move inertially, PersistenceOptions.star_tolerance_rad) and is
  // refused.
  // Is there a source at inertial direction u_eci in the frame process()
  // took last (pixels: that frame)? A detection within tolerance_px of its
  // pixel, or a matched-filter peak there (aided detection with a
  // tolerance_px region), hot pixels not counted (this frame's lone sharp
  // pixels and the learned map, within hot_map_radius_px). nullopt: no
  // attitude, or off the sensor. Stars do not move inertially; a target
  // turns with its orbit (~4 deg/min), so a source seen again at the same
  // direction a frame later is a star.
  [[nodiscard]] std::optional<bool> source_at(std::span<const std::uint16_t> pixels, const Eigen::Vector3d& u_eci,
                                              const AidedDetectionOptions& options, double tolerance_px = 1.0) const;
  // The same in the frames before the last one: the most recent of the
  // kept frames (keep_recent_frames) whose sensor holds u_eci answers;
  // nullopt when none does (or none is kept).
  [[nodiscard]] std::optional<bool> source_before(const Eigen::Vector3d& u_eci, const AidedDetectionOptions& options,
                                                  double tolerance_px = 1.0) const;
  // The sky at inertial direction u_eci stacked over the frames that show it
  // with the target elsewhere: the frame process() took last (pixels: that
  // frame) and the kept ones (keep_recent_frames). A frame in which the
  // direction lies within ring_px + 4 px of detection_px (the detection's
  // pixel in its own frame; the camera holds a target nearly still, so the
  // target would be there) is left out, the detection's own frame with it.
  // Forced photometry (forced_snr) of each frame at the direction and at
  // every whole-pixel offset within ring_px, summed over the frames and
  // divided by sqrt(frames): unit variance on noise, sqrt(frames) deeper
  // than one frame. An offset whose kernel (half-width ceil(3 s)) holds one
  // of a frame's hot pixels (hot_pixels: fixed on the sensor, not in the
  // sky) leaves that frame out there. A star 2-6 px from a faint target
  // pulls its centroid by a good part of its 1-sigma (3 times as bright at
  // 5 px: 0.2 px), yet one fainter than the frame's threshold is found
  // neither by detect() nor by the blend test at a faint target's SNR
  // (docs/imp_samus.md "Faint stars beside a faint target"). nullopt: no
  // frame shows the direction.
  struct StackedSky {
    int frames = 0;
    double snr_at = 0.0;           // stacked nu at the direction itself
    double neighbour_snr = 0.0;    // the largest stacked nu at 1.5 px to ring_px from it
    double neighbour_threshold = 0.0;  // for neighbour_false_alarms on that annulus (false_alarm_threshold_snr)
    Eigen::Vector2d neighbour_offset_px = Eigen::Vector2d::Zero();
  };
  [[nodiscard]] std::optional<StackedSky> stacked_sky(std::span<const std::uint16_t> pixels,
                                                      const Eigen::Vector3d& u_eci,
                                                      const Eigen::Vector2d& detection_px,
                                                      const AidedDetectionOptions& options, double ring_px,
                                                      double neighbour_false_alarms) const;
  // Keep the pixels of the last n frames with an attitude (before the one
  // process() took last) for source_before. 0 (the default): none.
  void keep_recent_frames(int n);
  // expected_snr: the target's forced photometry of the recent frames
  // (ForcedPhotometry); when given, the centroid 1-sigma is computed at
  // snr_for_sigma(the detection's own SNR, expected_snr) instead of the
  // detection's own SNR, which near the threshold over-states the source,
  // averaged over that estimate's snr_posterior_variance (docs/imp_samus.md
  // section 9).
  std::optional<Candidate> aided_candidate(std::span<const std::uint16_t> pixels, const Eigen::Vector2d& predicted_px,
                                           const Eigen::Matrix2d& cov_px2, const AidedDetectionOptions& options,
                                           std::string* why = nullptr, std::optional<SnrPrior> expected_snr = std::nullopt);
  // SOD-aided search on the frame process() took last (pixels: that frame)
  // stacked with the kept frames (keep_recent_frames) along the target's
  // predicted motion (docs/imp_samus.md "The stacked aided search"; not in
  // the paper). predictions[0]: the target's predicted pixel in the last
  // frame; predictions[k]: in the k-th kept frame before it (most recent
  // first; its time must be that frame's), each from the prediction of its
  // own frame. Each frame is shifted by the whole pixels that bring its
  // prediction onto the last frame's and the frames are summed: a target K
  // frames long is sqrt(K) deeper than in one frame (the camera holds it
  // nearly still while the stars cross the field: a star lies in one frame
  // of the stack at most). The sum is searched as detect_near_prediction
  // does (the validity region of cov_px2, the last frame's; noise the
  // frames' in quadrature; the frames' detections and hot pixels avoided).
  // A peak found gives the mean offset of the target from its predictions
  // over the K frames (less the shifts' whole-pixel rounding), which is
  // taken as the last frame's: a bearing at the last frame's time. Refused
  // when one frame holds the light (a star or a cosmic ray crossing one
  // frame: its forced SNR more than kStackOneFrameExcess above the others'
  // mean) or the stack leaves the sensor. Its 1-sigma is
  // detect_near_prediction's at the stack's own SNR, averaged over that
  // SNR's unit noise: the forced photometry of the recent frames would
  // over-state the signal, the stack being made of frames where the target
  // was not found (PSE SV3's campaign mean NEES: 6.66 with it, 6.26 without).
  // Candidate::stacked_frames = K.
  static constexpr double kStackOneFrameExcess = 5.0;
  struct StackedPrediction {
    double t_s = 0.0;
    Eigen::Vector2d px = Eigen::Vector2d::Zero();
  };
  std::optional<Candidate> stacked_aided_candidate(std::span<const std::uint16_t> pixels,
                                                   const std::vector<StackedPrediction>& predictions,
                                                   const Eigen::Matrix2d& cov_px2,
                                                   const AidedDetectionOptions& options, std::string* why = nullptr);
  // Forced photometry at a pixel of the frame process() took last
  // (pixels: that frame), with its noise; nullopt near the edge or without a frame.
  [[nodiscard]] std::optional<double> forced_snr(std::span<const std::uint16_t> pixels, const Eigen::Vector2d& px,
                                                 const AidedDetectionOptions& options) const;

 private:
  std::vector<Eigen::Vector3d> blend_stars_;
  // FrameProcessorOptions::focal_search_fraction: identification over
  // focal-length scales about the current one; on success dirs, id, K_ and
  // focal_scale_ hold the refined scale's.
  // The focal length in use: the nominal one times scale (K_, focal_scale_).
  void use_focal_scale(double scale);
  // Camera directions of the pixels px with the nominal focal length times scale.
  std::vector<Eigen::Vector3d> directions_at(const std::vector<Eigen::Vector2d>& px, double scale) const;
  // q-method residual (rad) of r's identified stars at that scale.
  double scale_residual_rad(const std::vector<Eigen::Vector2d>& px, const StarIdResult& r, double scale) const;
  double refine_focal_scale(const std::vector<Eigen::Vector2d>& px, StarIdResult& r, double scale) const;
  bool search_focal_length(const std::vector<Eigen::Vector2d>& px, std::vector<Eigen::Vector3d>& dirs,
                           StarIdResult& id);
  struct Seen {
    double t_s;
    std::vector<Eigen::Vector2d> px;
    std::vector<Eigen::Vector3d> u_eci;
  };
  Intrinsics K_;
  Intrinsics K_nominal_;
  std::deque<double> psf_widths_;  // learn_psf: the last frames' median star widths
  double focal_scale_ = 1.0;
  const StarIdCatalog& catalog_;
  FrameProcessorOptions opt_;
  std::optional<Eigen::Quaterniond> prior_;
  double prior_t_s_ = 0.0;
  std::deque<Seen> history_;
  // An aided candidate at pixel px of the last frame from the found search
  // a, with centroid 1-sigma sigma_px, under process()'s blend rules;
  // blended_before: a blend in a stacked frame before the last.
  [[nodiscard]] Candidate aided_candidate_at(const AidedDetection& a, const Eigen::Vector2d& px, double sigma_px,
                                             bool blended_before = false) const;
  // The last frame, for aided_candidate().
  struct Last {
    bool attitude_usable = false;
    double t_s = 0.0;
    double noise_dn = 0.0;
    double attitude_sigma_rad = 0.0;
    Eigen::Matrix3d R_eci_from_cam = Eigen::Matrix3d::Identity();
    std::vector<Eigen::Vector2d> detections_px;
    std::vector<Eigen::Vector2d> hot_px;  // this frame's lone sharp pixels (DetectionResult::hot_suspects)
    std::vector<Eigen::Vector2d> catalog_px;  // the blend check's catalogued stars on the sensor
    std::vector<std::uint16_t> pixels;    // kept for source_before only
  } last_;
  std::deque<Last> recent_;  // frames with an attitude before last_, most recent first
  std::size_t keep_recent_ = 0;
  [[nodiscard]] std::optional<bool> source_in(const Last& frame, std::span<const std::uint16_t> pixels,
                                              const Eigen::Vector3d& u_eci, const AidedDetectionOptions& options,
                                              double tolerance_px) const;
  // Hot pixels (fixed on the sensor, not in the sky) at a frame: its lone
  // sharp pixels and the learned map.
  [[nodiscard]] std::vector<Eigen::Vector2d> hot_pixels(const Last& frame) const;
  std::deque<std::pair<double, Eigen::Vector3d>> aided_seen_;  // (t_s, u_eci) of earlier aided detections
  std::unordered_map<std::size_t, int> hot_counts_;     // pixel index -> frames it looked hot in
  std::vector<Eigen::Vector2d> hot_known_px_;          // pixels with hot_map_min_frames or more
};

}  // namespace artms::imp
