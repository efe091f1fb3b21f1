// BOD (paper, "Batch Orbit Determination"): closed loop on bearings from a
// numerically integrated J2 world (perfect and noisy, from a shifted prior),
// the sensitivity matrix against numerical derivatives, the covariance
// formula against a Monte Carlo of the batch, and the verdicts.
#include "artms/bod/bod.hpp"

#include <gtest/gtest.h>

#include <random>

#include "artms/astro/bearing.hpp"
#include "artms/astro/constants.hpp"
#include "artms/dynamics/gve.hpp"
#include "artms/testing/testing.hpp"

namespace artms::bod {
namespace {

using astro::kArcsecToRad;
using astro::Vec3;
using astro::Vec6;

// Named tolerances of the closed loop.
constexpr double kModelRangeErrorFraction = 1e-3;    // perfect bearings from BOD's own model: 0.1 % of range
constexpr double kModelRoeErrorM = 1.0;               // ... and 1 m in a*da, a*de, a*di
// Perfect bearings from the numerically integrated J2 world: the first-order
// mean theory leaves ~1 arcsec of systematic residual, which moves the
// weakly observable range by a few percent.
constexpr double kPerfectRangeErrorFraction = 0.03;
constexpr double kNoisyRangeErrorFraction = 0.05;    // 5 arcsec noise: 5 % of range (issue 16)
constexpr double kPerfectRoeErrorM = 100.0;          // a*da, a*de, a*di with perfect bearings of that world
constexpr double kSensitivityRelTol = 0.03;          // analytic vs numerical sensitivity, per ROE column
constexpr double kSensitivityRelTolA = 0.10;         // ... for the observer's a (a small column)
constexpr double kNoise_rad = 5.0 * kArcsecToRad;

const dynamics::ForceModel& j2_forces() {
  static const dynamics::ForceModel f =
      dynamics::ForceModel::load(dynamics::ForceModelOptions::parse("j2"), ARTMS_DATA_DIR);
  return f;
}

// A world integrated with the J2 force model (not the mean theory BOD uses):
// the observer in a 500 km sun-synchronous orbit and a target ~50 km ahead on
// a PSE-like relative orbit, imaged by a velocity-pointing camera every 60 s.
struct World {
  astro::TimeTT t0 = astro::tt_from_utc_string("2024-05-08T00:00:00Z");
  astro::QnsElements obs0{astro::kRadiusEarth_m + 500e3, 2e-4, 9e-4, 97.6 * astro::kDegToRad, 30.0 * astro::kDegToRad,
                          0.3};
  Vec6 a_roe_m = (Vec6() << 3.0, 50e3, 300.0, -200.0, 250.0, 400.0).finished();
  std::vector<astro::QnsElements> obs, tgt;
  std::vector<astro::TimeTT> t;

  explicit World(double span_s = 1.5 * 5677.0, double cadence_s = 60.0, Vec6 roe = Vec6::Zero()) {
    if (roe.norm() > 0.0) a_roe_m = roe;
    const dynamics::GveRk4Propagator prop(j2_forces(), dynamics::SpacecraftProperties{});
    astro::QnsElements o = obs0, d = astro::qns_from_roe(obs0, astro::Roe::from_scaled_m(a_roe_m, obs0.a_m));
    astro::TimeTT tc = t0;
    for (double s = 0.0; s <= span_s + 1e-6; s += cadence_s) {
      const astro::TimeTT tn = t0.plus_seconds(s);
      o = prop.propagate(o, tc, tn);
      d = prop.propagate(d, tc, tn);
      tc = tn;
      obs.push_back(o);
      tgt.push_back(d);
      t.push_back(tn);
    }
  }
  // Bearings with Gaussian noise of noise_rad per angle (the camera frame of
  // a velocity-pointing star tracker).
  std::vector<Measurement> bearings(double noise_rad, std::mt19937_64* rng) const {
    std::vector<Measurement> out;
    std::normal_distribution<double> n01;
    for (std::size_t j = 0; j < t.size(); ++j) {
      const astro::StateVector xo = astro::cartesian_from_qns(obs[j]), xt = astro::cartesian_from_qns(tgt[j]);
      Measurement m;
      m.t = t[j];
      m.R_v_from_eci = astro::R_v_from_eci(xo, astro::Boresight::kPlusVelocity);
      astro::Bearing b = astro::bearing_from_los(m.R_v_from_eci * (xt.r_m - xo.r_m));
      if (rng) {
        b.az_rad += noise_rad * n01(*rng);
        b.el_rad += noise_rad * n01(*rng);
      }
      m.u_eci = m.R_v_from_eci.transpose() * astro::unit_los_from_bearing(b);
      out.push_back(m);
    }
    return out;
  }
  // The observer's coarse orbit at the last epoch: mean elements of the
  // truth, plus an error drawn from P_prior when rng is given, and a shift
  // of its semi-major axis.
  ObserverPrior prior(double a_shift_m, std::mt19937_64* rng) const {
    ObserverPrior p;
    p.t_est = t.back();
    p.mean = dynamics::mean_from_osculating(obs.back());
    p.mean.a_m += a_shift_m;
    // GNSS-like: 10 m in position -> ~1.5e-6 in each angle-like element.
    const double s = 10.0 / obs0.a_m;
    p.P_prior = Mat5::Identity() * s * s;
    if (rng) {
      std::normal_distribution<double> n01;
      p.mean.ex += s * n01(*rng);
      p.mean.ey += s * n01(*rng);
      p.mean.i_rad += s * n01(*rng);
      p.mean.raan_rad += s * n01(*rng);
      p.mean.u_rad += s * n01(*rng);
    }
    return p;
  }
  // The target's true mean ROE at the last epoch (a*ROE meters).
  [[nodiscard]] Vec6 true_a_roe_m() const {
    const auto mo = dynamics::mean_from_osculating(obs.back());
    const auto mt = dynamics::mean_from_osculating(tgt.back());
    return astro::roe_from_qns(mo, mt).as_vector() * mo.a_m;
  }
};

Options fast_options() {
  Options o;
  o.range_min_m = 5e3;
  o.range_max_m = 200e3;
  o.samples = 60;
  return o;
}

TEST(Bod, PerfectBearingsFromAShiftedStartRecoverTheRelativeOrbit) {
  const World w;
  const Result r = solve(w.bearings(0.0, nullptr), w.prior(20.0, nullptr), fast_options());
  ASSERT_TRUE(r.usable()) << r.brief();
  const Vec6 truth = w.true_a_roe_m();
  const Vec6 est = r.roe_mean.as_vector() * r.a_observer_m;
  EXPECT_LT(std::abs(est[1] - truth[1]), kPerfectRangeErrorFraction * std::abs(truth[1]))
      << "a*dlambda " << est[1] << " truth " << truth[1] << ": " << r.brief();
  for (int k : {0, 2, 3, 4, 5}) {
    EXPECT_LT(std::abs(est[k] - truth[k]), kPerfectRoeErrorM) << "component " << k << ": " << est[k] << " vs " << truth[k];
  }
  // The observer's a is refined from the 20 m shifted start.
  EXPECT_LT(std::abs(r.a_observer_m - dynamics::mean_from_osculating(w.obs.back()).a_m), 40.0);
  // The residual curve is convex around its minimum (paper, Figure "BOD").
  ASSERT_GT(r.best_sample, 0);
  EXPECT_LT(r.curve[static_cast<std::size_t>(r.best_sample)].chi2, r.curve.front().chi2);
  EXPECT_LT(r.curve[static_cast<std::size_t>(r.best_sample)].chi2, r.curve.back().chi2);
}

TEST(Bod, PerfectBearingsOfTheMeanModelItselfAreRecovered) {
  // Bearings from BOD's own dynamics (mean J2 propagation, the J2 STM of the
  // ROE, mean-to-osculating conversion): the solver alone, from zero ROE.
  const astro::TimeTT t0 = astro::tt_from_utc_string("2024-05-08T00:00:00Z");
  const astro::QnsElements mean0{astro::kRadiusEarth_m + 500e3, 2e-4, 9e-4, 97.6 * astro::kDegToRad,
                                 30.0 * astro::kDegToRad, 0.3};
  const Vec6 a_roe = (Vec6() << 3.0, 50e3, 300.0, -200.0, 250.0, 400.0).finished();
  std::vector<Measurement> batch;
  for (int j = 0; j <= 142; ++j) {
    const double dt = 60.0 * j;
    const auto o = dynamics::propagate_mean_j2(mean0, dt);
    const auto d = astro::qns_from_roe(o, astro::Roe::from_vector(dynamics::roe_stm_j2(mean0, dt) * a_roe / mean0.a_m));
    const auto xo = astro::cartesian_from_qns(dynamics::osculating_from_mean(o));
    const auto xd = astro::cartesian_from_qns(dynamics::osculating_from_mean(d));
    Measurement m;
    m.t = t0.plus_seconds(dt);
    m.R_v_from_eci = astro::R_v_from_eci(xo, astro::Boresight::kPlusVelocity);
    m.u_eci = (xd.r_m - xo.r_m).normalized();
    batch.push_back(m);
  }
  ObserverPrior prior;
  prior.t_est = t0;
  prior.mean = mean0;
  prior.P_prior = Mat5::Identity() * 2e-12;
  const Result r = solve(batch, prior, fast_options());
  ASSERT_TRUE(r.usable()) << r.brief();
  const Vec6 est = r.roe_mean.as_vector() * r.a_observer_m;
  EXPECT_LT(std::abs(est[1] - a_roe[1]), kModelRangeErrorFraction * a_roe[1]) << r.brief();
  for (int k : {0, 2, 3, 4, 5}) EXPECT_LT(std::abs(est[k] - a_roe[k]), kModelRoeErrorM) << "component " << k;
  EXPECT_LT(std::abs(r.a_observer_m - mean0.a_m), 1.0);
}

TEST(Bod, NoisyBearingsGiveARangeInsideFivePercentAndThreeSigma) {
  const World w;
  std::mt19937_64 rng(7);
  const Result r = solve(w.bearings(kNoise_rad, &rng), w.prior(0.0, &rng), fast_options());
  ASSERT_TRUE(r.usable()) << r.brief();
  const Vec6 truth = w.true_a_roe_m();
  const double err = r.roe_mean.dlambda * r.a_observer_m - truth[1];
  EXPECT_LT(std::abs(err), kNoisyRangeErrorFraction * std::abs(truth[1])) << r.brief();
  EXPECT_LT(std::abs(err), 3.0 * r.sigma_range_m) << r.brief();
  // R_vbs from the post-fit residuals recovers the injected noise (+-30 %).
  EXPECT_NEAR(std::sqrt(r.R_vbs(0, 0)) / kNoise_rad, 1.0, 0.3);
  EXPECT_NEAR(std::sqrt(r.R_vbs(1, 1)) / kNoise_rad, 1.0, 0.3);
}

TEST(Bod, SensitivityMatrixMatchesNumericalDerivatives) {
  const World w;
  const ObserverPrior p = w.prior(0.0, nullptr);
  const BatchModel model(w.bearings(0.0, nullptr), p, dynamics::J2Constants{});
  BatchModel::Vec7 x;
  x << p.mean.a_m, w.a_roe_m;
  const double h[7] = {1.0, 0.1, 1.0, 0.1, 0.1, 0.1, 0.1};
  for (int j = 0; j < model.size(); j += 10) {
    Eigen::Matrix<double, 2, 7> S;
    (void)model.modelled(j, x, &S);
    for (int k = 0; k < 7; ++k) {
      BatchModel::Vec7 a = x, b = x;
      a[k] += h[k];
      b[k] -= h[k];
      const Eigen::Vector2d num = (model.modelled(j, a) - model.modelled(j, b)) / (2.0 * h[k]);
      EXPECT_LT((S.col(k) - num).norm(), (k == 0 ? kSensitivityRelTolA : kSensitivityRelTol) * num.norm() + 1e-13)
          << "measurement " << j << " column " << k << ": analytic " << S.col(k).transpose() << " numerical "
          << num.transpose();
    }
  }
  // The linearised model against the full nonlinear chain it stands for.
  for (int j = 0; j < model.size(); j += 10) {
    const Eigen::Vector2d d = model.modelled(j, x) - model.modelled_exact(j, x, Eigen::Matrix<double, 5, 1>::Zero());
    EXPECT_LT(d.norm(), 0.05 * kArcsecToRad) << "measurement " << j;
  }
}

TEST(Bod, CovarianceMatchesAMonteCarloOfTheBatch) {
  // Noise and prior errors drawn afresh per run; the sample covariance of
  // the estimates against the mean of BOD's P (per component, a*ROE meters).
  const World w;
  Options o = fast_options();
  o.range_min_m = 30e3;
  o.range_max_m = 80e3;
  o.samples = 25;
  o.model_sigma_m = 0.0;  // the paper's formula alone: noise and prior errors
  o.model_sigma_range_fraction = 0.0;
  constexpr int kRuns = 80;
  std::mt19937_64 rng(11);
  std::vector<Vec6> est;
  Vec6 mean_var = Vec6::Zero();
  for (int run = 0; run < kRuns; ++run) {
    const Result r = solve(w.bearings(kNoise_rad, &rng), w.prior(0.0, &rng), o);
    ASSERT_TRUE(r.usable()) << "run " << run << ": " << r.brief();
    est.push_back(r.roe_mean.as_vector() * r.a_observer_m);
    mean_var += r.P_roe_mean.diagonal() * r.a_observer_m * r.a_observer_m / kRuns;
  }
  Vec6 mean = Vec6::Zero();
  for (const auto& e : est) mean += e / kRuns;
  Vec6 var = Vec6::Zero();
  for (const auto& e : est) var += (e - mean).cwiseAbs2() / (kRuns - 1);
  for (int k = 0; k < 6; ++k) {
    const double ratio = var[k] / mean_var[k];
    // 80 runs: the sample variance is within +-40 % of the truth at ~3 sigma.
    EXPECT_GT(ratio, 0.55) << "component " << k << ": Monte Carlo " << std::sqrt(var[k]) << " m, BOD "
                           << std::sqrt(mean_var[k]) << " m";
    EXPECT_LT(ratio, 1.6) << "component " << k << ": Monte Carlo " << std::sqrt(var[k]) << " m, BOD "
                          << std::sqrt(mean_var[k]) << " m";
  }
}

TEST(Bod, TooFewBearingsAreRefusedWithTheCount) {
  const World w(20 * 60.0);
  const Result r = solve(w.bearings(0.0, nullptr), w.prior(0.0, nullptr), fast_options());
  EXPECT_EQ(r.verdict, Verdict::kTooFewMeasurements);
  EXPECT_NE(r.why.find("fewer than 50 bearings (21)"), std::string::npos) << r.why;
}

TEST(Bod, ARangeBeyondTheSamplesIsRefused) {
  const World w;
  Options o = fast_options();
  o.range_min_m = 1e3;
  o.range_max_m = 20e3;
  const Result r = solve(w.bearings(0.0, nullptr), w.prior(0.0, nullptr), o);
  EXPECT_EQ(r.verdict, Verdict::kMinimumAtEdge) << r.brief();
}

TEST(Bod, ABatchMixingTwoObjectsIsOutsideTheTolerances) {
  const World a, b(1.5 * 5677.0, 60.0, (Vec6() << -5.0, 30e3, -500.0, 300.0, -400.0, 200.0).finished());
  auto ma = a.bearings(0.0, nullptr), mb = b.bearings(0.0, nullptr);
  std::vector<Measurement> mixed;
  for (std::size_t j = 0; j < ma.size(); ++j) mixed.push_back(j % 2 ? mb[j] : ma[j]);
  const Result r = solve(mixed, a.prior(0.0, nullptr), fast_options());
  EXPECT_FALSE(r.usable()) << r.brief();
}

TEST(Bod, OptionsAreValidatedByName) {
  Options o;
  o.range_max_m = 1.0;
  try {
    o.validate();
    FAIL() << "accepted range_max_m < range_min_m";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("range_max_m"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace artms::bod

namespace artms::bod {
namespace {

// Model correction (Options::onboard_forces): in a world of 10x10 gravity,
// drag, Sun and Moon, the mean J2 theory's range is biased by ~2 % for a
// target 155 km behind (the PSE's SV3 as seen by SV4, an anti-velocity
// camera, two orbits of noise-free bearings); corrected with the same
// numerical model on board, the bias is gone. Also the 52 km target (SV2).
constexpr double kUncorrectedBiasFraction = 0.01;   // the bias without the correction is above this
constexpr double kCorrectedRangeErrorFraction = 0.002;
// Noise-free bearings every 60 s over duration_s from an anti-velocity
// camera, both spacecraft propagated in world from obs0 and a_roe at t0;
// the prior at the last bearing, and the truth's mean a*dlambda there.
struct NumericalBatch {
  std::vector<Measurement> batch;
  ObserverPrior prior;
  double truth_a_dlambda_m = 0.0;
};
NumericalBatch numerical_batch(const dynamics::ForceModel& world, const dynamics::SpacecraftProperties& observer,
                               const dynamics::SpacecraftProperties& target, const astro::QnsElements& obs0,
                               const Vec6& a_roe, astro::TimeTT t0, double duration_s) {
  const dynamics::GveRk4Propagator prop_o(world, observer), prop_d(world, target);
  astro::QnsElements o = obs0, d = astro::qns_from_roe(obs0, astro::Roe::from_scaled_m(a_roe, obs0.a_m));
  astro::TimeTT tc = t0;
  NumericalBatch out;
  for (double s = 0.0; s <= duration_s + 1e-6; s += 60.0) {
    const astro::TimeTT tn = t0.plus_seconds(s);
    o = prop_o.propagate(o, tc, tn);
    d = prop_d.propagate(d, tc, tn);
    tc = tn;
    const auto xo = astro::cartesian_from_qns(o), xd = astro::cartesian_from_qns(d);
    Measurement m;
    m.t = tn;
    m.R_v_from_eci = astro::R_v_from_eci(xo, astro::Boresight::kMinusVelocity);
    m.u_eci = (xd.r_m - xo.r_m).normalized();
    out.batch.push_back(m);
  }
  out.prior.t_est = tc;
  out.prior.mean = dynamics::mean_from_osculating(o);
  out.prior.P_prior = Mat5::Identity() * std::pow(10.0 / obs0.a_m, 2);
  out.truth_a_dlambda_m =
      astro::roe_from_qns(out.prior.mean, dynamics::mean_from_osculating(d)).dlambda * out.prior.mean.a_m;
  return out;
}

TEST(Bod, ModelCorrectionRemovesTheMeanTheorysBiasInANumericalWorld) {
  const dynamics::ForceModel world =
      dynamics::ForceModel::load(dynamics::ForceModelOptions::parse("grav10,drag,sun,moon"), ARTMS_DATA_DIR);
  const astro::TimeTT t0 = astro::tt_from_utc_string("2024-05-08T00:00:00Z");
  const astro::QnsElements obs0 = dynamics::osculating_from_mean(astro::QnsElements{
      6943e3, 1e-4, 1.6e-3, 99.4 * astro::kDegToRad, -38.0 * astro::kDegToRad, -153.0 * astro::kDegToRad});
  for (double range_m : {52266.0, 155320.0}) {
    const Vec6 a_roe = (Vec6() << -30.0, -range_m, -297.0, -315.0, 16.0, 1144.0).finished();
    const NumericalBatch nb = numerical_batch(world, {}, {}, obs0, a_roe, t0, 2.0 * 5760.0);
    const std::vector<Measurement>& batch = nb.batch;
    const ObserverPrior& prior = nb.prior;
    const double truth = nb.truth_a_dlambda_m;
    Options opt = fast_options();
    opt.range_max_m = 250e3;
    const Result plain = solve(batch, prior, opt);
    opt.onboard_forces = &world;
    const Result corrected = solve(batch, prior, opt);
    ASSERT_TRUE(plain.usable()) << plain.brief();
    ASSERT_TRUE(corrected.usable()) << corrected.brief();
    const double e_plain = plain.roe_mean.dlambda * plain.a_observer_m - truth;
    const double e_corr = corrected.roe_mean.dlambda * corrected.a_observer_m - truth;
    EXPECT_GT(std::abs(e_plain), kUncorrectedBiasFraction * range_m) << "range " << range_m << ": " << plain.brief();
    EXPECT_LT(std::abs(e_corr), kCorrectedRangeErrorFraction * range_m) << "range " << range_m << ": " << corrected.brief();
    EXPECT_EQ(plain.model_correction_rms_rad, 0.0);
    EXPECT_GT(corrected.model_correction_rms_rad, 0.0);
    EXPECT_DOUBLE_EQ(corrected.uncorrected_range_m, plain.range_m);
    EXPECT_EQ(corrected.curve.size(), plain.curve.size());  // the residual curve is the measured bearings'
  }
}

// A target whose drag differs from the observer's (twice the area, at
// 420 km where drag matters): the model correction propagates it with its
// own properties (Options::target_properties, which the navigator fills with
// SOD's estimated differential ballistic coefficient). With the observer's
// properties for both, the correction leaves the differential drag in the
// bearings and the range follows it.
TEST(Bod, ModelCorrectionPropagatesTheTargetWithItsOwnDrag) {
  const dynamics::ForceModel world =
      dynamics::ForceModel::load(dynamics::ForceModelOptions::parse("grav10,drag,sun,moon"), ARTMS_DATA_DIR);
  const astro::TimeTT t0 = astro::tt_from_utc_string("2024-05-08T00:00:00Z");
  const astro::QnsElements obs0 = dynamics::osculating_from_mean(astro::QnsElements{
      6798e3, 1e-4, 1.6e-3, 99.4 * astro::kDegToRad, -38.0 * astro::kDegToRad, -153.0 * astro::kDegToRad});
  const double range_m = 52266.0;
  const Vec6 a_roe = (Vec6() << -30.0, -range_m, -297.0, -315.0, 16.0, 1144.0).finished();
  dynamics::SpacecraftProperties observer, target;
  target.drag_area_m2 = 2.0 * observer.drag_area_m2;
  const NumericalBatch nb = numerical_batch(world, observer, target, obs0, a_roe, t0, 2.0 * 5580.0);
  const std::vector<Measurement>& batch = nb.batch;
  const ObserverPrior& prior = nb.prior;
  const double truth = nb.truth_a_dlambda_m;
  Options opt = fast_options();
  opt.range_max_m = 250e3;
  opt.onboard_forces = &world;
  opt.onboard_properties = observer;
  const Result same = solve(batch, prior, opt);
  opt.target_properties = target;
  const Result own = solve(batch, prior, opt);
  ASSERT_TRUE(same.usable()) << same.brief();
  ASSERT_TRUE(own.usable()) << own.brief();
  const double e_same = same.roe_mean.dlambda * same.a_observer_m - truth;
  const double e_own = own.roe_mean.dlambda * own.a_observer_m - truth;
  std::printf("range error: %.1f m with the observer's drag for both, %.1f m with the target's own\n", e_same, e_own);
  EXPECT_LT(std::abs(e_own), kCorrectedRangeErrorFraction * range_m) << own.brief();
  EXPECT_GT(std::abs(e_same), 3.0 * std::abs(e_own)) << same.brief();
  EXPECT_LT(own.residual_rms_rad, same.residual_rms_rad);
}

}  // namespace
}  // namespace artms::bod

namespace artms::bod {
namespace {

// Not a test (disabled; run with --gtest_also_run_disabled_tests
// --gtest_filter='BodStudy.*'): the study behind Options::model_sigma_m and
// model_sigma_range_fraction with the model correction on (docs/bod.md).
// A flight-like world (GGM01S 20x20, Jacchia-scaled drag, SRP, Sun, Moon),
// the truth's Cd, Cr and drag-area variation of starling_pse_bod_two, the
// onboard 10x10 model for the correction, SV4's orbit and an
// anti-velocity camera, SV3's relative e/i at 52 and 155 km, two orbits of
// bearings every 60 s at 2" (52 km) and 6" (155 km), 20 noise seeds each:
// mean NEES of the six mean ROE and the RMS of range error / 1-sigma per
// pair of floors.
TEST(BodStudy, DISABLED_ModelErrorFloorsWithTheCorrection) {
  const dynamics::ForceModel world =
      dynamics::ForceModel::load(dynamics::ForceModelOptions::flight_like_truth(), ARTMS_DATA_DIR);
  const dynamics::ForceModel onboard =
      dynamics::ForceModel::load(dynamics::ForceModelOptions::parse("grav10,drag,sun,moon"), ARTMS_DATA_DIR);
  const astro::TimeTT t0 = astro::tt_from_utc_string("2024-05-08T00:00:00Z");
  const astro::QnsElements obs0 = dynamics::osculating_from_mean(astro::QnsElements{
      6943e3, 1e-4, 1.6e-3, 99.4 * astro::kDegToRad, -38.0 * astro::kDegToRad, -153.0 * astro::kDegToRad});
  const std::vector<std::pair<double, double>> floors = {{0.0, 0.0}, {0.0, 0.001}, {0.0, 0.003}, {0.3, 0.003},
                                                         {0.7, 0.003}, {0.7, 0.01}};
  for (double range_m : {52266.0, 155320.0}) {
    const double noise = (range_m < 1e5 ? 2.0 : 6.0) * kArcsecToRad;
    const Vec6 a_roe = (Vec6() << -30.0, -range_m, -297.0, -315.0, 16.0, 1144.0).finished();
    // Truth properties the onboard model does not know (starling_pse_bod_two's SV4 and SV2).
    dynamics::SpacecraftProperties so, sd;
    so.drag_area_variation = sd.drag_area_variation = 0.2;
    sd.cd = 2.5;
    sd.cr = 1.5;
    const dynamics::GveRk4Propagator prop_o(world, so), prop_d(world, sd);
    astro::QnsElements o = obs0, d = astro::qns_from_roe(obs0, astro::Roe::from_scaled_m(a_roe, obs0.a_m));
    astro::TimeTT tc = t0;
    std::vector<astro::StateVector> xo, xd;
    std::vector<astro::TimeTT> ts;
    for (double s = 0.0; s <= 2.0 * 5760.0 + 1e-6; s += 60.0) {
      const astro::TimeTT tn = t0.plus_seconds(s);
      o = prop_o.propagate(o, tc, tn);
      d = prop_d.propagate(d, tc, tn);
      tc = tn;
      xo.push_back(astro::cartesian_from_qns(o));
      xd.push_back(astro::cartesian_from_qns(d));
      ts.push_back(tn);
    }
    const astro::QnsElements mo = dynamics::mean_from_osculating(o);
    const Vec6 truth = astro::roe_from_qns(mo, dynamics::mean_from_osculating(d)).as_vector() * mo.a_m;
    for (const auto& [sigma_m, fraction] : floors) {
      double nees = 0.0, z2 = 0.0;
      int n = 0;
      for (int seed = 1; seed <= 20; ++seed) {
        std::mt19937_64 rng(seed);
        std::normal_distribution<double> n01;
        std::vector<Measurement> batch;
        for (std::size_t j = 0; j < ts.size(); ++j) {
          Measurement m;
          m.t = ts[j];
          m.R_v_from_eci = astro::R_v_from_eci(xo[j], astro::Boresight::kMinusVelocity);
          astro::Bearing b = astro::bearing_from_los(m.R_v_from_eci * (xd[j].r_m - xo[j].r_m));
          b.az_rad += noise * n01(rng);
          b.el_rad += noise * n01(rng);
          m.u_eci = m.R_v_from_eci.transpose() * astro::unit_los_from_bearing(b);
          batch.push_back(m);
        }
        ObserverPrior prior;
        prior.t_est = tc;
        prior.mean = mo;
        prior.P_prior = Mat5::Identity() * std::pow(10.0 / obs0.a_m, 2);
        Options opt = fast_options();
        opt.range_max_m = 250e3;
        opt.onboard_forces = &onboard;
        opt.model_sigma_m = sigma_m;
        opt.model_sigma_range_fraction = fraction;
        const Result r = solve(batch, prior, opt);
        if (!r.usable()) continue;
        const Vec6 e = r.roe_mean.as_vector() * r.a_observer_m - truth;
        const astro::Mat6 P = r.P_roe_mean * r.a_observer_m * r.a_observer_m;
        nees += e.dot(P.ldlt().solve(e));
        z2 += e[1] * e[1] / P(1, 1);
        ++n;
      }
      std::printf("range %.0f km, floors %.1f m and %.1f %% of range: %d usable, mean NEES %.2f, RMS range z %.2f\n",
                  range_m / 1e3, sigma_m, 100.0 * fraction, n, nees / std::max(1, n), std::sqrt(z2 / std::max(1, n)));
    }
  }
}

}  // namespace
}  // namespace artms::bod
