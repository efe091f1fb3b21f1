// Image formation: PSF integration and flux, centroid accuracy (acceptance),
// noise statistics per term, hot pixels, saturation, determinism, PNG I/O.
#include "artms/imaging/image.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <numeric>
#include <random>
#include <set>

#include "artms/astro/constants.hpp"
#include "artms/testing/testing.hpp"

namespace artms::imaging {
namespace {

using astro::kDegToRad;

// Centroid acceptance bound (brief: 0.02 px) and the window used to measure
// it (radius 5 px = 4.2 sigma of the NST PSF).
constexpr double kCentroidTol_px = 0.02;
constexpr int kCentroidRadius_px = 5;

struct Stats {
  double mean = 0.0;
  double var = 0.0;
};
template <typename T>
Stats stats(const std::vector<T>& v) {
  double s = 0.0, s2 = 0.0;
  for (const T x : v) s += static_cast<double>(x);
  const double mean = s / static_cast<double>(v.size());
  for (const T x : v) s2 += (static_cast<double>(x) - mean) * (static_cast<double>(x) - mean);
  return {mean, s2 / static_cast<double>(v.size() - 1)};
}

// Intensity-weighted centroid over a (2R+1)^2 window centred on the pixel
// nearest to (x0, y0), after subtracting a known background level.
Vec2 centroid(const std::vector<float>& img, int width, double x0, double y0, double background,
              int radius = kCentroidRadius_px) {
  const int xc = static_cast<int>(std::lround(x0)), yc = static_cast<int>(std::lround(y0));
  double sw = 0.0, sx = 0.0, sy = 0.0;
  for (int y = yc - radius; y <= yc + radius; ++y) {
    for (int x = xc - radius; x <= xc + radius; ++x) {
      const double w =
          static_cast<double>(img[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                                  static_cast<std::size_t>(x)]) -
          background;
      sw += w;
      sx += w * x;
      sy += w * y;
    }
  }
  return {sx / sw, sy / sw};
}

CameraModel camera_without_hot_pixels() {
  CameraModel cam;
  cam.hot_pixel_count = 0;
  return cam;
}

TEST(Psf, ConservesFluxAndIntegratesOverPixelArea) {
  const CameraModel cam;
  std::vector<float> img(static_cast<std::size_t>(cam.width_px * cam.height_px), 0.0f);
  const PointSource s{400.37, 300.81, 12345.0};
  add_gaussian_psf(img, cam.width_px, cam.height_px, s, cam.psf_sigma_px);
  const double sum = std::accumulate(img.begin(), img.end(), 0.0);
  EXPECT_NEAR(sum / s.electrons, 1.0, 1e-5);  // 5-sigma window: 1e-6 lost in the tails

  // A narrow PSF centred on a pixel corner puts a quarter into each of the
  // four pixels (point sampling at pixel centres would not).
  std::vector<float> corner(100 * 100, 0.0f);
  add_gaussian_psf(corner, 100, 100, {10.5, 20.5, 1000.0}, 0.2);
  for (const auto& [x, y] : {std::pair{10, 20}, {11, 20}, {10, 21}, {11, 21}}) {
    EXPECT_NEAR(corner[static_cast<std::size_t>(y * 100 + x)], 250.0, 1e-3);
  }
  // Against a direct 2-D integration for a general position.
  std::vector<float> one(50 * 50, 0.0f);
  const PointSource g{20.3, 24.9, 1.0};
  const double sg = 1.2;
  add_gaussian_psf(one, 50, 50, g, sg);
  double max_diff = 0.0;
  for (int y = 20; y <= 29; ++y) {
    for (int x = 16; x <= 25; ++x) {
      double integral = 0.0;  // midpoint rule, 200 x 200 sub-samples
      for (int j = 0; j < 200; ++j) {
        for (int i = 0; i < 200; ++i) {
          const double px = x - 0.5 + (i + 0.5) / 200.0, py = y - 0.5 + (j + 0.5) / 200.0;
          integral += std::exp(-((px - g.x_px) * (px - g.x_px) + (py - g.y_px) * (py - g.y_px)) /
                               (2 * sg * sg));
        }
      }
      integral /= 200.0 * 200.0 * 2.0 * astro::kPi * sg * sg;
      max_diff = std::max(max_diff, std::abs(integral - one[static_cast<std::size_t>(y * 50 + x)]));
    }
  }
  EXPECT_LT(max_diff, 1e-6);

  // Off-sensor light is lost, not wrapped; non-finite sources are ignored.
  std::vector<float> edge(100 * 100, 0.0f);
  add_gaussian_psf(edge, 100, 100, {-0.5, 50.0, 1000.0}, 1.2);
  EXPECT_NEAR(std::accumulate(edge.begin(), edge.end(), 0.0), 500.0, 1e-2);
  add_gaussian_psf(edge, 100, 100, {std::nan(""), 50.0, 1000.0}, 1.2);
  add_gaussian_psf(edge, 100, 100, {-1e9, 50.0, 1000.0}, 1.2);
  EXPECT_NEAR(std::accumulate(edge.begin(), edge.end(), 0.0), 500.0, 1e-2);
}

// ACCEPTANCE: noise-free isolated point sources at random sub-pixel
// positions; the background-subtracted intensity-weighted centroid lies
// within 0.02 px of the truth.
TEST(ImageAcceptance, CentroidOfRandomSubpixelSourcesWithin002Px) {
  const ImageFormer former(camera_without_hot_pixels());
  const CameraModel& cam = former.camera();
  NoiseOptions opts = NoiseOptions::noise_free();
  opts.saturation = false;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> frac(-0.5, 0.5), flux(200.0, 2e5);
  std::vector<PointSource> sources;
  for (int gy = 30; gy < cam.height_px - 30; gy += 40) {  // one source per 40 px cell
    for (int gx = 30; gx < cam.width_px - 30; gx += 40) {
      sources.push_back({gx + 10 * frac(rng), gy + 10 * frac(rng), flux(rng)});
    }
  }
  const std::vector<float> img = former.render_float(sources, 1, opts);
  const double background_dn = (cam.background_e_per_px_per_s + cam.dark_current_e_per_s) *
                                   cam.exposure_s / cam.gain_e_per_dn +
                               cam.bias_dn;
  double max_err = 0.0, sum_err2 = 0.0;
  for (const PointSource& s : sources) {
    const Vec2 c = centroid(img, cam.width_px, s.x_px, s.y_px, background_dn);
    const double err = (c - Vec2(s.x_px, s.y_px)).norm();
    max_err = std::max(max_err, err);
    sum_err2 += err * err;
  }
  std::cout << "[ centroid ] " << sources.size() << " random sub-pixel sources: max error "
            << max_err << " px, rms " << std::sqrt(sum_err2 / static_cast<double>(sources.size()))
            << " px\n";
  EXPECT_LT(max_err, kCentroidTol_px);
  EXPECT_GT(sources.size(), 600u);
}

// ACCEPTANCE: the same for real catalog stars at a few attitudes.
TEST(ImageAcceptance, CentroidOfCatalogStarsWithin002Px) {
  const StarCatalog catalog =
      StarCatalog::load_bsc5(std::string(ARTMS_DATA_DIR) + "/stars/bsc5.dat", 7.0);
  const ImageFormer former(camera_without_hot_pixels());
  const CameraModel& cam = former.camera();
  NoiseOptions opts = NoiseOptions::noise_free();
  opts.saturation = false;  // saturated cores would be clipped (a real bias, not the PSF's)
  const double background_dn = (cam.background_e_per_px_per_s + cam.dark_current_e_per_s) *
                                   cam.exposure_s / cam.gain_e_per_dn +
                               cam.bias_dn;
  const astro::TimeTT t = astro::tt_from_utc_string("2024-05-08T00:00:00Z");
  // Boresights (RA, Dec in deg) through Orion, the Pleiades, Crux, Cygnus;
  // camera x rotated about the boresight by a different angle each.
  const double pointings[][3] = {
      {83.8, -5.4, 10.0}, {56.9, 24.1, 75.0}, {187.0, -60.0, -30.0}, {305.0, 40.0, 140.0}};
  int measured = 0;
  double max_err = 0.0;
  for (const auto& p : pointings) {
    const double ra = p[0] * kDegToRad, dec = p[1] * kDegToRad, roll = p[2] * kDegToRad;
    const Vec3 z(std::cos(dec) * std::cos(ra), std::cos(dec) * std::sin(ra), std::sin(dec));
    const Vec3 east(-std::sin(ra), std::cos(ra), 0.0);
    const Vec3 north = z.cross(east);
    const Vec3 x = std::cos(roll) * east + std::sin(roll) * north;
    Eigen::Matrix3d R_cam_from_eci;
    R_cam_from_eci.row(0) = x.transpose();
    R_cam_from_eci.row(1) = z.cross(x).transpose();
    R_cam_from_eci.row(2) = z.transpose();
    const Eigen::Quaterniond q_cam_from_eci(R_cam_from_eci);

    const std::vector<StarInFrame> stars = stars_in_frame(catalog, cam, q_cam_from_eci, t, 8.0);
    ASSERT_GT(stars.size(), 5u);
    for (const StarInFrame& s : stars) {  // each really projects where the attitude says
      const Vec3 v_cam = R_cam_from_eci * s.star->unit_eci_at(t);
      EXPECT_NEAR(s.x_px, cam.cx_px + cam.fx_px * v_cam.x() / v_cam.z(), 1e-9);
      EXPECT_NEAR(s.y_px, cam.cy_px + cam.fy_px * v_cam.y() / v_cam.z(), 1e-9);
    }
    const std::vector<float> img = former.render_float(point_sources(stars), 5, opts);
    for (const StarInFrame& s : stars) {
      // Isolated (nothing within 14 px, counting neighbours 1000x fainter
      // or brighter alike) and well inside the sensor.
      const bool inside =
          s.x_px > 8 && s.x_px < cam.width_px - 9 && s.y_px > 8 && s.y_px < cam.height_px - 9;
      const bool isolated = std::none_of(stars.begin(), stars.end(), [&s](const StarInFrame& o) {
        return &o != &s && std::hypot(o.x_px - s.x_px, o.y_px - s.y_px) < 14.0;
      });
      if (!inside || !isolated) continue;
      const Vec2 c = centroid(img, cam.width_px, s.x_px, s.y_px, background_dn);
      const double err = (c - Vec2(s.x_px, s.y_px)).norm();
      EXPECT_LT(err, kCentroidTol_px) << "HR " << s.star->catalog_id << " V " << s.star->vmag;
      max_err = std::max(max_err, err);
      ++measured;
    }
  }
  std::cout << "[ centroid ] " << measured << " isolated catalog stars (V <= 7): max error "
            << max_err << " px\n";
  EXPECT_GT(measured, 40);
}

TEST(ImageNoise, FlatDarkFrameMeanAndVarianceMatchTheModel) {
  const ImageFormer former(camera_without_hot_pixels());
  const CameraModel& cam = former.camera();
  const double lam = (cam.background_e_per_px_per_s + cam.dark_current_e_per_s) * cam.exposure_s;
  const double g = cam.gain_e_per_dn, rn = cam.read_noise_e;
  // 12-bit frame: Poisson(lam) + N(0, rn^2) electrons, / gain, + bias, rounded
  // (uniform rounding error adds 1/12 DN^2).
  const std::vector<std::uint16_t> frame = former.render({}, 42);
  const Stats s = stats(frame);
  const double mean_expected = cam.bias_dn + lam / g;
  const double var_expected = (lam + rn * rn) / (g * g) + 1.0 / 12.0;
  std::cout << "[ noise ] flat frame: mean " << s.mean << " DN (model " << mean_expected
            << "), variance " << s.var << " DN^2 (model " << var_expected << ")\n";
  EXPECT_NEAR(s.mean, mean_expected, 0.01 * lam / g);
  EXPECT_NEAR(s.var, var_expected, 0.02 * var_expected);

  // A brighter flat frame (mean 400 e-), through the same tabulated path.
  CameraModel bright = cam;
  bright.background_e_per_px_per_s = 400.0 / cam.exposure_s - cam.dark_current_e_per_s;
  const Stats b = stats(ImageFormer(bright).render({}, 43));
  EXPECT_NEAR(b.mean, cam.bias_dn + 400.0 / g, 0.005 * 400.0 / g);
  EXPECT_NEAR(b.var, (400.0 + rn * rn) / (g * g) + 1.0 / 12.0, 0.02 * (500.0 / (g * g)));
}

TEST(ImageNoise, EachTermSwitchesAlone) {
  const CameraModel base = camera_without_hot_pixels();
  const double g = base.gain_e_per_dn;
  NoiseOptions none = NoiseOptions::noise_free();
  none.background = none.dark_current = false;

  // Read noise only: variance rn^2 / g^2, mean = bias.
  NoiseOptions read = none;
  read.read_noise = true;
  const Stats r = stats(ImageFormer(base).render_float({}, 1, read));
  EXPECT_NEAR(r.mean, base.bias_dn, 0.01);
  EXPECT_NEAR(r.var, base.read_noise_e * base.read_noise_e / (g * g), 0.02 * 16.0);

  // Shot noise only, small mean (inversion sampler) and large mean (PTRS):
  // Poisson variance = mean.
  for (const double lam : {3.0, 37.0, 900.0}) {
    CameraModel cam = base;
    cam.background_e_per_px_per_s = lam / cam.exposure_s;
    NoiseOptions shot = none;
    shot.background = true;
    shot.shot_noise = true;
    const Stats s = stats(ImageFormer(cam).render_float({}, 2, shot));
    EXPECT_NEAR(s.mean, base.bias_dn + lam / g, 0.003 * lam / g + 1e-3) << lam;
    EXPECT_NEAR(s.var, lam / (g * g), 0.02 * lam / (g * g)) << lam;
  }

  // Background and dark current each add their expected electrons.
  NoiseOptions bg = none;
  bg.background = true;
  NoiseOptions dark = none;
  dark.dark_current = true;
  const ImageFormer former(base);
  EXPECT_NEAR(former.render_float({}, 3, bg)[777],
              base.bias_dn + base.background_e_per_px_per_s * base.exposure_s / g, 1e-4);
  EXPECT_NEAR(former.render_float({}, 3, dark)[777],
              base.bias_dn + base.dark_current_e_per_s * base.exposure_s / g, 1e-4);
  // Bias off: zero.
  NoiseOptions nothing = NoiseOptions::sources_only();
  EXPECT_EQ(former.render_float({}, 3, nothing)[777], 0.0f);

  // Noise-free: render_float is exactly the expected signal in DN.
  const std::vector<PointSource> src{{100.2, 200.7, 5e4}};
  const std::vector<float> e = former.expected_electrons(src, NoiseOptions::noise_free());
  const std::vector<float> dn = former.render_float(src, 9, NoiseOptions::noise_free());
  for (std::size_t i = 0; i < e.size(); i += 997) {
    EXPECT_NEAR(dn[i], std::min<double>(e[i], base.full_well_e) / g + base.bias_dn, 1e-3);
  }
}

// Field effects of real optics (issue 19): vignetting takes its corner loss
// from a source in the corner and from the sky there, the PSF widens off
// axis, and the background follows its gradient; all off by default.
TEST(ImageFormation, VignettingOffAxisBlurAndBackgroundGradient) {
  CameraModel cam;
  cam.hot_pixel_count = 0;
  cam.vignetting_corner_loss = 0.3;
  cam.psf_growth_corner = 0.5;
  cam.background_gradient = 0.2;
  const ImageFormer former(cam);
  NoiseOptions src_only = NoiseOptions::sources_only();
  // A source at the centre and one near the corner (r / r_corner ~ 0.99).
  const double xc = cam.cx_px, yc = cam.cy_px, xk = 8.0, yk = 6.0;
  const std::vector<PointSource> two{{xc, yc, 1e5}, {xk, yk, 1e5}};
  const std::vector<float> e = former.expected_electrons(two, src_only);
  const auto stats = [&](double x0, double y0) {
    double sum = 0.0, m2 = 0.0;
    for (int y = static_cast<int>(y0) - 8; y <= static_cast<int>(y0) + 8; ++y) {
      for (int x = static_cast<int>(x0) - 8; x <= static_cast<int>(x0) + 8; ++x) {
        if (x < 0 || y < 0) continue;
        const double v = e[static_cast<std::size_t>(y) * static_cast<std::size_t>(cam.width_px) + static_cast<std::size_t>(x)];
        sum += v;
        m2 += v * (std::pow(x - x0, 2) + std::pow(y - y0, 2));
      }
    }
    return std::make_pair(sum, std::sqrt(0.5 * m2 / sum - 1.0 / 12.0));
  };
  const double q = (std::pow(xk - cam.cx_px, 2) + std::pow(yk - cam.cy_px, 2)) /
                   (std::pow(cam.cx_px, 2) + std::pow(cam.cy_px, 2));
  const auto [flux_c, width_c] = stats(xc, yc);
  const auto [flux_k, width_k] = stats(xk, yk);
  EXPECT_NEAR(flux_c, 1e5, 1e5 * 1e-3);
  EXPECT_NEAR(flux_k, 1e5 * (1.0 - 0.3 * q), 1e5 * 1e-2);
  EXPECT_NEAR(width_c, cam.psf_sigma_px, 0.02);
  EXPECT_NEAR(width_k, cam.psf_sigma_px * (1.0 + 0.5 * q), 0.05);
  // Sky: the gradient and the vignetting, both in the expected electrons.
  NoiseOptions bg = NoiseOptions::sources_only();
  bg.background = true;
  const std::vector<float> sky = former.expected_electrons({}, bg);
  const double b0 = cam.background_e_per_px_per_s * cam.exposure_s;
  const auto at = [&](int x, int y) { return sky[static_cast<std::size_t>(y) * static_cast<std::size_t>(cam.width_px) + static_cast<std::size_t>(x)]; };
  const int ym = static_cast<int>(cam.cy_px);
  EXPECT_NEAR(at(static_cast<int>(cam.cx_px), ym), b0, b0 * 1e-3);
  const double right_q = std::pow(cam.width_px - 1 - cam.cx_px, 2) / (std::pow(cam.cx_px, 2) + std::pow(cam.cy_px, 2));
  EXPECT_NEAR(at(cam.width_px - 1, ym),
              b0 * (1.0 - 0.3 * right_q) * (1.0 + 0.2 * (cam.width_px - 1 - cam.cx_px) / (0.5 * cam.width_px)), b0 * 2e-3);
  // Off by default: the NST file renders as before.
  const CameraModel plain;
  EXPECT_EQ(plain.vignetting_corner_loss, 0.0);
  EXPECT_EQ(plain.psf_growth_corner, 0.0);
  EXPECT_EQ(plain.background_gradient, 0.0);
}

TEST(ImageNoise, HotPixelsStayPutAcrossFramesAndSeeds) {
  const CameraModel cam;  // 250 hot pixels
  const ImageFormer former(cam);
  ASSERT_EQ(former.hot_pixels().size(), static_cast<std::size_t>(cam.hot_pixel_count));
  std::set<std::pair<int, int>> truth;
  for (const HotPixel& hp : former.hot_pixels()) {
    EXPECT_GE(hp.dark_e_per_s, cam.hot_pixel_dark_min_e_per_s);
    EXPECT_LE(hp.dark_e_per_s, cam.hot_pixel_dark_max_e_per_s);
    truth.insert({hp.x, hp.y});
  }
  EXPECT_EQ(truth.size(), former.hot_pixels().size());  // distinct

  // Hot pixels are > 160 DN above a ~24 DN background with sigma ~4.2 DN.
  const auto detect = [&cam](const std::vector<std::uint16_t>& f) {
    std::set<std::pair<int, int>> found;
    for (std::size_t i = 0; i < f.size(); ++i) {
      if (f[i] > 100) {
        found.insert({static_cast<int>(i % static_cast<std::size_t>(cam.width_px)),
                      static_cast<int>(i / static_cast<std::size_t>(cam.width_px))});
      }
    }
    return found;
  };
  const auto a = former.render({}, 1001);
  const auto b = former.render({}, 2002);
  EXPECT_NE(a, b);
  EXPECT_EQ(detect(a), truth);
  EXPECT_EQ(detect(b), truth);
  // Another former for the same camera unit: the same hot pixels; another
  // unit (seed): different ones.
  EXPECT_EQ(detect(ImageFormer(cam).render({}, 3003)), truth);
  CameraModel other = cam;
  other.hot_pixel_seed = 2;
  const auto c = detect(ImageFormer(other).render({}, 1001));
  EXPECT_EQ(c.size(), truth.size());
  EXPECT_NE(c, truth);
  // Switching them off removes them.
  NoiseOptions off;
  off.hot_pixels = false;
  EXPECT_TRUE(detect(former.render({}, 1001, off)).empty());
}

TEST(ImageNoise, SaturationAndQuantisationBounds) {
  const ImageFormer former{CameraModel{}};
  const CameraModel& cam = former.camera();
  // A V = -4 source and a washed-out corner.
  const std::vector<PointSource> src{{300.3, 400.6, cam.electrons_from_vmag(-4.0)},
                                     {900.0, 100.0, 50.0}};
  const auto stray = sun_washout(cam, Vec3(std::sin(40 * kDegToRad), 0, std::cos(40 * kDegToRad)));
  ASSERT_TRUE(stray.has_value());
  const std::vector<std::uint16_t> f = former.render(src, 77, {}, std::span(&*stray, 1));
  const auto max_dn = *std::max_element(f.begin(), f.end());
  EXPECT_EQ(max_dn, 4095);
  EXPECT_EQ(f[400 * 1280 + 300], 4095);
  EXPECT_TRUE(std::all_of(f.begin(), f.end(), [](std::uint16_t v) { return v <= 4095; }));
  // Float output is clipped to the same range, and integer-valued output
  // is what render() returns.
  const std::vector<float> ff = former.render_float(src, 77, {}, std::span(&*stray, 1));
  EXPECT_LE(*std::max_element(ff.begin(), ff.end()), 4095.0f);
  EXPECT_GE(*std::min_element(ff.begin(), ff.end()), 0.0f);
  const std::vector<float> nf = former.render_float(src, 0, NoiseOptions::noise_free());
  // Noise-free: the core is clipped at the full well, which lies beyond the
  // ADC range (full well / gain + bias > 4095), so it reads 4095.
  ASSERT_GT(cam.full_well_e / cam.gain_e_per_dn + cam.bias_dn, 4095.0);
  EXPECT_FLOAT_EQ(nf[400 * 1280 + 300], 4095.0f);
  // Without saturation the same core exceeds 12 bits.
  NoiseOptions raw = NoiseOptions::noise_free();
  raw.saturation = false;
  EXPECT_GT(former.render(src, 0, raw)[400 * 1280 + 300], 4095);
}

TEST(ImageNoise, DeterministicPerSeedAndPerRow) {
  const ImageFormer former{CameraModel{}};
  const std::vector<PointSource> one{{200.0, 100.0, 1e5}};
  const std::vector<PointSource> two{{200.0, 100.0, 1e5}, {700.0, 800.0, 1e5}};
  const auto a = former.render(one, 5);
  EXPECT_EQ(a, former.render(one, 5));
  EXPECT_NE(a, former.render(one, 6));
  // A second star changes only the rows its PSF reaches.
  const auto b = former.render(two, 5);
  const int w = former.camera().width_px;
  for (int y = 0; y < former.camera().height_px; ++y) {
    const bool same = std::equal(a.begin() + y * w, a.begin() + (y + 1) * w, b.begin() + y * w);
    if (y < 793 || y > 807) {
      EXPECT_TRUE(same) << "row " << y;
    }
  }
  EXPECT_NE(a, b);
}

TEST(ImageWashout, SunNearTheFieldRaisesARampTowardsIt) {
  const CameraModel cam;
  EXPECT_FALSE(sun_washout(cam, Vec3(0, 0, -1)).has_value());
  EXPECT_FALSE(sun_washout(cam, Vec3(std::sin(50 * kDegToRad), 0, std::cos(50 * kDegToRad))));
  // Sun 30 deg off the boresight towards -y (up in the image).
  const auto s = sun_washout(cam, Vec3(0, -std::sin(30 * kDegToRad), std::cos(30 * kDegToRad)));
  ASSERT_TRUE(s.has_value());
  const ImageFormer former(cam);
  NoiseOptions opts = NoiseOptions::noise_free();
  opts.hot_pixels = false;
  const std::vector<float> f = former.render_float({}, 0, opts, std::span(&*s, 1));
  const float top = f[640], middle = f[512 * 1280 + 640], bottom = f[1023 * 1280 + 640];
  EXPECT_GT(top, middle);
  EXPECT_GT(middle, bottom);
  EXPECT_FLOAT_EQ(top, 4095.0f);  // the near edge saturates
  EXPECT_LT(bottom, 4095.0f);
  // Severity grows as the Sun closes in.
  const auto closer =
      sun_washout(cam, Vec3(0, -std::sin(10 * kDegToRad), std::cos(10 * kDegToRad)));
  EXPECT_GT(closer->centre_rate_e_per_px_per_s, s->centre_rate_e_per_px_per_s);
}

// Blooming: a source far above the full well spills along its column only,
// and the charge is conserved; without blooming the excess is lost.
TEST(ImageFormerRealism, BloomingSpillsAlongTheColumnAndConservesCharge) {
  CameraModel cam;
  cam.hot_pixel_count = 0;
  cam.blooming = true;
  const ImageFormer former(cam);
  NoiseOptions opts = NoiseOptions::noise_free();
  opts.background = false;
  opts.dark_current = false;
  const std::vector<PointSource> star{{640.0, 512.0, 2.0e6}};  // ~200 full wells
  const std::vector<float> e = former.expected_electrons(star, opts);
  double total = 0.0;
  int full_in_column = 0, full_in_row = 0;
  for (std::size_t i = 0; i < e.size(); ++i) total += e[i];
  for (int y = 0; y < 1024; ++y) full_in_column += e[static_cast<std::size_t>(y) * 1280 + 640] >= 0.999f * 1e4f;
  for (int x = 0; x < 1280; ++x) full_in_row += e[512u * 1280u + static_cast<std::size_t>(x)] >= 0.999f * 1e4f;
  EXPECT_NEAR(total, 2.0e6, 2.0e6 * 1e-4);  // spilt, not lost
  EXPECT_GT(full_in_column, 3 * full_in_row);  // a vertical streak
  EXPECT_GT(full_in_column, 60);
  for (const float v : e) EXPECT_LE(v, 1e4f * 1.0001f);
  cam.blooming = false;
  const std::vector<float> clipped = ImageFormer(cam).expected_electrons(star, opts);
  int full_column_off = 0;
  for (int y = 0; y < 1024; ++y) full_column_off += clipped[static_cast<std::size_t>(y) * 1280 + 640] >= 1e4f;
  EXPECT_LT(full_column_off, full_in_column / 3);
}

// Chromatic PSF: a red star (B-V 1.6) spreads wider than a blue one (B-V
// -0.1) by the configured slope; solar-coloured sources are unchanged.
TEST(ImageFormerRealism, ColourWidensThePsfByTheConfiguredSlope) {
  CameraModel cam;
  cam.hot_pixel_count = 0;
  cam.psf_colour_slope_per_mag = 0.1;
  const ImageFormer former(cam);
  NoiseOptions opts = NoiseOptions::sources_only();
  const auto second_moment = [&](double bv) {
    const std::vector<PointSource> star{{640.3, 512.6, 1e5, bv}};
    const std::vector<float> e = former.expected_electrons(star, opts);
    double s0 = 0.0, s2 = 0.0;
    for (int y = 500; y < 525; ++y) {
      for (int x = 628; x < 653; ++x) {
        const double v = e[static_cast<std::size_t>(y) * 1280 + static_cast<std::size_t>(x)];
        s0 += v;
        s2 += v * (std::pow(x - 640.3, 2) + std::pow(y - 512.6, 2));
      }
    }
    return std::sqrt(s2 / s0 / 2.0 - 1.0 / 12.0);  // per-axis sigma, pixel box removed
  };
  EXPECT_NEAR(second_moment(kSolarBMinusV), cam.psf_sigma_px, 0.01);
  EXPECT_NEAR(second_moment(1.6), cam.psf_sigma_px * (1.0 + 0.1 * (1.6 - kSolarBMinusV)), 0.01);
  EXPECT_NEAR(second_moment(-0.1), cam.psf_sigma_px * (1.0 + 0.1 * (-0.1 - kSolarBMinusV)), 0.01);
}

// Stray light beyond an exclusion cone: the edge rate at the cone, falling
// by e per falloff angle, ramping towards the body; off when the rate is 0.
TEST(ImageFormerRealism, StrayLightBeyondExclusionFallsOffWithAngle) {
  CameraModel cam;
  cam.stray_falloff_rad = 4.0 * kDegToRad;
  const auto at = [&](double deg) {
    return Vec3(0.0, -std::sin(deg * kDegToRad), std::cos(deg * kDegToRad));
  };
  EXPECT_FALSE(stray_light_beyond_exclusion(cam, at(50), cam.sun_exclusion_rad, 0.0).has_value());
  const auto edge = stray_light_beyond_exclusion(cam, at(45), cam.sun_exclusion_rad, 300.0);
  const auto far = stray_light_beyond_exclusion(cam, at(53), cam.sun_exclusion_rad, 300.0);
  const auto inside = stray_light_beyond_exclusion(cam, at(30), cam.sun_exclusion_rad, 300.0);
  ASSERT_TRUE(edge && far && inside);
  EXPECT_NEAR(edge->centre_rate_e_per_px_per_s, 300.0, 1e-9);
  EXPECT_NEAR(far->centre_rate_e_per_px_per_s, 300.0 * std::exp(-2.0), 1e-9);
  EXPECT_NEAR(inside->centre_rate_e_per_px_per_s, 300.0, 1e-9);
  EXPECT_NEAR(far->dir_y, -1.0, 1e-12);  // towards the body: up in the image
  EXPECT_FALSE(stray_light_beyond_exclusion(cam, at(170), cam.sun_exclusion_rad, 300.0).has_value());
  // Two ramps add.
  cam.hot_pixel_count = 0;
  const ImageFormer former(cam);
  NoiseOptions opts = NoiseOptions::noise_free();
  opts.dark_current = false;
  const std::vector<StrayLight> two{*edge, *far};
  const std::vector<float> f2 = former.expected_electrons({}, opts, two);
  const std::vector<float> f0 = former.expected_electrons({}, opts);
  const std::size_t centre = 511u * 1280u + 639u;
  EXPECT_NEAR(f2[centre] - f0[centre],
              (300.0 + 300.0 * std::exp(-2.0)) * cam.exposure_s * std::exp(0.5 / 300.0 * 1.0), 0.05);
  EXPECT_GT(f2[640], f2[1023u * 1280u + 640u]);
}

TEST(ImagePng, SixteenBitRoundTripAndPreview) {
  const ImageFormer former{CameraModel{}};
  const std::vector<PointSource> star{{640.0, 512.0, 1e5}};
  const std::vector<std::uint16_t> frame = former.render(star, 8);
  const auto dir = std::filesystem::path(::testing::TempDir()) / "artms_imaging_tests";
  std::filesystem::create_directories(dir);
  const std::string path16 = (dir / "frame.png").string();
  const std::string path8 = (dir / "preview.png").string();
  write_png16(path16, frame, 1280, 1024);
  const Image16 back = read_png16(path16);
  EXPECT_EQ(back.width, 1280);
  EXPECT_EQ(back.height, 1024);
  EXPECT_EQ(back.pixels, frame);

  write_preview_png8(path8, frame, 1280, 1024);
  const Image16 preview = read_png16(path8);
  ASSERT_EQ(preview.pixels.size(), frame.size());
  EXPECT_EQ(preview.pixels[512 * 1280 + 640], 255);  // the star is white
  const auto dark = std::count_if(preview.pixels.begin(), preview.pixels.end(),
                                  [](std::uint16_t v) { return v < 128; });
  EXPECT_GT(dark, static_cast<long>(frame.size() / 2));  // the sky is dark

  EXPECT_THROW(write_png16(path16, frame, 1280, 1000), std::runtime_error);
  EXPECT_THROW(read_png16((dir / "absent.png").string()), std::runtime_error);
  EXPECT_THROW(write_png16((dir / "no/such/dir/x.png").string(), frame, 1280, 1024),
               std::runtime_error);
}

}  // namespace
}  // namespace artms::imaging
