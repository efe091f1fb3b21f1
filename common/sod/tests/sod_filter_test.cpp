// SOD unit tests: options, gating, the four health checks, re-initialisation,
// failure statuses, and numerical checks of the unscented updates against
// linearised (central-difference) propagation and measurement maps.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include "artms/dynamics/j2_mean.hpp"
#include "artms/sod/apriori.hpp"
#include "artms/sod/sod_filter.hpp"
#include "artms/testing/testing.hpp"
#include "sod_scenario.hpp"

namespace artms::sod {
namespace {

using artms::testing::IsSymmetricPositiveDefinite;
using testing::Truth;

const TimeTT kT0 = astro::tt_from_utc_string("2024-05-08T00:00:00Z");

// A filter at the truth (2 targets) with a small diagonal covariance.
struct Fixture {
  Truth truth;
  SodFilter filter;
  explicit Fixture(SodOptions o = {}, double dlambda_frac = 0.01, double other_m = 20.0)
      : truth(kT0, testing::observer_at_start(),
              {testing::starling_a_roe_m()[0], testing::starling_a_roe_m()[1]}),
        filter(testing::j2_forces(), dynamics::SpacecraftProperties{},
               dynamics::SpacecraftProperties{}, StateLayout{2, 0}, std::move(o)) {
    testing::InitialGuess g = testing::shifted_initial_guess(
        testing::observer_at_start(),
        {testing::starling_a_roe_m()[0], testing::starling_a_roe_m()[1]}, dlambda_frac, other_m);
    filter.initialize(kT0, truth.state(), g.P);
  }
};

void expect_invalid(const std::function<void(SodOptions&)>& edit, const std::string& field) {
  SodOptions o;
  edit(o);
  try {
    o.validate();
    ADD_FAILURE() << "no exception for " << field;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
  }
}

TEST(SodOptions, DefaultsAreValidAndErrorsNameTheField) {
  EXPECT_NO_THROW(SodOptions{}.validate());
  expect_invalid([](SodOptions& o) { o.ukf_alpha = 0.0; }, "ukf_alpha");
  expect_invalid([](SodOptions& o) { o.ukf_beta = -1.0; }, "ukf_beta");
  expect_invalid([](SodOptions& o) { o.propagator.step_s = 0.0; }, "propagator.step_s");
  expect_invalid([](SodOptions& o) { o.q_observer[3] = -1.0; }, "q_observer[3]");
  expect_invalid([](SodOptions& o) { o.q_target_a_roe_m2ps[1] = kNaN; }, "q_target_a_roe_m2ps[1]");
  expect_invalid([](SodOptions& o) { o.adaptive.time_constant_s = 0.0; }, "adaptive.time_constant_s");
  expect_invalid([](SodOptions& o) { o.adaptive.ceiling_factor = 0.5; }, "adaptive.ceiling_factor");
  expect_invalid([](SodOptions& o) { o.bearing_gate_mahalanobis = 0.0; }, "bearing_gate_mahalanobis");
  expect_invalid([](SodOptions& o) { o.health.max_steps_without_update = 0; },
                 "health.max_steps_without_update");
  expect_invalid([](SodOptions& o) { o.health.max_a_m = 1.0; }, "health.min_a_m");
  EXPECT_THROW(SodFilter(testing::j2_forces(), {}, {}, StateLayout{0, 0}), std::invalid_argument);
  AprioriErrorModel m;
  m.sigma_a_da0_m = -1.0;
  try {
    m.validate();
    ADD_FAILURE();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("sigma_a_da0_m"), std::string::npos);
  }
}

TEST(SodFilter, InitializeRejectsBadInput) {
  Fixture f;
  const VectorXd x = f.truth.state();
  MatrixXd P = f.filter.covariance();
  EXPECT_THROW(f.filter.initialize(kT0, x.head(12), P), std::invalid_argument);
  P(0, 0) = -1.0;
  EXPECT_THROW(f.filter.initialize(kT0, x, P), std::invalid_argument);
}

TEST(SodLayout, IndicesAndAngles) {
  const StateLayout l{3, 2};
  EXPECT_EQ(l.size(), 6 + 18 + 2);
  EXPECT_EQ(l.target_offset(2), 18);
  EXPECT_EQ(l.aux_offset(), 24);
  EXPECT_TRUE(l.is_angle(StateLayout::kU));
  EXPECT_TRUE(l.is_angle(StateLayout::kRaan));
  EXPECT_FALSE(l.is_angle(StateLayout::kA));
  EXPECT_TRUE(l.is_angle(l.target_offset(1) + StateLayout::kDlambda));
  EXPECT_FALSE(l.is_angle(l.target_offset(1) + StateLayout::kDa));
  EXPECT_FALSE(l.is_angle(l.aux_offset() + 1));
}

// An appended auxiliary state is held constant and random-walks with q_aux.
TEST(SodLayout, AuxiliaryStateIsConstantWithRandomWalk) {
  SodOptions o;
  o.q_aux = 1e-4;
  o.adaptive.enabled = false;
  SodFilter f(testing::j2_forces(), {}, {}, StateLayout{1, 1}, o);
  const astro::QnsElements obs = testing::observer_at_start();
  VectorXd aux(1);
  aux << 0.25;
  const VectorXd x = f.make_state(obs, {astro::Roe::from_scaled_m(testing::starling_a_roe_m()[0], obs.a_m)}, aux);
  VectorXd sd = VectorXd::Constant(13, 1e-8);
  sd[0] = 1.0;
  sd[12] = 0.01;
  f.initialize(kT0, x, sd.cwiseAbs2().asDiagonal());
  ASSERT_TRUE(f.time_update(kT0.plus_seconds(100.0)).usable);
  const int i = f.layout().aux_offset();
  EXPECT_NEAR(f.state()[i], 0.25, 1e-12);
  EXPECT_NEAR(f.covariance()(i, i), 1e-4 + 1e-4 * 100.0, 1e-12);
}

// Gating: a 0.05 rad outlier is rejected and counted, the state is untouched;
// the true measurement right after is accepted.
TEST(SodGating, RejectsOutlierAndCountsIt) {
  Fixture f;
  f.truth.advance_to(kT0.plus_seconds(60.0));
  ASSERT_TRUE(f.filter.time_update(f.truth.t()).usable);
  const VectorXd x_before = f.filter.state();
  BearingMeasurement bad = f.truth.bearing(0, 20 * astro::kArcsecToRad, 0.0, nullptr);
  bad.angles.el_rad += 0.05;
  const UpdateSummary s = f.filter.update_bearing(bad);
  EXPECT_FALSE(s.usable);
  EXPECT_TRUE(s.gated) << s.brief_report();
  EXPECT_GT(s.mahalanobis, f.filter.options().bearing_gate_mahalanobis);
  EXPECT_EQ(f.filter.rejected_total(), 1);
  EXPECT_EQ(f.filter.counters(0).rejected, 1);
  EXPECT_EQ(f.filter.state(), x_before);
  const UpdateSummary good = f.filter.update_bearing(f.truth.bearing(0, 20 * astro::kArcsecToRad, 0.0, nullptr));
  EXPECT_TRUE(good.usable) << good.brief_report();
  EXPECT_FALSE(good.gated);
  EXPECT_EQ(f.filter.counters(0).accepted, 1);
  EXPECT_LT(good.nis, 25.0);
}

// A camera attitude that puts target 1 behind the boresight with elevation
// pi - 1e-6: the sigma points straddle the +-pi cut of atan2, and a
// measurement 2e-6 rad further (at -pi + 1e-6) is a small wrapped residual.
TEST(SodGating, ElevationResidualIsWrappedAcrossPi) {
  Fixture f;
  const Vec3 u = (f.truth.target_eci(1).r_m - f.truth.observer_eci().r_m).normalized();
  const Vec3 p = u.cross(f.truth.observer_eci().r_m).normalized(), q = u.cross(p);
  const double eps = 1e-6;
  Mat3 R;
  R.row(0) = std::sin(eps) * u + std::cos(eps) * p;
  R.row(1) = -q;
  R.row(2) = -std::cos(eps) * u + std::sin(eps) * p;
  ASSERT_NEAR(R.determinant(), 1.0, 1e-12);
  BearingMeasurement m = f.truth.bearing(1, 20 * astro::kArcsecToRad, 0.0, nullptr);
  m.R_v_from_eci = R;
  m.angles = astro::bearing_from_eci(f.truth.observer_eci().r_m, f.truth.target_eci(1).r_m, R);
  ASSERT_NEAR(m.angles.el_rad, astro::kPi - eps, 1e-9);
  m.angles.el_rad = astro::wrap_pi(m.angles.el_rad + 2.0 * eps);
  ASSERT_LT(m.angles.el_rad, -3.0);
  const UpdateSummary s = f.filter.update_bearing(m);
  EXPECT_TRUE(s.usable) << s.brief_report();
  // Not 2 pi; the unscented mean differs from h(x) by second-order terms.
  EXPECT_NEAR(s.prefit_residual[1], 2.0 * eps, 1e-6);
  EXPECT_LT(s.mahalanobis, 1.0);
}

// Health (1): a BOD estimate 10 km away in a*dlambda with a tight covariance.
TEST(SodHealth, BodDisagreementTriggersAndReinitialisationClearsIt) {
  Fixture f;
  const double a = f.truth.observer().a_m;
  BodEstimate bod{kT0, f.truth.roe(0).as_vector(), Mat6::Identity() * std::pow(50.0 / a, 2)};
  EXPECT_FALSE(f.filter.check_bod(0, bod).disagrees);
  EXPECT_TRUE(f.filter.health().healthy());
  bod.roe[1] += 10e3 / a;
  const BodComparison c = f.filter.check_bod(0, bod);
  ASSERT_TRUE(c.usable) << c.why;
  EXPECT_TRUE(c.disagrees);
  const HealthReport h = f.filter.health();
  EXPECT_EQ(h.targets[0].condition, HealthCondition::kBodDisagreement) << h.targets[0].reason;
  EXPECT_TRUE(h.targets[1].healthy());
  EXPECT_TRUE(f.filter.reinitialize_target_from_bod(0));
  EXPECT_TRUE(f.filter.health().healthy());
  EXPECT_NEAR(f.filter.roe(0).dlambda, bod.roe[1], 1e-15);
  EXPECT_THAT(MatrixXd(f.filter.covariance()), IsSymmetricPositiveDefinite(1e-20));
  EXPECT_DOUBLE_EQ(f.filter.covariance()(0, f.filter.layout().target_offset(0) + 1), 0.0);
  // A BOD estimate at another epoch is not comparable.
  bod.t = kT0.plus_seconds(10.0);
  EXPECT_FALSE(f.filter.check_bod(0, bod).usable);
}

// Health (2): more time updates than allowed without a measurement update.
TEST(SodHealth, StepsWithoutMeasurementUpdate) {
  SodOptions o;
  o.health.max_steps_without_update = 3;
  Fixture f(o);
  for (int s = 1; s <= 3; ++s) ASSERT_TRUE(f.filter.time_update(kT0.plus_seconds(60.0 * s)).usable);
  EXPECT_TRUE(f.filter.health().healthy());
  f.truth.advance_to(kT0.plus_seconds(240.0));
  // Target 1 is measured at the fourth step, target 0 is not.
  ASSERT_TRUE(f.filter.update_bearing(f.truth.bearing(1, 20 * astro::kArcsecToRad, 0.0, nullptr)).usable);
  const HealthReport h = f.filter.health();
  EXPECT_EQ(h.targets[0].condition, HealthCondition::kNoMeasurementUpdate) << h.targets[0].reason;
  EXPECT_TRUE(h.targets[1].healthy());
  EXPECT_TRUE(h.filter.healthy());
  ASSERT_TRUE(f.filter.time_update(kT0.plus_seconds(300.0)).usable);
  for (int s = 6; s <= 8; ++s) ASSERT_TRUE(f.filter.time_update(kT0.plus_seconds(60.0 * s)).usable);
  EXPECT_EQ(f.filter.health().filter.condition, HealthCondition::kNoMeasurementUpdate);
}

// Health (3): successive large pre-fit residuals (gated ones count).
TEST(SodHealth, SuccessiveLargeResiduals) {
  SodOptions o;
  o.health.max_large_residuals = 2;
  Fixture f(o);
  BearingMeasurement bad = f.truth.bearing(0, 20 * astro::kArcsecToRad, 0.0, nullptr);
  bad.angles.az_rad += 0.02;
  for (int i = 0; i < 2; ++i) EXPECT_TRUE(f.filter.update_bearing(bad).gated);
  EXPECT_TRUE(f.filter.health().healthy());
  EXPECT_TRUE(f.filter.update_bearing(bad).gated);
  const HealthReport h = f.filter.health();
  EXPECT_EQ(h.targets[0].condition, HealthCondition::kLargeResiduals) << h.targets[0].reason;
  EXPECT_EQ(f.filter.counters(0).consecutive_large_residuals, 3);
  // A good measurement resets the count.
  EXPECT_TRUE(f.filter.update_bearing(f.truth.bearing(0, 20 * astro::kArcsecToRad, 0.0, nullptr)).usable);
  EXPECT_TRUE(f.filter.health().healthy());
}

// Health (4): observer a below R_earth + 100 km, a target beyond max_a_roe_m.
TEST(SodHealth, StateOutsideValidRange) {
  Fixture f;
  Mat6 P = f.filter.covariance().topLeftCorner<6, 6>();
  astro::QnsElements low = f.truth.observer();
  low.a_m = astro::kRadiusEarth_m + 50e3;
  f.filter.reinitialize_observer(low, P);
  HealthReport h = f.filter.health();
  EXPECT_EQ(h.filter.condition, HealthCondition::kOutOfRange) << h.filter.reason;
  Fixture g;
  Vec6 far = g.truth.roe(1).as_vector();
  far[1] = 3000e3 / g.truth.observer().a_m;
  g.filter.reinitialize_target(1, far, Mat6::Identity() * 1e-10);
  h = g.filter.health();
  EXPECT_TRUE(h.filter.healthy());
  EXPECT_EQ(h.targets[1].condition, HealthCondition::kOutOfRange) << h.targets[1].reason;
}

// A sigma point the dynamics cannot handle (e > 1) gives a status, and the
// estimate is left as it was.
TEST(SodFilter, FailedTimeUpdateReturnsStatusAndKeepsState) {
  Fixture f;
  astro::QnsElements bad = f.truth.observer();
  bad.ex = 1.5;
  f.filter.reinitialize_observer(bad, Mat6::Identity() * 1e-12);
  const VectorXd x = f.filter.state();
  const TimeUpdateSummary s = f.filter.time_update(kT0.plus_seconds(60.0));
  EXPECT_FALSE(s.usable);
  EXPECT_FALSE(s.why.empty());
  EXPECT_EQ(f.filter.state(), x);
  EXPECT_EQ(f.filter.epoch(), kT0);
  EXPECT_EQ(f.filter.health().filter.condition, HealthCondition::kOutOfRange);
}

// The propagation map of one time update: observer and targets through
// qns_from_roe, GVE-RK4 and roe_from_qns (what the sigma points go through).
VectorXd propagate_state(const VectorXd& x, TimeTT t0, TimeTT t1) {
  const dynamics::GveRk4Propagator prop(testing::j2_forces(), dynamics::SpacecraftProperties{});
  const astro::QnsElements o0 = astro::QnsElements::from_vector(x.head<6>());
  const astro::QnsElements o1 = prop.propagate(o0, t0, t1);
  VectorXd y(x.size());
  y.head<6>() = o1.as_vector();
  for (int off = 6; off < x.size(); off += 6) {
    const auto tq = astro::qns_from_roe(o0, astro::Roe::from_vector(x.segment<6>(off)));
    y.segment<6>(off) = astro::roe_from_qns(o1, prop.propagate(tq, t0, t1)).as_vector();
  }
  return y;
}

// For a small covariance the unscented time update equals the linearised
// P- = F P F^T with F by central differences of the full propagation map;
// this also checks the Cholesky-structure reuse of propagations.
TEST(SodNumerics, TimeUpdateCovarianceMatchesLinearisedPropagation) {
  SodOptions o;
  o.q_observer.setZero();
  o.q_target_a_roe_m2ps.setZero();
  o.adaptive.enabled = false;
  Fixture f(o, 1e-4, 1.0);
  const VectorXd x0 = f.filter.state();
  const MatrixXd P0 = f.filter.covariance();
  const TimeTT t1 = kT0.plus_seconds(600.0);
  const TimeUpdateSummary s = f.filter.time_update(t1);
  ASSERT_TRUE(s.usable) << s.why;
  // Propagations: observer 1 + 12, target k 1 + 2 * (6 + 6 (k + 1)).
  EXPECT_EQ(s.propagations, 13 + 25 + 37);
  const int n = static_cast<int>(x0.size());
  MatrixXd F(n, n);
  for (int k = 0; k < n; ++k) {
    const double h = std::sqrt(P0(k, k));
    VectorXd xp = x0, xm = x0;
    xp[k] += h;
    xm[k] -= h;
    F.col(k) = f.filter.state_difference(propagate_state(xp, kT0, t1), propagate_state(xm, kT0, t1)) /
               (2.0 * h);
  }
  const MatrixXd P_lin = F * P0 * F.transpose();
  const MatrixXd& P = f.filter.covariance();
  // Compare in correlation-normalised form (state scales differ by 1e14).
  const VectorXd s_lin = P_lin.diagonal().cwiseSqrt();
  const MatrixXd D = s_lin.cwiseInverse().asDiagonal();
  EXPECT_LT(((D * (P - P_lin) * D)).cwiseAbs().maxCoeff(), 1e-3);
  const VectorXd dx = f.filter.state_difference(f.filter.state(), propagate_state(x0, kT0, t1));
  EXPECT_LT(dx.cwiseQuotient(s_lin).cwiseAbs().maxCoeff(), 1e-3);
}

// The linearised prediction (telemetry, IMP) stays close to the unscented
// time update over the ~20 min a multi-observer filter runs behind the clock.
TEST(SodNumerics, LinearisedPredictionMatchesTheTimeUpdateOver20Minutes) {
  Fixture f(SodOptions{}, 1e-4, 1.0);
  SodFilter lin = f.filter;
  const TimeTT t1 = kT0.plus_seconds(1200.0);
  ASSERT_TRUE(f.filter.time_update(t1).usable);
  const TimeUpdateSummary s = lin.predict_linearised(t1);
  ASSERT_TRUE(s.usable) << s.why;
  // The observer, each target, and each target again per ROE for its block.
  EXPECT_EQ(s.propagations, 1 + 7 * f.filter.layout().n_targets);
  EXPECT_EQ(lin.epoch(), t1);
  const VectorXd sd = f.filter.covariance().diagonal().cwiseSqrt();
  const VectorXd sd_lin = lin.covariance().diagonal().cwiseSqrt();
  for (int i = 0; i < sd.size(); ++i) EXPECT_NEAR(sd_lin[i] / sd[i], 1.0, 0.02) << i;
  const MatrixXd D = sd.cwiseInverse().asDiagonal();
  const MatrixXd dC = (D * (lin.covariance() - f.filter.covariance()) * D).cwiseAbs();
  Eigen::Index r = 0, c = 0;
  // Osculating a and ey beat with J2's short-period terms, which the
  // Keplerian map leaves out: their correlation differs by ~0.06 after 20 min.
  EXPECT_LT(dC.maxCoeff(&r, &c), 0.1) << r << "," << c;
  const VectorXd dx = f.filter.state_difference(lin.state(), f.filter.state());
  EXPECT_LT(dx.cwiseQuotient(sd).cwiseAbs().maxCoeff(), 0.01);
}

// A target whose dlambda is known to 1 % of range (~550 m) and every other
// ROE to 0.2 m, as after a clock state or early in convergence: over the 10
// minutes the navigator's telemetry may lag, the linearised prediction keeps
// the covariance's thin directions as the unscented time update does (every
// generalised eigenvalue of the target block within 20 %). The Keplerian map
// it used before left the osculating ROE's short-period J2 coupling of dlambda
// out: its generalised eigenvalues were 0.004-233, some directions reported
// 10-15 x too tight in 1-sigma, others as much too wide.
TEST(SodNumerics, LinearisedPredictionKeepsTheThinDirectionsOfAnUncertainRange) {
  Fixture f(SodOptions{}, 0.01, 0.2);
  SodFilter lin = f.filter;
  const TimeTT t1 = kT0.plus_seconds(600.0);
  ASSERT_TRUE(f.filter.time_update(t1).usable);
  ASSERT_TRUE(lin.predict_linearised(t1).usable);
  for (int k = 0; k < 2; ++k) {
    const int off = f.filter.layout().target_offset(k);
    const Mat6 P_ukf = f.filter.covariance().block<6, 6>(off, off);
    const Mat6 P_lin = lin.covariance().block<6, 6>(off, off);
    const Eigen::GeneralizedSelfAdjointEigenSolver<Mat6> ge(P_lin, P_ukf);
    ASSERT_EQ(ge.info(), Eigen::Success);
    EXPECT_GT(ge.eigenvalues().minCoeff(), 0.8) << "target " << k;
    EXPECT_LT(ge.eigenvalues().maxCoeff(), 1.25) << "target " << k;
  }
}

// For a small covariance the unscented bearing update equals the Kalman
// update with H from central differences of the bearing model.
TEST(SodNumerics, BearingUpdateMatchesLinearisedKalmanUpdate) {
  Fixture f(SodOptions{}, 1e-4, 1.0);
  const VectorXd x0 = f.filter.state();
  const MatrixXd P0 = f.filter.covariance();
  const double sigma = 20 * astro::kArcsecToRad;
  BearingMeasurement m = f.truth.bearing(1, sigma, 0.0, nullptr);
  m.angles.az_rad += sigma;
  m.angles.el_rad -= sigma;
  const auto h = [&](const VectorXd& x) -> Eigen::Vector2d {
    const auto o = astro::QnsElements::from_vector(x.head<6>());
    const auto t = astro::qns_from_roe(o, astro::Roe::from_vector(x.segment<6>(12)));
    return astro::bearing_from_eci(astro::cartesian_from_qns(o).r_m, astro::cartesian_from_qns(t).r_m,
                                   m.R_v_from_eci)
        .as_vector();
  };
  const int n = static_cast<int>(x0.size());
  MatrixXd H(2, n);
  for (int k = 0; k < n; ++k) {
    const double step = 1e-2 * std::sqrt(P0(k, k));
    VectorXd xp = x0, xm = x0;
    xp[k] += step;
    xm[k] -= step;
    H.col(k) = (h(xp) - h(xm)) / (2.0 * step);
  }
  const Eigen::Matrix2d S = H * P0 * H.transpose() + Eigen::Matrix2d::Identity() * sigma * sigma;
  const MatrixXd K = P0 * H.transpose() * S.inverse();
  const Eigen::Vector2d nu = m.angles.as_vector() - h(x0);
  const VectorXd x_lin = x0 + K * nu;
  const MatrixXd P_lin = P0 - K * S * K.transpose();
  const UpdateSummary s = f.filter.update_bearing(m);
  ASSERT_TRUE(s.usable) << s.brief_report();
  EXPECT_NEAR(s.nis, nu.dot(S.inverse() * nu), 1e-3 * s.nis);
  const VectorXd sd = P0.diagonal().cwiseSqrt();
  EXPECT_LT(f.filter.state_difference(f.filter.state(), x_lin).cwiseQuotient(sd).cwiseAbs().maxCoeff(), 1e-3);
  const MatrixXd D = sd.cwiseInverse().asDiagonal();
  EXPECT_LT((D * (f.filter.covariance() - P_lin) * D).cwiseAbs().maxCoeff(), 1e-3);
}

TEST(SodNumerics, UkfWeightsAndNees) {
  Fixture f;
  const int n = f.filter.layout().size();
  EXPECT_NEAR(f.filter.weights_mean().sum(), 1.0, 1e-12);
  const SodOptions& o = f.filter.options();
  EXPECT_NEAR(f.filter.weights_covariance().sum(),
              1.0 + 1.0 - o.ukf_alpha * o.ukf_alpha + o.ukf_beta, 1e-12);
  EXPECT_EQ(f.filter.weights_mean().size(), 2 * n + 1);
  EXPECT_DOUBLE_EQ(f.filter.nees(f.filter.state()), 0.0);
  // Diagonal P: one sigma off in one component gives NEES 1; u wraps.
  VectorXd x = f.filter.state();
  const int i = StateLayout::kU;
  x[i] = astro::wrap_two_pi(x[i] + std::sqrt(f.filter.covariance()(i, i)) + astro::kTwoPi);
  EXPECT_NEAR(f.filter.nees(x), 1.0, 1e-6);
}

// 20 bearings 0.01 rad off, alternately either side: corrections far larger
// than expected, so the adaptive process noise grows. A time update after
// each when asked.
void drive_large_corrections(Fixture& f, bool time_updates) {
  for (int s = 1; s <= 20; ++s) {
    f.truth.advance_to(kT0.plus_seconds(60.0 * s));
    BearingMeasurement m = f.truth.bearing(0, 20 * astro::kArcsecToRad, 0.0, nullptr);
    m.angles.az_rad += (s % 2 ? 1 : -1) * 0.01;
    ASSERT_TRUE(f.filter.update_bearing(m).usable);
    if (time_updates) {
      ASSERT_TRUE(f.filter.time_update(kT0.plus_seconds(60.0 * s + 30.0)).usable);
    }
  }
}

// The adaptive estimate stays inside [floor, ceiling] x nominal.
TEST(SodAdaptiveNoise, ClampedBetweenFloorAndCeiling) {
  SodOptions o;
  o.adaptive.time_constant_s = 87.0;  // a gain of 1/87 s per correction: fast, as the old forgetting 0.5 was
  o.bearing_gate_mahalanobis = kInf;
  Fixture f(o, 0.05, 100.0);
  const VectorXd q0 = f.filter.process_noise_rate();
  ASSERT_NO_FATAL_FAILURE(drive_large_corrections(f, false));
  ASSERT_TRUE(f.filter.time_update(kT0.plus_seconds(60.0 * 21)).usable);
  const VectorXd& q = f.filter.process_noise_rate();
  EXPECT_GT(q.maxCoeff(), 0.0);
  for (int i = 0; i < q.size(); ++i) {
    EXPECT_GE(q[i], o.adaptive.floor_factor * q0[i] * (1 - 1e-12)) << i;
    EXPECT_LE(q[i], o.adaptive.ceiling_factor * q0[i] * (1 + 1e-12)) << i;
  }
  const int dl = f.filter.layout().target_offset(0) + StateLayout::kDlambda;
  EXPECT_GT(q[dl], q0[dl]);
}

// The adaptation runs in time (docs/sod.md, "Adaptive process noise"): the
// same bearings give the same rate whether the 60 s before each is one time
// update or two (59.5 s and 0.5 s, as a navigator that predicts to an image
// time first does). Diagonal without a clamp: the corrections' gain 1/tau
// (divided by the last interval, the 0.5 s step made the rate 120 times
// larger). Block with the unclamped average and the default clamp: the
// average outside [floor, ceiling] relaxes towards the rate over the whole
// 60 s, however it was split.
TEST(SodAdaptiveNoise, RateDoesNotDependOnHowTimeUpdatesSplitTheInterval) {
  for (const bool block : {false, true}) {
    SodOptions o;
    if (block) {
      o.adaptive.form = AdaptiveNoiseForm::kBlock;
      o.adaptive.average = AdaptiveNoiseAverage::kUnclamped;
    } else {
      o.adaptive.floor_factor = 0.0;
      o.adaptive.ceiling_factor = 1e12;  // no clamp: the estimate itself is compared
    }
    o.bearing_gate_mahalanobis = kInf;
    Fixture one(o), two(o);
    const VectorXd q0 = one.filter.process_noise_rate();
    for (int s = 1; s <= 10; ++s) {
      const TimeTT t = kT0.plus_seconds(60.0 * s);
      ASSERT_TRUE(two.filter.time_update(t.plus_seconds(-0.5)).usable);
      for (Fixture* f : {&one, &two}) {
        f->truth.advance_to(t);
        BearingMeasurement m = f->truth.bearing(0, 20 * astro::kArcsecToRad, 0.0, nullptr);
        m.angles.az_rad += (s % 2 ? 1 : -1) * 2e-3;
        ASSERT_TRUE(f->filter.update_bearing(m).usable);
      }
    }
    for (Fixture* f : {&one, &two}) ASSERT_TRUE(f->filter.time_update(kT0.plus_seconds(60.0 * 11)).usable);
    // In the nominal's units, N^-1/2 Q N^-1/2.
    const VectorXd s_inv = q0.cwiseSqrt().cwiseInverse();
    const MatrixXd Q1 = s_inv.asDiagonal() * one.filter.process_noise_rate_matrix() * s_inv.asDiagonal();
    const MatrixXd Q2 = s_inv.asDiagonal() * two.filter.process_noise_rate_matrix() * s_inv.asDiagonal();
    const int dl = one.filter.layout().target_offset(0) + StateLayout::kDlambda;
    EXPECT_GT(Q1(dl, dl), 5.0) << block;  // the corrections raised it
    for (int i = 0; i < Q1.rows(); ++i)
      for (int j = 0; j < Q1.cols(); ++j)
        EXPECT_NEAR(Q2(i, j), Q1(i, j), 1e-3 * std::max(1.0, std::abs(Q1(i, j)))) << block << " " << i << " " << j;
  }
}

// Block form (docs/sod.md): each spacecraft's 6x6 rate is symmetric, couples
// its components, and stays within [floor, ceiling] x the nominal in the
// Loewner order (eigenvalues of N^-1/2 Q N^-1/2), with either average.
TEST(SodAdaptiveNoise, BlockFormStaysBetweenFloorAndCeilingInTheLoewnerOrder) {
  for (const auto average : {AdaptiveNoiseAverage::kClamped, AdaptiveNoiseAverage::kUnclamped}) {
    SodOptions o;
    o.adaptive.form = AdaptiveNoiseForm::kBlock;
    o.adaptive.average = average;
    o.adaptive.time_constant_s = 87.0;  // a gain of 1/87 s per correction: fast, as the old forgetting 0.5 was
    o.bearing_gate_mahalanobis = kInf;
    Fixture f(o, 0.05, 100.0);
    const VectorXd q0 = f.filter.process_noise_rate();
    ASSERT_NO_FATAL_FAILURE(drive_large_corrections(f, true));
    const MatrixXd& Q = f.filter.process_noise_rate_matrix();
    const int off = f.filter.layout().target_offset(0);
    const Mat6 Qt = Q.block<6, 6>(off, off);
    EXPECT_LT((Qt - Qt.transpose()).cwiseAbs().maxCoeff(), 1e-12 * Qt.cwiseAbs().maxCoeff());
    EXPECT_GT((Qt - Mat6(Qt.diagonal().asDiagonal())).cwiseAbs().maxCoeff(), 0.0);  // coupled
    const Vec6 s_inv = q0.segment<6>(off).cwiseSqrt().cwiseInverse();
    const Eigen::SelfAdjointEigenSolver<Mat6> eig(s_inv.asDiagonal() * Qt * s_inv.asDiagonal());
    EXPECT_GE(eig.eigenvalues().minCoeff(), o.adaptive.floor_factor * (1 - 1e-9));
    EXPECT_LE(eig.eigenvalues().maxCoeff(), o.adaptive.ceiling_factor * (1 + 1e-9));
    EXPECT_GT(eig.eigenvalues().maxCoeff(), 1.0);  // the large corrections raised it
    // Outside the spacecraft blocks nothing couples.
    EXPECT_EQ(Q.block(0, off, 6, 6).cwiseAbs().maxCoeff(), 0.0);
  }
}

// A re-initialisation replaces the target's estimate: the corrections made to
// the replaced one since the last adaptation do not enter the next (with
// them, the filter re-initialised after a bearing 0.01 rad off adapts as if
// it had kept that estimate). Diagonal form without a clamp, so that the
// estimates themselves are compared.
TEST(SodAdaptiveNoise, ReinitialisationDropsTheReplacedEstimatesCorrections) {
  SodOptions o;
  o.adaptive.floor_factor = 0.0;
  o.adaptive.ceiling_factor = 1e12;
  o.bearing_gate_mahalanobis = kInf;
  // kept: the bearing, no re-initialisation; reinit: the bearing, then a
  // re-initialisation; none: the re-initialisation alone.
  Fixture kept(o), reinit(o), none(o);
  const int off = kept.filter.layout().target_offset(0);
  const Vec6 roe = kept.filter.state().segment<6>(off);
  const Mat6 P_roe = kept.filter.covariance().block<6, 6>(off, off);
  const TimeTT t = kT0.plus_seconds(60.0);
  for (Fixture* f : {&kept, &reinit, &none}) {
    ASSERT_TRUE(f->filter.time_update(t).usable);
    f->truth.advance_to(t);
  }
  for (Fixture* f : {&kept, &reinit}) {
    BearingMeasurement m = f->truth.bearing(0, 20 * astro::kArcsecToRad, 0.0, nullptr);
    m.angles.az_rad += 0.01;
    ASSERT_TRUE(f->filter.update_bearing(m).usable);
  }
  for (Fixture* f : {&reinit, &none}) f->filter.reinitialize_target(0, roe, P_roe);
  for (Fixture* f : {&kept, &reinit, &none}) ASSERT_TRUE(f->filter.time_update(t.plus_seconds(60.0)).usable);
  const VectorXd &qk = kept.filter.process_noise_rate(), &qr = reinit.filter.process_noise_rate(),
                 &qn = none.filter.process_noise_rate();
  for (int i = off; i < off + 6; ++i) {
    EXPECT_NEAR(qr[i], qn[i], 1e-9 * std::abs(qn[i])) << i;
  }
  const int dl = off + StateLayout::kDlambda;
  EXPECT_GT(qk[dl], 10.0 * qn[dl]);  // the bearing's correction would have raised it
}

// The a-priori model's drift term against two-body propagation of a
// semi-major-axis error: dlambda(t) - dlambda(0) = -1.5 n da t.
TEST(SodApriori, DlambdaDriftMatchesPropagatedSemiMajorAxisError) {
  const auto forces = dynamics::ForceModel::load(dynamics::ForceModelOptions::parse("two-body"),
                                                 ARTMS_DATA_DIR);
  const dynamics::GveRk4Propagator prop(forces, dynamics::SpacecraftProperties{});
  const astro::QnsElements o0 = testing::observer_at_start();
  const double a_da_m = 15.0;
  const astro::QnsElements t0q =
      astro::qns_from_roe(o0, astro::Roe::from_scaled_m((Vec6() << a_da_m, 0, 0, 0, 0, 0).finished(), o0.a_m));
  const double age_days = 1.5, t = age_days * astro::kSecondsPerDay;
  const TimeTT t1 = kT0.plus_seconds(t);
  const double a_dl_m =
      o0.a_m * astro::roe_from_qns(prop.propagate(o0, kT0, t1), prop.propagate(t0q, kT0, t1)).dlambda;
  AprioriErrorModel m;
  m.sigma_a_da0_m = a_da_m;
  m.sigma_a_dlambda0_m = m.sigma_a_da_rate_mpd = 0.0;
  const AprioriRoe ap = apriori_from_age(age_days, o0.a_m, m);
  EXPECT_NEAR(ap.sigma_a_roe_m[1], std::abs(a_dl_m), 1e-3 * std::abs(a_dl_m));
  // The correlation has the sign of the drift: -1.5 n da t.
  EXPECT_NEAR(ap.P_a_roe_m2(0, 1), a_da_m * a_dl_m, 1e-3 * std::abs(a_da_m * a_dl_m));
}

// Carried later in a run (a restart from the ground a-priori), the relative
// eccentricity vector turns at the perigee's J2 rate: 3.5 h turn Table 2's
// 700 m PSE vector by ~6 m, twelve times the 0.5 m the Keplerian drift
// leaves at its place. At dt = 0 the uplinked values are used as they are.
TEST(SodApriori, CarriedWithTheJ2DriftTheEccentricityVectorTurns) {
  const astro::QnsElements o = testing::observer_at_start();
  const Vec6 roe = (Vec6() << 23, -52266, -471, -523, 35, 1811).finished() / o.a_m;
  const Mat6 P = Mat6::Identity() * std::pow(30.0 / o.a_m, 2);
  EXPECT_EQ(apriori_roe_at(roe, o, 0.0), roe);
  EXPECT_EQ(apriori_covariance_at(P, o, 0.0), P);
  const double dt = 3.5 * 3600.0;
  const Vec6 j2 = apriori_roe_at(roe, o, dt), kepler = apriori_roe_drifted(roe, o.a_m, dt);
  const double w_dot = dynamics::j2_secular_rates(dynamics::mean_from_osculating(o)).argp_dot_radps;
  const double turned = std::atan2(j2[3], j2[2]) - std::atan2(roe[3], roe[2]);
  EXPECT_NEAR(turned, w_dot * dt, 0.05 * std::abs(w_dot * dt));
  EXPECT_GT(o.a_m * std::hypot(j2[2] - kepler[2], j2[3] - kepler[3]), 4.0);  // m
  // The along-track drift kept (-1.5 n da dt = -490 m), and J2's own part of it from dix (~1 m).
  EXPECT_NEAR(o.a_m * (kepler[1] - roe[1]), -1.5 * std::sqrt(astro::kGmEarth_m3ps2 / std::pow(o.a_m, 3)) * 23.0 * dt,
              1e-6);
  EXPECT_NEAR(o.a_m * j2[1], o.a_m * kepler[1], 5.0);
  const Mat6 Pj = apriori_covariance_at(P, o, dt);
  EXPECT_TRUE(Pj.isApprox(Pj.transpose(), 1e-12));
  EXPECT_GT(Pj(1, 1), P(1, 1));
}

TEST(SodApriori, GrowsWithAgeAndDrawsMatchCovariance) {
  const double a = testing::observer_at_start().a_m;
  const AprioriRoe fresh = apriori_from_age(0.0, a), old = apriori_from_age(3.0, a);
  EXPECT_NEAR(fresh.sigma_a_roe_m[1], AprioriErrorModel{}.sigma_a_dlambda0_m, 1e-9);
  for (int i = 0; i < 6; ++i) EXPECT_GE(old.sigma_a_roe_m[i], fresh.sigma_a_roe_m[i]);
  EXPECT_GT(old.sigma_a_roe_m[1], 10.0 * fresh.sigma_a_roe_m[1]);
  EXPECT_NEAR((old.P_roe * a * a - old.P_a_roe_m2).cwiseAbs().maxCoeff(), 0.0,
              1e-9 * old.P_a_roe_m2.maxCoeff());
  EXPECT_THROW(apriori_from_age(-1.0, a), std::invalid_argument);
  std::mt19937_64 rng(7);
  Mat6 C = Mat6::Zero();
  const int kDraws = 20000;
  for (int k = 0; k < kDraws; ++k) {
    const Vec6 e = draw_apriori_error_a_roe_m(old, rng);
    C += e * e.transpose() / kDraws;
  }
  for (int i = 0; i < 6; ++i)
    EXPECT_NEAR(C(i, i), old.P_a_roe_m2(i, i), 0.05 * old.P_a_roe_m2(i, i)) << i;
  const double rho = old.P_a_roe_m2(0, 1) / std::sqrt(old.P_a_roe_m2(0, 0) * old.P_a_roe_m2(1, 1));
  EXPECT_NEAR(C(0, 1) / std::sqrt(C(0, 0) * C(1, 1)), rho, 0.03);
}

TEST(SodProcessNoise, UnmodelledAccelerationThroughGaussEquations) {
  // Oracle: a constant along-track acceleration f over dt raises a by
  // 2 f dt / n (Gauss); as white noise of PSD 2 sigma^2 tau its variance rate
  // is (2/n)^2 2 sigma^2 tau.
  const double a = 6945e3, i = 99.4 * M_PI / 180.0, sigma = 1.5e-7, tau = 5760.0;
  const Vec6 q = observer_process_noise_from_acceleration(a, i, sigma, tau);
  const double n = std::sqrt(astro::kGmEarth_m3ps2 / (a * a * a));
  EXPECT_NEAR(q[0], std::pow(2.0 / n, 2) * 2.0 * sigma * sigma * tau, 1e-12 * q[0]);
  EXPECT_NEAR(q[0], 8.9e-4, 0.3e-4);  // m^2/s: ~22 x SodOptions' built-in 4e-5
  EXPECT_DOUBLE_EQ(q[1], q[2]);
  EXPECT_NEAR(q[5] / q[1], 4.0 / 2.5, 1e-12);
  EXPECT_GT(q[4], q[3]);  // RAAN: 1 / sin^2 i
  EXPECT_TRUE(observer_process_noise_from_acceleration(a, i, 0.0, tau).isZero());
  EXPECT_THROW(observer_process_noise_from_acceleration(-1.0, i, sigma, tau), std::invalid_argument);
}

TEST(SodCoarseOrbit, DrawsMatchTheirCartesianCovariance) {
  // Mode 4's coarse orbit: the error drawn as a*ROE of truth relative to the
  // uplinked orbit has the requested 1-sigma, and the Cartesian covariance
  // that goes up with it is consistent with the Cartesian errors (mean NEES 6).
  const astro::StateVector truth = astro::cartesian_from_qns(testing::observer_at_start());
  const Vec6 sigma = (Vec6() << 20.0, 5000.0, 500.0, 500.0, 500.0, 500.0).finished();
  std::mt19937_64 rng(11);
  const int kDraws = 4000;
  Vec6 var = Vec6::Zero();
  double nees = 0.0, nees_r = 0.0, nees_v = 0.0;
  for (int k = 0; k < kDraws; ++k) {
    const CoarseOrbit c = draw_coarse_orbit(truth, sigma, rng);
    const astro::QnsElements q = astro::qns_from_cartesian(c.x_eci);
    const Vec6 e = q.a_m * astro::roe_from_qns(q, astro::qns_from_cartesian(truth)).as_vector();
    var += e.cwiseAbs2() / kDraws;
    Vec6 d;
    d << truth.r_m - c.x_eci.r_m, truth.v_mps - c.x_eci.v_mps;
    nees += d.dot(c.P_rv.ldlt().solve(d)) / kDraws;
    nees_r += d.head<3>().dot(c.P_rv.topLeftCorner<3, 3>().ldlt().solve(d.head<3>())) / kDraws;
    nees_v += d.tail<3>().dot(c.P_rv.bottomRightCorner<3, 3>().ldlt().solve(d.tail<3>())) / kDraws;
  }
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(std::sqrt(var[i]), sigma[i], 0.05 * sigma[i]) << i;
  // Position and velocity each consistent (3 dof); jointly 6 within 10 %: the
  // 5 km along-track error's curvature shows in the thin directions of the
  // strongly correlated [r; v] covariance (first order).
  EXPECT_NEAR(nees_r, 3.0, 0.2);
  EXPECT_NEAR(nees_v, 3.0, 0.2);
  EXPECT_NEAR(nees, 6.0, 0.6);
  EXPECT_THROW(coarse_orbit_covariance_rv(truth, Vec6::Zero()), std::invalid_argument);
}

}  // namespace
}  // namespace artms::sod
