#include "artms/imp/detection.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace artms::imp {

// ---------------------------------------------------------------------------
// Intrinsics
// ---------------------------------------------------------------------------

namespace {
// Brown's distortion of normalised coordinates (Intrinsics).
Vec2 distort(const Vec2& n, const Intrinsics& K) {
  const double x = n.x(), y = n.y(), r2 = x * x + y * y;
  const double s = 1.0 + r2 * (K.k1 + K.k2 * r2);
  return {x * s + 2.0 * K.p1 * x * y + K.p2 * (r2 + 2.0 * x * x),
          y * s + K.p1 * (r2 + 2.0 * y * y) + 2.0 * K.p2 * x * y};
}
}  // namespace

Vec3 Intrinsics::unproject(Vec2 px) const {
  const Vec2 xd((px.x() - cx) / fx, (px.y() - cy) / fy);
  if (p1 != 0.0 || p2 != 0.0) {
    // Newton in 2-D on distort(n) = xd from n = xd.
    Vec2 n = xd;
    for (int it = 0; it < 50; ++it) {
      const double x = n.x(), y = n.y(), r2 = x * x + y * y;
      const double s = 1.0 + r2 * (k1 + k2 * r2);
      const double ds = 2.0 * (k1 + 2.0 * k2 * r2);
      Eigen::Matrix2d J;
      J << s + ds * x * x + 2.0 * p1 * y + 6.0 * p2 * x, ds * x * y + 2.0 * p1 * x + 2.0 * p2 * y,
          ds * x * y + 2.0 * p1 * x + 2.0 * p2 * y, s + ds * y * y + 6.0 * p1 * y + 2.0 * p2 * x;
      const Vec2 step = J.inverse() * (distort(n, *this) - xd);
      if (!step.allFinite()) break;
      n -= step;
      if (step.norm() <= 1e-16 * std::max(1.0, n.norm())) break;
    }
    return Vec3(n.x(), n.y(), 1.0).normalized();
  }
  const double rd = xd.norm();
  Vec2 xn = xd;
  if (rd > 0.0 && (k1 != 0.0 || k2 != 0.0)) {
    // g(r) = r (1 + k1 r^2 + k2 r^4) - rd = 0 by Newton from r = rd.
    double r = rd;
    for (int it = 0; it < 50; ++it) {
      const double r2 = r * r;
      const double g = r * (1.0 + r2 * (k1 + k2 * r2)) - rd;
      const double dg = 1.0 + r2 * (3.0 * k1 + 5.0 * k2 * r2);
      if (dg <= 0.0) break;
      const double step = g / dg;
      r -= step;
      if (std::abs(step) <= 1e-16 * std::max(1.0, r)) break;
    }
    xn = xd * (r / rd);
  }
  return Vec3(xn.x(), xn.y(), 1.0).normalized();
}

std::optional<Vec2> Intrinsics::project(Vec3 v_cam) const {
  if (!(v_cam.z() > 0.0)) return std::nullopt;
  const Vec2 d = distort(Vec2(v_cam.x() / v_cam.z(), v_cam.y() / v_cam.z()), *this);
  const Vec2 px(cx + fx * d.x(), cy + fy * d.y());
  if (!(px.x() >= -0.5 && px.x() <= width - 0.5 && px.y() >= -0.5 && px.y() <= height - 0.5)) {
    return std::nullopt;
  }
  return px;
}

double Intrinsics::half_diagonal_fov_rad() const {
  double worst = 0.0;
  for (const double x : {-0.5, width - 0.5}) {
    for (const double y : {-0.5, height - 0.5}) {
      const Vec3 u = unproject(Vec2(x, y));
      worst = std::max(worst, std::atan2(u.head<2>().norm(), u.z()));
    }
  }
  return worst;
}

void Intrinsics::validate() const {
  auto bad = [](const std::string& what) { throw std::invalid_argument("Intrinsics: " + what); };
  if (width <= 0 || height <= 0) bad("width and height must be positive");
  if (!(fx > 0.0) || !(fy > 0.0) || !std::isfinite(fx) || !std::isfinite(fy)) {
    bad("fx and fy must be positive and finite");
  }
  if (!std::isfinite(cx) || !std::isfinite(cy)) bad("cx and cy must be finite");
  if (!std::isfinite(k1) || !std::isfinite(k2)) bad("k1 and k2 must be finite");
  if (!std::isfinite(p1) || !std::isfinite(p2)) bad("p1 and p2 must be finite");
}

// ---------------------------------------------------------------------------
// Options
// ---------------------------------------------------------------------------

void DetectionOptions::validate() const {
  auto bad = [](const std::string& what) {
    throw std::invalid_argument("DetectionOptions: " + what);
  };
  if (!(centroid_sigma_floor_px >= 0.0) || !std::isfinite(centroid_sigma_floor_px)) {
    bad("centroid_sigma_floor_px must be finite and >= 0");
  }
  if (!(threshold_sigma > 0.0) || !std::isfinite(threshold_sigma)) {
    bad("threshold_sigma must be positive");
  }
  if (!(grow_sigma > 0.0) || grow_sigma > threshold_sigma) {
    bad("grow_sigma must be in (0, threshold_sigma]");
  }
  if (min_pixels < 1) bad("min_pixels must be at least 1");
  if (max_pixels < min_pixels) bad("max_pixels must be at least min_pixels");
  if (background_cell_px < 8) bad("background_cell_px must be at least 8");
  if (!(psf_sigma_px > 0.0) || !std::isfinite(psf_sigma_px)) bad("psf_sigma_px must be positive");
  if (window_half_px < 0) bad("window_half_px must be >= 0 (0 = automatic)");
  if (max_iterations < 1) bad("max_iterations must be at least 1");
  if (!(convergence_px > 0.0)) bad("convergence_px must be positive");
  if (gaussian_fit_iterations < 1) bad("gaussian_fit_iterations must be at least 1");
  if (!(gain_e_per_dn > 0.0) || !std::isfinite(gain_e_per_dn))
    bad("gain_e_per_dn must be positive");
  if (!(psf_model_error >= 0.0 && psf_model_error < 1.0)) bad("psf_model_error must be in [0, 1)");
  if (!(saturation_dn > 0.0)) bad("saturation_dn must be positive");
  if (!(saturated_sigma_px >= 0.0) || !std::isfinite(saturated_sigma_px)) bad("saturated_sigma_px must be finite and >= 0");
  if (!(max_sharpness >= 0.0)) bad("max_sharpness must be >= 0 (0 disables)");
  if (!(edge_margin_px >= 0.0)) bad("edge_margin_px must be >= 0");
  if (!(deblend_min_separation_px > 0.0)) bad("deblend_min_separation_px must be positive");
  if (!(deblend_dip_fraction > 0.0 && deblend_dip_fraction <= 1.0))
    bad("deblend_dip_fraction must be in (0, 1]");
  if (!(washout_fraction > 0.0)) bad("washout_fraction must be positive");
  if (max_components < 1) bad("max_components must be at least 1");
}

// ---------------------------------------------------------------------------
// Detection
// ---------------------------------------------------------------------------

namespace {

constexpr double kQ16 = 0.15865525393145707;  // Phi(-1)
// Quantisation noise of integer data, 1/sqrt(12) DN: the noise floor.
const double kMinNoiseDn = 1.0 / std::sqrt(12.0);

// Quantile p of integer samples, each read as spread uniformly over
// [v - 1/2, v + 1/2): continuous, so the result of quantised data is not
// itself quantised. Reorders v.
double interpolated_quantile(std::vector<std::uint16_t>& v, double p) {
  const auto n = v.size();
  const double t = p * static_cast<double>(n);
  auto k = static_cast<std::size_t>(t);
  if (k >= n) k = n - 1;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  const std::uint16_t q = v[k];
  std::size_t lt = 0, eq = 0;
  for (const std::uint16_t x : v) {
    lt += x < q ? 1U : 0U;
    eq += x == q ? 1U : 0U;
  }
  const double frac = (t - static_cast<double>(lt)) / static_cast<double>(eq);
  return static_cast<double>(q) - 0.5 + std::clamp(frac, 0.0, 1.0);
}

// The same quantiles of one sample set from its histogram (one pass over
// the samples, a scan of the bins up to the larger quantile): the k-th
// smallest value, and the counts below and at it, are those
// interpolated_quantile finds, so the results are identical. Falls back to
// it when the values span too many bins.
std::pair<double, double> interpolated_quantiles(std::vector<std::uint16_t>& v, double p1, double p2,
                                                 std::vector<std::uint32_t>& hist) {
  const auto [lo_it, hi_it] = std::minmax_element(v.begin(), v.end());
  const std::uint16_t lo = *lo_it, hi = *hi_it;
  if (static_cast<int>(hi) - static_cast<int>(lo) > 8192) {
    const double a = interpolated_quantile(v, p1);
    return {a, interpolated_quantile(v, p2)};
  }
  hist.assign(static_cast<std::size_t>(hi - lo) + 1, 0U);
  for (const std::uint16_t x : v) ++hist[static_cast<std::size_t>(x - lo)];
  const auto n = v.size();
  const auto quantile = [&](double p) {
    const double t = p * static_cast<double>(n);
    auto k = static_cast<std::size_t>(t);
    if (k >= n) k = n - 1;
    std::size_t below = 0, b = 0;
    while (below + hist[b] <= k) below += hist[b++];
    const double frac = (t - static_cast<double>(below)) / static_cast<double>(hist[b]);
    return static_cast<double>(lo + b) - 0.5 + std::clamp(frac, 0.0, 1.0);
  };
  return {quantile(p1), quantile(p2)};
}

// Cell boundaries: n cells over [0, size), boundaries k * size / n.
std::vector<int> cell_edges(int size, int n) {
  std::vector<int> e(static_cast<std::size_t>(n) + 1);
  for (int k = 0; k <= n; ++k) {
    e[static_cast<std::size_t>(k)] = static_cast<int>(static_cast<long long>(k) * size / n);
  }
  return e;
}

// Bilinear interpolation between cell centres: for each pixel coordinate,
// the lower cell index and the weight of the upper one (flat outside).
struct Interp1d {
  std::vector<int> i0;
  std::vector<float> w1;
};
Interp1d interp_table(int size, const std::vector<int>& edges) {
  const int n = static_cast<int>(edges.size()) - 1;
  std::vector<double> centre(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    centre[ku] = 0.5 * (edges[ku] + edges[ku + 1] - 1);
  }
  Interp1d t;
  t.i0.resize(static_cast<std::size_t>(size));
  t.w1.resize(static_cast<std::size_t>(size));
  int k = 0;
  for (int x = 0; x < size; ++x) {
    const auto xu = static_cast<std::size_t>(x);
    while (k + 1 < n && centre[static_cast<std::size_t>(k + 1)] <= x) ++k;
    if (n == 1 || x <= centre[0]) {
      t.i0[xu] = 0;
      t.w1[xu] = 0.0F;
    } else if (k + 1 >= n) {
      t.i0[xu] = n - 1;
      t.w1[xu] = 0.0F;
    } else {
      const auto ku = static_cast<std::size_t>(k);
      t.i0[xu] = k;
      t.w1[xu] = static_cast<float>((x - centre[ku]) / (centre[ku + 1] - centre[ku]));
    }
  }
  return t;
}

struct Grid {
  int ncx = 0, ncy = 0;
  std::vector<double> bg, noise;  // ncy x ncx, row-major
  Interp1d ix, iy;
  [[nodiscard]] double at(const std::vector<double>& g, int x, int y) const {
    const auto xu = static_cast<std::size_t>(x), yu = static_cast<std::size_t>(y);
    const int i0 = ix.i0[xu], j0 = iy.i0[yu];
    const double wx = ix.w1[xu], wy = iy.w1[yu];
    const int i1 = std::min(i0 + 1, ncx - 1), j1 = std::min(j0 + 1, ncy - 1);
    auto v = [&](int i, int j) {
      return g[static_cast<std::size_t>(j) * static_cast<std::size_t>(ncx) +
               static_cast<std::size_t>(i)];
    };
    return (1.0 - wy) * ((1.0 - wx) * v(i0, j0) + wx * v(i1, j0)) +
           wy * ((1.0 - wx) * v(i0, j1) + wx * v(i1, j1));
  }
};

Grid background_grid(std::span<const std::uint16_t> px, int w, int h, int cell) {
  Grid g;
  g.ncx = std::max(1, static_cast<int>(std::lround(static_cast<double>(w) / cell)));
  g.ncy = std::max(1, static_cast<int>(std::lround(static_cast<double>(h) / cell)));
  const auto ex = cell_edges(w, g.ncx), ey = cell_edges(h, g.ncy);
  g.bg.resize(static_cast<std::size_t>(g.ncx * g.ncy));
  g.noise.resize(g.bg.size());
  std::vector<std::uint16_t> samples;
  std::vector<std::uint32_t> hist;
  for (int j = 0; j < g.ncy; ++j) {
    for (int i = 0; i < g.ncx; ++i) {
      samples.clear();
      const int x0 = ex[static_cast<std::size_t>(i)], x1 = ex[static_cast<std::size_t>(i) + 1];
      const int y0 = ey[static_cast<std::size_t>(j)], y1 = ey[static_cast<std::size_t>(j) + 1];
      // Stride-2 lattice unless the cell is small.
      const int stride = (x1 - x0) * (y1 - y0) >= 1024 ? 2 : 1;
      for (int y = y0; y < y1; y += stride) {
        const std::uint16_t* row =
            px.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(w);
        for (int x = x0; x < x1; x += stride) samples.push_back(row[x]);
      }
      const auto [med, q16] = interpolated_quantiles(samples, 0.5, kQ16, hist);
      const auto k = static_cast<std::size_t>(j * g.ncx + i);
      g.bg[k] = med;
      g.noise[k] = std::max(kMinNoiseDn, med - q16);
    }
  }
  // The noise of one cell is known to ~6 % (quantiles of ~1000 samples);
  // averaging over the 3x3 neighbourhood brings that to ~2-3 %. Noise varies
  // slowly (as the square root of the background), so this costs nothing.
  std::vector<double> smooth(g.noise.size());
  for (int j = 0; j < g.ncy; ++j) {
    for (int i = 0; i < g.ncx; ++i) {
      double sum = 0.0;
      int cnt = 0;
      for (int jj = std::max(0, j - 1); jj <= std::min(g.ncy - 1, j + 1); ++jj) {
        for (int ii = std::max(0, i - 1); ii <= std::min(g.ncx - 1, i + 1); ++ii) {
          sum += g.noise[static_cast<std::size_t>(jj * g.ncx + ii)];
          ++cnt;
        }
      }
      smooth[static_cast<std::size_t>(j * g.ncx + i)] = sum / cnt;
    }
  }
  g.noise = std::move(smooth);
  g.ix = interp_table(w, ex);
  g.iy = interp_table(h, ey);
  return g;
}

double median_of(std::vector<double> v) {
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

struct Frame {
  std::span<const std::uint16_t> px;
  int w = 0, h = 0;
  const Grid* grid = nullptr;
  // Hot pixels masked inside the current component: (index, replacement
  // signal). Usually empty.
  std::vector<std::pair<std::size_t, double>> mask;
  [[nodiscard]] std::size_t index(int x, int y) const {
    return static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x);
  }
  [[nodiscard]] double value(int x, int y) const { return px[index(x, y)]; }
  [[nodiscard]] const std::pair<std::size_t, double>* masked(int x, int y) const {
    if (mask.empty()) return nullptr;
    const std::size_t k = index(x, y);
    for (const auto& m : mask) {
      if (m.first == k) return &m;
    }
    return nullptr;
  }
  // Background-subtracted value (the replacement for a masked hot pixel).
  [[nodiscard]] double signal(int x, int y) const {
    if (const auto* m = masked(x, y)) return m->second;
    return value(x, y) - grid->at(grid->bg, x, y);
  }
  // Hot pixels of the whole frame (sharper than the PSF allows, found before
  // the components): index -> replacement signal. A centroid window reaches
  // 3 PSF sigmas; a hot pixel 3-4 px from a faint source is not in its
  // component but biases its centroid (IT, SV2: +0.2 px over 8 frames).
  std::vector<std::pair<std::size_t, double>> frame_hot;  // sorted by index
  // What the centroid, the fit and the flux see: signal() with the frame's
  // hot pixels replaced as well.
  [[nodiscard]] double centroid_signal(int x, int y) const {
    if (!frame_hot.empty()) {
      const std::size_t k = index(x, y);
      const auto it = std::lower_bound(frame_hot.begin(), frame_hot.end(), std::make_pair(k, -1e300));
      if (it != frame_hot.end() && it->first == k) return it->second;
    }
    return signal(x, y);
  }
  // Mean background-subtracted value of the 4 edge neighbours inside the frame.
  [[nodiscard]] double neighbour_mean(int x, int y) const {
    double sum = 0.0;
    int n = 0;
    const int nb[4][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
    for (const auto& d : nb) {
      const int xx = x + d[0], yy = y + d[1];
      if (xx < 0 || yy < 0 || xx >= w || yy >= h) continue;
      sum += value(xx, yy) - grid->at(grid->bg, xx, yy);
      ++n;
    }
    return n > 0 ? sum / n : 0.0;
  }
};

// Iterative weighted centre of gravity from (x, y); returns false if the
// weighted sum vanished.
bool iwcog(const Frame& f, double s_w, int half, int max_it, double tol, double* x, double* y) {
  const double inv2s2 = 1.0 / (2.0 * s_w * s_w);
  double xc = *x, yc = *y;
  for (int it = 0; it < max_it; ++it) {
    const int ix = static_cast<int>(std::lround(xc)), iy = static_cast<int>(std::lround(yc));
    double sw = 0.0, sx = 0.0, sy = 0.0;
    for (int yy = std::max(0, iy - half); yy <= std::min(f.h - 1, iy + half); ++yy) {
      const double dy = yy - yc;
      for (int xx = std::max(0, ix - half); xx <= std::min(f.w - 1, ix + half); ++xx) {
        const double dx = xx - xc;
        const double s = f.centroid_signal(xx, yy);
        const double wi = std::exp(-(dx * dx + dy * dy) * inv2s2) * s;
        sw += wi;
        sx += wi * xx;
        sy += wi * yy;
      }
    }
    if (!(sw > 0.0)) return false;
    const double xn = sx / sw, yn = sy / sw;
    const double step = std::hypot(xn - xc, yn - yc);
    xc = xn;
    yc = yn;
    if (step < tol) break;
  }
  *x = xc;
  *y = yc;
  return true;
}

// Levenberg-damped Gauss-Newton fit of A exp(-|p - p0|^2 / (2 s^2)) to the
// background-subtracted window around (x, y), weights 1 / (noise^2 +
// signal / gain), saturated pixels left out. Returns false unless it
// converged to a sensible solution.
bool gaussian_fit(const Frame& f, const DetectionOptions& o, double noise_dn, int half, double* x,
                  double* y, double* s_out) {
  const int ix = static_cast<int>(std::lround(*x)), iy = static_cast<int>(std::lround(*y));
  struct Px {
    double x, y, v, w;
  };
  std::vector<Px> pts;
  double peak = 0.0;
  for (int yy = std::max(0, iy - half); yy <= std::min(f.h - 1, iy + half); ++yy) {
    for (int xx = std::max(0, ix - half); xx <= std::min(f.w - 1, ix + half); ++xx) {
      if (f.value(xx, yy) >= o.saturation_dn || f.masked(xx, yy) != nullptr) continue;
      const double v = f.centroid_signal(xx, yy);
      pts.push_back({static_cast<double>(xx), static_cast<double>(yy), v,
                     1.0 / (noise_dn * noise_dn + std::max(v, 0.0) / o.gain_e_per_dn)});
      peak = std::max(peak, v);
    }
  }
  if (pts.size() < 6 || !(peak > 0.0)) return false;
  Eigen::Vector4d p(peak, *x, *y, o.psf_sigma_px);  // A, x0, y0, s
  auto cost = [&](const Eigen::Vector4d& q) {
    double c = 0.0;
    for (const auto& t : pts) {
      const double r2 = (t.x - q[1]) * (t.x - q[1]) + (t.y - q[2]) * (t.y - q[2]);
      const double m = q[0] * std::exp(-r2 / (2.0 * q[3] * q[3]));
      c += t.w * (t.v - m) * (t.v - m);
    }
    return c;
  };
  double c = cost(p), lambda = 1e-3;
  for (int it = 0; it < o.gaussian_fit_iterations; ++it) {
    Eigen::Matrix4d JtJ = Eigen::Matrix4d::Zero();
    Eigen::Vector4d Jtr = Eigen::Vector4d::Zero();
    const double s2 = p[3] * p[3];
    for (const auto& t : pts) {
      const double dx = t.x - p[1], dy = t.y - p[2];
      const double r2 = dx * dx + dy * dy;
      const double e = std::exp(-r2 / (2.0 * s2));
      const double m = p[0] * e;
      const Eigen::Vector4d J(e, m * dx / s2, m * dy / s2, m * r2 / (s2 * p[3]));
      JtJ.noalias() += t.w * J * J.transpose();
      Jtr.noalias() += t.w * J * (t.v - m);
    }
    // Gauss-Newton step, damped (Levenberg-Marquardt) only when it fails to
    // lower the cost.
    double step = -1.0;
    for (int tries = 0; tries < 8; ++tries) {
      Eigen::Matrix4d A = JtJ;
      A.diagonal() *= 1.0 + lambda;
      const Eigen::Vector4d d = A.ldlt().solve(Jtr);
      const Eigen::Vector4d pn = p + d;
      const double cn = (pn[0] > 0.0 && pn[3] > 0.2) ? cost(pn) : 1e300;
      if (cn <= c) {
        step = std::hypot(d[1], d[2]);
        p = pn;
        c = cn;
        lambda = std::max(1e-7, lambda * 0.1);
        break;
      }
      lambda *= 10.0;
    }
    if (step < o.convergence_px) break;  // converged, or no step lowers the cost
  }
  // Accept the result if it stayed inside the window with a plausible width.
  if (!(std::abs(p[1] - *x) < half && std::abs(p[2] - *y) < half && p[3] < half && p[0] > 0.0)) {
    return false;
  }
  *x = p[1];
  *y = p[2];
  *s_out = p[3];
  return true;
}

// Centroid variance per axis (px^2), header item 5. A pixel integrates the
// PSF, so the sampled spot has the variance s^2 + 1/12 per axis.
//
// Cramer-Rao bound (the Gaussian fit attains it):
//   var = s_p^2 / N + 8 pi s_p^4 b / N^2,  s_p^2 = s^2 + 1/12.
double cramer_rao_variance_px2(double s_psf, double n_e, double b_e2) {
  if (!(n_e > 0.0)) return 0.0;
  const double sp2 = s_psf * s_psf + 1.0 / 12.0;
  return sp2 / n_e + 8.0 * std::numbers::pi * sp2 * sp2 * b_e2 / (n_e * n_e);
}

// Goodness of fit of a single PSF at the centroid (header, item 6) over the
// window's unsaturated, unmasked pixels.
double psf_chi2_z(const Frame& f, const DetectionOptions& o, double noise_dn, int half, double xc, double yc) {
  const int ix = static_cast<int>(std::lround(xc)), iy = static_cast<int>(std::lround(yc));
  std::vector<PsfFitPixel> pts;
  pts.reserve(static_cast<std::size_t>((2 * half + 1) * (2 * half + 1)));
  for (int yy = std::max(0, iy - half); yy <= std::min(f.h - 1, iy + half); ++yy) {
    for (int xx = std::max(0, ix - half); xx <= std::min(f.w - 1, ix + half); ++xx) {
      if (f.value(xx, yy) >= o.saturation_dn || f.masked(xx, yy) != nullptr) continue;
      pts.push_back({f.centroid_signal(xx, yy), pixel_psf_fraction(xx, yy, xc, yc, o.psf_sigma_px)});
    }
  }
  return psf_fit_chi2_z(pts, noise_dn, o.gain_e_per_dn, o.psf_model_error);
}

int centroid_window_half_px(const DetectionOptions& o) {
  return o.window_half_px > 0 ? o.window_half_px : static_cast<int>(std::ceil(3.0 * o.psf_sigma_px));
}

}  // namespace

// IWCoG with a Gaussian weight of width s_w on a spot of width s_p, by
// linearising x = sum w I x / sum w I at its fixed point: the weighted sum
// captures r = s_w^2 / (s_w^2 + s_p^2) of the flux and the re-centring
// multiplies a fixed window's error by 1 / r, so
//   var = A / (N r^4) + pi s_w^4 b / (2 N^2 r^4),
//   A = [h / (h + s_p^2)] [h s_p^2 / (h + s_p^2)],  h = s_w^2 / 2
// (photon term: the integral of w^2 x^2 over the spot; background term: of
// w^2 x^2 over the plane). For s_w = s_p = s this is 16 s^2 / (9 N) +
// 8 pi s^4 b / N^2: the bound's background term but 1.78 times its photon
// term, which is why bright stars scattered 1.4 times the Cramer-Rao figure.
double iwcog_variance_px2(double s_w, double s_psf, double n_e, double b_e2) {
  if (!(n_e > 0.0)) return 0.0;
  const double sp2 = s_psf * s_psf + 1.0 / 12.0, sw2 = s_w * s_w;
  const double r = sw2 / (sw2 + sp2), r4 = r * r * r * r;
  const double h = 0.5 * sw2;
  const double a = (h / (h + sp2)) * (h * sp2 / (h + sp2));
  return a / (n_e * r4) + std::numbers::pi * sw2 * sw2 * b_e2 / (2.0 * n_e * n_e * r4);
}

SignalPosteriorFactors signal_posterior_factors(double signal, double variance) {
  if (!(signal > 0.0) || !(variance > 0.0) || !std::isfinite(variance)) return {};
  const double r2 = std::min(variance / (signal * signal), kMaxSignalRelVariance);
  return {1.0 + r2, 1.0 + 3.0 * r2};
}

double centroid_sigma_px(const DetectionOptions& o, double signal_dn, double noise_dn, double psf_width_px,
                         double weight_width_px, bool saturated, double signal_variance_dn2) {
  const double n_e = signal_dn * o.gain_e_per_dn;
  const double b_e2 = std::pow(noise_dn * o.gain_e_per_dn, 2);
  const auto variance = [&](double b2) {
    return o.centroid_method == CentroidMethod::kGaussianFit
               ? cramer_rao_variance_px2(psf_width_px, n_e, b2)
               : iwcog_variance_px2(weight_width_px, psf_width_px, n_e, b2);
  };
  double var_px2 = variance(b_e2);
  if (signal_variance_dn2 > 0.0) {
    const double photon = variance(0.0);
    const SignalPosteriorFactors f = signal_posterior_factors(signal_dn, signal_variance_dn2);
    var_px2 = f.photon * photon + f.background * (var_px2 - photon);
  }
  double sigma = n_e > 0.0 ? std::sqrt(var_px2 + o.centroid_sigma_floor_px * o.centroid_sigma_floor_px)
                           : static_cast<double>(centroid_window_half_px(o));
  if (saturated) sigma = std::max(sigma, o.saturated_sigma_px);
  return sigma;
}

double window_signal_variance_dn2(const DetectionOptions& o, double signal_dn, double noise_dn) {
  const double side = 2.0 * centroid_window_half_px(o) + 1.0;
  return side * side * noise_dn * noise_dn + std::max(signal_dn, 0.0) / o.gain_e_per_dn;
}

double pixel_psf_fraction(int x, int y, double xc, double yc, double psf_sigma_px) {
  const double k = 1.0 / (std::numbers::sqrt2 * psf_sigma_px);
  const double u = x - xc, v = y - yc;
  return 0.25 * (std::erf((u + 0.5) * k) - std::erf((u - 0.5) * k)) * (std::erf((v + 0.5) * k) - std::erf((v - 0.5) * k));
}

double psf_fit_chi2_z(std::span<const PsfFitPixel> pts, double noise_dn, double gain_e_per_dn, double psf_model_error) {
  const std::size_t n = pts.size();
  if (n < 8) return 0.0;
  const double var0 = noise_dn * noise_dn;
  auto variance = [&](double model) {
    return var0 + std::max(model, 0.0) / gain_e_per_dn + std::pow(psf_model_error * model, 2);
  };
  // Amplitude: ordinary least squares, then once more with the variances of that model.
  double svm = 0.0, smm = 0.0;
  for (const auto& p : pts) {
    svm += p.signal_dn * p.psf_fraction;
    smm += p.psf_fraction * p.psf_fraction;
  }
  double a = smm > 0.0 ? svm / smm : 0.0;
  svm = smm = 0.0;
  for (const auto& p : pts) {
    const double w = 1.0 / variance(a * p.psf_fraction);
    svm += w * p.signal_dn * p.psf_fraction;
    smm += w * p.psf_fraction * p.psf_fraction;
  }
  a = smm > 0.0 ? svm / smm : 0.0;
  double chi2 = 0.0;
  for (const auto& p : pts) {
    const double r = p.signal_dn - a * p.psf_fraction;
    chi2 += r * r / variance(a * p.psf_fraction);
  }
  const double dof = static_cast<double>(n) - 3.0;
  return (chi2 - dof) / std::sqrt(2.0 * dof);
}

DetectionResult detect(std::span<const std::uint16_t> pixels, int width, int height,
                       const DetectionOptions& o) {
  o.validate();
  if (width <= 0 || height <= 0 ||
      pixels.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height)) {
    throw std::invalid_argument("detect: pixel buffer of " + std::to_string(pixels.size()) +
                                " values does not match " + std::to_string(width) + " x " +
                                std::to_string(height));
  }
  DetectionResult res;
  const Grid grid = background_grid(pixels, width, height, o.background_cell_px);
  res.background_dn = median_of(grid.bg);
  res.noise_dn = median_of(grid.noise);
  if (res.background_dn > o.washout_fraction * o.saturation_dn) {
    res.usable = false;
    res.why = "washed out: median background " + std::to_string(res.background_dn) + " DN";
    return res;
  }
  Frame f{pixels, width, height, &grid, {}, {}};

  // Lit pixels (hysteresis): seeds above background + threshold_sigma *
  // noise, grown through pixels above background + grow_sigma * noise. Per
  // row, a quick reject against the row's lowest grow threshold; the
  // interpolated thresholds only for pixels above it.
  const auto W = static_cast<std::size_t>(width);
  constexpr std::uint8_t kGrow = 1, kSeed = 2, kDone = 3;
  std::vector<std::uint8_t> lit(pixels.size(), 0);
  std::vector<double> cell_grow(static_cast<std::size_t>(grid.ncx * grid.ncy));
  for (std::size_t k = 0; k < cell_grow.size(); ++k)
    cell_grow[k] = grid.bg[k] + o.grow_sigma * grid.noise[k];
  std::vector<std::size_t> seeds;
  for (int y = 0; y < height; ++y) {
    const int j0 = grid.iy.i0[static_cast<std::size_t>(y)];
    const int j1 = std::min(j0 + 1, grid.ncy - 1);
    double row_min = 1e300;
    for (int i = 0; i < grid.ncx; ++i) {
      row_min = std::min({row_min, cell_grow[static_cast<std::size_t>(j0 * grid.ncx + i)],
                          cell_grow[static_cast<std::size_t>(j1 * grid.ncx + i)]});
    }
    const std::uint16_t* row = pixels.data() + static_cast<std::size_t>(y) * W;
    const auto quick = static_cast<std::uint16_t>(std::clamp(std::floor(row_min), 0.0, 65535.0));
    for (int x = 0; x < width; ++x) {
      if (row[x] <= quick) continue;
      const double bg = grid.at(grid.bg, x, y);
      const double excess = row[x] - bg;
      const double noise = grid.at(grid.noise, x, y);
      if (excess <= o.grow_sigma * noise) continue;
      const std::size_t k = static_cast<std::size_t>(y) * W + static_cast<std::size_t>(x);
      if (excess > o.threshold_sigma * noise) {
        lit[k] = kSeed;
        seeds.push_back(k);
      } else {
        lit[k] = kGrow;
      }
    }
  }

  // 8-connected components (depth-first flood fill) from each seed, in scan
  // order.
  const int half = centroid_window_half_px(o);
  std::vector<std::size_t> stack, comp;
  std::vector<std::array<double, 3>> maxima;  // x, y, signal
  int n_components = 0;
  // Hot pixels: a pixel of at least 10 noise sigmas far sharper than the PSF
  // allows (max_sharpness times the mean of its 4 neighbours) is replaced by
  // that mean; appends (index, replacement) to `out` if so.
  auto collect_hot = [&](std::size_t k, std::vector<std::pair<std::size_t, double>>& out) {
    const int x = static_cast<int>(k % W), y = static_cast<int>(k / W);
    const double sk = f.signal(x, y);
    if (sk < 10.0 * grid.at(grid.noise, x, y)) return;
    const double nmean = f.neighbour_mean(x, y);
    if (sk > o.max_sharpness * nmean) out.emplace_back(k, std::max(nmean, 0.0));
  };
  if (o.max_sharpness > 0.0) {
    for (const std::size_t k : seeds) collect_hot(k, f.frame_hot);
    std::sort(f.frame_hot.begin(), f.frame_hot.end());
  }
  for (const std::size_t start : seeds) {
    if (lit[start] == kDone) continue;
    comp.clear();
    stack.assign(1, start);
    lit[start] = kDone;
    while (!stack.empty()) {
      const std::size_t k = stack.back();
      stack.pop_back();
      comp.push_back(k);
      const int x = static_cast<int>(k % W), y = static_cast<int>(k / W);
      for (int dy = -1; dy <= 1; ++dy) {
        const int yy = y + dy;
        if (yy < 0 || yy >= height) continue;
        for (int dx = -1; dx <= 1; ++dx) {
          const int xx = x + dx;
          if (xx < 0 || xx >= width || (dx == 0 && dy == 0)) continue;
          const std::size_t kk = static_cast<std::size_t>(yy) * W + static_cast<std::size_t>(xx);
          if (lit[kk] == kGrow || lit[kk] == kSeed) {
            lit[kk] = kDone;
            stack.push_back(kk);
          }
        }
      }
    }
    ++n_components;
    const int npx = static_cast<int>(comp.size());
    if (npx < o.min_pixels) {
      ++res.rejected_single_pixel;
      if (npx == 1) {
        const int x = static_cast<int>(comp[0] % W), y = static_cast<int>(comp[0] / W);
        if (f.signal(x, y) >= 10.0 * grid.at(grid.noise, x, y)) res.hot_suspects.push_back(comp[0]);
      }
      continue;
    }
    if (npx > o.max_pixels) {
      ++res.rejected_oversized;
      continue;
    }
    // Hot pixels: a pixel far sharper than the PSF allows (see
    // max_sharpness) is masked, i.e. replaced by the mean of its neighbours;
    // the rest of the component (a star under the hot pixel) survives.
    f.mask.clear();
    if (o.max_sharpness > 0.0) {
      for (const std::size_t k : comp) collect_hot(k, f.mask);
      res.masked_hot_pixels += static_cast<int>(f.mask.size());
      for (const auto& m : f.mask) res.hot_suspects.push_back(m.first);
      if (npx - static_cast<int>(f.mask.size()) < o.min_pixels) {
        ++res.rejected_sharp;
        continue;
      }
    }
    // Peak and the plain centre of gravity.
    double peak = -1e300, sum = 0.0, sx = 0.0, sy = 0.0;
    for (const std::size_t k : comp) {
      const int x = static_cast<int>(k % W), y = static_cast<int>(k / W);
      const double s = f.signal(x, y);
      peak = std::max(peak, s);
      const double sp = std::max(s, 0.0);
      sum += sp;
      sx += sp * x;
      sy += sp * y;
    }
    if (!(sum > 0.0)) continue;

    // Starting points: the component's centre of gravity, or, when it holds
    // several separate peaks (a blended pair), each peak.
    struct Start {
      double x, y, peak;
    };
    std::vector<Start> starts;
    if (o.deblend && npx >= 2 * o.min_pixels) {
      maxima.clear();
      for (const std::size_t k : comp) {
        const int x = static_cast<int>(k % W), y = static_cast<int>(k / W);
        const double sk = f.signal(x, y);
        if (sk < o.threshold_sigma * grid.at(grid.noise, x, y)) continue;
        bool is_max = true;
        for (int dy = -1; dy <= 1 && is_max; ++dy) {
          for (int dx = -1; dx <= 1 && is_max; ++dx) {
            const int xx = x + dx, yy = y + dy;
            if ((dx == 0 && dy == 0) || xx < 0 || yy < 0 || xx >= width || yy >= height) continue;
            const double sn = f.signal(xx, yy);
            // Ties (flat saturated tops) go to the first pixel in scan order.
            is_max = sn < sk || (sn == sk && (dy > 0 || (dy == 0 && dx > 0)));
          }
        }
        if (is_max) maxima.push_back({static_cast<double>(x), static_cast<double>(y), sk});
      }
      std::sort(maxima.begin(), maxima.end(),
                [](const auto& p, const auto& q) { return p[2] > q[2]; });
      for (const auto& m : maxima) {
        bool separate = true;
        for (const auto& acc : starts) {
          const double d = std::hypot(m[0] - acc.x, m[1] - acc.y);
          if (d < o.deblend_min_separation_px) {
            separate = false;
            break;
          }
          // The profile between the two peaks must dip below
          // deblend_dip_fraction of the fainter one.
          double lowest = m[2];
          const int steps = static_cast<int>(std::ceil(d));
          for (int t = 1; t < steps; ++t) {
            const double u = static_cast<double>(t) / steps;
            const int xx = static_cast<int>(std::lround(m[0] + u * (acc.x - m[0])));
            const int yy = static_cast<int>(std::lround(m[1] + u * (acc.y - m[1])));
            lowest = std::min(lowest, f.signal(xx, yy));
          }
          if (lowest > o.deblend_dip_fraction * m[2]) {
            separate = false;
            break;
          }
        }
        if (separate) starts.push_back({m[0], m[1], m[2]});
      }
    }
    if (starts.size() <= 1) {
      starts.assign(1, {sx / sum, sy / sum, peak});
    }
    const int n_before = static_cast<int>(res.centroids.size());
    for (const auto& st : starts) {
      double xc = st.x, yc = st.y;
      if (!iwcog(f, o.psf_sigma_px, half, o.max_iterations, o.convergence_px, &xc, &yc) ||
          std::hypot(xc - st.x, yc - st.y) > half) {
        xc = st.x;
        yc = st.y;
      }
      const double noise_c =
          grid.at(grid.noise, static_cast<int>(std::lround(std::clamp(xc, 0.0, width - 1.0))),
                  static_cast<int>(std::lround(std::clamp(yc, 0.0, height - 1.0))));
      double s_psf = o.psf_sigma_px;
      if (o.centroid_method == CentroidMethod::kGaussianFit) {
        double xf = xc, yf = yc, sf = s_psf;
        if (gaussian_fit(f, o, noise_c, half, &xf, &yf, &sf)) {
          xc = xf;
          yc = yf;
          // The fit sees a pixel-sampled PSF: s^2 = s_psf^2 + 1/12.
          s_psf = std::sqrt(std::max(sf * sf - 1.0 / 12.0, 0.25 * sf * sf));
        }
      }
      if (xc < o.edge_margin_px || yc < o.edge_margin_px || xc > width - 1 - o.edge_margin_px ||
          yc > height - 1 - o.edge_margin_px) {
        ++res.rejected_edge;
        continue;
      }
      // Two starts that converged to one source.
      bool duplicate = false;
      for (int m = n_before; m < static_cast<int>(res.centroids.size()); ++m) {
        const auto& other = res.centroids[static_cast<std::size_t>(m)];
        duplicate = duplicate || std::hypot(other.x_px - xc, other.y_px - yc) < 1.0;
      }
      if (duplicate) continue;
      // Flux: plain sum over the window around the centroid; saturation:
      // any unmasked saturated pixel in it.
      const int ix = static_cast<int>(std::lround(xc)), iy = static_cast<int>(std::lround(yc));
      double flux = 0.0, m2 = 0.0;
      bool sat = false;
      for (int yy = std::max(0, iy - half); yy <= std::min(height - 1, iy + half); ++yy) {
        for (int xx = std::max(0, ix - half); xx <= std::min(width - 1, ix + half); ++xx) {
          const double sig = f.centroid_signal(xx, yy);
          flux += sig;
          m2 += sig * ((xx - xc) * (xx - xc) + (yy - yc) * (yy - yc));
          sat = sat || (f.value(xx, yy) >= o.saturation_dn && f.masked(xx, yy) == nullptr);
        }
      }
      Centroid c;
      c.x_px = xc;
      c.y_px = yc;
      c.flux_dn = flux;
      c.peak_dn = st.peak;
      c.pixels = npx;
      c.saturated = sat;
      c.psf_chi2_z = sat ? 0.0 : psf_chi2_z(f, o, noise_c, half, xc, yc);
      if (!sat && flux > 0.0) {
        const double v = 0.5 * m2 / flux - 1.0 / 12.0;
        c.moment_sigma_px = v > 0.0 ? std::sqrt(v) : 0.0;
      }
      c.signal_dn = std::max(flux, st.peak);
      c.noise_dn = noise_c;
      c.psf_width_px = s_psf;
      c.weight_width_px = o.psf_sigma_px;
      c.sigma_px = centroid_sigma_px(o, c.signal_dn, noise_c, s_psf, o.psf_sigma_px, sat);
      res.centroids.push_back(c);
    }
  }
  std::sort(res.centroids.begin(), res.centroids.end(),
            [](const Centroid& a, const Centroid& b) { return a.flux_dn > b.flux_dn; });
  if (n_components > o.max_components) {
    res.usable = false;
    res.why = "too many components (" + std::to_string(n_components) +
              "): a noise frame or a threshold far too low";
  } else if (res.centroids.empty()) {
    res.usable = false;
    res.why = "no point sources above threshold";
  } else {
    res.usable = true;
  }
  return res;
}

}  // namespace artms::imp
