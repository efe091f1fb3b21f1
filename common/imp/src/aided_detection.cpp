#include "artms/imp/aided_detection.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace artms::imp {

void AidedDetectionOptions::validate() const {
  if (!(threshold_snr > 0.0)) throw std::invalid_argument("AidedDetectionOptions.threshold_snr must be > 0");
  if (!(false_alarms_per_search >= 0.0 && false_alarms_per_search < 1.0))
    throw std::invalid_argument("AidedDetectionOptions.false_alarms_per_search must be in [0, 1)");
  if (!(gate_chi2 > 0.0)) throw std::invalid_argument("AidedDetectionOptions.gate_chi2 must be > 0");
  if (!(max_half_window_px >= 1.0)) throw std::invalid_argument("AidedDetectionOptions.max_half_window_px must be >= 1");
  if (!(psf_sigma_px > 0.0)) throw std::invalid_argument("AidedDetectionOptions.psf_sigma_px must be > 0");
  if (!(gain_e_per_dn > 0.0)) throw std::invalid_argument("AidedDetectionOptions.gain_e_per_dn must be > 0");
  if (!(centroid_sigma_floor_px >= 0.0)) throw std::invalid_argument("AidedDetectionOptions.centroid_sigma_floor_px must be >= 0");
  if (!(min_separation_px >= 0.0)) throw std::invalid_argument("AidedDetectionOptions.min_separation_px must be >= 0");
  if (!(psf_model_error >= 0.0 && psf_model_error < 1.0))
    throw std::invalid_argument("AidedDetectionOptions.psf_model_error must be in [0, 1)");
}

double expected_noise_peaks(double u, double area_px2, double perimeter_px, double psf_sigma_px) {
  constexpr double kTwoPi = 2.0 * std::numbers::pi;
  const double lambda = 1.0 / (2.0 * psf_sigma_px * psf_sigma_px);
  const double e = std::exp(-0.5 * u * u);
  return 0.5 * std::erfc(u / std::numbers::sqrt2) + 0.5 * perimeter_px * std::sqrt(lambda) * e / kTwoPi +
         area_px2 * lambda * u * e / std::pow(kTwoPi, 1.5);
}

SearchRegion search_region(const Eigen::Matrix2d& cov_px2, double psf_sigma_px, double gate_chi2) {
  const Eigen::Matrix2d S = cov_px2 + psf_sigma_px * psf_sigma_px * Eigen::Matrix2d::Identity();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(S);
  const double a = std::sqrt(gate_chi2 * std::max(es.eigenvalues()(1), 0.0));
  const double b = std::sqrt(gate_chi2 * std::max(es.eigenvalues()(0), 0.0));
  SearchRegion r;
  r.area_px2 = std::numbers::pi * a * b;
  r.perimeter_px = std::numbers::pi * (3.0 * (a + b) - std::sqrt((3.0 * a + b) * (a + 3.0 * b)));
  return r;
}

double false_alarm_threshold_snr(double false_alarms, const SearchRegion& region, double psf_sigma_px) {
  if (!(false_alarms > 0.0 && false_alarms < 1.0))
    throw std::invalid_argument("false_alarm_threshold_snr: false_alarms must be in (0, 1)");
  if (!(region.area_px2 >= 0.0 && region.perimeter_px >= 0.0 && psf_sigma_px > 0.0))
    throw std::invalid_argument("false_alarm_threshold_snr: region and psf_sigma_px must be non-negative and positive");
  // Decreasing in u on [1, 12] for any region.
  double lo = 1.0, hi = 12.0;
  if (expected_noise_peaks(hi, region.area_px2, region.perimeter_px, psf_sigma_px) >= false_alarms) return hi;
  if (expected_noise_peaks(lo, region.area_px2, region.perimeter_px, psf_sigma_px) <= false_alarms) return lo;
  for (int it = 0; it < 60; ++it) {
    const double mid = 0.5 * (lo + hi);
    (expected_noise_peaks(mid, region.area_px2, region.perimeter_px, psf_sigma_px) > false_alarms ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

AidedDetection detect_near_prediction(std::span<const std::uint16_t> pixels, int width, int height,
                                      const Eigen::Vector2d& predicted_px, const Eigen::Matrix2d& cov_px2,
                                      double noise_dn, const std::vector<Eigen::Vector2d>& detections_px,
                                      const AidedDetectionOptions& opt) {
  opt.validate();
  if (width <= 0 || height <= 0 || pixels.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height))
    throw std::invalid_argument("detect_near_prediction: pixels.size() != width * height");
  AidedDetection out;
  const double s = opt.psf_sigma_px;
  const Eigen::Matrix2d S = cov_px2 + s * s * Eigen::Matrix2d::Identity();
  const Eigen::Matrix2d S_inv = S.inverse();
  const double reach = std::sqrt(opt.gate_chi2 * S.diagonal().maxCoeff());
  if (!predicted_px.allFinite() || !S_inv.allFinite() || !(noise_dn > 0.0)) {
    out.why = "outside";
    return out;
  }
  if (reach > opt.max_half_window_px) {
    out.why = "too wide";
    return out;
  }
  const int r = static_cast<int>(std::ceil(3.0 * s));  // kernel half-width
  const int half = static_cast<int>(std::ceil(reach)) + r;
  const int x0 = std::max(0, static_cast<int>(std::floor(predicted_px.x())) - half);
  const int x1 = std::min(width - 1, static_cast<int>(std::ceil(predicted_px.x())) + half);
  const int y0 = std::max(0, static_cast<int>(std::floor(predicted_px.y())) - half);
  const int y1 = std::min(height - 1, static_cast<int>(std::ceil(predicted_px.y())) + half);
  if (x1 - x0 < 2 * r + 1 || y1 - y0 < 2 * r + 1) {
    out.why = "outside";
    return out;
  }
  const double threshold = opt.false_alarms_per_search > 0.0
                               ? false_alarm_threshold_snr(opt.false_alarms_per_search,
                                                           search_region(cov_px2, s, opt.gate_chi2), s)
                               : opt.threshold_snr;
  out.threshold_snr = threshold;
  const int w = x1 - x0 + 1, h = y1 - y0 + 1;
  auto at = [&](int x, int y) { return static_cast<double>(pixels[static_cast<std::size_t>(y) * width + x]); };
  // Local background: the window's median.
  std::vector<double> values;
  values.reserve(static_cast<std::size_t>(w * h));
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x) values.push_back(at(x, y));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2), values.end());
  const double b = values[values.size() / 2];
  // Unit-norm Gaussian kernel.
  std::vector<double> G(static_cast<std::size_t>((2 * r + 1) * (2 * r + 1)));
  double g2 = 0.0;
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx) {
      const double g = std::exp(-0.5 * (dx * dx + dy * dy) / (s * s));
      G[static_cast<std::size_t>((dy + r) * (2 * r + 1) + dx + r)] = g;
      g2 += g * g;
    }
  for (double& g : G) g /= std::sqrt(g2);
  // Matched-filter SNR on the inner window (where the kernel fits).
  const int iw = w - 2 * r, ih = h - 2 * r;
  std::vector<double> nu(static_cast<std::size_t>(iw * ih));
  for (int y = 0; y < ih; ++y)
    for (int x = 0; x < iw; ++x) {
      double m = 0.0;
      for (int dy = -r; dy <= r; ++dy)
        for (int dx = -r; dx <= r; ++dx)
          m += G[static_cast<std::size_t>((dy + r) * (2 * r + 1) + dx + r)] *
               (at(x0 + r + x + dx, y0 + r + y + dy) - b);
      nu[static_cast<std::size_t>(y * iw + x)] = m / noise_dn;
    }
  auto nu_at = [&](int x, int y) { return nu[static_cast<std::size_t>(y * iw + x)]; };
  // Local maxima above the threshold inside the validity region.
  int best_x = -1, best_y = -1;
  double best = 0.0;
  bool near_detection = false;
  for (int y = 1; y + 1 < ih; ++y)
    for (int x = 1; x + 1 < iw; ++x) {
      const double v = nu_at(x, y);
      if (!(v >= threshold)) continue;
      bool peak = true;
      for (int dy = -1; dy <= 1 && peak; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
          if ((dx != 0 || dy != 0) && nu_at(x + dx, y + dy) > v) peak = false;
      if (!peak) continue;
      const Eigen::Vector2d px(x0 + r + x, y0 + r + y);
      const Eigen::Vector2d d = px - predicted_px;
      if (d.dot(S_inv * d) > opt.gate_chi2) continue;
      bool near = false;
      for (const auto& q : detections_px)
        if ((q - px).norm() < opt.min_separation_px) near = true;
      if (near) {
        near_detection = true;
        continue;
      }
      ++out.peaks;
      if (v > best) {
        best = v;
        best_x = x0 + r + x;
        best_y = y0 + r + y;
      }
    }
  if (out.peaks != 1) {
    out.why = out.peaks > 1 ? "ambiguous" : (near_detection ? "near a detection" : "none");
    return out;
  }
  // IWCoG around the peak (weights: the PSF at the current estimate).
  double cx = best_x, cy = best_y;
  for (int it = 0; it < 20; ++it) {
    double sw = 0.0, sx = 0.0, sy = 0.0;
    for (int y = std::max(0, best_y - r); y <= std::min(height - 1, best_y + r); ++y)
      for (int x = std::max(0, best_x - r); x <= std::min(width - 1, best_x + r); ++x) {
        const double wgt = std::exp(-0.5 * ((x - cx) * (x - cx) + (y - cy) * (y - cy)) / (s * s)) * (at(x, y) - b);
        sw += wgt;
        sx += wgt * x;
        sy += wgt * y;
      }
    if (!(sw > 0.0)) break;
    const double nx = sx / sw, ny = sy / sw;
    if (std::hypot(nx - best_x, ny - best_y) > 1.5) break;  // pulled away by noise: keep the peak
    const bool done = std::hypot(nx - cx, ny - cy) < 1e-4;
    cx = nx;
    cy = ny;
    if (done) break;
  }
  double flux = 0.0;
  for (int y = std::max(0, best_y - r); y <= std::min(height - 1, best_y + r); ++y)
    for (int x = std::max(0, best_x - r); x <= std::min(width - 1, best_x + r); ++x) flux += at(x, y) - b;
  out.found = true;
  out.snr = best;
  out.centroid.x_px = cx;
  out.centroid.y_px = cy;
  out.centroid.flux_dn = flux;
  out.centroid.peak_dn = at(best_x, best_y) - b;
  out.centroid.pixels = 1;
  out.centroid.sigma_px = aided_centroid_sigma_px(best, flux, opt, 1.0);  // its own nu alone: noise 1
  {
    const int ix = static_cast<int>(std::lround(cx)), iy = static_cast<int>(std::lround(cy));
    std::vector<PsfFitPixel> fit;
    for (int y = std::max(0, iy - r); y <= std::min(height - 1, iy + r); ++y)
      for (int x = std::max(0, ix - r); x <= std::min(width - 1, ix + r); ++x)
        fit.push_back({at(x, y) - b, pixel_psf_fraction(x, y, cx, cy, s)});
    out.psf_chi2_z = psf_fit_chi2_z(fit, noise_dn, opt.gain_e_per_dn, opt.psf_model_error);
  }
  return out;
}

double aided_centroid_sigma_px(double nu, double flux_dn, const AidedDetectionOptions& opt, double nu_variance) {
  const double s = opt.psf_sigma_px;
  const double N = std::max(flux_dn, 1.0) * opt.gain_e_per_dn;
  // The photon term of the IWCoG above (weights of the PSF's width), 1.95
  // times the bound's s^2 / N at s = 1.2 px (iwcog_variance_px2).
  const double background = signal_posterior_factors(nu, nu_variance).background;
  return std::sqrt(background * 2.0 * s * s / (nu * nu) + iwcog_variance_px2(s, s, N, 0.0) +
                   opt.centroid_sigma_floor_px * opt.centroid_sigma_floor_px);
}

std::optional<double> forced_snr(std::span<const std::uint16_t> pixels, int width, int height,
                                 const Eigen::Vector2d& px, double noise_dn, double psf_sigma_px) {
  if (width <= 0 || height <= 0 || pixels.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height))
    throw std::invalid_argument("forced_snr: pixels.size() != width * height");
  if (!px.allFinite() || !(noise_dn > 0.0) || !(psf_sigma_px > 0.0)) return std::nullopt;
  const double s = psf_sigma_px;
  const int r = static_cast<int>(std::ceil(3.0 * s));
  const int half = r + 4;
  const int xc = static_cast<int>(std::lround(px.x())), yc = static_cast<int>(std::lround(px.y()));
  if (xc - half < 0 || yc - half < 0 || xc + half >= width || yc + half >= height) return std::nullopt;
  auto at = [&](int x, int y) { return static_cast<double>(pixels[static_cast<std::size_t>(y) * width + x]); };
  std::vector<double> values;
  values.reserve(static_cast<std::size_t>((2 * half + 1) * (2 * half + 1)));
  for (int y = yc - half; y <= yc + half; ++y)
    for (int x = xc - half; x <= xc + half; ++x)
      if (std::abs(x - xc) > r || std::abs(y - yc) > r) values.push_back(at(x, y));  // outside the kernel
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2), values.end());
  const double b = values[values.size() / 2];
  double m = 0.0, g2 = 0.0;
  for (int y = yc - r; y <= yc + r; ++y)
    for (int x = xc - r; x <= xc + r; ++x) {
      const double g = std::exp(-0.5 * ((x - px.x()) * (x - px.x()) + (y - px.y()) * (y - px.y())) / (s * s));
      m += g * (at(x, y) - b);
      g2 += g * g;
    }
  return m / std::sqrt(g2) / noise_dn;
}

double forced_photometry_gain(const Eigen::Matrix2d& cov_px2, double psf_sigma_px) {
  if (!cov_px2.allFinite() || !(psf_sigma_px > 0.0)) return 0.0;
  const Eigen::Matrix2d m = Eigen::Matrix2d::Identity() + cov_px2 / (2.0 * psf_sigma_px * psf_sigma_px);
  const double det = m.determinant();
  return det >= 1.0 ? 1.0 / std::sqrt(det) : 1.0;  // a covariance that is not positive: no loss claimed
}

namespace {

// Mean, sample variance (0 below 2 values) and mean noise variance of the
// values kept in (t_s - window_s, t_s): the current time excluded.
struct WindowMoments {
  int n = 0;
  double mean = 0.0, variance = 0.0, noise_variance = 0.0;
};
WindowMoments window_moments(const std::deque<TimedValue>& seen, double t_s, double window_s) {
  double sum = 0.0, sum2 = 0.0, noise = 0.0;
  WindowMoments m;
  for (const auto& s : seen) {
    if (s.t_s < t_s && t_s - s.t_s < window_s) {
      sum += s.value;
      sum2 += s.value * s.value;
      noise += s.noise_variance;
      ++m.n;
    }
  }
  if (m.n == 0) return m;
  m.mean = sum / m.n;
  m.variance = m.n > 1 ? std::max(0.0, (sum2 - m.n * m.mean * m.mean) / (m.n - 1)) : 0.0;
  m.noise_variance = noise / m.n;
  return m;
}

// The spread of a source's true value from frame to frame plus the
// uncertainty of its mean, from n values of sample variance `variance` whose
// noise has mean variance `noise_variance`: tau^2 = max(S^2 - V, 0) + S^2 / n.
double true_spread(double variance, double noise_variance, int n) {
  return std::max(variance - noise_variance, 0.0) + variance / n;
}

}  // namespace

void ForcedPhotometry::add(double t_s, double nu, double gain) {
  if (!(gain >= kMinGain) || !std::isfinite(nu)) return;
  const double g = std::min(gain, 1.0);
  seen_.push_back({t_s, nu / g, 1.0 / (g * g)});
  while (seen_.size() > 64) seen_.pop_front();
}

std::optional<SnrPrior> ForcedPhotometry::expected_before(double t_s, double window_s, int min_frames) const {
  const WindowMoments m = window_moments(seen_, t_s, window_s);
  if (m.n < min_frames || m.n == 0) return std::nullopt;
  SnrPrior p;
  p.frames = m.n;
  p.mean = m.mean;
  p.variance = m.variance;
  p.noise_variance = m.noise_variance;
  return p;
}

namespace {
double snr_spread(const SnrPrior& prior) {
  return prior.frames >= 4 ? true_spread(prior.variance, prior.noise_variance, prior.frames) : 0.0;
}
}  // namespace

double snr_for_sigma(double nu_detection, const SnrPrior& prior) {
  const double tau2 = snr_spread(prior);
  return std::max(1.0, (tau2 * nu_detection + prior.mean) / (tau2 + 1.0));
}

double snr_posterior_variance(const SnrPrior& prior) {
  const double tau2 = snr_spread(prior);
  return tau2 / (tau2 + 1.0);
}

void SignalHistory::add(double t_s, double signal_dn, double variance_dn2) {
  if (!std::isfinite(t_s) || !std::isfinite(signal_dn) || !(signal_dn > 0.0) || !(variance_dn2 > 0.0)) return;
  seen_.push_back({t_s, signal_dn, variance_dn2});
  while (seen_.size() > kMaxKept) seen_.pop_front();
}

double SignalHistory::last_t_s() const {
  return seen_.empty() ? -std::numeric_limits<double>::infinity() : seen_.back().t_s;
}

double SignalHistory::expected(double t_s, double signal_dn, double variance_dn2, double window_s,
                               int min_frames) const {
  return estimate(t_s, signal_dn, variance_dn2, window_s, min_frames).signal_dn;
}

SignalHistory::Estimate SignalHistory::estimate(double t_s, double signal_dn, double variance_dn2, double window_s,
                                                int min_frames) const {
  if (!(variance_dn2 > 0.0) || !std::isfinite(signal_dn)) return {signal_dn, 0.0};
  const WindowMoments m = window_moments(seen_, t_s, window_s);
  if (m.n < std::max(min_frames, 2)) return {signal_dn, variance_dn2};
  const double tau2 = true_spread(m.variance, m.noise_variance, m.n);
  return {(tau2 * signal_dn + variance_dn2 * m.mean) / (tau2 + variance_dn2),
          tau2 * variance_dn2 / (tau2 + variance_dn2)};
}

}  // namespace artms::imp
