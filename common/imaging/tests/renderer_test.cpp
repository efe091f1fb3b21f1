// Renderer checks: detection SNR of stars and swarm targets with the shipped
// NST camera and its full noise model (renderer issue, acceptance 2; the
// printed table is the one in docs/imaging.md, section "Detection SNR").
#include "artms/imaging/renderer.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "artms/astro/aberration.hpp"
#include "artms/astro/constants.hpp"
#include "artms/astro/time.hpp"
#include "artms/dynamics/ephemeris.hpp"

namespace artms::imaging {
namespace {

using astro::kDegToRad;
using dynamics::kAstronomicalUnit_m;

// Measurement (documented in docs/imaging.md):
// - aperture: 5 x 5 px centred on the pixel holding the source (sources sit
//   at pixel centres; a 1.2 px PSF puts 92.8 % of the light in it);
// - background estimate: the mean of the square annulus 8..12 px
//   (Chebyshev distance) around the source, times 25, in each frame;
// - SNR = mean(aperture sum - background) / std(aperture sum - background)
//   over kFrames noisy frames (seeds 1..kFrames) x kCopies copies of the
//   source at different places, away from hot pixels and other sources.
constexpr int kApertureHalf = 2;
constexpr int kAnnulusIn = 8;
constexpr int kAnnulusOut = 12;
constexpr int kGrid_px = 40;  // source spacing (> 2 kAnnulusOut + PSF)
constexpr int kCopies = 8;
constexpr int kFrames = 128;

struct SnrRow {
  std::string label;
  double vmag = 0.0;
  std::vector<std::pair<int, int>> where;  // pixel positions of the copies
  double signal_e = 0.0, noise_e = 0.0, snr = 0.0, snr_predicted = 0.0;
};

// CCD equation for the same estimator: shot noise of the source and of the
// sky + dark in the aperture, read and quantisation noise, and the noise the
// annulus mean brings in (n_ap^2 / n_ann times the per-pixel variance).
double predicted_snr(const CameraModel& c, double vmag) {
  const double ee1 = std::erf((kApertureHalf + 0.5) / (std::sqrt(2.0) * c.psf_sigma_px));
  const double s = c.electrons_from_vmag(vmag) * ee1 * ee1;
  const double n_ap = (2 * kApertureHalf + 1) * (2 * kApertureHalf + 1);
  const double n_ann =
      (2 * kAnnulusOut + 1) * (2 * kAnnulusOut + 1) - (2 * kAnnulusIn - 1) * (2 * kAnnulusIn - 1);
  const double var_px = (c.background_e_per_px_per_s + c.dark_current_e_per_s) * c.exposure_s +
                        c.read_noise_e * c.read_noise_e + c.gain_e_per_dn * c.gain_e_per_dn / 12.0;
  return s / std::sqrt(s + n_ap * var_px + n_ap * n_ap / n_ann * var_px);
}

TEST(RendererSnr, TableForDocs) {
  // The NST's photometry on the axis, without the real-hardware effects
  // (nst.yaml's DN encoding and stray light would only rescale and offset).
  const CameraModel cam = CameraModel::load(std::string(ARTMS_CONFIG_DIR) + "/cameras/nst_ideal.yaml");
  const ImageFormer former(cam);
  const int w = cam.width_px, h = cam.height_px;

  std::vector<SnrRow> rows;
  const double star_v[] = {3.0, 4.0, 5.0, 6.0, 6.5, 7.0, 7.5, 8.0, 9.0};
  for (const double v : star_v) rows.push_back({"star", v, {}, 0, 0, 0, 0});
  // Default CubeSat (photometry.hpp) at 1 AU from the Sun, fully lit;
  // flight-like = +1.5 mag (without the per-frame 0.3 mag draw).
  const TargetOptics optics;
  const double ranges_km[] = {50.0, 100.0, 150.0};
  const double phases_deg[] = {30.0, 90.0};
  for (const bool flight : {false, true}) {
    for (const double ph : phases_deg) {
      for (const double r : ranges_km) {
        const double v = diffuse_sphere_vmag(optics.radius_m, optics.geometric_albedo, r * 1e3,
                                             ph * kDegToRad, kAstronomicalUnit_m) +
                         (flight ? TargetProfile::flight_like().loss_mag : 0.0);
        char label[64];
        std::snprintf(label, sizeof label, "target %s %3.0f km %2.0f deg",
                      flight ? "flight-like" : "nominal    ", r, ph);
        rows.push_back({label, v, {}, 0, 0, 0, 0});
      }
    }
  }

  // Grid cells whose annulus is free of hot pixels, handed out row by row.
  std::vector<std::pair<int, int>> cells;
  for (int y = kGrid_px; y + kGrid_px < h; y += kGrid_px) {
    for (int x = kGrid_px; x + kGrid_px < w; x += kGrid_px) {
      bool clean = true;
      for (const HotPixel& hp : former.hot_pixels()) {
        if (std::abs(hp.x - x) <= kAnnulusOut + 1 && std::abs(hp.y - y) <= kAnnulusOut + 1)
          clean = false;
      }
      if (clean) cells.emplace_back(x, y);
    }
  }
  ASSERT_GE(cells.size(), rows.size() * kCopies);
  std::vector<PointSource> sources;
  std::size_t next = 0;
  for (int k = 0; k < kCopies; ++k) {
    for (SnrRow& row : rows) {
      const auto [x, y] = cells[next++ * (cells.size() / (rows.size() * kCopies))];
      row.where.emplace_back(x, y);
      sources.push_back(
          {static_cast<double>(x), static_cast<double>(y), cam.electrons_from_vmag(row.vmag)});
    }
  }

  // Samples of (aperture sum - background estimate), in DN.
  std::vector<std::vector<double>> samples(rows.size());
  const double n_ap = (2 * kApertureHalf + 1) * (2 * kApertureHalf + 1);
  for (int f = 0; f < kFrames; ++f) {
    const std::vector<std::uint16_t> img =
        former.render(sources, static_cast<std::uint64_t>(f + 1));
    for (std::size_t i = 0; i < rows.size(); ++i) {
      for (const auto& [x0, y0] : rows[i].where) {
        double ap = 0.0, ann = 0.0;
        int n_ann = 0;
        for (int dy = -kAnnulusOut; dy <= kAnnulusOut; ++dy) {
          for (int dx = -kAnnulusOut; dx <= kAnnulusOut; ++dx) {
            const double v = img[static_cast<std::size_t>(y0 + dy) * static_cast<std::size_t>(w) +
                                 static_cast<std::size_t>(x0 + dx)];
            const int d = std::max(std::abs(dx), std::abs(dy));
            if (d <= kApertureHalf) ap += v;
            if (d >= kAnnulusIn) {
              ann += v;
              ++n_ann;
            }
          }
        }
        samples[i].push_back(ap - n_ap * ann / n_ann);
      }
    }
  }
  for (std::size_t i = 0; i < rows.size(); ++i) {
    double m = 0.0, v = 0.0;
    for (const double s : samples[i]) m += s;
    m /= static_cast<double>(samples[i].size());
    for (const double s : samples[i]) v += (s - m) * (s - m);
    v /= static_cast<double>(samples[i].size() - 1);
    rows[i].signal_e = m * cam.gain_e_per_dn;
    rows[i].noise_e = std::sqrt(v) * cam.gain_e_per_dn;
    rows[i].snr = m / std::sqrt(v);
    rows[i].snr_predicted = predicted_snr(cam, rows[i].vmag);
  }

  std::printf(
      "Detection SNR, %s camera, full noise model, %dx%d px aperture, %d frames x %d copies\n",
      cam.name.c_str(), 2 * kApertureHalf + 1, 2 * kApertureHalf + 1, kFrames, kCopies);
  std::printf("| source | V | signal (e-) | noise (e-) | SNR measured | SNR predicted |\n");
  for (const SnrRow& r : rows) {
    std::printf("| %s | %.2f | %.0f | %.1f | %.1f | %.1f |\n", r.label.c_str(), r.vmag, r.signal_e,
                r.noise_e, r.snr, r.snr_predicted);
  }

  // The measurement agrees with the CCD equation (statistical error of an
  // SNR from 1024 samples: ~2.2 %).
  for (const SnrRow& r : rows)
    EXPECT_NEAR(r.snr / r.snr_predicted, 1.0, 0.1) << r.label << " V " << r.vmag;
  // Stars: SNR falls with magnitude; the camera defaults put 5 sigma near
  // V = 7.5 (camera.hpp, exposure_s): within a factor 2 of it.
  for (std::size_t i = 1; i < std::size(star_v); ++i)
    EXPECT_LT(rows[i].snr, rows[i - 1].snr) << "V " << star_v[i];
  const SnrRow& v75 = rows[6];
  ASSERT_DOUBLE_EQ(v75.vmag, 7.5);
  EXPECT_GT(v75.snr, 2.5);
  EXPECT_LT(v75.snr, 10.0);
  // Bright stars approach the shot-noise limit sqrt(signal) (V = 3: ~90 %,
  // the sky, dark and read noise of 25 pixels take the rest); faint ones are
  // sky- and read-noise limited (noise independent of the source).
  EXPECT_LT(rows[0].snr, std::sqrt(rows[0].signal_e));
  EXPECT_GT(rows[0].snr, 0.8 * std::sqrt(rows[0].signal_e));
  EXPECT_NEAR(rows[8].noise_e / rows[7].noise_e, 1.0, 0.1);
  // Targets (after the 9 stars): per profile and phase, 50, 100, 150 km.
  const std::size_t t0 = std::size(star_v);
  auto target = [&](bool flight, int phase, int range) -> const SnrRow& {
    return rows[t0 + static_cast<std::size_t>((flight ? 6 : 0) + phase * 3 + range)];
  };
  for (const bool flight : {false, true}) {
    for (int p = 0; p < 2; ++p) {
      EXPECT_LT(target(flight, p, 1).snr, target(flight, p, 0).snr);
      EXPECT_LT(target(flight, p, 2).snr, target(flight, p, 1).snr);
      for (int r = 0; r < 3; ++r) EXPECT_LT(target(true, p, r).snr, target(false, p, r).snr);
    }
  }
  // The paper's picture: the nominal 50 km target is well detected at any of
  // these phases, the flight-like 150 km one at 90 deg phase is not.
  // (Measured ~110 and ~55 for the former, ~2.6 for the latter; asserted
  // with margin.)
  EXPECT_GT(target(false, 0, 0).snr, 2 * 5.0);
  EXPECT_GT(target(false, 1, 0).snr, 2 * 5.0);
  EXPECT_LT(target(true, 1, 2).snr, 0.8 * 5.0);
}

}  // namespace
}  // namespace artms::imaging

namespace artms::imaging {
namespace {

// A horizontal boresight (velocity direction) at 7000 km from the Earth's
// centre: the limb is ~21 deg below it, 6 deg beyond a 15 deg exclusion.
RenderRequest limb_request() {
  RenderRequest req;
  req.observer = "SV2";
  req.t = astro::TimeTT{0};
  req.observer_eci.r_m = dynamics::Vec3(7.0e6, 0.0, 0.0);
  req.observer_eci.v_mps = dynamics::Vec3(0.0, 7.5e3, 0.0);
  // Camera z = ECI +y (velocity), x = ECI +z, y = z cross x = ECI +x (up:
  // image rows grow away from the Earth).
  Eigen::Matrix3d R_cam_from_eci;
  R_cam_from_eci.row(0) = Eigen::RowVector3d(0, 0, 1);
  R_cam_from_eci.row(1) = Eigen::RowVector3d(1, 0, 0);
  R_cam_from_eci.row(2) = Eigen::RowVector3d(0, 1, 0);
  req.q_cam_from_eci = Eigen::Quaterniond(R_cam_from_eci);
  return req;
}

double mean_dn(const std::vector<std::uint16_t>& px) {
  double s = 0.0;
  for (const auto v : px) s += v;
  return s / static_cast<double>(px.size());
}

// Earth-limb stray light (camera file stray_light.earth_edge_e_per_px_per_s):
// present when the limb below the boresight is sunlit, absent when it is in
// night, brighter towards the Earth (image +y is away from the Earth here:
// camera y = ECI +x = up), and absent with the key at 0. The renderer also
// writes DN shifted by sensor.dn_shift_bits.
TEST(RendererRealism, EarthLimbStrayLightFollowsTheSunAndPixelEncodingShifts) {
  CameraModel cam = CameraModel::load(std::string(ARTMS_CONFIG_DIR) + "/cameras/nst_ideal.yaml");
  cam.hot_pixel_count = 0;
  cam.stray_earth_edge_e_per_px_per_s = 500.0;
  RenderOptions opt;
  opt.noise = NoiseOptions::noise_free();
  opt.faint_stars = false;
  const FrameRenderer lit(cam, StarCatalog{}, opt);
  RenderRequest req = limb_request();
  // Find a time when the Sun is near +x (limb below the boresight sunlit at
  // noon) and one when it is near -x, from the ephemeris, over a year.
  astro::TimeTT t_day{0}, t_night{0};
  double best_day = -2.0, best_night = 2.0;
  for (int d = 0; d < 365; ++d) {
    const astro::TimeTT t{static_cast<std::int64_t>(d) * 86400LL * 1000000000LL};
    const double c = dynamics::sun_position_eci_m(t).normalized().x();
    if (c > best_day) best_day = c, t_day = t;
    if (c < best_night) best_night = c, t_night = t;
  }
  req.t = t_day;
  const RenderedFrame day = lit.render(req);
  req.t = t_night;
  const RenderedFrame night = lit.render(req);
  cam.stray_earth_edge_e_per_px_per_s = 0.0;
  const FrameRenderer off(cam, StarCatalog{}, opt);
  req.t = t_day;
  const RenderedFrame none = off.render(req);
  ASSERT_FALSE(day.exclusion.excluded);
  // 500 e-/px/s at the edge, 6 deg beyond with a 4 deg falloff, 0.2 s,
  // 2.4 e-/DN: ~9 DN at the centre, times cos(zenith) ~0.9.
  const double centre = static_cast<double>(day.pixels[512u * 1280u + 640u]) - none.pixels[512u * 1280u + 640u];
  EXPECT_GT(centre, 5.0);
  EXPECT_LT(centre, 12.0);
  EXPECT_NEAR(mean_dn(night.pixels), mean_dn(none.pixels), 0.01);
  // Towards the Earth (top rows, camera -y = ECI -x) brighter than away.
  EXPECT_GT(day.pixels[5u * 1280u + 640u], day.pixels[1018u * 1280u + 640u] + 20u);

  cam.dn_shift_bits = 4;
  const FrameRenderer shifted(cam, StarCatalog{}, opt);
  const RenderedFrame s = shifted.render(req);
  ASSERT_EQ(s.pixels.size(), none.pixels.size());
  for (std::size_t i = 0; i < s.pixels.size(); i += 997) EXPECT_EQ(s.pixels[i], none.pixels[i] << 4);
}

// Stellar aberration (RenderOptions::stellar_aberration): every star moves
// by the angle astro::aberrated_direction gives for the observer's velocity
// about the barycentre (the Earth's plus its own, up to ~26"), a target
// that moves with the observer does not.
TEST(RendererRealism, StarsCarryTheObserversAberrationTargetsDoNot) {
  const CameraModel cam = CameraModel::load(std::string(ARTMS_CONFIG_DIR) + "/cameras/nst_ideal.yaml");
  const StarCatalog catalog = StarCatalog::load_bsc5(std::string(ARTMS_DATA_DIR) + "/stars/bsc5.dat", 7.0);
  RenderOptions opt;
  opt.noise = NoiseOptions::noise_free();
  opt.faint_stars = false;
  const FrameRenderer plain(cam, catalog, opt);
  opt.stellar_aberration = true;
  const FrameRenderer aberrated(cam, catalog, opt);
  RenderRequest req = limb_request();
  req.t = astro::tt_from_utc_string("2024-05-08T00:00:00Z");
  req.targets.push_back({"SV4", req.observer_eci.r_m + dynamics::Vec3(0.0, 50e3, 300.0)});
  const RenderedFrame a = plain.render(req), b = aberrated.render(req);
  const Eigen::Matrix3d R = req.q_cam_from_eci.toRotationMatrix();
  const dynamics::Vec3 v = dynamics::earth_velocity_bcrs_mps(req.t) + req.observer_eci.v_mps;
  int compared = 0;
  double worst = 0.0, largest = 0.0;
  for (const auto& sa : a.stars) {
    for (const auto& sb : b.stars) {
      if (sb.catalog_id != sa.catalog_id) continue;
      const Star* star = catalog.find(sa.catalog_id);
      ASSERT_NE(star, nullptr);
      const auto px = cam.project(R * astro::aberrated_direction(star->unit_eci_at(req.t), v));
      ASSERT_TRUE(px.has_value());
      worst = std::max(worst, std::hypot(sb.x_px - px->x(), sb.y_px - px->y()));
      largest = std::max(largest, std::hypot(sb.x_px - sa.x_px, sb.y_px - sa.y_px));
      ++compared;
    }
  }
  EXPECT_GE(compared, 5);
  EXPECT_LT(worst, 1e-6);
  // The shift itself: ~0.3-0.8 px on the NST (~25"/px) for this geometry.
  EXPECT_GT(largest * 206264.806 / cam.fx_px, 8.0);
  ASSERT_EQ(a.targets.size(), 1u);
  EXPECT_EQ(a.targets[0].x_px, b.targets[0].x_px);
  EXPECT_EQ(a.targets[0].y_px, b.targets[0].y_px);
}

}  // namespace
}  // namespace artms::imaging
