// q-method: scipy reference solutions of Wahba's problem, noise-free
// recovery, degenerate inputs, and the covariance against Monte Carlo.
#include "artms/imp/qmethod.hpp"

#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "artms/testing/testing.hpp"

namespace artms::imp {
namespace {

using artms::testing::IsNearMatrix;
using artms::testing::IsNearQuaternion;
using Eigen::Matrix3d;
using Eigen::Quaterniond;

Vec3 vec3(const nlohmann::json& a) {
  return {a[0].get<double>(), a[1].get<double>(), a[2].get<double>()};
}

Matrix3d mat3(const nlohmann::json& a) {
  Matrix3d M;
  for (int i = 0; i < 3; ++i) M.row(i) = vec3(a[static_cast<std::size_t>(i)]).transpose();
  return M;
}

Quaterniond random_quaternion(std::mt19937_64& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return Quaterniond(g(rng), g(rng), g(rng), g(rng)).normalized();
}

Vec3 random_unit(std::mt19937_64& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return Vec3(g(rng), g(rng), g(rng)).normalized();
}

// Rotates unit vector v by small random angles, sigma per perpendicular axis.
Vec3 perturb(const Vec3& v, double sigma, std::mt19937_64& rng) {
  std::normal_distribution<double> g(0.0, sigma);
  const Vec3 e1 = v.unitOrthogonal();
  const Vec3 e2 = v.cross(e1);
  return (v + g(rng) * e1 + g(rng) * e2).normalized();
}

TEST(QMethod, MatchesScipyWahbaReference) {
  // tests/data/wahba_qmethod_reference.json minimises 1/2 sum w |b - A r|^2
  // with b = obs_body, r = ref_inertial and A "inertial -> body". scipy's
  // Rotation.align_vectors(a, b) returns the rotation C minimising
  // 1/2 sum w |a_i - C b_i|^2, i.e. C maps b onto a; the file called it with
  // a = obs_body, b = ref_inertial, so A_opt = C = R_body_from_ref, the
  // matrix of our q_body_from_ref. q_opt is Shuster's [q1 q2 q3 q4] with
  // A(q) = (q4^2 - |q|^2) I + 2 q q^T - 2 q4 [q x], which is Eigen's
  // (w, x, y, z) = (q4, -q1, -q2, -q3).
  const auto j =
      artms::testing::load_json(artms::testing::test_data_path("wahba_qmethod_reference.json"));
  ASSERT_EQ(j["cases"].size(), 5u);
  for (const auto& c : j["cases"]) {
    SCOPED_TRACE(c["name"].get<std::string>());
    std::vector<WeightedPair> pairs;
    double w_sum = 0.0;
    for (std::size_t i = 0; i < c["weights"].size(); ++i) {
      pairs.push_back(
          {vec3(c["obs_body"][i]), vec3(c["ref_inertial"][i]), c["weights"][i].get<double>()});
      w_sum += pairs.back().weight;
    }
    const AttitudeSolution s = q_method(pairs);
    ASSERT_TRUE(s.usable) << s.why;
    EXPECT_TRUE(s.why.empty());
    EXPECT_EQ(s.n, c["n_obs"].get<int>());
    EXPECT_THAT(Matrix3d(s.q_body_from_ref.toRotationMatrix()),
                IsNearMatrix(mat3(c["A_opt_inertial_to_body_scipy"]), 1e-12));
    const auto& qs = c["q_opt_shuster_xyz_w"];
    const Quaterniond q_ref(qs[3].get<double>(), -qs[0].get<double>(), -qs[1].get<double>(),
                            -qs[2].get<double>());
    EXPECT_THAT(s.q_body_from_ref, IsNearQuaternion(q_ref, 1e-12));
    EXPECT_GE(s.q_body_from_ref.w(), 0.0);
    EXPECT_NEAR(s.lambda_max, c["lambda_max"].get<double>(), 1e-12 * w_sum);
    EXPECT_NEAR(s.loss, c["wahba_loss"].get<double>(), 1e-13 * w_sum);
    EXPECT_NEAR(s.loss, w_sum - s.lambda_max, 1e-13 * w_sum);
    if (c["noise_sigma_arcsec"].get<double>() == 0.0) {
      const Quaterniond q_true(mat3(c["A_true_inertial_to_body"]));
      EXPECT_THAT(s.q_body_from_ref, IsNearQuaternion(q_true, 1e-12));
      EXPECT_LT(s.residual_rms_rad, 1e-12);
    } else {
      // Residuals of the order of the noise.
      const double sigma = c["noise_sigma_arcsec"].get<double>() * std::numbers::pi / 648000.0;
      EXPECT_GT(s.residual_rms_rad, 0.2 * sigma);
      EXPECT_LT(s.residual_rms_rad, 5.0 * sigma);
    }
  }
}

TEST(QMethod, NoiseFreeRandomCasesRecoverTheRotation) {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> uw(0.1, 10.0);
  double worst = 0.0;
  for (int trial = 0; trial < 500; ++trial) {
    const Quaterniond q_true = random_quaternion(rng);
    const int n = 2 + trial % 19;
    std::vector<WeightedPair> pairs;
    for (int i = 0; i < n; ++i) {
      const Vec3 r = random_unit(rng);
      pairs.push_back({q_true * r, r, uw(rng)});
    }
    // Two random directions can be nearly parallel; keep them >= 0.2 rad apart.
    if (n == 2 && pairs[0].reference.cross(pairs[1].reference).norm() < 0.2) continue;
    const AttitudeSolution s = q_method(pairs);
    ASSERT_TRUE(s.usable) << s.why;
    worst = std::max(worst, s.q_body_from_ref.angularDistance(q_true));
    EXPECT_THAT(s.q_body_from_ref, IsNearQuaternion(q_true, 1e-12)) << "trial " << trial;
    EXPECT_LT(s.loss, 1e-24 * 10.0 * n + 1e-28);
  }
  std::printf("[qmethod] noise-free random cases: max angle error %.3e rad\n", worst);
}

TEST(QMethod, NarrowFieldOfViewNoiseFree) {
  // Stars within a few degrees of the boresight, as for the VBS.
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-0.08, 0.08);
  for (int trial = 0; trial < 100; ++trial) {
    const Quaterniond q_body_from_eci = random_quaternion(rng);
    std::vector<WeightedPair> pairs;
    for (int i = 0; i < 3 + trial % 10; ++i) {
      const Vec3 b = Vec3(u(rng), u(rng), 1.0).normalized();
      pairs.push_back({b, q_body_from_eci.conjugate() * b, 1.0});
    }
    const AttitudeSolution s = q_method(pairs);
    ASSERT_TRUE(s.usable) << s.why;
    EXPECT_THAT(s.q_body_from_ref, IsNearQuaternion(q_body_from_eci, 1e-12));
  }
}

TEST(QMethod, SmallGapWithUnequalWeightsStaysAccurate) {
  // Two stars 0.08 rad apart with weights 1e7 and 4e10: the K eigenvalue gap
  // is ~3e-6 of the weights, and the bare eigenvector is off by ~1e-10 rad
  // (the oracle's worst case, against scipy, before the QUEST refinement).
  // Refined, the answer is within a few 1e-15 of the exact optimum (checked
  // offline with 40-digit mpmath), which itself is ~4e-15 from the truth
  // because the inputs are rounded.
  std::mt19937_64 rng(15);
  double worst = 0.0;
  for (int trial = 0; trial < 200; ++trial) {
    const Quaterniond q_true = random_quaternion(rng);
    const Vec3 b1 = Vec3(0.01, -0.02, 1.0).normalized();
    const Vec3 b2 =
        Vec3(0.01 + 0.08 * std::cos(trial), -0.02 + 0.08 * std::sin(trial), 1.0).normalized();
    const std::vector<WeightedPair> pairs{{b1, q_true.conjugate() * b1, 1e7},
                                          {b2, q_true.conjugate() * b2, 4e10}};
    const AttitudeSolution s = q_method(pairs);
    ASSERT_TRUE(s.usable) << s.why;
    EXPECT_LT(s.eigen_gap / (1e7 + 4e10), 1e-5);
    worst = std::max(worst, s.q_body_from_ref.angularDistance(q_true));
  }
  std::printf("[qmethod] small-gap unequal weights: max angle error %.3e rad\n", worst);
  EXPECT_LT(worst, 5e-14);
}

TEST(QMethod, NormalisesInputAndIgnoresWeightScale) {
  std::mt19937_64 rng(5);
  const Quaterniond q_true = random_quaternion(rng);
  std::vector<WeightedPair> pairs, scaled;
  for (int i = 0; i < 6; ++i) {
    const Vec3 r = random_unit(rng);
    const Vec3 b = perturb(q_true * r, 1e-3, rng);
    pairs.push_back({b, r, 1.0 + i});
    scaled.push_back({3.7 * b, 0.01 * r, 1e8 * (1.0 + i)});
  }
  const AttitudeSolution a = q_method(pairs);
  const AttitudeSolution b = q_method(scaled);
  ASSERT_TRUE(a.usable && b.usable);
  EXPECT_THAT(b.q_body_from_ref, IsNearQuaternion(a.q_body_from_ref, 1e-13));
  EXPECT_NEAR(b.loss, 1e8 * a.loss, 1e-9 * b.loss);
  EXPECT_NEAR(b.residual_rms_rad, a.residual_rms_rad, 1e-12);
  EXPECT_THAT(Matrix3d(b.covariance_rad2 * 1e8),
              IsNearMatrix(a.covariance_rad2, 1e-9 * a.covariance_rad2.norm()));
}

TEST(QMethod, DegenerateInputsAreUnusableWithAReason) {
  const auto why = [](const std::vector<WeightedPair>& p, const QMethodOptions& o = {}) {
    const AttitudeSolution s = q_method(p, o);
    EXPECT_FALSE(s.usable);
    EXPECT_TRUE(std::isnan(s.loss));
    EXPECT_TRUE(s.covariance_rad2.array().isNaN().all());
    EXPECT_EQ(s.n, static_cast<int>(p.size()));
    return s.why;
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const Vec3 x = Vec3::UnitX(), y = Vec3::UnitY(), z = Vec3::UnitZ();
  EXPECT_THAT(why({}), ::testing::HasSubstr("at least 2"));
  EXPECT_THAT(why({{x, x, 1.0}}), ::testing::HasSubstr("at least 2"));
  EXPECT_THAT(why({{x, x, 1.0}, {x, x, 2.0}, {x, x, 1.0}}), ::testing::HasSubstr("collinear"));
  EXPECT_THAT(why({{x, x, 1.0}, {-x, -x, 2.0}}),
              ::testing::HasSubstr("reference vectors collinear"));
  EXPECT_THAT(why({{x, x, 1.0}, {y, Vec3(1.0, 1e-9, 0.0), 1.0}}),
              ::testing::HasSubstr("reference vectors collinear"));
  EXPECT_THAT(why({{x, x, 1.0}, {x, y, 1.0}}), ::testing::HasSubstr("body vectors collinear"));
  EXPECT_THAT(why({{x, x, 1.0}, {Vec3(nan, 0, 0), y, 1.0}}),
              ::testing::HasSubstr("pair 1: non-finite body"));
  EXPECT_THAT(why({{x, Vec3(0, inf, 0), 1.0}, {y, y, 1.0}}),
              ::testing::HasSubstr("pair 0: non-finite reference"));
  EXPECT_THAT(why({{x, x, nan}, {y, y, 1.0}}), ::testing::HasSubstr("non-finite weight"));
  EXPECT_THAT(why({{x, x, 1.0}, {y, y, 0.0}}), ::testing::HasSubstr("weight must be positive"));
  EXPECT_THAT(why({{x, x, -1.0}, {y, y, 1.0}}), ::testing::HasSubstr("weight must be positive"));
  EXPECT_THAT(why({{Vec3::Zero(), x, 1.0}, {y, y, 1.0}}), ::testing::HasSubstr("zero-length body"));
  EXPECT_THAT(why({{x, x, 1.0}, {y, Vec3::Zero(), 1.0}}),
              ::testing::HasSubstr("zero-length reference"));
  // Collinear input with the spread check off: the eigenvalue gap catches it.
  EXPECT_THAT(why({{x, x, 1.0}, {x, x, 1.0}}, {0.0, 1e-12}),
              ::testing::HasSubstr("eigenvalue gap"));
  // Valid geometry but a gap threshold above what it can reach (<= 2 sum w).
  EXPECT_THAT(why({{x, x, 1.0}, {y, y, 1.0}, {z, z, 1.0}}, {1e-6, 3.0}),
              ::testing::HasSubstr("eigenvalue gap"));
  // The same pairs are fine with the default options.
  EXPECT_TRUE(q_method(std::vector<WeightedPair>{{x, x, 1.0}, {y, y, 1.0}}).usable);
}

TEST(QMethod, BadOptionsThrowNamingTheField) {
  const std::vector<WeightedPair> p{{Vec3::UnitX(), Vec3::UnitX(), 1.0},
                                    {Vec3::UnitY(), Vec3::UnitY(), 1.0}};
  try {
    (void)q_method(p, {-1.0, 1e-12});
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_THAT(std::string(e.what()), ::testing::HasSubstr("min_spread_rad"));
  }
  try {
    (void)q_method(p, {1e-6, std::numeric_limits<double>::quiet_NaN()});
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_THAT(std::string(e.what()), ::testing::HasSubstr("min_relative_gap"));
  }
}

TEST(QMethod, CovarianceMatchesMonteCarloInBodyAxes) {
  // Eight stars within ~5 deg of the boresight z_body, 20 arcsec noise per
  // axis, weights 1 / sigma^2: roll about z_body is poorly determined. The
  // predicted covariance (body axes) must match the scatter of the error
  // dtheta, q_true = dq(dtheta) * q_est, over many noise draws.
  std::mt19937_64 rng(99);
  const Quaterniond q_true = random_quaternion(rng);  // body from ECI
  const double sigma = 20.0 * std::numbers::pi / 648000.0;
  std::uniform_real_distribution<double> u(-0.09, 0.09);
  std::vector<Vec3> b_true;
  for (int i = 0; i < 8; ++i) b_true.push_back(Vec3(u(rng), u(rng), 1.0).normalized());
  const int trials = 4000;
  Matrix3d scatter = Matrix3d::Zero();
  Matrix3d predicted = Matrix3d::Zero();
  double rms = 0.0;
  for (int t = 0; t < trials; ++t) {
    std::vector<WeightedPair> pairs;
    for (const Vec3& b : b_true) {
      pairs.push_back({perturb(b, sigma, rng), q_true.conjugate() * b, 1.0 / (sigma * sigma)});
    }
    const AttitudeSolution s = q_method(pairs);
    ASSERT_TRUE(s.usable) << s.why;
    Quaterniond dq = q_true * s.q_body_from_ref.conjugate();
    if (dq.w() < 0.0) dq.coeffs() *= -1.0;
    const Vec3 dtheta = 2.0 * dq.vec();
    scatter += dtheta * dtheta.transpose();
    predicted = s.covariance_rad2;
    rms += s.residual_rms_rad * s.residual_rms_rad;
  }
  scatter /= trials;
  std::printf(
      "[qmethod] Monte Carlo sigma (arcsec) x %.2f y %.2f z %.2f, predicted %.2f %.2f %.2f\n",
      std::sqrt(scatter(0, 0)) * 648000.0 / std::numbers::pi,
      std::sqrt(scatter(1, 1)) * 648000.0 / std::numbers::pi,
      std::sqrt(scatter(2, 2)) * 648000.0 / std::numbers::pi,
      std::sqrt(predicted(0, 0)) * 648000.0 / std::numbers::pi,
      std::sqrt(predicted(1, 1)) * 648000.0 / std::numbers::pi,
      std::sqrt(predicted(2, 2)) * 648000.0 / std::numbers::pi);
  EXPECT_THAT(predicted, artms::testing::IsSymmetricPositiveDefinite(1e-20));
  EXPECT_GT(predicted(2, 2), 50.0 * predicted(0, 0));  // roll about the boresight
  for (int i = 0; i < 3; ++i) {
    for (int k = 0; k < 3; ++k) {
      // 4000 draws: ~2 % standard error on the variances.
      EXPECT_NEAR(scatter(i, k), predicted(i, k),
                  0.1 * std::sqrt(predicted(i, i) * predicted(k, k)))
          << "element " << i << "," << k;
    }
  }
  // The per-vector residuals: 2 sigma^2 per vector less the 3 fitted angles.
  EXPECT_NEAR(std::sqrt(rms / trials), sigma * std::sqrt(2.0 * (8.0 - 1.5) / 8.0), 0.05 * sigma);
}

}  // namespace
}  // namespace artms::imp
