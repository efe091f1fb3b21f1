// Image formation and noise (see image.hpp for the model and conventions).
#include "artms/imaging/image.hpp"

#include "artms/astro/aberration.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <unordered_set>

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wold-style-cast"
#pragma GCC diagnostic ignored "-Wconversion"
#pragma GCC diagnostic ignored "-Wsign-conversion"
#pragma GCC diagnostic ignored "-Wshadow"
#pragma GCC diagnostic ignored "-Wpedantic"
#pragma GCC diagnostic ignored "-Wcast-align"
#pragma GCC diagnostic ignored "-Woverloaded-virtual"
#pragma GCC diagnostic ignored "-Wnon-virtual-dtor"
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#pragma GCC diagnostic pop

namespace artms::imaging {

namespace {

constexpr double kSqrt2 = 1.4142135623730951;
constexpr double kTwoPi = 6.283185307179586;
constexpr double kUnit53 = 1.0 / 9007199254740992.0;  // 2^-53

// SplitMix64 (Steele, Lea & Flood 2014): seeds the generator below and
// decorrelates the per-row streams.
std::uint64_t splitmix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9E3779B97F4A7C15ULL);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

// xoshiro256** 1.0 (Blackman & Vigna 2018, "Scrambled linear pseudorandom
// number generators"), state filled from SplitMix64 as its authors advise.
// Chosen over std::mt19937_64 for the per-pixel noise: 0.7 ns against
// 6.1 ns per 64-bit draw on the 2.1 GHz build machine, with 32 bytes of
// state, so a fresh stream per image row costs nothing. Like every
// sampler here it is our own code: the same seed gives the same frame
// with any standard library.
class Xoshiro256ss {
 public:
  explicit Xoshiro256ss(std::uint64_t seed) {
    for (auto& word : s_) word = splitmix64(seed);
  }
  std::uint64_t operator()() {
    const std::uint64_t result = rotl(s_[1] * 5, 7) * 9;
    const std::uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = rotl(s_[3], 45);
    return result;
  }

 private:
  static std::uint64_t rotl(std::uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  std::array<std::uint64_t, 4> s_{};
};

// Stream for row `row` of the frame with seed `seed`.
std::uint64_t row_seed(std::uint64_t seed, int row) {
  std::uint64_t st = seed;
  return splitmix64(st) ^ (0xD1B54A32D192ED03ULL * (static_cast<std::uint64_t>(row) + 1));
}

// log(k!) for k >= 0: a table below 64, Stirling's series for ln Gamma(k + 1)
// above (Abramowitz & Stegun 6.1.41; truncation error < 1e-17 there).
double log_factorial(std::int64_t k) {
  static const std::array<double, 64> table = [] {
    std::array<double, 64> t{};
    for (std::size_t i = 1; i < t.size(); ++i) t[i] = t[i - 1] + std::log(static_cast<double>(i));
    return t;
  }();
  if (k < 64) return table[static_cast<std::size_t>(k)];
  const double x = static_cast<double>(k) + 1.0;
  const double ix = 1.0 / x, ix2 = ix * ix;
  constexpr double kHalfLog2Pi = 0.91893853320467274;
  return (x - 0.5) * std::log(x) - x + kHalfLog2Pi +
         ix * (1.0 / 12.0 - ix2 * (1.0 / 360.0 - ix2 * (1.0 / 1260.0 - ix2 / 1680.0)));
}

// Uniform, normal and Poisson deviates from xoshiro256**.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : eng_(seed) {}

  std::uint64_t bits() { return eng_(); }
  // Uniform in [0, 1) and in (0, 1], 53 random bits.
  double uniform() { return static_cast<double>(eng_() >> 11) * kUnit53; }
  double uniform_pos() { return static_cast<double>((eng_() >> 11) + 1) * kUnit53; }

  // Standard normal, Box-Muller (Box & Muller 1958), both values used.
  double normal() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    const double r = std::sqrt(-2.0 * std::log(uniform_pos()));
    const double th = kTwoPi * uniform();
    spare_ = r * std::sin(th);
    has_spare_ = true;
    return r * std::cos(th);
  }

  // Poisson deviate. Mean < 10: inversion by sequential search (Devroye
  // 1986, sec. X.3.3). Otherwise Hormann's (1993) transformed rejection with
  // squeeze, PTRS, exact for every mean >= 10.
  std::int64_t poisson(double lam) {
    if (!(lam > 0.0)) return 0;
    if (lam < 10.0) {
      // exp(-lam) of the previous mean is reused (neighbouring pixels share it).
      if (lam != small_lam_) {
        small_lam_ = lam;
        exp_minus_lam_ = std::exp(-lam);
      }
      double p = exp_minus_lam_;
      double cdf = p;
      const double u = uniform();
      std::int64_t k = 0;
      while (u >= cdf && k < 200) {
        ++k;
        p *= lam / static_cast<double>(k);
        cdf += p;
      }
      return k;
    }
    // The constants of the previous mean are reused (same values, bit for bit).
    if (lam != ptrs_.lam) {
      ptrs_.lam = lam;
      ptrs_.loglam = std::log(lam);
      ptrs_.b = 0.931 + 2.53 * std::sqrt(lam);
      ptrs_.a = -0.059 + 0.02483 * ptrs_.b;
      ptrs_.inv_alpha = 1.1239 + 1.1328 / (ptrs_.b - 3.4);
      ptrs_.v_r = 0.9277 - 3.6224 / (ptrs_.b - 2.0);
    }
    const double loglam = ptrs_.loglam, b = ptrs_.b, a = ptrs_.a, inv_alpha = ptrs_.inv_alpha, v_r = ptrs_.v_r;
    for (;;) {
      const double u = uniform() - 0.5;
      const double v = uniform();
      const double us = 0.5 - std::abs(u);
      const double kd = std::floor((2.0 * a / us + b) * u + lam + 0.43);
      if (us >= 0.07 && v <= v_r) return static_cast<std::int64_t>(kd);
      if (kd < 0.0 || (us < 0.013 && v > us)) continue;
      const auto k = static_cast<std::int64_t>(kd);
      if (std::log(v) + std::log(inv_alpha) - std::log(a / (us * us) + b) <=
          -lam + kd * loglam - log_factorial(k)) {
        return k;
      }
    }
  }

 private:
  Xoshiro256ss eng_;
  double spare_ = 0.0;
  bool has_spare_ = false;
  double small_lam_ = -1.0, exp_minus_lam_ = 0.0;
  struct {
    double lam = -1.0, loglam = 0.0, b = 0.0, a = 0.0, inv_alpha = 0.0, v_r = 0.0;
  } ptrs_;
};

// The conversion chain electrons -> DN for one set of options.
struct Chain {
  bool shot = true;
  double read_sigma_e = 0.0;
  double full_well_e = std::numeric_limits<double>::infinity();
  double gain_e_per_dn = 1.0;
  double bias_dn = 0.0;
  double dn_max = 65535.0;
  bool clip_float = true;  // clip the float output to [0, dn_max]

  [[nodiscard]] bool random() const { return shot || read_sigma_e > 0.0; }
  bool operator==(const Chain&) const = default;

  // Noise-free DN of a pixel with expected electrons lam.
  [[nodiscard]] double expected(double lam) const {
    return std::min(lam, full_well_e) / gain_e_per_dn + bias_dn;
  }
  // Unrounded DN of one pixel with expected electrons lam.
  double sample(double lam, Rng& rng) const {
    if (!random()) return expected(lam);
    double e = shot ? static_cast<double>(rng.poisson(lam)) : lam;
    e = std::min(e, full_well_e);
    if (read_sigma_e > 0.0) e += read_sigma_e * rng.normal();
    return e / gain_e_per_dn + bias_dn;
  }
  // Rounded to nearest, half up, within the output range.
  [[nodiscard]] std::uint16_t quantize(double dn) const {
    return static_cast<std::uint16_t>(std::clamp(std::floor(dn + 0.5), 0.0, dn_max));
  }
};

Chain make_chain(const CameraModel& c, const NoiseOptions& o) {
  Chain m;
  m.shot = o.shot_noise;
  m.read_sigma_e = o.read_noise ? c.read_noise_e : 0.0;
  m.gain_e_per_dn = c.gain_e_per_dn;
  m.bias_dn = o.bias ? c.bias_dn : 0.0;
  if (o.saturation) {
    m.full_well_e = c.full_well_e;
    m.dn_max = c.max_dn();
  }
  m.clip_float = o.saturation;
  return m;
}

// P(a <= Z < b) for a standard normal Z, accurate in both tails.
double normal_cell(double a, double b) {
  if (a >= 0.0) return 0.5 * (std::erfc(a / kSqrt2) - std::erfc(b / kSqrt2));
  if (b <= 0.0) return 0.5 * (std::erfc(-b / kSqrt2) - std::erfc(-a / kSqrt2));
  return 1.0 - 0.5 * (std::erfc(b / kSqrt2) + std::erfc(-a / kSqrt2));
}

// The exact distribution of the quantised DN of a pixel with expected
// electrons lam (Poisson electrons, clipped at the full well, plus Gaussian
// read noise, rounded), sampled in O(1) with Vose's (1991) alias method.
// Most pixels of a star field share one mean (background + dark), so one
// table replaces a Poisson and a normal deviate per pixel by one 64-bit draw.
class PixelTable {
 public:
  // nullopt if the table would be too large to be worth building.
  static std::optional<PixelTable> build(double lam, const Chain& m) {
    // Electron values and their probabilities.
    std::vector<std::pair<double, double>> electrons;
    if (m.shot && lam > 0.0) {
      const double span = 12.0 * std::sqrt(lam) + 12.0;
      const auto k_lo = static_cast<std::int64_t>(std::max(0.0, std::floor(lam - span)));
      const auto k_hi = static_cast<std::int64_t>(std::ceil(lam + span));
      const double log_lam = std::log(lam);
      for (std::int64_t k = k_lo; k <= k_hi; ++k) {
        const double p = std::exp(-lam + static_cast<double>(k) * log_lam - log_factorial(k));
        electrons.emplace_back(std::min(static_cast<double>(k), m.full_well_e), p);
      }
    } else {
      electrons.emplace_back(std::min(std::max(lam, 0.0), m.full_well_e), 1.0);
    }
    const double reach = 9.0 * m.read_sigma_e;
    const double e_min = electrons.front().first - reach, e_max = electrons.back().first + reach;
    const double d_lo =
        std::clamp(std::floor(e_min / m.gain_e_per_dn + m.bias_dn) - 1.0, 0.0, m.dn_max);
    const double d_hi =
        std::clamp(std::ceil(e_max / m.gain_e_per_dn + m.bias_dn) + 1.0, 0.0, m.dn_max);
    const auto n = static_cast<std::size_t>(d_hi - d_lo) + 1;
    if (static_cast<double>(n) * static_cast<double>(electrons.size()) > 4e6) return std::nullopt;

    std::vector<double> p(n, 0.0);
    for (const auto& [e, w] : electrons) {
      if (m.read_sigma_e > 0.0) {
        const double lo = std::max(d_lo, std::floor((e - reach) / m.gain_e_per_dn + m.bias_dn));
        const double hi = std::min(d_hi, std::ceil((e + reach) / m.gain_e_per_dn + m.bias_dn));
        for (double d = lo; d <= hi; d += 1.0) {
          const double a = d <= 0.0
                               ? -std::numeric_limits<double>::infinity()
                               : (m.gain_e_per_dn * (d - 0.5 - m.bias_dn) - e) / m.read_sigma_e;
          const double b = d >= m.dn_max
                               ? std::numeric_limits<double>::infinity()
                               : (m.gain_e_per_dn * (d + 0.5 - m.bias_dn) - e) / m.read_sigma_e;
          p[static_cast<std::size_t>(d - d_lo)] += w * normal_cell(a, b);
        }
      } else {
        const double d = std::clamp(std::floor(e / m.gain_e_per_dn + m.bias_dn + 0.5), d_lo, d_hi);
        p[static_cast<std::size_t>(d - d_lo)] += w;
      }
    }
    double total = 0.0;
    for (const double x : p) total += x;

    // Vose's alias method. A column whose own probability is 1 gets itself
    // as alias, so the 32-bit threshold never needs the value 2^32.
    PixelTable t;
    t.columns_.resize(n);
    std::vector<double> scaled(n);
    std::vector<std::size_t> small, large;
    for (std::size_t i = 0; i < n; ++i) {
      scaled[i] = p[i] / total * static_cast<double>(n);
      const auto dn = static_cast<std::uint16_t>(d_lo + static_cast<double>(i));
      t.columns_[i] = {0xFFFFFFFFU, dn, dn};
      (scaled[i] < 1.0 ? small : large).push_back(i);
    }
    constexpr double k2p32 = 4294967296.0;
    while (!small.empty() && !large.empty()) {
      const std::size_t s = small.back(), l = large.back();
      small.pop_back();
      t.columns_[s].threshold =
          static_cast<std::uint32_t>(std::min(scaled[s] * k2p32, k2p32 - 1.0));
      t.columns_[s].alias = t.columns_[l].own;
      scaled[l] -= 1.0 - scaled[s];
      if (scaled[l] < 1.0) {
        large.pop_back();
        small.push_back(l);
      }
    }
    return t;
  }

  // One 64-bit draw: the high half picks a column, the low half decides
  // between the column's own value and its alias (probabilities to 2^-32).
  // Branch-free: the choice is random, so a branch would mispredict half
  // the time.
  [[nodiscard]] std::uint16_t sample(std::uint64_t bits) const {
    const Column c = columns_[((bits >> 32) * columns_.size()) >> 32];
    const auto take_alias = static_cast<std::uint16_t>(
        -static_cast<std::int32_t>(static_cast<std::uint32_t>(bits) >= c.threshold));
    return static_cast<std::uint16_t>(c.own ^ ((c.own ^ c.alias) & take_alias));
  }

 private:
  struct Column {
    std::uint32_t threshold;  // keep `own` if the low 32 bits are below
    std::uint16_t own;
    std::uint16_t alias;
  };
  std::vector<Column> columns_;
};

float base_electrons(const CameraModel& c, const NoiseOptions& o) {
  double e = 0.0;
  if (o.background) e += c.background_e_per_px_per_s * c.exposure_s;
  if (o.dark_current) e += c.dark_current_e_per_s * c.exposure_s;
  return static_cast<float>(e);
}

void check_size(std::span<const std::uint16_t> pixels, int width, int height,
                const std::string& path) {
  if (width <= 0 || height <= 0 ||
      pixels.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height)) {
    throw std::runtime_error(path + ": image buffer of " + std::to_string(pixels.size()) +
                             " pixels does not match " + std::to_string(width) + " x " +
                             std::to_string(height));
  }
}

void write_png(const std::string& path, const cv::Mat& mat) {
  bool ok = false;
  try {
    ok = cv::imwrite(path, mat, {cv::IMWRITE_PNG_COMPRESSION, 1});
  } catch (const cv::Exception& ex) {
    throw std::runtime_error(path + ": cannot write PNG: " + ex.what());
  }
  if (!ok) throw std::runtime_error(path + ": cannot write PNG");
}

}  // namespace

// ---------------------------------------------------------------------------

// Faint pixel levels 0, kLevelStep_e, ..., kLevelMax_e (ImageFormer::render).
constexpr double kLevelStep_e = 0.5;
constexpr float kLevelMax_e = 64.0f;

struct ImageFormer::LevelTables {
  explicit LevelTables(const Chain& c) : chain(c) {
    const auto n = static_cast<std::size_t>(kLevelMax_e / kLevelStep_e) + 1;
    tables.reserve(n);
    for (std::size_t k = 0; k < n; ++k) tables.push_back(PixelTable::build(static_cast<double>(k) * kLevelStep_e, c));
  }
  Chain chain;
  std::vector<std::optional<PixelTable>> tables;
};

double StrayLight::rate_at(double x_px, double y_px, double cx_px, double cy_px) const {
  return centre_rate_e_per_px_per_s *
         std::exp(((x_px - cx_px) * dir_x + (y_px - cy_px) * dir_y) / scale_px);
}

std::optional<StrayLight> washout(const CameraModel& camera, const Vec3& body_dir_cam,
                                  double exclusion_half_angle_rad, double centre_fill) {
  const double angle = CameraModel::off_boresight_rad(body_dir_cam);
  if (!(exclusion_half_angle_rad > 0.0) || !(angle < exclusion_half_angle_rad)) {
    return std::nullopt;
  }
  const double severity = 1.0 - angle / exclusion_half_angle_rad;
  StrayLight s;
  s.centre_rate_e_per_px_per_s = centre_fill * severity * camera.full_well_e / camera.exposure_s;
  // Image-plane direction towards the body (x along columns, y along rows);
  // on the boresight any direction will do.
  const double rho = body_dir_cam.head<2>().norm();
  if (rho > 0.0) {
    s.dir_x = body_dir_cam.x() / rho;
    s.dir_y = body_dir_cam.y() / rho;
  }
  return s;
}

std::optional<StrayLight> stray_light_beyond_exclusion(const CameraModel& camera, const Vec3& body_dir_cam,
                                                       double exclusion_half_angle_rad,
                                                       double edge_rate_e_per_px_per_s) {
  if (!(edge_rate_e_per_px_per_s > 0.0) || !(camera.stray_falloff_rad > 0.0) || body_dir_cam.norm() == 0.0) {
    return std::nullopt;
  }
  const double angle = CameraModel::off_boresight_rad(body_dir_cam);
  const double beyond = std::max(0.0, angle - exclusion_half_angle_rad);
  if (beyond > 20.0 * camera.stray_falloff_rad) return std::nullopt;  // below 2e-9 of the edge rate
  StrayLight s;
  s.centre_rate_e_per_px_per_s = edge_rate_e_per_px_per_s * std::exp(-beyond / camera.stray_falloff_rad);
  const double rho = body_dir_cam.head<2>().norm();
  if (rho > 0.0) {
    s.dir_x = body_dir_cam.x() / rho;
    s.dir_y = body_dir_cam.y() / rho;
  }
  return s;
}

void bloom_columns(std::span<float> image_e, int width, int height, double full_well_e) {
  const float well = static_cast<float>(full_well_e);
  const auto at = [&](int x, int y) -> float& {
    return image_e[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)];
  };
  for (int x = 0; x < width; ++x) {
    for (int y = 0; y < height; ++y) {
      float& p = at(x, y);
      if (!(p > well)) continue;
      const float excess = p - well;
      p = well;
      // Half up, half down; each share fills pixels to the well in turn.
      for (const int step : {-1, 1}) {
        float share = 0.5f * excess;
        for (int yy = y + step; share > 0.0f && yy >= 0 && yy < height; yy += step) {
          float& q = at(x, yy);
          const float room = std::max(0.0f, well - q);
          const float put = std::min(room, share);
          q += put;
          share -= put;
        }
      }
    }
  }
}

void add_gaussian_psf(std::span<float> image_e, int width, int height, const PointSource& source,
                      double sigma_px, double window_sigmas) {
  if (!std::isfinite(source.x_px) || !std::isfinite(source.y_px) ||
      !std::isfinite(source.electrons) || !(sigma_px > 0.0) || source.electrons == 0.0) {
    return;
  }
  const double reach = window_sigmas * sigma_px;
  // Pixel i covers [i - 1/2, i + 1/2]; take every pixel overlapping
  // [x0 - reach, x0 + reach], clipped to the sensor.
  const auto range = [reach](double x0, int n, int& lo, int& hi) {
    const double a = std::floor(x0 - reach - 0.5) + 1.0;
    const double b = std::ceil(x0 + reach + 0.5) - 1.0;
    if (b < 0.0 || a > n - 1.0) return false;
    lo = static_cast<int>(std::max(a, 0.0));
    hi = static_cast<int>(std::min(b, n - 1.0));
    return lo <= hi;
  };
  int x_lo = 0, x_hi = 0, y_lo = 0, y_hi = 0;
  if (!range(source.x_px, width, x_lo, x_hi) || !range(source.y_px, height, y_lo, y_hi)) return;

  // Per-axis fractions of the PSF falling on each pixel (erf differences).
  const double k = 1.0 / (kSqrt2 * sigma_px);
  const auto fractions = [k](double x0, int lo, int hi) {
    std::vector<double> f(static_cast<std::size_t>(hi - lo + 1));
    double prev = std::erf((lo - 0.5 - x0) * k);
    for (int i = lo; i <= hi; ++i) {
      const double next = std::erf((i + 0.5 - x0) * k);
      f[static_cast<std::size_t>(i - lo)] = 0.5 * (next - prev);
      prev = next;
    }
    return f;
  };
  const std::vector<double> fx = fractions(source.x_px, x_lo, x_hi);
  const std::vector<double> fy = fractions(source.y_px, y_lo, y_hi);
  for (int y = y_lo; y <= y_hi; ++y) {
    const double row = source.electrons * fy[static_cast<std::size_t>(y - y_lo)];
    float* out = image_e.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(width);
    for (int x = x_lo; x <= x_hi; ++x) {
      out[x] += static_cast<float>(row * fx[static_cast<std::size_t>(x - x_lo)]);
    }
  }
}

ImageFormer::ImageFormer(CameraModel camera) : camera_(std::move(camera)) {
  if (camera_.width_px <= 0 || camera_.height_px <= 0) {
    throw std::invalid_argument("ImageFormer: camera has an empty sensor");
  }
  const std::uint64_t n_px =
      static_cast<std::uint64_t>(camera_.width_px) * static_cast<std::uint64_t>(camera_.height_px);
  const auto count = static_cast<std::uint64_t>(std::max(0, camera_.hot_pixel_count));
  if (count > n_px) throw std::invalid_argument("ImageFormer: more hot pixels than pixels");
  Xoshiro256ss eng(camera_.hot_pixel_seed);
  std::unordered_set<std::uint64_t> taken;
  const double lo = camera_.hot_pixel_dark_min_e_per_s;
  const double ratio = camera_.hot_pixel_dark_max_e_per_s / lo;
  while (hot_pixels_.size() < count) {
    // Position uniform over the sensor (modulo bias < n_px / 2^64).
    const std::uint64_t index = eng() % n_px;
    const double u = static_cast<double>(eng() >> 11) * kUnit53;
    if (!taken.insert(index).second) continue;
    const auto w = static_cast<std::uint64_t>(camera_.width_px);
    hot_pixels_.push_back({static_cast<int>(index % w), static_cast<int>(index / w),
                           lo * std::pow(ratio, u)});  // log-uniform in [min, max]
  }
}

std::vector<float> ImageFormer::expected_electrons(std::span<const PointSource> sources,
                                                   const NoiseOptions& options,
                                                   std::span<const StrayLight> stray) const {
  const CameraModel& c = camera_;
  const int w = c.width_px, h = c.height_px;
  std::vector<float> img(static_cast<std::size_t>(w) * static_cast<std::size_t>(h),
                         base_electrons(c, options));
  if (options.background) {
    const double cx = (w - 1) / 2.0, cy = (h - 1) / 2.0;
    for (const StrayLight& sl : stray) {
      // rate_at is separable: exp(a x) exp(b y).
      std::vector<double> ex(static_cast<std::size_t>(w));
      for (int x = 0; x < w; ++x) ex[static_cast<std::size_t>(x)] = std::exp((x - cx) * sl.dir_x / sl.scale_px);
      for (int y = 0; y < h; ++y) {
        const double ey = sl.centre_rate_e_per_px_per_s * c.exposure_s * std::exp((y - cy) * sl.dir_y / sl.scale_px);
        float* row = img.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(w);
        for (int x = 0; x < w; ++x) row[x] += static_cast<float>(ey * ex[static_cast<std::size_t>(x)]);
      }
    }
  }
  if (options.hot_pixels) {
    for (const HotPixel& hp : hot_pixels_) {
      img[static_cast<std::size_t>(hp.y) * static_cast<std::size_t>(w) +
          static_cast<std::size_t>(hp.x)] += static_cast<float>(hp.dark_e_per_s * c.exposure_s);
    }
  }
  const auto colour = [&c](const PointSource& s) {
    return std::max(0.2, 1.0 + c.psf_colour_slope_per_mag * (s.b_minus_v - kSolarBMinusV));
  };
  const auto bloom = [&] {
    if (c.blooming && options.saturation) bloom_columns(img, w, h, c.full_well_e);
  };
  const bool field = c.vignetting_corner_loss > 0.0 || c.psf_growth_corner > 0.0 || c.background_gradient != 0.0;
  if (!field) {
    for (const PointSource& s : sources) add_gaussian_psf(img, w, h, s, c.psf_sigma_px * colour(s));
    bloom();
    return img;
  }
  // Field effects (CameraModel: vignetting, off-axis PSF growth, background
  // gradient), in the corner-normalised radius from the principal point.
  const double r2_corner = std::max(std::pow(std::max(c.cx_px, w - 1 - c.cx_px), 2) +
                                        std::pow(std::max(c.cy_px, h - 1 - c.cy_px), 2),
                                    1.0);
  if (options.background && (c.vignetting_corner_loss > 0.0 || c.background_gradient != 0.0)) {
    const float sky = static_cast<float>(c.background_e_per_px_per_s * c.exposure_s);
    for (int y = 0; y < h; ++y) {
      float* row = img.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(w);
      for (int x = 0; x < w; ++x) {
        const double q = (std::pow(x - c.cx_px, 2) + std::pow(y - c.cy_px, 2)) / r2_corner;
        const double g = 1.0 + c.background_gradient * (x - c.cx_px) / (0.5 * w);
        row[x] += static_cast<float>(sky * ((1.0 - c.vignetting_corner_loss * q) * g - 1.0));
      }
    }
  }
  for (const PointSource& s : sources) {
    const double q = (std::pow(s.x_px - c.cx_px, 2) + std::pow(s.y_px - c.cy_px, 2)) / r2_corner;
    PointSource v = s;
    v.electrons = s.electrons * (1.0 - c.vignetting_corner_loss * std::min(q, 1.0));
    add_gaussian_psf(img, w, h, v, c.psf_sigma_px * colour(s) * (1.0 + c.psf_growth_corner * std::min(q, 1.0)));
  }
  bloom();
  return img;
}

std::vector<std::uint16_t> ImageFormer::render(std::span<const PointSource> sources,
                                               std::uint64_t seed, const NoiseOptions& options,
                                               std::span<const StrayLight> stray) const {
  const std::vector<float> lam = expected_electrons(sources, options, stray);
  const Chain m = make_chain(camera_, options);
  const int w = camera_.width_px, h = camera_.height_px;
  std::vector<std::uint16_t> out(lam.size());
  if (!m.random()) {
    for (std::size_t i = 0; i < lam.size(); ++i) out[i] = m.quantize(m.expected(lam[i]));
    return out;
  }
  const float base = base_electrons(camera_, options);
  const std::optional<PixelTable> table = PixelTable::build(base, m);
  // Where the background varies across the field (stray light, vignetting,
  // a gradient), faint pixels off the base level (that background, the
  // wings of sources) take the table of their mean rounded to kLevelStep_e:
  // a mean error of at most 0.25 e-, against a noise of >= 10 e- (read
  // noise alone), for a one-draw sample instead of a Poisson and a normal
  // deviate. Brighter pixels, and every pixel under a flat sky, are sampled
  // exactly.
  const bool varying = (options.background && !stray.empty()) ||
                       (options.background && (camera_.vignetting_corner_loss > 0.0 || camera_.background_gradient != 0.0));
  std::shared_ptr<const LevelTables> cache;
  if (varying) {
    const std::lock_guard<std::mutex> lock(*levels_mutex_);
    if (!levels_ || !(levels_->chain == m)) levels_ = std::make_shared<const LevelTables>(m);
    cache = levels_;
  }
  static const std::vector<std::optional<PixelTable>> kNone;
  const std::vector<std::optional<PixelTable>>& levels = cache ? cache->tables : kNone;
  for (int y = 0; y < h; ++y) {
    Rng rng(row_seed(seed, y));
    const std::size_t row = static_cast<std::size_t>(y) * static_cast<std::size_t>(w);
    const float* in = lam.data() + row;
    std::uint16_t* dst = out.data() + row;
    for (int x = 0; x < w; ++x) {
      if (table && in[x] == base) {
        dst[x] = table->sample(rng.bits());
        continue;
      }
      if (cache && in[x] >= 0.0f && in[x] < kLevelMax_e) {
        const auto k = static_cast<std::size_t>(std::lround(in[x] / kLevelStep_e));
        if (levels[k]) {
          dst[x] = levels[k]->sample(rng.bits());
          continue;
        }
      }
      dst[x] = m.quantize(m.sample(in[x], rng));
    }
  }
  return out;
}

std::vector<float> ImageFormer::render_float(std::span<const PointSource> sources,
                                             std::uint64_t seed, const NoiseOptions& options,
                                             std::span<const StrayLight> stray) const {
  std::vector<float> img = expected_electrons(sources, options, stray);
  const Chain m = make_chain(camera_, options);
  const int w = camera_.width_px, h = camera_.height_px;
  for (int y = 0; y < h; ++y) {
    Rng rng(row_seed(seed, y));
    float* px = img.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(w);
    for (int x = 0; x < w; ++x) {
      double dn = m.sample(px[x], rng);
      if (m.clip_float) dn = std::clamp(dn, 0.0, m.dn_max);
      px[x] = static_cast<float>(dn);
    }
  }
  return img;
}

std::vector<StarInFrame> stars_in_frame(const StarCatalog& catalog, const CameraModel& camera,
                                        const Eigen::Quaterniond& q_cam_from_eci, astro::TimeTT t,
                                        double margin_px, const Eigen::Vector3d* observer_velocity_mps) {
  const Eigen::Matrix3d R_cam_from_eci = q_cam_from_eci.normalized().toRotationMatrix();
  const Vec3 boresight_eci = R_cam_from_eci.row(2).transpose();
  // A cone that surely holds the grown sensor; project() makes the cut.
  const double half = camera.half_diagonal_fov_rad() +
                      std::atan(std::max(margin_px, 0.0) / std::min(camera.fx_px, camera.fy_px)) +
                      1.0 * astro::kDegToRad;
  std::vector<StarInFrame> out;
  for (const Star* s : catalog.in_cone(boresight_eci, std::min(half, astro::kPi / 2.0), t)) {
    const Vec3 u = observer_velocity_mps ? astro::aberrated_direction(s->unit_eci_at(t), *observer_velocity_mps)
                                         : s->unit_eci_at(t);
    const auto px = camera.project(R_cam_from_eci * u, margin_px);
    if (!px) continue;
    out.push_back({s, px->x(), px->y(), camera.electrons_from_vmag(s->vmag)});
  }
  return out;
}

std::vector<PointSource> point_sources(std::span<const StarInFrame> stars) {
  std::vector<PointSource> out;
  out.reserve(stars.size());
  for (const StarInFrame& s : stars) out.push_back({s.x_px, s.y_px, s.electrons, s.star ? s.star->b_minus_v : kSolarBMinusV});
  return out;
}

void write_png16(const std::string& path, std::span<const std::uint16_t> pixels, int width,
                 int height) {
  check_size(pixels, width, height, path);
  // cv::Mat does not write through this pointer (imwrite takes it const).
  const cv::Mat mat(height, width, CV_16UC1, const_cast<std::uint16_t*>(pixels.data()));
  write_png(path, mat);
}

void write_preview_png8(const std::string& path, std::span<const std::uint16_t> pixels, int width,
                        int height) {
  check_size(pixels, width, height, path);
  std::vector<std::size_t> hist(65536, 0);
  for (const std::uint16_t v : pixels) ++hist[v];
  const auto percentile = [&hist, n = pixels.size()](double q) {
    const auto target = static_cast<std::size_t>(q * static_cast<double>(n - 1));
    std::size_t acc = 0;
    for (std::size_t v = 0; v < hist.size(); ++v) {
      acc += hist[v];
      if (acc > target) return static_cast<double>(v);
    }
    return 65535.0;
  };
  // Sky level and noise from the histogram (median, median - 16th percentile).
  const double sky = percentile(0.5);
  const double sigma = std::max(sky - percentile(0.1587), 0.5);
  const double black = std::max(sky - sigma, 0.0);
  const double white = std::max(std::min(sky + 50.0 * sigma, percentile(1.0)), black + 1.0);
  std::array<std::uint8_t, 65536> lut{};
  for (std::size_t v = 0; v < lut.size(); ++v) {
    const double f = std::clamp((static_cast<double>(v) - black) / (white - black), 0.0, 1.0);
    lut[v] = static_cast<std::uint8_t>(std::lround(255.0 * std::sqrt(f)));
  }
  cv::Mat mat(height, width, CV_8UC1);
  for (int y = 0; y < height; ++y) {
    auto* row = mat.ptr<std::uint8_t>(y);
    const std::uint16_t* in =
        pixels.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(width);
    for (int x = 0; x < width; ++x) row[x] = lut[in[x]];
  }
  write_png(path, mat);
}

Image16 read_png16(const std::string& path) {
  cv::Mat mat;
  try {
    mat = cv::imread(path, cv::IMREAD_ANYDEPTH | cv::IMREAD_GRAYSCALE);
  } catch (const cv::Exception& ex) {
    throw std::runtime_error(path + ": cannot read image: " + ex.what());
  }
  if (mat.empty()) throw std::runtime_error(path + ": cannot read image (missing or not an image)");
  if (mat.depth() == CV_8U) {
    cv::Mat wide;
    mat.convertTo(wide, CV_16U);
    mat = wide;
  }
  if (mat.type() != CV_16UC1) {
    throw std::runtime_error(path + ": unsupported pixel type (expected 8- or 16-bit gray)");
  }
  Image16 img;
  img.width = mat.cols;
  img.height = mat.rows;
  img.pixels.resize(static_cast<std::size_t>(mat.cols) * static_cast<std::size_t>(mat.rows));
  for (int y = 0; y < mat.rows; ++y) {
    const auto* row = mat.ptr<std::uint16_t>(y);
    std::copy(row, row + mat.cols, img.pixels.begin() + static_cast<std::ptrdiff_t>(y) * mat.cols);
  }
  return img;
}

}  // namespace artms::imaging
