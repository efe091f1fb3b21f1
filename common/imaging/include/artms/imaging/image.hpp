// Image formation: point sources through a Gaussian PSF integrated over each
// pixel, background, dark current, fixed hot pixels, photon shot noise, read
// noise, gain, full-well and ADC saturation, 12-bit quantisation; PNG I/O.
//
// Pixel convention as in camera.hpp: (0, 0) is the centre of the top-left
// pixel, x along columns, y along rows; images are row-major, width * height,
// index = y * width + x.
//
// Random numbers: every frame is a pure function of (sources, options,
// seed). Row r draws from its own xoshiro256** stream (Blackman & Vigna
// 2018) seeded from (seed, r) through SplitMix64, so the noise of a pixel
// does not depend on what other rows contain. The generator and all
// samplers (Poisson, normal, the tabulated pixel distribution) are
// implemented in image.cpp, not taken from <random>, so the output does not
// depend on the standard library. std::mt19937_64 was measured at 6.1 ns per
// draw on the build machine, which alone would have cost 8 ms per frame.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "artms/astro/time.hpp"
#include "artms/imaging/camera.hpp"
#include "artms/imaging/star_catalog.hpp"

namespace artms::imaging {

// B-V colour index of the Sun (and of sunlight reflected by a grey target).
inline constexpr double kSolarBMinusV = 0.65;

// A point source on the focal plane: position in pixels, and the
// photo-electrons it deposits over the whole exposure (all pixels).
struct PointSource {
  double x_px = 0.0;
  double y_px = 0.0;
  double electrons = 0.0;
  double b_minus_v = kSolarBMinusV;  // colour index (CameraModel::psf_colour_slope_per_mag)
};

// A pixel with an anomalously high dark current.
struct HotPixel {
  int x = 0;
  int y = 0;
  double dark_e_per_s = 0.0;
};

// Stray light from a bright body near the field (Sun, Moon, lit Earth): an
// exponential ramp across the sensor, rising towards the body,
//   rate(p) = centre_rate * exp(((p - c) . dir) / scale_px),
// with c the sensor centre and dir the unit image-plane direction towards
// the body. An ad-hoc model for washed-out frames, not a baffle simulation.
struct StrayLight {
  double centre_rate_e_per_px_per_s = 0.0;
  double dir_x = 1.0;
  double dir_y = 0.0;
  double scale_px = 300.0;
  [[nodiscard]] double rate_at(double x_px, double y_px, double cx_px, double cy_px) const;
};

// Washout from a body at direction body_dir_cam (camera components) when it
// is within exclusion_half_angle_rad of the boresight; nullopt otherwise.
// Severity s = 1 - angle / exclusion in (0, 1]; the frame centre receives
// centre_fill * s full wells per exposure (default 2: the centre saturates
// once the body is within half the exclusion angle) and the ramp rises
// towards the body with a 300 px e-folding length, so the near edge
// saturates first.
std::optional<StrayLight> washout(const CameraModel& camera, const Vec3& body_dir_cam,
                                  double exclusion_half_angle_rad, double centre_fill = 2.0);
inline std::optional<StrayLight> sun_washout(const CameraModel& camera, const Vec3& sun_dir_cam) {
  return washout(camera, sun_dir_cam, camera.sun_exclusion_rad);
}

// Stray light from a body outside its exclusion cone (CameraModel::stray_*):
// centre rate edge_rate_e_per_px_per_s * exp(-(angle - exclusion) /
// camera.stray_falloff_rad), rising towards the body across the sensor with
// the washout ramp's 300 px e-folding length (so the far edge gets about a
// tenth of the near one); inside the cone the same as at its edge (the
// washout adds to it). nullopt when the rate is 0 or the body is behind the
// camera plane by more than 90 deg plus 6 e-folds.
std::optional<StrayLight> stray_light_beyond_exclusion(const CameraModel& camera, const Vec3& body_dir_cam,
                                                       double exclusion_half_angle_rad,
                                                       double edge_rate_e_per_px_per_s);

// Charge above the full well spilt along columns (CameraModel::blooming):
// each pixel's excess goes half up, half down its column, filling pixels to
// the full well in turn; what runs off the sensor is lost. In place, on
// electrons.
void bloom_columns(std::span<float> image_e, int width, int height, double full_well_e);

// Which terms of the image model are on. Each noise term switches alone.
struct NoiseOptions {
  bool background = true;    // sky background and any stray light
  bool dark_current = true;  // uniform dark current
  bool hot_pixels = true;    // fixed hot pixels (extra dark current)
  bool shot_noise = true;    // Poisson statistics of all collected electrons
  bool read_noise = true;    // Gaussian read noise
  bool bias = true;          // ADC pedestal (camera.bias_dn)
  bool saturation = true;    // clip at the full well and at [0, max_dn]

  // Expected values: background, dark current, hot pixels and bias kept,
  // no shot or read noise.
  static NoiseOptions noise_free() {
    NoiseOptions o;
    o.shot_noise = false;
    o.read_noise = false;
    return o;
  }
  // Only the point sources, in DN, no pedestal, no clipping.
  static NoiseOptions sources_only() { return {false, false, false, false, false, false, false}; }
};

// Adds the image of a point source with a circular Gaussian PSF of sigma_px
// to image_e (row-major width x height): each pixel receives the PSF
// integrated over its area, separably per axis,
//   f_i = [erf((i + 1/2 - x0) / (sqrt2 s)) - erf((i - 1/2 - x0) / (sqrt2 s))] / 2,
// within +-window_sigmas * sigma of the source. Sources partly or wholly off
// the sensor lose the light that falls outside it. Non-finite inputs are
// ignored.
void add_gaussian_psf(std::span<float> image_e, int width, int height, const PointSource& source,
                      double sigma_px, double window_sigmas = 5.0);

class ImageFormer {
 public:
  // Hot-pixel positions and rates are drawn once here from
  // camera.hot_pixel_seed: the same pixels in every frame.
  explicit ImageFormer(CameraModel camera);

  [[nodiscard]] const CameraModel& camera() const { return camera_; }
  [[nodiscard]] const std::vector<HotPixel>& hot_pixels() const { return hot_pixels_; }

  // Expected electrons per pixel before noise and clipping (row-major).
  [[nodiscard]] std::vector<float> expected_electrons(
      std::span<const PointSource> sources, const NoiseOptions& options = {},
      std::span<const StrayLight> stray = {}) const;

  // The frame as the camera reads it out: integer DN in [0, max_dn]
  // (in [0, 65535] when options.saturation is off), rounded to nearest.
  [[nodiscard]] std::vector<std::uint16_t> render(
      std::span<const PointSource> sources, std::uint64_t seed, const NoiseOptions& options = {},
      std::span<const StrayLight> stray = {}) const;

  // The same in DN as float, without quantisation (clipped to [0, max_dn]
  // when options.saturation is on). With NoiseOptions::noise_free() this is
  // the expected signal: electrons / gain + bias.
  [[nodiscard]] std::vector<float> render_float(
      std::span<const PointSource> sources, std::uint64_t seed, const NoiseOptions& options = {},
      std::span<const StrayLight> stray = {}) const;

 private:
  CameraModel camera_;
  std::vector<HotPixel> hot_pixels_;
  // Sampling tables of the faint pixel levels (image.cpp), built once per
  // set of noise options and shared by every frame and copy.
  struct LevelTables;
  mutable std::shared_ptr<const LevelTables> levels_;
  std::shared_ptr<std::mutex> levels_mutex_ = std::make_shared<std::mutex>();
};

// A catalog star imaged by the camera.
struct StarInFrame {
  const Star* star = nullptr;
  double x_px = 0.0;
  double y_px = 0.0;
  double electrons = 0.0;  // camera.electrons_from_vmag(star->vmag)
};

// Catalog stars whose direction at t falls on the sensor grown by margin_px
// (use a few PSF sigmas so that stars just off the edge still leave their
// tails), for the attitude q_cam_from_eci (rotates ECI components into
// camera components). observer_velocity_mps (the observer's velocity
// relative to the solar-system barycentre, ECI components; nullptr: none)
// aberrates each star's direction as that observer sees it
// (astro/aberration.hpp).
std::vector<StarInFrame> stars_in_frame(const StarCatalog& catalog, const CameraModel& camera,
                                        const Eigen::Quaterniond& q_cam_from_eci, astro::TimeTT t,
                                        double margin_px = 0.0, const Eigen::Vector3d* observer_velocity_mps = nullptr);
std::vector<PointSource> point_sources(std::span<const StarInFrame> stars);

// A 16-bit grayscale image.
struct Image16 {
  int width = 0;
  int height = 0;
  std::vector<std::uint16_t> pixels;  // row-major
};

// 16-bit grayscale PNG holding the DN values as they are (12-bit frames are
// not rescaled). Throws std::runtime_error naming the path on failure.
void write_png16(const std::string& path, std::span<const std::uint16_t> pixels, int width,
                 int height);
// 8-bit PNG stretched for eyes: with the sky level taken as the median and
// its noise sigma as median - 16th percentile, black one sigma below the sky,
// white 50 sigma above it (or at the brightest pixel if that is lower),
// gamma 1/2 in between: the sky shows as dark-grey noise, stars and hot
// pixels as white dots, a washed-out frame as a grey ramp into white.
void write_preview_png8(const std::string& path, std::span<const std::uint16_t> pixels, int width,
                        int height);
// Reads a grayscale PNG (8 or 16 bit; colour is converted to gray) as
// 16-bit values. Throws std::runtime_error naming the path on failure.
Image16 read_png16(const std::string& path);

}  // namespace artms::imaging
