// SOD-aided detection (aided_detection.hpp) on synthetic frames: a Gaussian
// spot below the full-frame threshold is found near its prediction, with a
// centroid sigma that matches its scatter; pure noise gives no detection at
// the documented false-alarm level; a wing of a known detection is refused.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "artms/imp/aided_detection.hpp"
#include "artms/imp/detection.hpp"

namespace artms::imp {
namespace {

constexpr int kW = 200, kH = 160;
constexpr double kBackground = 100.0, kNoise = 5.0, kPsf = 1.2;

std::vector<std::uint16_t> frame(std::mt19937_64& rng, double x, double y, double peak_sigmas) {
  std::normal_distribution<double> g(0.0, kNoise);
  std::vector<std::uint16_t> px(static_cast<std::size_t>(kW * kH));
  for (int r = 0; r < kH; ++r) {
    for (int c = 0; c < kW; ++c) {
      const double s = peak_sigmas * kNoise * std::exp(-0.5 * ((c - x) * (c - x) + (r - y) * (r - y)) / (kPsf * kPsf));
      px[static_cast<std::size_t>(r * kW + c)] = static_cast<std::uint16_t>(std::lround(kBackground + s + g(rng)));
    }
  }
  return px;
}

TEST(AidedDetection, FindsASourceBelowTheFrameThresholdWithAnHonestSigma) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> sub(-0.5, 0.5);
  AidedDetectionOptions opt;
  opt.psf_sigma_px = kPsf;
  int found = 0, frame_found = 0;
  double z2 = 0.0;
  const int n = 200;
  for (int i = 0; i < n; ++i) {
    const double x = 100.0 + sub(rng), y = 80.0 + sub(rng);
    const auto px = frame(rng, x, y, 3.5);  // 3.5 peak sigmas: under detect()'s 5
    DetectionOptions d;
    d.psf_sigma_px = kPsf;
    if (!detect(px, kW, kH, d).centroids.empty()) ++frame_found;
    // Prediction 3 px off with a 3 px 1-sigma.
    const auto a = detect_near_prediction(px, kW, kH, {x + 3.0, y - 2.0}, 9.0 * Eigen::Matrix2d::Identity(), kNoise, {},
                                          opt);
    if (!a.found) continue;
    ++found;
    const double s = a.centroid.sigma_px;
    z2 += (std::pow(a.centroid.x_px - x, 2) + std::pow(a.centroid.y_px - y, 2)) / (2.0 * s * s);
  }
  std::printf("3.5-sigma peak: full-frame detection %d / %d, aided %d / %d, normalised centroid variance %.2f\n",
              frame_found, n, found, n, z2 / std::max(found, 1));
  EXPECT_LT(frame_found, n / 4);
  EXPECT_GT(found, 9 * n / 10);
  // The centroid 1-sigma is neither optimistic nor far too conservative.
  EXPECT_GT(z2 / found, 0.5);
  EXPECT_LT(z2 / found, 1.6);
}

TEST(AidedDetection, PureNoiseRarelyGivesADetection) {
  std::mt19937_64 rng(5);
  AidedDetectionOptions opt;
  opt.psf_sigma_px = kPsf;
  int found = 0;
  for (int i = 0; i < 300; ++i) {
    const auto px = frame(rng, 0.0, 0.0, 0.0);
    if (detect_near_prediction(px, kW, kH, {100.0, 80.0}, 25.0 * Eigen::Matrix2d::Identity(), kNoise, {}, opt).found)
      ++found;
  }
  // ~250 independent matched-filter positions per region at nu >= 5.5:
  // P ~ 250 * 1.9e-8 per frame.
  EXPECT_LE(found, 1);
}

TEST(AidedDetection, RefusesWideRegionsAndWingsOfKnownDetections) {
  std::mt19937_64 rng(7);
  AidedDetectionOptions opt;
  opt.psf_sigma_px = kPsf;
  const auto px = frame(rng, 100.0, 80.0, 4.0);
  const auto wide = detect_near_prediction(px, kW, kH, {100.0, 80.0}, 400.0 * Eigen::Matrix2d::Identity(), kNoise, {}, opt);
  EXPECT_FALSE(wide.found);
  EXPECT_EQ(wide.why, "too wide");
  const auto near = detect_near_prediction(px, kW, kH, {100.0, 80.0}, 4.0 * Eigen::Matrix2d::Identity(), kNoise,
                                           {Eigen::Vector2d(101.5, 80.5)}, opt);
  EXPECT_FALSE(near.found);
  EXPECT_EQ(near.why, "near a detection");
  AidedDetectionOptions bad = opt;
  bad.threshold_snr = 0.0;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
  EXPECT_THROW((void)detect_near_prediction(std::span<const std::uint16_t>(px.data(), 10), kW, kH, {1, 1},
                                            Eigen::Matrix2d::Identity(), kNoise, {}, opt),
               std::invalid_argument);
}

// detect() reports lone sharp pixels (the input of FrameProcessor's learned
// hot-pixel map), and not the pixels of a real source.
TEST(Detection, ReportsHotPixelSuspectsButNotSources) {
  std::mt19937_64 rng(9);
  auto px = frame(rng, 60.3, 40.6, 40.0);  // a bright star
  const std::size_t hot = 120 * kW + 150;
  px[hot] = static_cast<std::uint16_t>(kBackground + 60.0 * kNoise);  // a hot pixel, alone
  DetectionOptions d;
  d.psf_sigma_px = kPsf;
  const DetectionResult r = detect(px, kW, kH, d);
  ASSERT_EQ(r.centroids.size(), 1u);
  EXPECT_NEAR(r.centroids[0].x_px, 60.3, 0.1);
  ASSERT_EQ(r.hot_suspects.size(), 1u);
  EXPECT_EQ(r.hot_suspects[0], hot);
  // A floor, when set, is in every centroid sigma.
  d.centroid_sigma_floor_px = 0.5;
  EXPECT_GE(detect(px, kW, kH, d).centroids.at(0).sigma_px, 0.5);
}

}  // namespace
}  // namespace artms::imp
