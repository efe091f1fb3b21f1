// SOD-aided detection of a faint target near its predicted pixel (an
// extension beyond the paper, docs/imp_samus.md "Aided detection"). The paper
// feeds SOD's predictions to SAMUS only; a target fainter than the frame's
// detection threshold is then never measured, which is why SV3 beyond 100 km
// got fewer than 20 bearings in flight. Inside the prediction's validity
// region, a few hundred pixels at most, a PSF-matched filter can accept a
// much lower signal for the same false-alarm rate as the full-frame
// threshold:
//   m(x) = sum_k G_k (I(x + k) - b) / sqrt(sum_k G_k^2),
// G the Gaussian PSF (sigma psf_sigma_px); m / noise is the matched-filter
// SNR nu (white noise of 1-sigma `noise`). For a Gaussian PSF of sigma s the
// peak-pixel SNR that the full-frame detector thresholds is nu / (sqrt(pi) s)
// (0.47 nu for s = 1.2 px): nu >= 4.5 reaches sources of 2.1 peak sigmas,
// where detect() needs 5. The background is the window's median. The
// threshold is set per search for a constant false-alarm rate
// (false_alarm_threshold_snr): 4.67 for an exact prediction, 5.50 for one of
// 10 px 1-sigma at 1e-4 noise peaks per search.
// Centroid: iteratively weighted centre of gravity (IWCoG, as detect()); its
// 1-sigma per axis in the background-limited case is sqrt(2) s / nu (the
// Cramer-Rao bound of a Gaussian spot, with N / sqrt(b) = nu sqrt(4 pi) s)
// combined with the photon term s^2 / N and the floor of DetectionOptions.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <deque>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "artms/imp/detection.hpp"

namespace artms::imp {

struct AidedDetectionOptions {
  // The threshold on nu. With false_alarms_per_search > 0 it is set per
  // search so that white noise gives that many local maxima above it inside
  // the validity region on average (false_alarm_threshold_snr): a narrow
  // region accepts a fainter peak, a wide one needs a brighter one. With 0
  // it is threshold_snr (5.5: 2.6 peak-pixel sigmas for s = 1.2 px).
  double false_alarms_per_search = 1e-4;
  double threshold_snr = 5.5;
  double gate_chi2 = 9.21;         // 2 dof, 99 %: the validity region around the prediction
  double max_half_window_px = 40;  // wider predictions are not searched
  double psf_sigma_px = 1.2;
  double gain_e_per_dn = 2.4;
  double centroid_sigma_floor_px = 0.0;  // as DetectionOptions
  // A peak this close to a detection of the frame (a star, another target,
  // a candidate) is that detection's wing, not a new source.
  double min_separation_px = 4.0;
  // The blend test's PSF model error (DetectionOptions::psf_model_error).
  double psf_model_error = 0.05;
  void validate() const;
};

struct AidedDetection {
  bool found = false;
  std::string why;       // when not found: "outside", "too wide", "none", "ambiguous", "near a detection"
  Centroid centroid;     // pixel position, flux, sigma_px
  double snr = 0.0;      // matched-filter nu at the peak
  int peaks = 0;         // local maxima above the threshold inside the region
  double threshold_snr = 0.0;  // the threshold this search used (0: not searched)
  // The blend test of detect() (detection.hpp, item 6) at the centroid, over
  // the centroid window: about N(0, 1) for an isolated spot. At a faint
  // target's SNR a neighbour 2.5 px away hardly moves it (mean 0.5 for one
  // as bright): FrameProcessor::stacked_sky looks for those.
  double psf_chi2_z = 0.0;
};

// Expected number of local maxima above u of the matched-filter SNR field of
// white noise (unit variance, Gaussian kernel of sigma s) inside a convex
// region of area A and perimeter L: the expected Euler characteristic of the
// excursion set, which counts those maxima at high u (Gaussian kinematic
// formula; Worsley 1996, "The geometry of random images", Chance 9(1);
// Adler & Taylor 2007, Random Fields and Geometry, ch. 12-13):
//   E = (1 - Phi(u)) + (L / 2) sqrt(lambda) e^(-u^2/2) / (2 pi)
//       + A lambda u e^(-u^2/2) / (2 pi)^(3/2),
// lambda = 1 / (2 s^2), the field's second spectral moment (its correlation
// exp(-d^2 / (4 s^2))). The search sees the field on the pixel grid and misses
// peaks that clear u only between pixels, so this bounds its false alarms
// from above (0.4-0.75 of it measured at u 3.3-4.4).
[[nodiscard]] double expected_noise_peaks(double u, double area_px2, double perimeter_px, double psf_sigma_px);

// The validity region of a prediction: {d : d^T S^-1 d <= gate_chi2},
// S = cov_px2 + s^2 I; its area pi g sqrt(det S) and perimeter (Ramanujan's
// approximation for the ellipse).
struct SearchRegion {
  double area_px2 = 0.0;
  double perimeter_px = 0.0;
};
[[nodiscard]] SearchRegion search_region(const Eigen::Matrix2d& cov_px2, double psf_sigma_px, double gate_chi2);

// The u at which expected_noise_peaks equals false_alarms (bisection on
// [1, 12]; false_alarms in (0, 1)).
[[nodiscard]] double false_alarm_threshold_snr(double false_alarms, const SearchRegion& region, double psf_sigma_px);

// pixels: row-major width x height. predicted_px / cov_px2: the predicted
// target position and its covariance (pixels); noise_dn: the frame's
// noise (DetectionResult); detections_px: the
// frame's detections. Exactly one local maximum of nu above the threshold
// inside the validity region, not near a detection: found. Its centroid's
// sigma_px is aided_centroid_sigma_px at its own nu, averaged over that
// nu's unit noise.
AidedDetection detect_near_prediction(std::span<const std::uint16_t> pixels, int width, int height,
                                      const Eigen::Vector2d& predicted_px, const Eigen::Matrix2d& cov_px2,
                                      double noise_dn,
                                      const std::vector<Eigen::Vector2d>& detections_px,
                                      const AidedDetectionOptions& options = {});

// Centroid 1-sigma per axis (pixels) of a Gaussian spot of PSF sigma
// options.psf_sigma_px seen at matched-filter SNR nu with flux_dn: the
// background-limited Cramer-Rao term sqrt(2) s / nu (which the IWCoG with
// weights of the PSF's width attains), the IWCoG's photon term
// (iwcog_variance_px2 with no background: 1.95 s^2 / N at s = 1.2 px, where
// the bound has s^2 / N) and the floor. With the bound's photon term, SOD-aided
// centroids of 600-1500 e- on NST frames had a mean (error / 1-sigma)^2 per
// axis of 1.07-1.28 (docs/imp_samus.md, section 9).
// With nu_variance > 0 (the variance of what is known of the SNR:
// snr_posterior_variance, or 1 for a detection's own nu alone), the
// background term is its expectation over that SNR, times 1 + 3 r^2 with
// r^2 = nu_variance / nu^2 (signal_posterior_factors).
[[nodiscard]] double aided_centroid_sigma_px(double nu, double flux_dn, const AidedDetectionOptions& options,
                                             double nu_variance = 0.0);

// Forced photometry: the matched-filter SNR nu at a given sub-pixel position
// (the kernel centred there, background the median of the ring of pixels
// between the kernel's half-width 3 s and 3 s + 4), measured whether or not anything is detected.
// Unlike the SNR of a detection, it is not selected by the noise: near the
// threshold a detection is one where the noise happened to add up, and its
// own nu over-states the source (docs/imp_samus.md section 9). nullopt: too
// close to the edge.
[[nodiscard]] std::optional<double> forced_snr(std::span<const std::uint16_t> pixels, int width, int height,
                                               const Eigen::Vector2d& px, double noise_dn, double psf_sigma_px);

// The fraction of a source's matched-filter SNR that forced photometry
// measures at a prediction of covariance cov_px2 (pixels^2), on average:
// the kernel's overlap with a Gaussian spot offset by d is exp(-|d|^2 / (4 s^2)),
// and over d ~ N(0, C) its mean is det(I + C / (2 s^2))^(-1/2).
[[nodiscard]] double forced_photometry_gain(const Eigen::Matrix2d& cov_px2, double psf_sigma_px);

// A target's recent forced-photometry SNRs (one per frame at its predicted
// pixel), each divided by its gain (forced_photometry_gain), so that a
// prediction wider than the PSF does not read as a fainter source; frames
// with gain below kMinGain (a prediction 1-sigma of about the PSF sigma or
// more) measure the prediction's error more than the source and are not
// kept. expected_before(t) is their mean over (t - window_s, t), the current
// frame excluded, when at least min_frames are there.
// A value kept with its time and its noise's variance (ForcedPhotometry,
// SignalHistory).
struct TimedValue {
  double t_s = 0.0, value = 0.0, noise_variance = 0.0;
};

struct SnrPrior {
  double mean = 0.0;            // mean gain-corrected forced SNR of the recent frames
  double variance = 0.0;        // their sample variance (0 with fewer than 2 frames)
  int frames = 0;
  double noise_variance = 1.0;  // the noise's part of that variance: mean of 1 / gain^2
};
class ForcedPhotometry {
 public:
  static constexpr double kMinGain = 0.5;
  void add(double t_s, double nu, double gain = 1.0);
  [[nodiscard]] std::optional<SnrPrior> expected_before(double t_s, double window_s = 600.0, int min_frames = 2) const;

 private:
  std::deque<TimedValue> seen_;  // gain-corrected SNRs, oldest first
};

// The SNR for an aided detection's 1-sigma: the current frame's true SNR
// estimated from the detection's own nu (noise 1-sigma 1) and the recent
// frames' forced photometry as a prior (docs/imp_samus.md section 9),
//   nu = (tau^2 nu_detection + mean) / (tau^2 + 1),
//   tau^2 = max(variance - noise_variance, 0) + variance / frames,
// tau^2 the spread of the true SNR from frame to frame (the forced values
// scatter by the noise (1 / gain^2) plus the target's own fluctuation; flight-like
// targets flicker by 0.3 mag) plus the uncertainty of the mean. A steady
// target gets the history's mean (a detection near the threshold is one the
// noise lifted, so its own nu over-states the source); a flickering one
// leans on its own nu (a detection is more likely in a frame where the
// target is bright, which the mean of all frames under-states). Variance
// is only trusted from 4 frames on (below: tau^2 = 0). At least 1.
[[nodiscard]] double snr_for_sigma(double nu_detection, const SnrPrior& prior);
// The variance of that estimate of the true SNR: tau^2 / (tau^2 + 1) (0 with
// tau^2 = 0: a steady target's mean taken as known).
[[nodiscard]] double snr_posterior_variance(const SnrPrior& prior);

// A source's recent detected signals (Centroid::signal_dn, DN), each with its
// noise variance (window_signal_variance_dn2), for the 1-sigma of its next
// detection (FrameProcessor::sigma_rad_for_signal). A faint source's centroid
// 1-sigma goes as 1 / signal, and its window signal is measured to 20-50 %
// near the threshold, so 1 / sigma^2 is noisy: a filter weighing by it leans
// on the detections whose noise raised their signal and ends over-confident
// by about the weights' relative spread squared (unit test
// SignalHistory.FaintSpotsWeighedByTheirSourcesSignalAreConsistent: 1.16
// and 1.12 in (error / sigma)^2 at 500 and 600 e-, 1.02 with this). Like
// snr_for_sigma for aided detections, expected() shrinks the detection's
// own signal x (variance v) towards the mean m of the source's earlier ones
// within window_s:
//   s = (tau^2 x + v m) / (tau^2 + v),
//   tau^2 = max(S^2 - V, 0) + S^2 / n,
// S^2 their sample variance, V the mean of their noise variances, n their
// number: a steady source gets its history's mean, a flickering one its own
// signal. With fewer than min_frames earlier ones: x.
class SignalHistory {
 public:
  static constexpr std::size_t kMaxKept = 32;
  void add(double t_s, double signal_dn, double variance_dn2);
  [[nodiscard]] double expected(double t_s, double signal_dn, double variance_dn2, double window_s = 1800.0,
                                int min_frames = 4) const;
  // expected() and the variance of that estimate of the signal:
  // tau^2 v / (tau^2 + v), or v itself with fewer than min_frames earlier ones.
  struct Estimate {
    double signal_dn = 0.0, variance_dn2 = 0.0;
  };
  [[nodiscard]] Estimate estimate(double t_s, double signal_dn, double variance_dn2, double window_s = 1800.0,
                                  int min_frames = 4) const;
  // Time of the latest signal kept; -infinity when none.
  [[nodiscard]] double last_t_s() const;

 private:
  std::deque<TimedValue> seen_;  // signals (DN) and their variances (DN^2), oldest first
};

}  // namespace artms::imp
