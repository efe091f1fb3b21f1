// Camera model: the shipped NST file, located load errors, the pixel
// convention, and project/unproject round trips with radial distortion.
#include "artms/imaging/camera.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>

#include "artms/testing/testing.hpp"

namespace artms::imaging {
namespace {

using astro::kDegToRad;

const std::string kNstPath = std::string(ARTMS_CONFIG_DIR) + "/cameras/nst.yaml";

// The message of the std::runtime_error thrown by parse(), or "" if none.
std::string parse_error(const std::string& yaml) {
  try {
    CameraModel::parse(yaml, "cam.yaml");
  } catch (const std::runtime_error& ex) {
    return ex.what();
  }
  return "";
}

const char* const kMinimal =
    "sensor: {width_px: 1280, height_px: 1024, pixel_pitch_um: 5.3, bit_depth: 12}\n"
    "optics: {focal_length_mm: 30}\n";

TEST(CameraModel, ShippedNstFileMatchesPaperTable1) {
  const CameraModel cam = CameraModel::load(kNstPath);
  EXPECT_EQ(cam.name, "nst");
  EXPECT_EQ(cam.width_px, 1280);
  EXPECT_EQ(cam.height_px, 1024);
  EXPECT_DOUBLE_EQ(cam.pixel_pitch_m, 5.3e-6);
  EXPECT_DOUBLE_EQ(cam.focal_length_m, 30e-3);
  EXPECT_EQ(cam.bit_depth, 12);
  EXPECT_EQ(cam.max_dn(), 4095);
  EXPECT_NEAR(cam.fx_px, 30.0 / 5.3e-3, 1e-9);
  EXPECT_NEAR(cam.fy_px, 30.0 / 5.3e-3, 1e-9);
  EXPECT_DOUBLE_EQ(cam.cx_px, 639.5);
  EXPECT_DOUBLE_EQ(cam.cy_px, 511.5);
  // Paper Table 1 rounds the field of view to 12 x 10 deg.
  EXPECT_NEAR(cam.fov_x_rad() / kDegToRad, 12.0, 1.0);
  EXPECT_NEAR(cam.fov_y_rad() / kDegToRad, 10.0, 0.5);
  EXPECT_NEAR(cam.half_diagonal_fov_rad() / kDegToRad, 8.24, 0.01);

  // The file spells out the same values as the struct's defaults.
  const CameraModel def;
  EXPECT_DOUBLE_EQ(cam.exposure_s, def.exposure_s);
  EXPECT_DOUBLE_EQ(cam.aperture_diameter_m, def.aperture_diameter_m);
  EXPECT_DOUBLE_EQ(cam.throughput_qe, def.throughput_qe);
  EXPECT_DOUBLE_EQ(cam.v0_photon_flux_per_s_m2, def.v0_photon_flux_per_s_m2);
  EXPECT_DOUBLE_EQ(cam.psf_sigma_px, def.psf_sigma_px);
  EXPECT_DOUBLE_EQ(cam.gain_e_per_dn, def.gain_e_per_dn);
  EXPECT_DOUBLE_EQ(cam.full_well_e, def.full_well_e);
  EXPECT_DOUBLE_EQ(cam.bias_dn, def.bias_dn);
  EXPECT_DOUBLE_EQ(cam.read_noise_e, def.read_noise_e);
  EXPECT_DOUBLE_EQ(cam.dark_current_e_per_s, def.dark_current_e_per_s);
  EXPECT_DOUBLE_EQ(cam.background_e_per_px_per_s, def.background_e_per_px_per_s);
  EXPECT_EQ(cam.hot_pixel_count, def.hot_pixel_count);
  EXPECT_DOUBLE_EQ(cam.hot_pixel_dark_min_e_per_s, def.hot_pixel_dark_min_e_per_s);
  EXPECT_DOUBLE_EQ(cam.hot_pixel_dark_max_e_per_s, def.hot_pixel_dark_max_e_per_s);
  EXPECT_EQ(cam.hot_pixel_seed, def.hot_pixel_seed);
  EXPECT_NEAR(cam.sun_exclusion_rad, def.sun_exclusion_rad, 1e-15);
  EXPECT_NEAR(cam.moon_exclusion_rad, def.moon_exclusion_rad, 1e-15);
  EXPECT_NEAR(cam.earth_limb_exclusion_rad, def.earth_limb_exclusion_rad, 1e-15);
  EXPECT_DOUBLE_EQ(cam.fx_px, def.fx_px);
  EXPECT_DOUBLE_EQ(cam.cx_px, def.cx_px);
}

TEST(CameraModel, ZeroPointAndMagnitudes) {
  const CameraModel cam;
  // flux(V=0) * pi D^2 / 4 * throughput*QE, D = 18.75 mm.
  const double expected = 1.0e10 * std::numbers::pi / 4.0 * 0.01875 * 0.01875 * 0.45;
  EXPECT_NEAR(cam.zero_point_e_per_s(), expected, 1e-6 * expected);
  EXPECT_NEAR(cam.electrons_from_vmag(0.0), expected * cam.exposure_s, 1e-6 * expected);
  // Pogson: 5 magnitudes = a factor 100.
  EXPECT_NEAR(cam.electrons_from_vmag(2.0) / cam.electrons_from_vmag(7.0), 100.0, 1e-9);
}

TEST(CameraModel, MinimalFileTakesDefaultsAndOverrides) {
  const CameraModel cam = CameraModel::parse(std::string(kMinimal) +
                                                 "photometry: {exposure_s: 0.5}\n"
                                                 "hot_pixels: {count: 0}\n"
                                                 "exclusion_deg: {sun: 30}\n",
                                             "cam.yaml");
  EXPECT_DOUBLE_EQ(cam.exposure_s, 0.5);
  EXPECT_EQ(cam.hot_pixel_count, 0);
  EXPECT_NEAR(cam.sun_exclusion_rad, 30.0 * kDegToRad, 1e-15);
  EXPECT_DOUBLE_EQ(cam.read_noise_e, CameraModel{}.read_noise_e);
  const CameraModel custom = CameraModel::parse(
      "sensor: {width_px: 640, height_px: 480, pixel_pitch_um: 10, bit_depth: 10}\n"
      "optics: {focal_length_mm: 50, cx_px: 300.25, fy_px: 5001, k1: -0.1, k2: 0.02}\n",
      "cam.yaml");
  EXPECT_DOUBLE_EQ(custom.fx_px, 5000.0);
  EXPECT_DOUBLE_EQ(custom.fy_px, 5001.0);
  EXPECT_DOUBLE_EQ(custom.cx_px, 300.25);
  EXPECT_DOUBLE_EQ(custom.cy_px, 239.5);
  EXPECT_DOUBLE_EQ(custom.k1, -0.1);
  EXPECT_DOUBLE_EQ(custom.k2, 0.02);
  EXPECT_EQ(custom.max_dn(), 1023);
}

// Pixel encoding and identification tolerance of a real camera's frames
// (issue 19): 12-bit data in 16-bit words, the shipped tetra3 sample file.
TEST(CameraModel, PixelEncodingAndMatchToleranceKeys) {
  EXPECT_EQ(CameraModel::parse(kMinimal, "cam.yaml").dn_shift_bits, 0);
  EXPECT_DOUBLE_EQ(CameraModel::parse(kMinimal, "cam.yaml").match_tolerance_rad, 0.0);
  const CameraModel cam = CameraModel::load(std::string(ARTMS_CONFIG_DIR) + "/cameras/tetra3_sample.yaml");
  EXPECT_EQ(cam.bit_depth, 12);
  EXPECT_EQ(cam.dn_shift_bits, 4);
  EXPECT_EQ(cam.max_dn(), 4095);
  EXPECT_NEAR(cam.match_tolerance_rad, 60.0 * astro::kArcsecToRad, 1e-15);
  EXPECT_DOUBLE_EQ(cam.fx_px, 5116.0);
  // 12 bits shifted by 5 do not fit a 16-bit word: the error names the key.
  const std::string shift = parse_error(
      "sensor: {width_px: 1280, height_px: 1024, pixel_pitch_um: 5.3, bit_depth: 12, dn_shift_bits: 5}\n"
      "optics: {focal_length_mm: 30}\n");
  EXPECT_NE(shift.find("sensor.dn_shift_bits"), std::string::npos) << shift;
  const std::string tol = parse_error(std::string(kMinimal) + "star_id: {match_tolerance_arcsec: 0}\n");
  EXPECT_NE(tol.find("star_id.match_tolerance_arcsec"), std::string::npos) << tol;
  // Centroid method: IWCoG unless the file asks for the Gaussian fit (the
  // tetra3 sample's undersampled PSF); any other name is an error at its line.
  EXPECT_FALSE(CameraModel::parse(kMinimal, "cam.yaml").centroid_gaussian_fit);
  EXPECT_TRUE(cam.centroid_gaussian_fit);
  EXPECT_FALSE(CameraModel::parse(std::string(kMinimal) + "centroid: {method: iwcog}\n", "cam.yaml").centroid_gaussian_fit);
  const std::string method = parse_error(std::string(kMinimal) + "centroid: {method: moments}\n");
  EXPECT_NE(method.find("centroid.method"), std::string::npos) << method;
  EXPECT_NE(method.find("moments"), std::string::npos) << method;
}

// The real-hardware effects: off when a file does not name them, on with
// the shipped nst.yaml's values, off in nst_ideal.yaml; bad values named.
TEST(CameraModel, RealHardwareEffectKeys) {
  const CameraModel minimal = CameraModel::parse(kMinimal, "cam.yaml");
  EXPECT_FALSE(minimal.blooming);
  EXPECT_DOUBLE_EQ(minimal.psf_colour_slope_per_mag, 0.0);
  EXPECT_DOUBLE_EQ(minimal.stray_earth_edge_e_per_px_per_s, 0.0);
  const CameraModel nst = CameraModel::load(kNstPath);
  EXPECT_TRUE(nst.blooming);
  EXPECT_EQ(nst.dn_shift_bits, 4);
  EXPECT_DOUBLE_EQ(nst.psf_colour_slope_per_mag, 0.08);
  EXPECT_DOUBLE_EQ(nst.vignetting_corner_loss, 0.3);
  EXPECT_DOUBLE_EQ(nst.stray_sun_edge_e_per_px_per_s, 300.0);
  EXPECT_DOUBLE_EQ(nst.stray_moon_edge_e_per_px_per_s, 50.0);
  EXPECT_DOUBLE_EQ(nst.stray_earth_edge_e_per_px_per_s, 150.0);
  EXPECT_NEAR(nst.stray_falloff_rad, 4.0 * astro::kDegToRad, 1e-15);
  const CameraModel ideal = CameraModel::load(std::string(ARTMS_CONFIG_DIR) + "/cameras/nst_ideal.yaml");
  EXPECT_FALSE(ideal.blooming);
  EXPECT_EQ(ideal.dn_shift_bits, 0);
  EXPECT_DOUBLE_EQ(ideal.vignetting_corner_loss + ideal.psf_growth_corner + ideal.background_gradient +
                       ideal.psf_colour_slope_per_mag + ideal.stray_sun_edge_e_per_px_per_s +
                       ideal.stray_moon_edge_e_per_px_per_s + ideal.stray_earth_edge_e_per_px_per_s,
                   0.0);
  EXPECT_EQ(ideal.fx_px, nst.fx_px);
  const std::string bloom = parse_error(
      "sensor: {width_px: 1280, height_px: 1024, pixel_pitch_um: 5.3, bit_depth: 12, blooming: maybe}\n"
      "optics: {focal_length_mm: 30}\n");
  EXPECT_NE(bloom.find("sensor.blooming"), std::string::npos) << bloom;
  EXPECT_NE(bloom.find("true or false"), std::string::npos) << bloom;
  const std::string fall = parse_error(std::string(kMinimal) + "stray_light: {falloff_deg: 0}\n");
  EXPECT_NE(fall.find("stray_light.falloff_deg"), std::string::npos) << fall;
  const std::string rate = parse_error(std::string(kMinimal) + "stray_light: {earth_edge_e_per_px_per_s: -1}\n");
  EXPECT_NE(rate.find("stray_light.earth_edge_e_per_px_per_s"), std::string::npos) << rate;
  const std::string slope = parse_error(
      "sensor: {width_px: 1280, height_px: 1024, pixel_pitch_um: 5.3, bit_depth: 12}\n"
      "optics: {focal_length_mm: 30, psf_colour_slope_per_mag: 2}\n");
  EXPECT_NE(slope.find("optics.psf_colour_slope_per_mag"), std::string::npos) << slope;
}

TEST(CameraModel, LoadErrorsNameFileLineColumnAndKey) {
  // Unknown (misspelt) key on line 4, column 3.
  const std::string typo = parse_error(
      "name: nst\n"
      "sensor: {width_px: 1280, height_px: 1024, pixel_pitch_um: 5.3, bit_depth: 12}\n"
      "optics:\n"
      "  focal_lenght_mm: 30\n");
  EXPECT_NE(typo.find("cam.yaml:4:3:"), std::string::npos) << typo;
  EXPECT_NE(typo.find("optics.focal_lenght_mm"), std::string::npos) << typo;
  EXPECT_NE(typo.find("unknown key"), std::string::npos) << typo;

  // Wrong type: the value's position.
  const std::string type = parse_error(std::string(kMinimal) + "photometry:\n  exposure_s: fast\n");
  EXPECT_NE(type.find("cam.yaml:4:15:"), std::string::npos) << type;
  EXPECT_NE(type.find("photometry.exposure_s"), std::string::npos) << type;
  EXPECT_NE(type.find("'fast'"), std::string::npos) << type;

  // Out of range.
  const std::string range = parse_error(std::string(kMinimal) + "hot_pixels: {count: -3}\n");
  EXPECT_NE(range.find("cam.yaml:3:21:"), std::string::npos) << range;
  EXPECT_NE(range.find("hot_pixels.count"), std::string::npos) << range;

  // A required key missing: the location of its mapping.
  const std::string missing = parse_error(
      "sensor: {width_px: 1280, height_px: 1024, bit_depth: 12}\n"
      "optics: {focal_length_mm: 30}\n");
  EXPECT_NE(missing.find("sensor.pixel_pitch_um: missing"), std::string::npos) << missing;
  EXPECT_NE(missing.find("cam.yaml:1:9:"), std::string::npos) << missing;

  // Unknown top-level key, repeated key, YAML syntax error.
  EXPECT_NE(
      parse_error(std::string(kMinimal) + "lens: {}\n").find("cam.yaml:3:1: lens: unknown key"),
      std::string::npos);
  EXPECT_NE(parse_error(std::string(kMinimal) + "optics: {focal_length_mm: 35}\n")
                .find("cam.yaml:3:1: optics: repeated key"),
            std::string::npos);
  const std::string syntax = parse_error(std::string(kMinimal) + "photometry: {exposure_s: 0.2\n");
  EXPECT_NE(syntax.find("cam.yaml:"), std::string::npos) << syntax;
  EXPECT_NE(syntax.find("YAML syntax error"), std::string::npos) << syntax;

  // A file that does not exist.
  EXPECT_THROW(CameraModel::load(std::string(ARTMS_CONFIG_DIR) + "/cameras/none.yaml"),
               std::runtime_error);
}

TEST(CameraModel, PixelConventionAndSensorBounds) {
  const CameraModel cam;
  // Boresight -> principal point; +x camera -> +column; +y camera -> +row.
  const auto centre = cam.project(Vec3(0, 0, 1));
  ASSERT_TRUE(centre.has_value());
  EXPECT_DOUBLE_EQ(centre->x(), 639.5);
  EXPECT_DOUBLE_EQ(centre->y(), 511.5);
  const auto right_down = cam.project(Vec3(0.01, 0.02, 1.0));
  ASSERT_TRUE(right_down.has_value());
  EXPECT_NEAR(right_down->x(), 639.5 + cam.fx_px * 0.01, 1e-9);
  EXPECT_NEAR(right_down->y(), 511.5 + cam.fy_px * 0.02, 1e-9);
  // Length of the input vector does not matter.
  EXPECT_NEAR((*cam.project(Vec3(0.03, 0.06, 3.0)) - *right_down).norm(), 0.0, 1e-9);

  EXPECT_FALSE(cam.project(Vec3(0, 0, -1)).has_value());    // behind
  EXPECT_FALSE(cam.project(Vec3(0.01, 0, 0)).has_value());  // Z = 0
  EXPECT_FALSE(cam.project(Vec3(0.2, 0, 1)).has_value());   // off the sensor
  EXPECT_TRUE(cam.project_unbounded(Vec3(0.2, 0, 1)).has_value());
  // The sensor area ends half a pixel beyond the outer pixel centres.
  const double edge = (1280 - 0.5 - cam.cx_px) / cam.fx_px;
  EXPECT_TRUE(cam.in_fov(Vec3(edge - 1e-9, 0, 1)));
  EXPECT_FALSE(cam.in_fov(Vec3(edge + 1e-6, 0, 1)));
  EXPECT_TRUE(cam.in_fov(Vec3(edge + 1e-6, 0, 1), 0.5));
  EXPECT_TRUE(cam.on_sensor(Vec2(-0.5, -0.5)));
  EXPECT_FALSE(cam.on_sensor(Vec2(-0.51, 3)));
  EXPECT_NEAR(CameraModel::off_boresight_rad(Vec3(1, 0, 1)), std::numbers::pi / 4, 1e-15);
}

TEST(CameraModel, ProjectUnprojectRoundTripWithDistortion) {
  CameraModel cam;
  cam.k1 = -0.35;  // strong barrel distortion: ~-5 px at the corners
  cam.k2 = 0.8;
  cam.cx_px = 641.3;  // off-centre principal point
  cam.fy_px = cam.fx_px * 1.001;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> ux(-0.5, 1279.5), uy(-0.5, 1023.5);
  double max_px_err = 0.0, max_ang_err = 0.0;
  for (int k = 0; k < 20000; ++k) {
    const Vec2 px(ux(rng), uy(rng));
    const Vec3 u = cam.unproject(px);
    EXPECT_NEAR(u.norm(), 1.0, 1e-15);
    const auto back = cam.project(u);
    ASSERT_TRUE(back.has_value()) << px.transpose();
    max_px_err = std::max(max_px_err, (*back - px).norm());
    // And from a direction: project then unproject.
    const auto px2 = cam.project_unbounded(u);
    const Vec3 u2 = cam.unproject(*px2);
    max_ang_err = std::max(max_ang_err, std::atan2(u2.cross(u).norm(), u2.dot(u)));
  }
  EXPECT_LT(max_px_err, 1e-9);
  EXPECT_LT(max_ang_err, 1e-13);
  // The distortion is really there: a corner moves by pixels.
  const Vec2 corner(-0.5, -0.5);
  const Vec2 xn = cam.normalized_from_pixel(corner);
  const Vec2 ideal(cam.cx_px + cam.fx_px * xn.x(), cam.cy_px + cam.fy_px * xn.y());
  EXPECT_GT((ideal - corner).norm(), 3.0);
}

// Brown's tangential terms (camera.hpp): a value worked by hand, and the
// round trip through the 2-D Newton inversion.
TEST(CameraModel, TangentialDistortionValueAndRoundTrip) {
  CameraModel cam;
  cam.k1 = -0.2;
  cam.k2 = 0.1;
  cam.p1 = 1e-3;
  cam.p2 = -2e-3;
  // xn = (0.1, -0.05): r^2 = 0.0125, s = 1 - 0.2 * 0.0125 + 0.1 * 0.0125^2 = 0.997515625;
  // xd = 0.1 s + 2e-3 * 0.1 * -0.05 - 2e-3 (0.0125 + 0.02) = 0.0996765625,
  // yd = -0.05 s + 1e-3 (0.0125 + 0.005) + 2 * -2e-3 * 0.1 * -0.05 = -0.04983828125.
  const Vec2 px = cam.pixel_from_normalized(Vec2(0.1, -0.05));
  EXPECT_NEAR((px.x() - cam.cx_px) / cam.fx_px, 0.0996765625, 1e-12);
  EXPECT_NEAR((px.y() - cam.cy_px) / cam.fy_px, -0.04983828125, 1e-12);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> ux(-0.5, 1279.5), uy(-0.5, 1023.5);
  double worst = 0.0;
  for (int k = 0; k < 5000; ++k) {
    const Vec2 p(ux(rng), uy(rng));
    worst = std::max(worst, (cam.pixel_from_normalized(cam.normalized_from_pixel(p)) - p).norm());
  }
  EXPECT_LT(worst, 1e-9);
  const CameraModel file = CameraModel::parse(
      "sensor: {width_px: 1280, height_px: 1024, pixel_pitch_um: 5.3, bit_depth: 12}\n"
      "optics: {focal_length_mm: 30, p1: 0.001, p2: -0.002}\n",
      "cam.yaml");
  EXPECT_DOUBLE_EQ(file.p1, 1e-3);
  EXPECT_DOUBLE_EQ(file.p2, -2e-3);
}

}  // namespace
}  // namespace artms::imaging
