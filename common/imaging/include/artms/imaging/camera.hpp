// Camera model: pinhole + radial distortion geometry of the NST-like vision
// based sensor, and the photometric/noise parameters the image former uses.
//
// Pixel convention (DESIGN.md section 7, docs/conventions.md): x = column to
// the right, y = row downwards, (0, 0) is the centre of the top-left pixel, so
// the sensor area spans [-0.5, width - 0.5] x [-0.5, height - 0.5]. Camera
// frame: z = boresight, x along +column, y along +row. Pinhole:
//   x_px = cx + fx * xd,  y_px = cy + fy * yd,
// where (xd, yd) are the distorted normalised coordinates of (xn, yn) =
// (X/Z, Y/Z) by Brown's model (Brown 1966; OpenCV's convention), radial and
// tangential (decentring), r^2 = xn^2 + yn^2, s = 1 + k1 r^2 + k2 r^4:
//   xd = xn s + 2 p1 xn yn + p2 (r^2 + 2 xn^2)
//   yd = yn s + p1 (r^2 + 2 yn^2) + 2 p2 xn yn.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>

#include "artms/astro/constants.hpp"

namespace artms::imaging {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;

// Defaults are the NST-like values shipped in config/cameras/nst.yaml
// (geometry: StarFOX paper Table 1; the rest: see the comment on each field),
// except the effects of real optics and sensors (vignetting, off-axis and
// chromatic PSF, background gradient, blooming, stray light outside the
// exclusion cones), which are off here and in a camera file that does not
// name them, and on in nst.yaml (config/cameras/nst_ideal.yaml: all off).
struct CameraModel {
  std::string name = "nst";

  // --- Geometry (paper Table 1) -------------------------------------------
  int width_px = 1280;
  int height_px = 1024;
  double pixel_pitch_m = 5.3e-6;
  double focal_length_m = 30e-3;
  int bit_depth = 12;
  // Pixel encoding of stored frames: values shifted up by this many bits
  // (12-bit data in 16-bit words, MSB-aligned: 4). Readers divide by
  // 2^dn_shift_bits to get DN; the renderer writes DN (0).
  int dn_shift_bits = 0;
  // Star identification: a measured and a catalog direction match within
  // this angle (uncalibrated distortion, refraction); 0: IMP's default.
  double match_tolerance_rad = 0.0;
  // IMP's centroids (camera file centroid.method): false = iterative
  // weighted centre of gravity (iwcog), true = a 2-D Gaussian fit
  // (gaussian_fit), for an undersampled PSF (sigma below ~0.8 px), where the
  // IWCoG is pulled towards pixel centres.
  bool centroid_gaussian_fit = false;
  // Focal lengths in pixels, fx = fy = f / pitch unless the file says otherwise.
  double fx_px = 30e-3 / 5.3e-6;
  double fy_px = 30e-3 / 5.3e-6;
  // Principal point: the geometric centre of the pixel grid, (N - 1) / 2.
  double cx_px = (1280 - 1) / 2.0;
  double cy_px = (1024 - 1) / 2.0;
  // Brown radial and tangential distortion on normalised coordinates (0 =
  // ideal pinhole).
  double k1 = 0.0;
  double k2 = 0.0;
  double p1 = 0.0;
  double p2 = 0.0;
  // Field effects of real optics (0 = off, the NST file's default): the
  // fraction of light lost at the sensor corner, growing as (r / r_corner)^2
  // from the principal point (vignetting; sources and sky background alike);
  // the PSF sigma's growth at the corner, sigma(r) = psf_sigma_px (1 + g
  // (r / r_corner)^2) (off-axis blur); and a linear sky-background gradient,
  // the background times 1 + b (x - cx) / (width / 2) (stray light from one
  // side).
  double vignetting_corner_loss = 0.0;
  double psf_growth_corner = 0.0;
  double background_gradient = 0.0;
  // Chromatic PSF: sigma times 1 + psf_colour_slope_per_mag (B-V - 0.65)
  // (red stars wider than the solar-coloured targets: the longitudinal
  // chromatic aberration of a refractive lens focused for ~550 nm); 0: off.
  double psf_colour_slope_per_mag = 0.0;
  // Blooming: the charge a pixel collects above the full well spills into
  // the pixels above and below it in its column, half each way, filling each
  // to the full well in turn (a sensor without an anti-blooming drain);
  // false: the excess is lost.
  bool blooming = false;
  // Stray light outside the exclusion cones (Sun, Moon, Earth limb): the
  // baffle's point-source transmittance falls roughly exponentially with
  // the body's angle from the boresight, so the background at the sensor
  // centre gains edge_rate * exp(-(angle - exclusion) / stray_falloff_rad),
  // ramping up across the sensor towards the body (StrayLight in image.hpp).
  // The Moon's rate is for a full Moon (times its illuminated fraction), the
  // Earth's for a limb under a zenith Sun (times the cosine of the Sun's
  // zenith angle at the limb point nearest the boresight). 0: off.
  double stray_sun_edge_e_per_px_per_s = 0.0;
  double stray_moon_edge_e_per_px_per_s = 0.0;
  double stray_earth_edge_e_per_px_per_s = 0.0;
  double stray_falloff_rad = 4.0 * astro::kDegToRad;

  // --- Optics and photometry -------------------------------------------------
  // Exposure (integration) time. The NST updates at up to 5 Hz, so 0.2 s is
  // the longest exposure its cadence allows; with the values below it puts
  // the 5-sigma limit near V = 7.5, the NST's published star sensitivity.
  double exposure_s = 0.2;
  // Clear aperture: a 30 mm f/1.6 lens (fast optics as in nanosat trackers).
  double aperture_diameter_m = 30e-3 / 1.6;
  // Band-averaged optics transmission (~0.8) times sensor QE (~0.56 for a
  // front-side-illuminated CMOS over 400-900 nm).
  double throughput_qe = 0.45;
  // Photon flux of a V = 0 star above the atmosphere: Bessell, Castelli &
  // Plez (1998) V zero point 3.63e-9 erg s^-1 cm^-2 A^-1 at 545 nm is
  // 995 photons s^-1 cm^-2 A^-1 (divide by hc/lambda); times the ~90 nm V
  // bandwidth gives 8.9e9 photons s^-1 m^-2, rounded to 1e10 for the wider
  // unfiltered silicon passband. Magnitudes are read as V (solar-type colours).
  double v0_photon_flux_per_s_m2 = 1.0e10;
  // Gaussian PSF 1-sigma (pixels): star trackers defocus so that a star
  // spreads over ~3x3..5x5 pixels for sub-pixel centroiding.
  double psf_sigma_px = 1.2;

  // --- Detector ---------------------------------------------------------------
  // Conversion gain: the 12-bit range spans bias + 4075 DN * 2.4 = 9780 e-,
  // just below the full well, so saturated pixels read 4095 as on most
  // sensors (the ADC clips before the well does).
  double gain_e_per_dn = 2.4;
  // Full-well capacity of a 5.3 um CMOS pixel (e2v EV76C560-class sensors
  // quote ~10 ke-).
  double full_well_e = 10000.0;
  // ADC pedestal (DN) so that read noise on a dark pixel is not clipped at 0.
  double bias_dn = 20.0;
  // Temporal read noise, rolling-shutter CMOS at low gain.
  double read_noise_e = 10.0;
  // Mean dark current at ~20 C for a 5.3 um CMOS pixel (10-50 e-/s typical).
  double dark_current_e_per_s = 20.0;
  // Diffuse background: zodiacal light ~V 22.5 mag/arcsec^2 over a
  // 36.4 arcsec pixel (1327 arcsec^2 -> V 14.7 per pixel) gives ~1.6 e-/s;
  // the rest is an allowance for stray light and earthshine off the baffle
  // (the paper reports lower image SNR than expected).
  double background_e_per_px_per_s = 30.0;
  // Hot pixels (radiation-induced dark-current spikes, paper: IMP removes
  // "camera hotspots" with unchanging pixel coordinates): ~0.02 % of the
  // 1.3 Mpx after months in LEO, each with a dark rate drawn once,
  // log-uniformly in [min, max], at positions fixed by `hot_pixel_seed`.
  int hot_pixel_count = 250;
  double hot_pixel_dark_min_e_per_s = 2.0e3;
  double hot_pixel_dark_max_e_per_s = 5.0e4;
  std::uint64_t hot_pixel_seed = 1;

  // --- Bright-body exclusion (half-angles from the boresight) ----------------
  // Typical of nanosat star trackers with a short baffle (e.g. the APST
  // baffle: 27 deg); within these the frame is washed out or unusable.
  double sun_exclusion_rad = 45.0 * astro::kDegToRad;
  double moon_exclusion_rad = 15.0 * astro::kDegToRad;
  double earth_limb_exclusion_rad = 15.0 * astro::kDegToRad;  // see config/cameras/nst.yaml

  // Loads a camera file (schema: config/cameras/nst.yaml). Geometry keys are
  // required; the rest default to the values above. Throws std::runtime_error
  // "file:line:column: key: what was expected" on a syntax error, an unknown
  // or missing key, a wrong type or an out-of-range value.
  static CameraModel load(const std::string& path);
  // The same from YAML text; `source_name` stands for the file in messages.
  static CameraModel parse(const std::string& yaml_text, const std::string& source_name);

  // Photo-electrons per second from a V = 0 star:
  // flux(V=0) * pi D^2 / 4 * throughput_qe.
  [[nodiscard]] double zero_point_e_per_s() const;
  // Photo-electrons collected in one exposure from a source of magnitude V
  // (Pogson: 10^(-0.4 V) relative to V = 0).
  [[nodiscard]] double electrons_from_vmag(double vmag) const;
  // Largest DN value, 2^bit_depth - 1.
  [[nodiscard]] int max_dn() const { return (1 << bit_depth) - 1; }

  // Normalised (undistorted) image coordinates -> pixel, with distortion.
  [[nodiscard]] Vec2 pixel_from_normalized(const Vec2& xn) const;
  // Pixel -> undistorted normalised coordinates (inverts the distortion by
  // Newton iteration: on the radius for a radial model, in 2-D with
  // tangential terms; exact to ~1e-15).
  [[nodiscard]] Vec2 normalized_from_pixel(const Vec2& px) const;

  // Pixel position of a direction given in camera components (any length).
  // nullopt if it is behind the camera (Z <= 0) or falls outside the sensor
  // area grown by margin_px on every side.
  [[nodiscard]] std::optional<Vec2> project(const Vec3& v_cam, double margin_px = 0.0) const;
  // The same without the sensor bound (only Z > 0 is required): for sources
  // just off the edge whose PSF still reaches the sensor.
  [[nodiscard]] std::optional<Vec2> project_unbounded(const Vec3& v_cam) const;
  // Unit line-of-sight vector in camera components for a pixel position.
  [[nodiscard]] Vec3 unproject(const Vec2& px) const;

  // True if px lies on the sensor area grown by margin_px.
  [[nodiscard]] bool on_sensor(const Vec2& px, double margin_px = 0.0) const;
  // True if the direction (camera components) images onto the sensor.
  [[nodiscard]] bool in_fov(const Vec3& v_cam, double margin_px = 0.0) const {
    return project(v_cam, margin_px).has_value();
  }
  // Full field of view along x and y through the principal point, and the
  // half-angle of the cone that contains the whole sensor (pinhole, corners
  // at the pixel-area edges), e.g. for a catalog cone query.
  [[nodiscard]] double fov_x_rad() const;
  [[nodiscard]] double fov_y_rad() const;
  [[nodiscard]] double half_diagonal_fov_rad() const;
  // Angle of a direction (camera components) from the boresight +z.
  [[nodiscard]] static double off_boresight_rad(const Vec3& v_cam) {
    return std::atan2(v_cam.head<2>().norm(), v_cam.z());
  }
};

}  // namespace artms::imaging
