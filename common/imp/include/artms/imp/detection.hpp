// Point-source detection and centroiding (paper, "Image Processing": "an
// iterative weighted center of gravity or fast Gaussian fitting centroiding
// algorithm is used to simplify the raw image into a list of pixel cluster
// centroids. Centroids are converted to unit vectors in the VBS frame using
// the calibrated sensor model").
//
// Pixel convention (DESIGN.md section 7, docs/conventions.md): x = column to
// the right, y = row downwards, (0, 0) is the centre of the top-left pixel;
// camera frame z = boresight, x along +column, y along +row. Images are
// row-major, index = y * width + x.
//
// The steps of detect(), in order:
//  1. Background and noise on a coarse grid. The frame is cut into square
//     cells of background_cell_px; in each cell (sampled on a stride-2 lattice)
//     the background is the median and the noise the distance from the 15.87 %
//     quantile to the median (one sigma of a Gaussian; only the lower half of
//     the distribution is used, so stars, hot pixels and cosmic rays - all
//     positive outliers - barely move it). Quantiles of integer data are
//     interpolated inside their histogram bin, so quantised 12-bit frames do
//     not get a quantised noise (floored at the quantisation noise
//     1/sqrt(12) DN). The noise grid is averaged over 3x3 cells (a cell's
//     quantiles of ~1000 samples give its noise to ~6 %; the noise varies
//     slowly, as the square root of the background). Cell values are interpolated bilinearly
//     between cell centres (flat beyond the outer centres): this follows smooth gradients
//     (vignetting, stray light) on scales larger than a cell. There is no
//     median filter across cells: it would bias the edge cells of a steep
//     gradient, and a point source moves a cell median by a fraction of the
//     noise (an extended source is rejected by max_pixels instead).
//  2. Threshold with hysteresis: a pixel above background + threshold_sigma *
//     noise at its position seeds a component, which grows through the
//     8-connected pixels above background + grow_sigma * noise. (A faint
//     star whose peak just clears the threshold keeps its shoulders, so it
//     is not mistaken for a single hot pixel.)
//  3. 8-connected components. Components smaller than
//     min_pixels are rejected (a hot pixel is a single bright pixel: its
//     neighbours are at the background, whereas a star's PSF spreads over
//     3x3..5x5 pixels); so are components larger than max_pixels (extended
//     objects, washed-out regions). Hot pixels on top of or next to a star
//     are masked: a pixel far sharper than the PSF allows (see max_sharpness)
//     is replaced by the mean of its four neighbours, and the component is
//     kept if it still has min_pixels other pixels.
//     Blended sources (deblend): a component with several local maxima above
//     the seed threshold, at least deblend_min_separation_px apart, with the
//     profile between them dipping below deblend_dip_fraction of the fainter
//     peak, gives one centroid per peak.
//  4. Centroid by iterative weighted centre of gravity (IWCoG; Wan et al.
//     2018, the paper's reference): start at the plain centre of gravity of
//     the component's background-subtracted pixels (at the peak pixel for a
//     deblended peak), then repeat
//       x_c <- sum_i w_i I_i x_i / sum_i w_i I_i,
//       w_i  = exp(-|x_i - x_c|^2 / (2 s_w^2)),
//     over a square window of +-window_half_px around the current x_c (all
//     pixels in it, lit or not), until the shift is below convergence_px or
//     max_iterations is reached. With s_w equal to the PSF sigma the weighted
//     CoG is the maximum-likelihood position for a Gaussian PSF in
//     background-limited noise, and it is free of the bias that a plain CoG
//     has when the window clips the PSF or contains noise.
//     Optionally (centroid_method = kGaussianFit), the IWCoG result seeds a
//     Gauss-Newton fit (Levenberg-Marquardt damped, gaussian_fit_iterations)
//     of A exp(-|x - x0|^2 / (2 s^2)) to the background-subtracted window,
//     saturated pixels excluded; the fit's position replaces the IWCoG one
//     when it converges inside the window, otherwise the IWCoG is kept.
//  5. Centroid 1-sigma per axis, for N = flux_dn * gain signal electrons
//     over a flat background of variance b electrons^2 per pixel (read
//     noise, background and dark shot noise, b = (noise_dn * gain)^2). A
//     pixel integrates the PSF, so the sampled spot has s_p^2 = s^2 + 1/12.
//     IWCoG (default): the variance of the weighted centroid at its fixed
//     point, linearised (weight width s_w = psf_sigma_px; r = s_w^2 /
//     (s_w^2 + s_p^2) is the flux fraction the weight keeps, 1 / r the
//     re-centring gain):
//       sigma^2 = A / (N r^4) + pi s_w^4 b / (2 N^2 r^4),
//       A = [h / (h + s_p^2)] [h s_p^2 / (h + s_p^2)],  h = s_w^2 / 2,
//     i.e. for s_w = s_p = s, 16 s^2 / (9 N) + 8 pi s^4 b / N^2: the
//     Cramer-Rao background term but 1.78 times its photon term (a matched
//     weight is not the photon-limited optimum). The Cramer-Rao bound
//     sigma^2 = s_p^2 / N + 8 pi s_p^4 b / N^2 (Fisher information of the
//     photon and background terms) was used before; it was 14 % (faint) to
//     41 % (bright) optimistic against the scatter of rendered spots; the
//     formula above is within 5 % (test
//     CentroidSigmaMatchesTheScatterFromFaintToBright). Gaussian fit: the
//     Cramer-Rao bound with the fitted width. Saturation, PSF mismatch,
//     background-estimate and flat-field errors are not in it;
//     centroid_sigma_floor_px is added in quadrature for them.
//  6. Blend test (Centroid::psf_chi2_z): the calibrated PSF (a Gaussian of
//     psf_sigma_px integrated over each pixel) is fitted at the centroid to
//     the window's unsaturated pixels, amplitude by weighted least squares,
//     and its chi^2 over dof = pixels - 3 is reported as
//     (chi^2 - dof) / sqrt(2 dof). A star of the uncatalogued population
//     (V 6.6-9) 2-4 px from a dim target is neither deblended (no dip
//     between the peaks) nor found on its own, yet it pulls the weighted
//     centroid by 0.1-0.3 px: the same error in every run, since the sky is
//     fixed (PSE, SV2: 20-seed mean centroid error 0.28 px at frame 307,
//     where the per-run scatter is 0.13 px). The fit's chi^2 sees the
//     neighbour's light; FrameProcessor treats a large value as a blend.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace artms::imp {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;

// The calibrated sensor model: pinhole with Brown radial distortion, the same
// model and pixel convention as the renderer's imaging::CameraModel (which
// IMP must not include):
//   x_px = cx + fx * xd,  y_px = cy + fy * yd,
//   xd = xn s + 2 p1 xn yn + p2 (r^2 + 2 xn^2),
//   yd = yn s + p1 (r^2 + 2 yn^2) + 2 p2 xn yn,
//   s = 1 + k1 r^2 + k2 r^4,  r^2 = xn^2 + yn^2,  (xn, yn) = (X / Z, Y / Z)
// (Brown 1966, radial and tangential; OpenCV's convention).
struct Intrinsics {
  int width = 0;
  int height = 0;
  double fx = 0.0;
  double fy = 0.0;
  double cx = 0.0;
  double cy = 0.0;
  double k1 = 0.0;
  double k2 = 0.0;
  double p1 = 0.0;
  double p2 = 0.0;

  // Unit line of sight in camera components for a pixel position (inverts
  // the distortion by Newton iteration: on the radius for a radial model,
  // in 2-D with tangential terms).
  [[nodiscard]] Vec3 unproject(Vec2 px) const;
  // Pixel position of a direction in camera components (any length);
  // nullopt behind the camera (Z <= 0) or outside the sensor area
  // [-0.5, width - 0.5] x [-0.5, height - 0.5].
  [[nodiscard]] std::optional<Vec2> project(Vec3 v_cam) const;
  // Half-angle of the cone from the boresight that contains the whole sensor.
  [[nodiscard]] double half_diagonal_fov_rad() const;
  // Throws std::invalid_argument if a value is out of range.
  void validate() const;
};

enum class CentroidMethod {
  kIterativeWeightedCog,  // default (IWCoG)
  kGaussianFit,           // IWCoG, then a 2-D Gaussian fit (Gauss-Newton)
};

struct DetectionOptions {
  // Lit pixels: above background + threshold_sigma * noise.
  double threshold_sigma = 5.0;
  // Components grow through pixels above background + grow_sigma * noise
  // (hysteresis; = threshold_sigma: none).
  double grow_sigma = 3.0;
  // Component size limits (8-connected pixels above the grow threshold).
  int min_pixels = 2;
  int max_pixels = 400;
  // Background grid cell size (pixels). Gradients on shorter scales are not
  // followed.
  int background_cell_px = 64;
  // PSF 1-sigma (pixels): the IWCoG weight width and the s of the centroid
  // sigma (NST-like camera: 1.2 px, config/cameras/nst.yaml).
  double psf_sigma_px = 1.2;
  // Half-width of the square centroid window (pixels); 0 = ceil(3 psf_sigma).
  int window_half_px = 0;
  CentroidMethod centroid_method = CentroidMethod::kIterativeWeightedCog;
  int max_iterations = 20;
  double convergence_px = 1e-4;
  int gaussian_fit_iterations = 6;
  // Added in quadrature to the bound of item 5 (the errors it leaves out).
  // Off by default: on the 12-orbit IT sequence (starling_it.yaml, nominal
  // photometry) SV3 centroids with a bound of 0.04-0.05 px scattered by
  // 0.07 px rms against the renderer's truth, and 0.06 px fixed that, but in
  // the flight-like PSE scenario the bound is right for SV2 (~0.1 px) and the
  // floor made its filter conservative (Monte Carlo NEES 3.5 instead of 6).
  double centroid_sigma_floor_px = 0.0;
  // Fractional error of the PSF model per pixel in the goodness-of-fit test
  // (Centroid::psf_chi2_z): (psf_model_error * model)^2 is added to each
  // pixel's variance, so that a bright, well-exposed source whose PSF
  // differs slightly from the calibrated Gaussian is not called a blend.
  double psf_model_error = 0.05;
  // Detector gain for the photon-noise term of the centroid sigma.
  double gain_e_per_dn = 2.4;
  // A pixel at or above this value is saturated (12-bit: 4095).
  double saturation_dn = 4095.0;
  // 1-sigma per axis of a saturated source's centroid (Centroid::saturated):
  // its flat top carries no position and the photon bound of item 5 would
  // claim hundredths of a pixel, so that one bright star outweighed every
  // other in the attitude (real frames, issue 19). A fraction of the PSF
  // width: the wings still place it.
  double saturated_sigma_px = 0.3;
  // Hot-pixel guard beyond min_pixels: a pixel of a component that is at
  // least 10 noise sigma above the background and exceeds max_sharpness
  // times the mean of its four edge neighbours (background-subtracted) is a
  // hot pixel and is masked. A Gaussian PSF of sigma s gives at most
  // ~exp(1 / (2 s^2)) at its peak (1.4 for s = 1.2 px, 2.2 for 0.8 px) and
  // less on its wings; a hot pixel gives tens. 0 disables the check.
  double max_sharpness = 6.0;
  // Split components holding separate peaks (close double stars, a target
  // next to a star).
  bool deblend = true;
  double deblend_min_separation_px = 2.5;
  double deblend_dip_fraction = 0.7;
  // Centroids closer than this to the sensor border are dropped: a source
  // centred off the sensor leaves a truncated PSF whose centroid is pulled
  // inwards by up to a few pixels.
  double edge_margin_px = 2.0;
  // A frame whose median background is above this fraction of saturation_dn
  // is not usable (washed out by stray light).
  double washout_fraction = 0.5;
  // More components than this: not usable (e.g. a noise frame, a threshold
  // far too low); the centroids found are still returned.
  int max_components = 5000;

  // Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

struct Centroid {
  double x_px = 0.0;
  double y_px = 0.0;
  double flux_dn = 0.0;   // background-subtracted sum over the centroid window
  double peak_dn = 0.0;   // brightest pixel, background-subtracted
  int pixels = 0;         // pixels in the component (above the grow threshold)
  double sigma_px = 0.0;  // centroid 1-sigma per axis (see the header comment)
  bool saturated = false;
  // Goodness of fit of one PSF at the centroid (header comment, item 6):
  // (chi^2 - dof) / sqrt(2 dof), about N(0, 1) for an isolated point source;
  // large for a source blended with a neighbour too faint or too close to be
  // found on its own. 0 when saturated.
  double psf_chi2_z = 0.0;
  // The source's own width: sqrt((Mxx + Myy) / 2 - 1/12) from the
  // background-subtracted second moments about the centroid over its window
  // (the 1/12 undoes the pixel's box), pixels; 0 when saturated or not
  // measurable. Noisy for faint sources: FrameProcessor learns the camera's
  // PSF from bright identified stars only.
  double moment_sigma_px = 0.0;
  // What sigma_px was computed from (centroid_sigma_px), so that it can be
  // computed again for another signal: max(flux_dn, peak_dn), the local
  // noise at the centroid (DN), and the PSF and weight widths (px).
  double signal_dn = 0.0;
  double noise_dn = 0.0;
  double psf_width_px = 0.0;
  double weight_width_px = 0.0;
};

// Centroid variance per axis (px^2) of the iteratively weighted centre of
// gravity with a Gaussian weight of width s_w_px on a Gaussian spot of width
// s_psf_px carrying n_e electrons over a background variance b_e2 (e-^2 per
// pixel): its photon term and its background term (detection.cpp derives
// them). With b_e2 = 0, the photon term alone: 16 s^2 / (9 N) for s_w = s_psf,
// 1.78 times the Cramer-Rao bound's.
[[nodiscard]] double iwcog_variance_px2(double s_w_px, double s_psf_px, double n_e, double b_e2);

// Centroid 1-sigma per axis (px) of item 5 for a source of signal_dn
// (max(flux_dn, peak_dn)) on a local noise of noise_dn, sampled-PSF width
// psf_width_px and IWCoG weight width weight_width_px (the Gaussian fit uses
// the Cramer-Rao bound with psf_width_px); centroid_sigma_floor_px added in
// quadrature, saturated_sigma_px the least when saturated; the centroid
// window's half-width when signal_dn is not positive. detect() calls it with
// the detection's own signal.
// With signal_variance_dn2 > 0, the variance of what is known of the signal
// (SignalHistory::estimate's posterior), the centroid variance is its
// expectation over that signal, not its value at the estimate: to second
// order the photon term (1 / N) times 1 + r^2 and the background term
// (1 / N^2) times 1 + 3 r^2, r^2 = signal_variance_dn2 / signal_dn^2, at
// most kMaxSignalRelVariance (beyond it the posterior is far from Gaussian).
// A filter weighing by 1 / sigma^2 is consistent when sigma^2 is the
// expected squared error given what it knows (docs/imp_samus.md section 9).
inline constexpr double kMaxSignalRelVariance = 0.25;
[[nodiscard]] double centroid_sigma_px(const DetectionOptions& o, double signal_dn, double noise_dn,
                                       double psf_width_px, double weight_width_px, bool saturated,
                                       double signal_variance_dn2 = 0.0);
// The factors above: E[1 / N] ~ (1 + r^2) / N and E[1 / N^2] ~ (1 + 3 r^2) / N^2
// for N ~ N(n, r^2 n^2), r^2 clamped to [0, kMaxSignalRelVariance].
struct SignalPosteriorFactors {
  double photon = 1.0, background = 1.0;
};
[[nodiscard]] SignalPosteriorFactors signal_posterior_factors(double signal, double variance);
// Variance (DN^2) of a centroid window's summed signal (flux_dn): the
// window's (2 half + 1)^2 pixels of noise noise_dn and the source's photon
// noise. Used to weigh one detection's signal against its source's earlier ones.
[[nodiscard]] double window_signal_variance_dn2(const DetectionOptions& o, double signal_dn, double noise_dn);

struct DetectionResult {
  std::vector<Centroid> centroids;  // sorted by flux, brightest first
  double background_dn = 0.0;       // median of the background grid
  double noise_dn = 0.0;            // median of the noise grid
  int rejected_single_pixel = 0;    // components below min_pixels
  int rejected_oversized = 0;       // components above max_pixels
  int rejected_sharp = 0;           // components left below min_pixels by masking
  int rejected_edge = 0;            // centroids within edge_margin_px of the border
  int masked_hot_pixels = 0;        // pixels masked by the max_sharpness test
  // Pixels (row-major index) that looked hot in this frame: single-pixel
  // components at least 10 noise sigma up, and pixels masked by the
  // max_sharpness test. FrameProcessor learns its hot-pixel map from them.
  std::vector<std::size_t> hot_suspects;
  bool usable = false;
  std::string why;  // empty when usable
};

// The blend test of item 6 on any window. PsfFitPixel: a pixel's
// background-subtracted value and the fraction of a unit-flux PSF on it
// (pixel_psf_fraction). The amplitude is fitted by weighted least squares
// (per-pixel variance noise^2 + model / gain + (model_error * model)^2, the
// model's variances iterated once); returns (chi^2 - dof) / sqrt(2 dof),
// dof = n - 3 (position and amplitude fitted), or 0 with fewer than 8 pixels.
struct PsfFitPixel {
  double signal_dn = 0.0;
  double psf_fraction = 0.0;
};
[[nodiscard]] double psf_fit_chi2_z(std::span<const PsfFitPixel> pixels, double noise_dn, double gain_e_per_dn,
                                    double psf_model_error);
// Fraction of a unit-flux Gaussian spot (sigma psf_sigma_px) centred at
// (xc, yc) that falls on pixel (x, y) (pixel centres at integers; erf
// differences per axis).
[[nodiscard]] double pixel_psf_fraction(int x, int y, double xc, double yc, double psf_sigma_px);

// Detects point sources in a width x height row-major frame.
// Throws std::invalid_argument if pixels.size() != width * height or the
// options are invalid.
DetectionResult detect(std::span<const std::uint16_t> pixels, int width, int height,
                       const DetectionOptions& options);

}  // namespace artms::imp
