// Pyramid star identification and tracking: the k-vector against a linear
// scan, frames rendered by the truth-side renderer at random attitudes
// (success rate, attitude error, wrong answers), skies without a catalog
// match, and real star-field photographs with a ground-based solution.
#include "artms/imp/star_id.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <numbers>
#include <random>
#include <regex>
#include <stdexcept>
#include <vector>

#include "artms/astro/aberration.hpp"
#include "artms/astro/constants.hpp"
#include "artms/dynamics/ephemeris.hpp"
#include "artms/imp/detection.hpp"
#include "artms/imp/frame_processor.hpp"
#include "artms/testing/testing.hpp"
#include "imp_test_frames.hpp"

namespace artms::imp {
namespace {

using imp::testing::attitude_error_cam;
using imp::testing::bsc5;
using imp::testing::frame_epoch;
using imp::testing::intrinsics_of;
using imp::testing::nst_camera;
using imp::testing::random_attitude;
using imp::testing::star_id_catalog;

constexpr double kArcsec = astro::kDegToRad / 3600.0;
// Stars the NST-like camera detects reliably; BSC5 is complete to ~6.5.
constexpr double kCatalogVmag = 6.5;

double diagonal_fov(const imaging::CameraModel& cam) {
  return 2.0 * cam.half_diagonal_fov_rad();
}

const StarIdCatalog& nst_catalog() {
  static const StarIdCatalog cat =
      star_id_catalog(frame_epoch(), kCatalogVmag, diagonal_fov(nst_camera()));
  return cat;
}

std::vector<Vec3> unit_vectors(const DetectionResult& det, const Intrinsics& k) {
  std::vector<Vec3> out;
  for (const auto& c : det.centroids) out.push_back(k.unproject(Vec2(c.x_px, c.y_px)));
  return out;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

// ---------------------------------------------------------------------------
// Catalog and k-vector
// ---------------------------------------------------------------------------

TEST(StarIdCatalog, PairTableAndKVectorMatchALinearScan) {
  const StarIdCatalog& cat = nst_catalog();
  const auto& stars = cat.stars();
  const double cmin = std::cos(cat.max_pair_angle_rad());
  std::size_t brute = 0;
  for (std::size_t a = 0; a < stars.size(); ++a) {
    for (std::size_t b = a + 1; b < stars.size(); ++b)
      brute += stars[a].u_eci.dot(stars[b].u_eci) >= cmin ? 1U : 0U;
  }
  std::printf("[ figures ] star-ID catalog: %zu stars (V <= %.1f), %zu pairs within %.2f deg\n",
              stars.size(), kCatalogVmag, cat.pairs().size(),
              cat.max_pair_angle_rad() / astro::kDegToRad);
  EXPECT_EQ(cat.pairs().size(), brute);
  EXPECT_GT(stars.size(), 8000U);
  const auto& P = cat.pairs();
  ASSERT_TRUE(std::is_sorted(
      P.begin(), P.end(), [](const auto& x, const auto& y) { return x.cos_angle < y.cos_angle; }));
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(cmin - 0.002, 1.0005), w(0.0, 2e-4);
  for (int n = 0; n < 5000; ++n) {
    const double a = u(rng), b = a + w(rng);
    const auto [first, last] = cat.pairs_in_cos_range(a, b);
    const auto lo = std::lower_bound(P.begin(), P.end(), a,
                                     [](const auto& p, double v) { return p.cos_angle < v; });
    const auto hi = std::upper_bound(P.begin(), P.end(), b,
                                     [](double v, const auto& p) { return v < p.cos_angle; });
    ASSERT_EQ(first, static_cast<std::size_t>(lo - P.begin())) << a << " " << b;
    ASSERT_EQ(last, static_cast<std::size_t>(hi - P.begin())) << a << " " << b;
  }
  // Exact bounds taken from the table itself are inclusive.
  const auto [f1, l1] = cat.pairs_in_cos_range(P[1000].cos_angle, P[1000].cos_angle);
  EXPECT_LE(f1, 1000U);
  EXPECT_GT(l1, 1000U);
  EXPECT_EQ(cat.index_of(stars[17].id), 17);
  EXPECT_EQ(cat.index_of(-5), -1);
}

TEST(StarIdCatalog, RejectsBadInput) {
  EXPECT_THROW(StarIdCatalog::build({}, 0.2), std::invalid_argument);
  EXPECT_THROW(StarIdCatalog::build({{1, Vec3::UnitX()}, {1, Vec3::UnitY()}}, 0.2),
               std::invalid_argument);
  EXPECT_THROW(StarIdCatalog::build({{1, Vec3::UnitX()}}, 0.0), std::invalid_argument);
  EXPECT_THROW(StarIdCatalog::build({{1, Vec3::Zero()}}, 0.2), std::invalid_argument);
  StarIdOptions o;
  o.max_stars = 2;
  EXPECT_THROW(o.validate(), std::invalid_argument);
  o = {};
  o.match_tolerance_rad = 0.0;
  EXPECT_THROW(identify_lost_in_space({}, nst_catalog(), o), std::invalid_argument);
}

TEST(StarId, WahbaSvdRecoversARotation) {
  std::mt19937_64 rng(9);
  std::normal_distribution<double> n01;
  for (int t = 0; t < 20; ++t) {
    const Eigen::Quaterniond q = random_attitude(rng);
    std::vector<Vec3> b, r;
    for (int k = 0; k < 5; ++k) {
      r.push_back(Vec3(n01(rng), n01(rng), n01(rng)).normalized());
      b.push_back(q * r.back());
    }
    EXPECT_THAT(solve_wahba_svd(b, r), artms::testing::IsNearQuaternion(q, 1e-12));
  }
}

// ---------------------------------------------------------------------------
// Rendered frames
// ---------------------------------------------------------------------------

// One full-noise frame (catalog stars, faint uncatalogued stars V 6.6-9,
// hot pixels) at a random attitude, detected.
struct SolvedFrame {
  imaging::RenderedFrame frame;
  Eigen::Quaterniond q_true;
  DetectionResult det;
  std::vector<Vec3> b_cam;
};

const std::vector<SolvedFrame>& rendered_frames() {
  static const std::vector<SolvedFrame> frames = [] {
    const auto cam = nst_camera();
    const imaging::FrameRenderer renderer(cam, bsc5(), imaging::RenderOptions{});
    const Intrinsics k = intrinsics_of(cam);
    std::mt19937_64 rng(2024);
    std::vector<SolvedFrame> out;
    for (std::uint64_t i = 0; i < 30; ++i) {
      auto sky = imp::testing::render_random_sky(renderer, rng, i);
      SolvedFrame s;
      s.det = detect(sky.frame.pixels, sky.frame.width, sky.frame.height, DetectionOptions{});
      s.b_cam = unit_vectors(s.det, k);
      s.frame = std::move(sky.frame);
      s.q_true = sky.q_cam_from_eci;
      out.push_back(std::move(s));
    }
    return out;
  }();
  return frames;
}

// Is `id` an imaged catalog star within 1.5 px of the centroid? (Close
// doubles: a V 6.6 companion 0.1 px from a V 5.8 star is in the frame truth,
// but the centroid is the brighter star's.)
bool truly_near(const SolvedFrame& f, int centroid, int id) {
  const auto& c = f.det.centroids[static_cast<std::size_t>(centroid)];
  for (const auto& s : f.frame.stars) {
    if (s.catalog_id == id && std::hypot(s.x_px - c.x_px, s.y_px - c.y_px) < 1.5) return true;
  }
  return false;
}

struct Verdict {
  bool correct = false;
  int wrong_matches = 0;
  Eigen::Vector3d err;  // cross-boresight x, y and roll (rad)
};
Verdict judge(const SolvedFrame& f, const StarIdResult& r) {
  Verdict v;
  v.err = attitude_error_cam(r.q_cam_from_eci, f.q_true);
  for (const auto& [i, id] : r.matches) v.wrong_matches += truly_near(f, i, id) ? 0 : 1;
  v.correct = r.usable && v.wrong_matches == 0 && v.err.norm() < 60.0 * kArcsec;
  return v;
}

TEST(StarId, PyramidIdentifiesRenderedNstFramesAtRandomAttitudes) {
  const auto& frames = rendered_frames();
  int ok = 0, wrong = 0, failed = 0;
  double max_xb = 0.0, ss_x = 0.0, ss_y = 0.0, ss_roll = 0.0, max_roll = 0.0;
  std::vector<double> ms, tri, nmatch, ncent;
  const StarIdCatalog& cat = nst_catalog();  // built once, outside the timing
  for (const auto& f : frames) {
    const auto t0 = std::chrono::steady_clock::now();
    const StarIdResult r = identify_lost_in_space(f.b_cam, cat, StarIdOptions{});
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    tri.push_back(r.triangles_tried);
    ncent.push_back(static_cast<double>(f.b_cam.size()));
    if (!r.usable) {
      ++failed;
      std::printf("  not identified: %zu centroids, %zu catalog stars imaged: %s\n", f.b_cam.size(),
                  f.frame.stars.size(), r.why.c_str());
      continue;
    }
    const Verdict v = judge(f, r);
    if (!v.correct) {
      ++wrong;
      std::printf("  WRONG: error %.1f arcsec, %d wrong matches of %zu\n", v.err.norm() / kArcsec,
                  v.wrong_matches, r.matches.size());
      continue;
    }
    ++ok;
    nmatch.push_back(static_cast<double>(r.matches.size()));
    max_xb = std::max(max_xb, v.err.head<2>().norm());
    max_roll = std::max(max_roll, std::abs(v.err.z()));
    ss_x += v.err.x() * v.err.x();
    ss_y += v.err.y() * v.err.y();
    ss_roll += v.err.z() * v.err.z();
  }
  const double n = static_cast<double>(frames.size());
  const double sx = std::sqrt(ss_x / std::max(ok, 1)), sy = std::sqrt(ss_y / std::max(ok, 1));
  std::printf(
      "[ figures ] Pyramid on %zu rendered NST frames (full noise, hot pixels, faint uncatalogued "
      "stars; "
      "catalog V <= %.1f): success %.1f %%, wrong %d, failed %d; cross-boresight error 1-sigma "
      "%.2f / %.2f "
      "arcsec (x / y), max %.2f arcsec; roll 1-sigma %.1f arcsec, max %.1f arcsec; median %g "
      "centroids, "
      "%g stars matched, %g triangles; median %.2f ms, max %.2f ms\n",
      frames.size(), kCatalogVmag, 100.0 * ok / n, wrong, failed, sx / kArcsec, sy / kArcsec,
      max_xb / kArcsec, std::sqrt(ss_roll / std::max(ok, 1)) / kArcsec, max_roll / kArcsec,
      median(ncent), median(nmatch), median(tri), median(ms),
      *std::max_element(ms.begin(), ms.end()));
  EXPECT_GE(frames.size(), 20U);
  EXPECT_EQ(wrong, 0);
  EXPECT_GE(ok, static_cast<int>(0.95 * n));
  EXPECT_LT(max_xb, 10.0 * kArcsec);
  EXPECT_LT(sx, 3.0 * kArcsec);
  EXPECT_LT(sy, 3.0 * kArcsec);
}

// Bright false stars ahead of the real ones (targets, planets, glints: the
// brightest centroids are not always catalog stars): Pyramid's triangle
// order must get past them, and no false star may be matched.
TEST(StarId, PyramidGetsPastBrightFalseStars) {
  std::mt19937_64 rng(404);
  std::uniform_real_distribution<double> ux(-0.1, 0.1), uy(-0.08, 0.08);
  int ok = 0, wrong = 0, matched_false = 0;
  std::vector<double> tri, ms;
  const StarIdCatalog& cat = nst_catalog();
  for (const auto& f : rendered_frames()) {
    std::vector<Vec3> b;
    for (int k = 0; k < 4; ++k) b.push_back(Vec3(ux(rng), uy(rng), 1.0).normalized());
    b.insert(b.end(), f.b_cam.begin(), f.b_cam.end());
    const auto t0 = std::chrono::steady_clock::now();
    const StarIdResult r = identify_lost_in_space(b, cat, StarIdOptions{});
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    tri.push_back(r.triangles_tried);
    if (!r.usable) continue;
    const Eigen::Vector3d err = attitude_error_cam(r.q_cam_from_eci, f.q_true);
    bool bad = err.norm() > 60.0 * kArcsec;
    for (const auto& [i, id] : r.matches) {
      if (i < 4) {
        ++matched_false;
        bad = true;
      } else {
        bad = bad || !truly_near(f, i - 4, id);
      }
    }
    (bad ? wrong : ok) += 1;
  }
  const double n = static_cast<double>(rendered_frames().size());
  std::printf(
      "[ figures ] Pyramid with 4 bright false stars first: success %.1f %%, wrong %d, false stars "
      "matched "
      "%d; median %g triangles (max %g), median %.2f ms (max %.2f ms)\n",
      100.0 * ok / n, wrong, matched_false, median(tri), *std::max_element(tri.begin(), tri.end()),
      median(ms), *std::max_element(ms.begin(), ms.end()));
  EXPECT_EQ(wrong, 0);
  EXPECT_EQ(matched_false, 0);
  EXPECT_GE(ok, static_cast<int>(0.95 * n));
}

// Tracking from a prior attitude 0.1 deg off gives the lost-in-space answer.
TEST(StarId, TrackingAgreesWithLostInSpace) {
  std::mt19937_64 rng(77);
  std::normal_distribution<double> n01;
  int compared = 0, agree = 0;
  double worst = 0.0;
  std::vector<double> ms;
  for (const auto& f : rendered_frames()) {
    const StarIdResult lis = identify_lost_in_space(f.b_cam, nst_catalog(), StarIdOptions{});
    if (!lis.usable) continue;
    const Vec3 axis = Vec3(n01(rng), n01(rng), n01(rng)).normalized();
    const Eigen::Quaterniond prior =
        Eigen::Quaterniond(Eigen::AngleAxisd(0.1 * astro::kDegToRad, axis)) * f.q_true;
    const auto t0 = std::chrono::steady_clock::now();
    const StarIdResult trk =
        identify_with_prior(f.b_cam, nst_catalog(), prior, 0.3 * astro::kDegToRad);
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    ++compared;
    ASSERT_TRUE(trk.usable) << trk.why;
    const double d = trk.q_cam_from_eci.angularDistance(lis.q_cam_from_eci);
    worst = std::max(worst, d);
    agree += (trk.matches == lis.matches && d < 0.5 * kArcsec) ? 1 : 0;
  }
  std::printf(
      "[ figures ] tracking (prior 0.1 deg off, tolerance 0.3 deg) vs lost in space: %d of %d "
      "frames "
      "identical matches, max attitude difference %.3f arcsec, median %.3f ms\n",
      agree, compared, worst / kArcsec, median(ms));
  EXPECT_GE(compared, 20);
  EXPECT_EQ(agree, compared);
}

// Skies that match no catalog: random directions, and the mirror image of a
// real frame (same pair angles, opposite handedness). Any "identification"
// would be a wrong answer.
TEST(StarId, NoAnswerForRandomOrMirroredSkies) {
  std::mt19937_64 rng(31);
  std::uniform_real_distribution<double> ux(-0.1, 0.1), uy(-0.08, 0.08);
  int claimed = 0;
  for (int t = 0; t < 60; ++t) {
    std::vector<Vec3> b;
    for (int k = 0; k < 12; ++k) b.push_back(Vec3(ux(rng), uy(rng), 1.0).normalized());
    claimed += identify_lost_in_space(b, nst_catalog(), StarIdOptions{}).usable ? 1 : 0;
  }
  int mirrored = 0, mirrored_claimed = 0;
  for (const auto& f : rendered_frames()) {
    std::vector<Vec3> b = f.b_cam;
    for (auto& v : b) v.x() = -v.x();
    ++mirrored;
    const auto r = identify_lost_in_space(b, nst_catalog(), StarIdOptions{});
    mirrored_claimed += r.usable ? 1 : 0;
  }
  std::printf("[ figures ] no-answer skies: random %d of 60 claimed, mirrored %d of %d claimed\n",
              claimed, mirrored_claimed, mirrored);
  EXPECT_EQ(claimed, 0);
  EXPECT_EQ(mirrored_claimed, 0);
}

TEST(StarId, TooFewStarsIsNotUsable) {
  const std::vector<Vec3> b = {Vec3(0, 0, 1), Vec3(0.01, 0, 1).normalized(),
                               Vec3(0, 0.01, 1).normalized()};
  const auto r = identify_lost_in_space(b, nst_catalog(), StarIdOptions{});
  EXPECT_FALSE(r.usable);
  EXPECT_FALSE(r.why.empty());
  const auto t = identify_with_prior({}, nst_catalog(), Eigen::Quaterniond::Identity(), 0.01);
  EXPECT_FALSE(t.usable);
}

// ---------------------------------------------------------------------------
// Real images (esa/tetra3 test data, /work/shared/data/images)
// ---------------------------------------------------------------------------

// The three labelled frames ship with the tests (tests/data/real_images);
// the five unlabelled ones stay in the shared data folder.
const std::string kImages = std::string(ARTMS_TEST_DATA_DIR) + "/real_images";
const std::string kUnlabelled = kImages + "/unlabelled";

// A ground camera of the tetra3 data set as a user would describe it: 35 mm
// lens, 1024 x 768, focal length ~5116 px, principal point at the centre.
// Their pixel convention puts (0, 0) at the top-left corner of the first
// pixel (centre (0.5, 0.5)), ours at its centre: their x = our x + 0.5.
Intrinsics tetra3_intrinsics(double focal_px) {
  Intrinsics k;
  k.width = 1024;
  k.height = 768;
  k.fx = k.fy = focal_px;
  k.cx = 1024 / 2.0 - 0.5;
  k.cy = 768 / 2.0 - 0.5;
  return k;
}

DetectionOptions real_image_detection() {
  DetectionOptions o;
  o.saturation_dn = 65535.0;  // 16-bit PNG (12-bit data x 16)
  o.psf_sigma_px = 1.0;
  o.gain_e_per_dn = 1.0 / 16.0;  // unknown; only the reported sigma uses it
  return o;
}

StarIdOptions real_image_star_id() {
  StarIdOptions o;
  // Ground-based frames: refraction across the field, lens distortion not
  // calibrated, focal length known to ~0.05 %: tens of arcsec.
  o.match_tolerance_rad = 60.0 * kArcsec;
  return o;
}

const StarIdCatalog& real_image_catalog() {
  static const StarIdCatalog cat =
      star_id_catalog(astro::tt_from_utc_string("2019-07-29T20:47:26Z"), 6.5,
                      2.0 * tetra3_intrinsics(5116.0).half_diagonal_fov_rad());
  return cat;
}

struct RealSolution {
  bool usable = false;
  std::string why;
  Eigen::Quaterniond q;
  double ra_deg = 0.0, dec_deg = 0.0;
  int centroids = 0, matched = 0;
  double residual_arcsec = 0.0;
  std::vector<std::pair<int, int>> matches;
  DetectionResult det;
};

RealSolution solve_real(const std::string& path, double focal_px) {
  RealSolution s;
  const imaging::Image16 img = imaging::read_png16(path);
  s.det = detect(img.pixels, img.width, img.height, real_image_detection());
  s.centroids = static_cast<int>(s.det.centroids.size());
  const auto b = unit_vectors(s.det, tetra3_intrinsics(focal_px));
  const auto r = identify_lost_in_space(b, real_image_catalog(), real_image_star_id());
  s.usable = r.usable;
  s.why = r.why;
  if (!r.usable) return s;
  s.q = r.q_cam_from_eci;
  const Vec3 bore = r.q_cam_from_eci.inverse() * Vec3::UnitZ();
  s.ra_deg = std::atan2(bore.y(), bore.x()) / astro::kDegToRad;
  if (s.ra_deg < 0) s.ra_deg += 360.0;
  s.dec_deg = std::asin(bore.z()) / astro::kDegToRad;
  s.matched = static_cast<int>(r.matches.size());
  s.residual_arcsec = r.residual_rms_rad / kArcsec;
  s.matches = r.matches;
  return s;
}

Vec3 radec_unit(double ra_deg, double dec_deg) {
  const double ra = ra_deg * astro::kDegToRad, dec = dec_deg * astro::kDegToRad;
  return {std::cos(dec) * std::cos(ra), std::cos(dec) * std::sin(ra), std::sin(dec)};
}

TEST(StarIdRealImages, BoresightMatchesTheGroundSolution) {
  ASSERT_TRUE(std::filesystem::exists(kImages + "/truth.json")) << kImages << " (tests/data/real_images)";
  const auto truth = artms::testing::load_json(kImages + "/truth.json");
  int n = 0;
  for (const auto& [name, t] : truth.items()) {
    const std::string stem = name.substr(0, name.rfind('.'));
    const std::string png = kImages + "/tetra3_" + stem + ".png";
    ASSERT_TRUE(std::filesystem::exists(png)) << png;
    const RealSolution s = solve_real(png, 5116.0);
    ASSERT_TRUE(s.usable) << name << ": " << s.why << " (" << s.centroids << " centroids)";
    ++n;
    const double ra_t = t["boresight_ra_deg"], dec_t = t["boresight_dec_deg"];
    const double bore_err_deg =
        std::acos(
            std::clamp(radec_unit(s.ra_deg, s.dec_deg).dot(radec_unit(ra_t, dec_t)), -1.0, 1.0)) /
        astro::kDegToRad;
    // Their camera: x = boresight, y = W/2 - x_px (left), z = H/2 - y_px (up);
    // ours: x right, y down, z boresight. R_ours_from_theirs maps their axes.
    const auto& qv = t["q_cam_to_icrs_xyzw"];
    const Eigen::Quaterniond q_icrs_from_theirs(qv[3].get<double>(), qv[0].get<double>(),
                                                qv[1].get<double>(), qv[2].get<double>());
    Eigen::Matrix3d R_ours_from_theirs;
    R_ours_from_theirs << 0, -1, 0,  //
        0, 0, -1,                    //
        1, 0, 0;
    const Eigen::Quaterniond q_truth(R_ours_from_theirs *
                                     q_icrs_from_theirs.toRotationMatrix().transpose());
    const Vec3 err = attitude_error_cam(s.q, q_truth);
    // Matched stars against the ground solution's.
    std::map<int, int> truth_hr_near;  // our centroid -> their HR (within 2 px)
    int agree = 0, compared = 0;
    Vec2 offset = Vec2::Zero();  // their pixel coordinates - ours, mean over common stars
    for (const auto& ms : t["matched_stars"]) {
      const double x = ms["x"].get<double>() - 0.5, y = ms["y"].get<double>() - 0.5;
      for (std::size_t c = 0; c < s.det.centroids.size(); ++c) {
        if (std::hypot(s.det.centroids[c].x_px - x, s.det.centroids[c].y_px - y) < 2.0) {
          offset += Vec2(ms["x"].get<double>() - s.det.centroids[c].x_px,
                         ms["y"].get<double>() - s.det.centroids[c].y_px);
          for (const auto& [ci, id] : s.matches) {
            if (ci == static_cast<int>(c)) {
              ++compared;
              agree += id == ms["HR"].get<int>() ? 1 : 0;
            }
          }
        }
      }
    }
    std::printf(
        "[ figures ] real image %s: %d centroids, %d stars matched (ground solve %d), %d of %d "
        "common "
        "matches agree; boresight RA %.4f Dec %.4f deg vs %.4f %.4f: error %.4f deg; roll error "
        "%.1f "
        "arcsec; residual %.1f arcsec rms; their pixel coordinates - ours %.2f, %.2f px\n",
        stem.c_str(), s.centroids, s.matched, t["n_matched"].get<int>(), agree, compared, s.ra_deg,
        s.dec_deg, ra_t, dec_t, bore_err_deg, err.z() / kArcsec, s.residual_arcsec,
        offset.x() / std::max(compared, 1), offset.y() / std::max(compared, 1));
    EXPECT_LT(bore_err_deg, 0.05) << name;
    EXPECT_LT(std::abs(err.z()), 0.05 * astro::kDegToRad) << name;
    EXPECT_EQ(agree, compared) << name;
    EXPECT_GE(compared, 4) << name;
  }
  EXPECT_EQ(n, 3);
}

// The five frames without truth (and the three with) were taken from one site
// at one time, the mount pointed at the altitude and azimuth in the file
// names: one rotation must carry every (azimuth, altitude) into the solved
// (RA, Dec), to within the mount's pointing error (the ground solutions
// themselves differ from their nominal alt/az by ~1-2 deg).
TEST(StarIdRealImages, AllEightFramesAreSelfConsistent) {
  ASSERT_TRUE(std::filesystem::exists(kUnlabelled)) << kUnlabelled << " (tests/data/real_images/unlabelled)";
  std::vector<std::string> files;
  for (const auto& dir : {kImages, kUnlabelled}) {
    for (const auto& e : std::filesystem::directory_iterator(dir)) {
      if (e.path().extension() == ".png") files.push_back(e.path().string());
    }
  }
  std::sort(files.begin(), files.end());
  const std::regex re("Alt(-?[0-9]+)_Azi(-?[0-9]+)");
  std::vector<Vec3> horiz, sky;
  std::vector<std::string> names;
  for (const auto& f : files) {
    std::smatch m;
    ASSERT_TRUE(std::regex_search(f, m, re)) << f;
    const double alt = std::stod(m[1]) * astro::kDegToRad, az = std::stod(m[2]) * astro::kDegToRad;
    const RealSolution s = solve_real(f, 5116.0);
    ASSERT_TRUE(s.usable) << f << ": " << s.why << " (" << s.centroids << " centroids)";
    std::printf("  %s: %d centroids, %d matched, residual %.1f arcsec, RA %.3f Dec %.3f deg\n",
                std::filesystem::path(f).filename().c_str(), s.centroids, s.matched,
                s.residual_arcsec, s.ra_deg, s.dec_deg);
    // Horizon frame: x north, y west, z up (right-handed; azimuth from north
    // through east).
    horiz.push_back(
        Vec3(std::cos(alt) * std::cos(az), -std::cos(alt) * std::sin(az), std::sin(alt)));
    sky.push_back(radec_unit(s.ra_deg, s.dec_deg));
    names.push_back(std::filesystem::path(f).filename().string());
  }
  ASSERT_EQ(sky.size(), 8U);
  const Eigen::Quaterniond q_sky_from_horizon = solve_wahba_svd(sky, horiz);
  double worst = 0.0;
  for (std::size_t i = 0; i < sky.size(); ++i) {
    const Vec3 p = q_sky_from_horizon * horiz[i];
    worst = std::max(worst, std::acos(std::clamp(p.dot(sky[i]), -1.0, 1.0)));
  }
  const Vec3 zenith = q_sky_from_horizon * Vec3::UnitZ();
  std::printf(
      "[ figures ] 8 real frames, one site and time: worst pointing residual %.2f deg after one "
      "horizon-to-sky rotation; implied site latitude %.2f deg, local sidereal time %.2f h\n",
      worst / astro::kDegToRad, std::asin(zenith.z()) / astro::kDegToRad,
      std::fmod(std::atan2(zenith.y(), zenith.x()) / astro::kDegToRad + 360.0, 360.0) / 15.0);
  EXPECT_LT(worst, 3.0 * astro::kDegToRad);
}

// Lost in space with a focal length 1 % long (FrameProcessorOptions::
// focal_search_fraction): every rendered frame is identified and its scale
// refined; FrameSummary::focal_scale_information is the curvature that
// makes the frames' scale errors unit-variance: z_k = (s_k - s_true) /
// sqrt(sigma^2 / I_k), sigma^2 the per-axis bearing variance (rms^2 / 2 of
// the frame's star residuals).
TEST(StarId, FocalSearchRefinesTheScaleWithItsInformation) {
  const auto cam = nst_camera();
  Intrinsics k = intrinsics_of(cam);
  k.fx *= 1.01;
  k.fy *= 1.01;
  const double s_true = 1.0 / 1.01;
  FrameProcessorOptions opt;
  opt.focal_search_fraction = 0.03;
  FrameProcessor processor(k, nst_catalog(), opt);
  const auto& frames = rendered_frames();
  int solved = 0;
  double z2 = 0.0, sw = 0.0, w = 0.0;
  for (std::size_t i = 0; i < 12; ++i) {
    const astro::TimeTT t = frame_epoch().plus_seconds(600.0 * static_cast<double>(i));
    const FrameSummary s = processor.process(frames[i].frame.pixels, t);
    if (s.status != "ok") continue;
    ++solved;
    ASSERT_GT(s.focal_scale_information, 0.0);
    const double sigma2 = 0.5 * s.residual_rms_rad * s.residual_rms_rad;
    const double z = (s.focal_scale - s_true) / std::sqrt(sigma2 / s.focal_scale_information);
    std::printf("  frame %zu: %d stars, scale error %+.1f ppm, 1-sigma %.1f ppm, z %+.2f\n", i, s.stars_matched,
                1e6 * (s.focal_scale - s_true), 1e6 * std::sqrt(sigma2 / s.focal_scale_information), z);
    z2 += z * z;
    sw += s.focal_scale * s.focal_scale_information / sigma2;
    w += s.focal_scale_information / sigma2;
  }
  ASSERT_GE(solved, 10);
  std::printf("[ figures ] %d frames with the focal length 1 %% long: rms z %.2f; weighted mean scale error %+.1f ppm "
              "(1-sigma %.1f ppm)\n",
              solved, std::sqrt(z2 / solved), 1e6 * (sw / w - s_true), 1e6 / std::sqrt(w));
  // The information is neither far too large nor far too small.
  EXPECT_GT(std::sqrt(z2 / solved), 0.4);
  EXPECT_LT(std::sqrt(z2 / solved), 2.5);
  EXPECT_LT(std::abs(sw / w - s_true), 4.0 / std::sqrt(w));
}

// The blend check against a catalog deeper than the identification one
// (FrameProcessor::set_blend_stars): a candidate on a rendered star too faint
// for the identification catalog (V > 6.5) is flagged on_catalog_star and its
// sigma carries blend_sigma_px; without the deeper catalog it is not (in
// starling_pse_flight a V 6.53 star 1.1 px from SV2 moved its centroid 15").
TEST(FrameProcessorBlends, ACandidateOnAStarTooFaintToIdentifyIsABlend) {
  const auto cam = nst_camera();
  const Intrinsics k = intrinsics_of(cam);
  std::vector<Eigen::Vector3d> all;
  for (const auto& st : bsc5().stars()) all.push_back(st.unit_eci_at(frame_epoch()));
  FrameProcessor plain(k, nst_catalog());
  FrameProcessor deep(k, nst_catalog());
  deep.set_blend_stars(all);
  const auto& frames = rendered_frames();
  int on_faint = 0, flagged_deep = 0, flagged_plain = 0, others_flagged = 0;
  for (std::size_t i = 0; i < 12; ++i) {
    const astro::TimeTT t = frame_epoch().plus_seconds(3600.0 * static_cast<double>(i));
    const FrameSummary a = plain.process(frames[i].frame.pixels, t);
    const FrameSummary b = deep.process(frames[i].frame.pixels, t);
    if (a.status != "ok" || b.status != "ok") continue;
    ASSERT_EQ(a.candidates.size(), b.candidates.size());
    for (std::size_t c = 0; c < b.candidates.size(); ++c) {
      bool faint_star = false;
      for (const auto& st : frames[i].frame.stars) {
        if (st.vmag > kCatalogVmag && std::hypot(st.x_px - b.candidates[c].x_px, st.y_px - b.candidates[c].y_px) < 1.0)
          faint_star = true;
      }
      if (faint_star) {
        ++on_faint;
        flagged_deep += b.candidates[c].on_catalog_star ? 1 : 0;
        flagged_plain += a.candidates[c].on_catalog_star ? 1 : 0;
        EXPECT_GE(b.candidates[c].sigma_rad, FrameProcessorOptions{}.blend_sigma_px / k.fx);
      } else if (b.candidates[c].on_catalog_star && !a.candidates[c].on_catalog_star) {
        ++others_flagged;  // a faint star within blend_radius_px of another candidate
      }
    }
  }
  std::printf("[ figures ] %d candidates on stars fainter than V %.1f: %d flagged with the deep catalog, %d without\n",
              on_faint, kCatalogVmag, flagged_deep, flagged_plain);
  ASSERT_GE(on_faint, 5);
  EXPECT_EQ(flagged_deep, on_faint);
  EXPECT_EQ(flagged_plain, 0);
  EXPECT_LE(others_flagged, on_faint);
}

// The faint-star check of single detections looks at the frames before too
// (FrameProcessor::source_before): a star seen in frame i, at its inertial
// direction, is still found there after frame i + 1 (another attitude) has
// been processed; an empty direction is not; a direction off frame i's
// sensor cannot be checked, nor anything when no frame is kept.
TEST(FrameProcessorFaintStars, TheFramesBeforeAreCheckedAtTheSameInertialDirection) {
  const auto cam = nst_camera();
  const Intrinsics k = intrinsics_of(cam);
  const auto& frames = rendered_frames();
  int checked = 0;
  for (std::size_t i = 0; i + 1 < frames.size() && checked < 4; ++i) {
    FrameProcessor p(k, nst_catalog());
    FrameProcessor forgetful(k, nst_catalog());
    p.keep_recent_frames(2);
    const astro::TimeTT t0 = frame_epoch();
    const FrameSummary a = p.process(frames[i].frame.pixels, t0);
    (void)forgetful.process(frames[i].frame.pixels, t0);
    if (!a.attitude_usable) continue;
    // A star fainter than the identification catalog, away from the edges and from other stars.
    const imaging::StarTruth* faint = nullptr;
    for (const auto& st : frames[i].frame.stars) {
      if (st.vmag <= kCatalogVmag || st.vmag > 7.5 || st.x_px < 60 || st.y_px < 60 || st.x_px > k.width - 60 ||
          st.y_px > k.height - 60)
        continue;
      bool alone = true;
      for (const auto& o : frames[i].frame.stars)
        if (&o != &st && std::hypot(o.x_px - st.x_px, o.y_px - st.y_px) < 40.0) alone = false;
      if (alone) faint = &st;
    }
    if (!faint) continue;
    const Eigen::Matrix3d R_eci_from_cam = a.q_cam_from_eci.toRotationMatrix().transpose();
    const Eigen::Vector3d u_star = (R_eci_from_cam * k.unproject({faint->x_px, faint->y_px})).normalized();
    const Eigen::Vector3d u_empty = (R_eci_from_cam * k.unproject({faint->x_px + 25.0, faint->y_px})).normalized();
    const Eigen::Vector3d u_off = (R_eci_from_cam * k.unproject({-200.0, faint->y_px})).normalized();
    const AidedDetectionOptions o;
    ASSERT_EQ(p.source_at(frames[i].frame.pixels, u_star, o), std::optional<bool>(true));
    EXPECT_FALSE(p.source_before(u_star, o).has_value());  // nothing before frame i
    const FrameSummary b = p.process(frames[i + 1].frame.pixels, t0.plus_seconds(60.0));
    (void)forgetful.process(frames[i + 1].frame.pixels, t0.plus_seconds(60.0));
    if (!b.attitude_usable) continue;
    EXPECT_EQ(p.source_before(u_star, o), std::optional<bool>(true)) << i;
    EXPECT_EQ(p.source_before(u_empty, o), std::optional<bool>(false)) << i;
    if (!p.source_at(frames[i + 1].frame.pixels, u_off, o).has_value()) {
      EXPECT_FALSE(p.source_before(u_off, o).has_value()) << i;
    }
    EXPECT_FALSE(forgetful.source_before(u_star, o).has_value()) << i;
    ++checked;
  }
  EXPECT_EQ(checked, 4);
}

// The stacked sky of a single detection (FrameProcessor::stacked_sky): two
// rendered frames whose attitudes differ by 4 deg about the camera's x axis
// (a minute of an along-track camera's turn with its orbit); the detection
// in the first, the stack from the second, where the sky under the detection
// lies some 400 px away. A faint star of matched-filter nu 5 (peak 2.3 noise
// sigmas, below detect()'s threshold) is put into the second frame at empty
// directions: the stack finds it at the direction, and as a neighbour 3 px
// beside it; without it the direction is quiet, and so is one whose annulus
// holds a hot pixel. The detection's own frame is never stacked.
TEST(FrameProcessorFaintStars, TheStackedSkyFindsAFaintStarAtOrBesideADetection) {
  const auto cam = nst_camera();
  const Intrinsics k = intrinsics_of(cam);
  const imaging::FrameRenderer renderer(cam, bsc5(), imaging::RenderOptions{});
  std::mt19937_64 rng(77);
  constexpr double kNu = 5.0, kPsf = 1.2;
  int tried = 0, at_star = 0, beside_star = 0, quiet = 0, hot_tried = 0, hot_quiet = 0;
  for (std::uint64_t i = 0; i < 8; ++i) {
    const auto a = imp::testing::render_random_sky(renderer, rng, 100 + 2 * i);
    imaging::RenderRequest req;
    req.observer = "SV4";
    req.frame_index = 101 + 2 * i;
    req.t = frame_epoch().plus_seconds(60.0);
    req.observer_eci.r_m = astro::Vec3(4000e3, -5000e3, 2500e3);
    req.observer_eci.v_mps = astro::Vec3(5.0e3, 4.0e3, 0.5e3).normalized() * 7.5e3;
    req.q_cam_from_eci =
        Eigen::Quaterniond(Eigen::AngleAxisd(4.0 * std::numbers::pi / 180.0, Eigen::Vector3d::UnitX())) *
        a.q_cam_from_eci;
    const imaging::RenderedFrame b = renderer.render(req);
    if (b.exclusion.excluded || b.dropped) continue;
    const DetectionResult da = detect(a.frame.pixels, k.width, k.height, DetectionOptions{});
    const DetectionResult db = detect(b.pixels, k.width, k.height, DetectionOptions{});
    const auto clear = [](const DetectionResult& d, const Eigen::Vector2d& px) {
      return std::none_of(d.centroids.begin(), d.centroids.end(),
                          [&](const Centroid& c) { return std::hypot(c.x_px - px.x(), c.y_px - px.y()) < 25.0; });
    };
    for (const Eigen::Vector2d& pa : {Eigen::Vector2d(300.0, 500.0), Eigen::Vector2d(640.5, 512.3),
                                     Eigen::Vector2d(980.2, 520.7)}) {
      FrameProcessor p(k, nst_catalog()), plain(k, nst_catalog());
      p.keep_recent_frames(2);
      plain.keep_recent_frames(2);
      const FrameSummary sa = p.process(a.frame.pixels, frame_epoch());
      (void)plain.process(a.frame.pixels, frame_epoch());
      if (!sa.attitude_usable || !clear(da, pa)) continue;
      const Eigen::Matrix3d Ra = sa.q_cam_from_eci.toRotationMatrix().transpose();
      const Eigen::Vector3d u = (Ra * k.unproject(pa)).normalized();
      const Eigen::Vector2d pa_beside = pa + Eigen::Vector2d(3.0, 0.0);
      const Eigen::Vector3d u_beside = (Ra * k.unproject(pa_beside)).normalized();
      // The faint star in frame b, where the true attitude puts u.
      const auto pb = k.project(req.q_cam_from_eci.toRotationMatrix() * u);
      if (!pb || pb->x() < 40 || pb->y() < 40 || pb->x() > k.width - 40 || pb->y() > k.height - 40 || !clear(db, *pb))
        continue;
      std::vector<std::uint16_t> with_star = b.pixels;
      const double flux = kNu * db.noise_dn * std::sqrt(4.0 * std::numbers::pi) * kPsf;
      for (int y = static_cast<int>(pb->y()) - 6; y <= static_cast<int>(pb->y()) + 6; ++y)
        for (int x = static_cast<int>(pb->x()) - 6; x <= static_cast<int>(pb->x()) + 6; ++x) {
          const double dx = x - pb->x(), dy = y - pb->y();
          auto& v = with_star[static_cast<std::size_t>(y) * static_cast<std::size_t>(k.width) + static_cast<std::size_t>(x)];
          v = static_cast<std::uint16_t>(std::lround(v + flux / (2.0 * std::numbers::pi * kPsf * kPsf) *
                                                           std::exp(-0.5 * (dx * dx + dy * dy) / (kPsf * kPsf))));
        }
      const FrameSummary sb = p.process(with_star, frame_epoch().plus_seconds(60.0));
      (void)plain.process(b.pixels, frame_epoch().plus_seconds(60.0));
      if (!sb.attitude_usable) continue;
      const AidedDetectionOptions o;
      const auto s_at = p.stacked_sky(with_star, u, pa, o, 6.0, 0.01);
      const auto s_beside = p.stacked_sky(with_star, u_beside, pa_beside, o, 6.0, 0.01);
      const auto s_quiet = plain.stacked_sky(b.pixels, u, pa, o, 6.0, 0.01);
      // A hot pixel of frame b (fixed on the sensor) 4.5 px from where the
      // sky under a detection lands: its light reaches the annulus through
      // the kernel's wings, and it is not a neighbour.
      for (const std::size_t idx : db.hot_suspects) {
        const Eigen::Vector2d hot(static_cast<double>(idx % static_cast<std::size_t>(k.width)),
                                  static_cast<double>(idx / static_cast<std::size_t>(k.width)));
        const Eigen::Vector2d pb_hot = hot - Eigen::Vector2d(4.5, 0.0);
        if (pb_hot.x() < 40 || pb_hot.y() < 40 || pb_hot.x() > k.width - 40 || pb_hot.y() > k.height - 40) continue;
        const Eigen::Vector3d u_hot =
            (req.q_cam_from_eci.toRotationMatrix().transpose() * k.unproject(pb_hot)).normalized();
        const auto pa_hot = k.project(sa.q_cam_from_eci.toRotationMatrix() * u_hot);
        if (!pa_hot) continue;
        const auto s_hot = plain.stacked_sky(b.pixels, u_hot, *pa_hot, o, 6.0, 0.01);
        if (!s_hot || s_hot->frames != 1) continue;
        ++hot_tried;
        if (s_hot->snr_at < 3.0 && s_hot->neighbour_snr < s_hot->neighbour_threshold) ++hot_quiet;
        break;
      }
      ASSERT_TRUE(s_at && s_beside && s_quiet);
      EXPECT_EQ(s_at->frames, 1);  // frame b only: frame a holds the detection
      ++tried;
      if (s_at->snr_at >= 3.0) ++at_star;
      if (s_beside->snr_at < 3.0 && s_beside->neighbour_snr >= s_beside->neighbour_threshold) ++beside_star;
      if (s_quiet->snr_at < 3.0 && s_quiet->neighbour_snr < s_quiet->neighbour_threshold) ++quiet;
    }
  }
  std::printf("[ figures ] stacked sky from one other frame, a star of nu %.0f put at %d directions: found at %d, "
              "beside %d; %d quiet without it; %d of %d quiet beside a hot pixel\n", kNu, tried, at_star,
              beside_star, quiet, hot_quiet, hot_tried);
  // Noise alone misses nu 5 at 3 in 2.3 % of the cases and at the annulus
  // threshold (3.7) in 10 %; a real faint star of the rendered sky may sit
  // in an annulus said to be quiet.
  ASSERT_GE(tried, 8);
  EXPECT_GE(at_star, 0.85 * tried);
  EXPECT_GE(beside_star, 0.8 * tried);
  EXPECT_GE(quiet, tried - 2);
  ASSERT_GE(hot_tried, 5);
  EXPECT_GE(hot_quiet, hot_tried - 1);
}

// The stacked aided search (FrameProcessor::stacked_aided_candidate): four
// rendered frames a minute apart whose attitudes turn 4 deg a frame about
// the camera's x axis (an along-track camera turning with its orbit; the
// stars cross ~400 px a frame), a target the camera holds near one pixel
// (drifting 0.3 px a frame) of matched-filter nu 3.2 in each frame, below
// the aided threshold of one frame (4.7 for this prediction) and 6.4 in the
// sum of four. The prediction is 0.4 px off in every frame: the stack
// finds the target where it is in the last frame, within its 1-sigma. With
// a source of nu 7 on the target in one frame (a star crossing; 10 in all,
// about detect()'s threshold) the stack is refused as that frame's light;
// predictions whose times are not the kept frames' are refused.
TEST(FrameProcessorStackedAided, AFaintTargetIsFoundOnFourFramesAndASourceInOneIsNot) {
  const auto cam = nst_camera();
  const Intrinsics k = intrinsics_of(cam);
  const imaging::FrameRenderer renderer(cam, bsc5(), imaging::RenderOptions{});
  std::mt19937_64 rng(91);
  constexpr double kNu = 3.2, kStarNu = 7.0, kPsf = 1.2;
  constexpr int kFrames = 4;
  const Eigen::Vector2d off(0.4, -0.3);
  const Eigen::Matrix2d cov = 0.25 * Eigen::Matrix2d::Identity();
  int trials = 0, found = 0, single_found = 0, star_trials = 0, star_found = 0, star_one_frame = 0;
  int found_blended = 0, neighbour_found = 0, neighbour_blended = 0;
  double sum_z2 = 0.0, max_z = 0.0;
  const auto add_spot = [&](std::vector<std::uint16_t>& px, const Eigen::Vector2d& at, double nu, double noise) {
    const double flux = nu * noise * std::sqrt(4.0 * std::numbers::pi) * kPsf;
    for (int y = static_cast<int>(at.y()) - 6; y <= static_cast<int>(at.y()) + 6; ++y)
      for (int x = static_cast<int>(at.x()) - 6; x <= static_cast<int>(at.x()) + 6; ++x) {
        // The Gaussian integrated over the pixel.
        const auto cdf = [&](double u) { return 0.5 * std::erfc(-u / (kPsf * std::sqrt(2.0))); };
        const double f = (cdf(x + 0.5 - at.x()) - cdf(x - 0.5 - at.x())) * (cdf(y + 0.5 - at.y()) - cdf(y - 0.5 - at.y()));
        auto& v = px[static_cast<std::size_t>(y) * static_cast<std::size_t>(k.width) + static_cast<std::size_t>(x)];
        v = static_cast<std::uint16_t>(std::lround(v + flux * f));
      }
  };
  for (std::uint64_t i = 0; i < 12; ++i) {
    const auto a = imp::testing::render_random_sky(renderer, rng, 300 + 10 * i);
    std::vector<std::vector<std::uint16_t>> frames{a.frame.pixels};
    bool clear = !a.frame.exclusion.excluded;
    for (int j = 1; j < kFrames && clear; ++j) {
      imaging::RenderRequest req;
      req.observer = "SV4";
      req.frame_index = 300 + 10 * i + static_cast<std::uint64_t>(j);
      req.t = frame_epoch().plus_seconds(60.0 * j);
      req.observer_eci.r_m = astro::Vec3(4000e3, -5000e3, 2500e3);
      req.observer_eci.v_mps = astro::Vec3(5.0e3, 4.0e3, 0.5e3).normalized() * 7.5e3;
      req.q_cam_from_eci =
          Eigen::Quaterniond(Eigen::AngleAxisd(4.0 * j * std::numbers::pi / 180.0, Eigen::Vector3d::UnitX())) *
          a.q_cam_from_eci;
      const imaging::RenderedFrame f = renderer.render(req);
      clear = !f.exclusion.excluded && !f.dropped;
      frames.push_back(f.pixels);
    }
    if (!clear) continue;
    // The target's true pixels, clear of every frame's detections.
    std::vector<Eigen::Vector2d> truth;
    std::vector<double> noise;
    for (int j = 0; j < kFrames; ++j) {
      truth.emplace_back(640.3 + 0.3 * j, 400.6 - 0.2 * j);
      const DetectionResult d = detect(frames[static_cast<std::size_t>(j)], k.width, k.height, DetectionOptions{});
      noise.push_back(d.noise_dn);
      for (const auto& c : d.centroids)
        if (std::hypot(c.x_px - truth.back().x(), c.y_px - truth.back().y()) < 25.0) clear = false;
    }
    if (!clear) continue;
    auto with_target = frames;
    for (int j = 0; j < kFrames; ++j) {
      add_spot(with_target[static_cast<std::size_t>(j)], truth[static_cast<std::size_t>(j)], kNu, noise[static_cast<std::size_t>(j)]);
    }
    auto with_star = with_target;
    add_spot(with_star[2], truth[2], kStarNu, noise[2]);
    // A source detect() finds, 5 px from the target in an earlier frame
    // (outside the search's 4 px avoidance, inside the 6 px blend radius).
    auto with_neighbour = with_target;
    add_spot(with_neighbour[1], truth[1] + Eigen::Vector2d(3.0, 4.0), 40.0, noise[1]);
    FrameProcessor p(k, nst_catalog()), q(k, nst_catalog()), r(k, nst_catalog());
    p.keep_recent_frames(kFrames);
    q.keep_recent_frames(kFrames);
    r.keep_recent_frames(kFrames);
    std::vector<FrameProcessor::StackedPrediction> predictions;
    for (int j = 0; j < kFrames; ++j) {
      const astro::TimeTT t = frame_epoch().plus_seconds(60.0 * j);
      const FrameSummary sp = p.process(with_target[static_cast<std::size_t>(j)], t);
      const FrameSummary sq = q.process(with_star[static_cast<std::size_t>(j)], t);
      const FrameSummary sr = r.process(with_neighbour[static_cast<std::size_t>(j)], t);
      if (!sp.attitude_usable || !sq.attitude_usable || !sr.attitude_usable) clear = false;
      predictions.insert(predictions.begin(), {t.seconds_since_j2000(), truth[static_cast<std::size_t>(j)] + off});
    }
    if (!clear) continue;
    const AidedDetectionOptions o;
    ++trials;
    if (p.aided_candidate(with_target.back(), predictions[0].px, cov, o)) ++single_found;
    std::string why;
    const auto c = p.stacked_aided_candidate(with_target.back(), predictions, cov, o, &why);
    if (c) {
      ++found;
      if (c->blended) ++found_blended;
      EXPECT_EQ(c->stacked_frames, kFrames);
      const double sigma_px = c->sigma_rad * k.fx;
      const double zx = (c->x_px - truth.back().x()) / sigma_px, zy = (c->y_px - truth.back().y()) / sigma_px;
      sum_z2 += 0.5 * (zx * zx + zy * zy);
      max_z = std::max({max_z, std::abs(zx), std::abs(zy)});
    }
    // The neighbour's light is in the sum: the stack is a blend, its
    // 1-sigma widened.
    if (const auto b = r.stacked_aided_candidate(with_neighbour.back(), predictions, cov, o, &why)) {
      ++neighbour_found;
      if (b->blended) ++neighbour_blended;
      if (c && !c->blended) {
        EXPECT_GT(b->sigma_rad, c->sigma_rad);
      }
    }
    // Wrong times: the kept frames are not the predictions'.
    auto shifted = predictions;
    shifted[2].t_s += 1.0;
    EXPECT_FALSE(p.stacked_aided_candidate(with_target.back(), shifted, cov, o, &why));
    EXPECT_EQ(why, "frames not kept");
    ++star_trials;
    if (q.stacked_aided_candidate(with_star.back(), predictions, cov, o, &why)) {
      ++star_found;
    } else if (why == "one frame's source") {
      ++star_one_frame;
    }
  }
  std::printf("[ figures ] %d trials: found in one frame %d, on four stacked frames %d (mean (error / sigma)^2 %.2f, "
              "max |error / sigma| %.2f); with a nu %.0f source in one frame too: found %d, refused as one frame's %d\n",
              trials, single_found, found, found ? sum_z2 / found : 0.0, max_z, kStarNu, star_found, star_one_frame);
  std::printf("[ figures ] blends: %d of %d stacks without the neighbour, %d of %d with a nu 40 source 5 px from "
              "the target in an earlier frame\n",
              found_blended, found, neighbour_blended, neighbour_found);
  ASSERT_GE(trials, 6);
  EXPECT_GE(neighbour_found, trials / 2);
  EXPECT_EQ(neighbour_blended, neighbour_found);
  EXPECT_LE(found_blended, 1);
  EXPECT_LE(single_found, trials / 3);
  EXPECT_GE(found, trials - 2);
  EXPECT_LT(max_z, 3.5);
  EXPECT_LT(sum_z2 / std::max(found, 1), 2.0);
  // The frame's excess, 7 +- 1.15, stays under kStackOneFrameExcess (5) in
  // 4 % of the trials; the source is found by detect() in its frame (then
  // avoided) in about a third.
  EXPECT_LE(star_found, 1);
  EXPECT_GE(star_one_frame, star_trials / 2);
}

}  // namespace
}  // namespace artms::imp

namespace artms::imp {
namespace {

// Stellar aberration (FrameProcessor::process's observer velocity): on
// frames whose stars carry the observer's aberration (the renderer's
// RenderOptions::stellar_aberration), the attitude solved with the same
// velocity is as good as on unaberrated frames, and without it is off by
// the aberration (~10-26" across the boresight for an observer in LEO).
TEST(FrameProcessorAberration, TheObserversVelocityTakesTheAberrationOutOfTheAttitude) {
  using imp::testing::attitude_error_cam;
  const auto cam = imp::testing::nst_camera();
  imaging::RenderOptions ro;
  ro.stellar_aberration = true;
  const imaging::FrameRenderer renderer(cam, imp::testing::bsc5(), ro);
  const Intrinsics k = imp::testing::intrinsics_of(cam);
  std::mt19937_64 rng(2026);
  double worst_with = 0.0, rms_with = 0.0;
  int solved = 0;
  for (std::uint64_t i = 0; i < 8; ++i) {
    const auto sky = imp::testing::render_random_sky(renderer, rng, 100 + i);
    // The observer of render_random_sky (imp_test_frames.hpp).
    const Eigen::Vector3d v = dynamics::earth_velocity_bcrs_mps(imp::testing::frame_epoch()) +
                              Eigen::Vector3d(5.0e3, 4.0e3, 0.5e3).normalized() * 7.5e3;
    FrameProcessor with(k, nst_catalog()), without(k, nst_catalog());
    const FrameSummary a = with.process(sky.frame.pixels, imp::testing::frame_epoch(), v);
    const FrameSummary b = without.process(sky.frame.pixels, imp::testing::frame_epoch());
    if (a.status != "ok" || b.status != "ok") continue;
    ++solved;
    const Eigen::Vector3d ea = attitude_error_cam(a.q_cam_from_eci, sky.q_cam_from_eci);
    const Eigen::Vector3d eb = attitude_error_cam(b.q_cam_from_eci, sky.q_cam_from_eci);
    const double across_a = std::hypot(ea.x(), ea.y()), across_b = std::hypot(eb.x(), eb.y());
    // What the aberration does at the boresight, for comparison.
    const Eigen::Vector3d bore = sky.q_cam_from_eci.toRotationMatrix().row(2).transpose();
    const double shift = std::acos(std::clamp(astro::aberrated_direction(bore, v).dot(bore), -1.0, 1.0));
    std::printf("  frame %llu: %d stars, across the boresight %.2f\" with the velocity, %.2f\" without "
                "(aberration at the boresight %.2f\")\n",
                static_cast<unsigned long long>(i), a.stars_matched, across_a / astro::kArcsecToRad,
                across_b / astro::kArcsecToRad, shift / astro::kArcsecToRad);
    worst_with = std::max(worst_with, across_a);
    rms_with += across_a * across_a;
    EXPECT_NEAR(across_b, shift, 3.0 * astro::kArcsecToRad) << "without: the aberration stays in the attitude";
  }
  ASSERT_GE(solved, 6);
  std::printf("[ figures ] aberrated frames: attitude across the boresight rms %.2f\", worst %.2f\" with the "
              "observer's velocity\n",
              std::sqrt(rms_with / solved) / astro::kArcsecToRad, worst_with / astro::kArcsecToRad);
  EXPECT_LT(worst_with, 3.0 * astro::kArcsecToRad);
}

}  // namespace
}  // namespace artms::imp
