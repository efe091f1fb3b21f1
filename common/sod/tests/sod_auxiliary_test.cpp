// Auxiliary states (paper, "System State") and health check 5: the camera's
// time-tag offset estimated from bearings, each target's differential
// ballistic coefficient estimated from bearings against a world with more
// drag than the onboard nominal, NIS-window over-confidence detection and
// covariance inflation, and the chi-square quantile they use.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <cmath>
#include <cstdio>
#include <memory>
#include <tuple>

#include "artms/sod/sod_filter.hpp"
#include "artms/testing/testing.hpp"
#include "sod_scenario.hpp"

namespace artms::sod {
namespace {

using testing::InitialGuess;
using testing::Truth;
using astro::Roe;

constexpr double kStep_s = 60.0;

// J2 and the onboard Harris-Priester drag.
const dynamics::ForceModel& j2_drag_forces() {
  static const dynamics::ForceModel forces =
      dynamics::ForceModel::load(dynamics::ForceModelOptions::parse("grav2_0,drag"), ARTMS_DATA_DIR);
  return forces;
}
const TimeTT kT0 = astro::tt_from_utc_string("2024-05-08T00:00:00Z");

TEST(SodChi2, QuantileMatchesScipy) {
  // scipy.stats.chi2.ppf(p, k), scipy 1.10 (Debian 12).
  struct Case {
    int k;
    double p, expected;
  };
  for (const Case c : {Case{40, 1 - 1e-4, 82.06229383534452}, Case{20, 0.999, 45.31474661812586},
                       Case{10, 0.99, 23.209251158954356}, Case{100, 1 - 1e-6, 182.12677711942618}}) {
    EXPECT_NEAR(chi2_quantile(c.k, c.p), c.expected, 0.005 * c.expected) << c.k << " " << c.p;
  }
  EXPECT_THROW(chi2_quantile(0, 0.5), std::invalid_argument);
  EXPECT_THROW(chi2_quantile(4, 1.0), std::invalid_argument);
}

struct AuxRun {
  double offset_s = kNaN, offset_sigma_s = kNaN;
  double dB = kNaN, dB_sigma = kNaN;
  std::vector<Vec6> err_a_roe_m, sigma_a_roe_m;
  bool inconsistent_seen = false;
  std::string first_unhealthy;
};

// Bearings every 60 s to two targets (5" noise) whose time tags are late by
// `tag_offset_s`; GNSS at the true epochs.
AuxRun run_time_tag(double tag_offset_s, int n_time_tag, int orbits, std::uint64_t seed) {
  const astro::QnsElements obs0 = testing::observer_at_start();
  std::vector<Vec6> a_roe = testing::starling_a_roe_m();
  a_roe.resize(2);
  Truth truth(kT0, obs0, a_roe);
  StateLayout layout{2, 0};
  layout.n_time_tag = n_time_tag;
  SodOptions o;
  o.q_time_tag_offset_s2ps = 1e-6 / 86400.0;
  SodFilter filter(testing::j2_forces(), {}, {}, layout, o);
  const InitialGuess g = testing::shifted_initial_guess(obs0, a_roe, 0.02, 30.0);
  MatrixXd P = MatrixXd::Zero(layout.size(), layout.size());
  P.topLeftCorner(g.P.rows(), g.P.cols()) = g.P;
  if (n_time_tag > 0) P(layout.time_tag_offset(), layout.time_tag_offset()) = 1.0;  // 1 s
  VectorXd x0 = VectorXd::Zero(layout.size());
  x0.head(g.x.size()) = g.x;
  filter.initialize(kT0, x0, P);
  std::mt19937_64 rng(seed);
  const double sigma = 5.0 * astro::kArcsecToRad;
  const int steps = static_cast<int>(orbits * astro::orbit_period_s(obs0.a_m) / kStep_s);
  AuxRun r;
  for (int s = 1; s <= steps; ++s) {
    truth.advance_to(kT0.plus_seconds(kStep_s * s));
    EXPECT_TRUE(filter.update_gnss(truth.gnss(3.0, 0.01, true, &rng)).usable);
    for (int k = 0; k < 2; ++k) {
      BearingMeasurement m = truth.bearing(k, sigma, sigma, &rng);
      m.t = m.t.plus_seconds(tag_offset_s);
      (void)filter.update_bearing(m);
    }
    const HealthReport h = filter.health();
    for (const auto& t : h.targets) {
      if (t.condition == HealthCondition::kInconsistent) r.inconsistent_seen = true;
      if (!t.healthy() && r.first_unhealthy.empty()) r.first_unhealthy = t.reason;
    }
  }
  // The filter is 0.5 s ahead of the truth's epoch after the last bearing.
  (void)filter.time_update(truth.t());
  if (n_time_tag > 0) {
    r.offset_s = filter.state()[layout.time_tag_offset()];
    r.offset_sigma_s = std::sqrt(filter.covariance()(layout.time_tag_offset(), layout.time_tag_offset()));
  }
  for (int k = 0; k < 2; ++k) {
    r.err_a_roe_m.push_back(filter.a_roe_m(k) - truth.a_roe_m(k));
    r.sigma_a_roe_m.push_back(filter.a_roe_sigma_m(k));
  }
  return r;
}

// A +0.5 s time-tag offset is estimated within 0.02 s in 6 orbits and the
// ROE stay within 3 sigma (issue 17, acceptance 4, in the filter alone).
// A target re-initialised from an estimator that used this filter's clock
// (BOD's batch): its covariance gains J P_clock J^T, its cross-covariances
// are -J P_clock,*, and the joint covariance stays positive definite. The
// estimate's error then matches a Monte Carlo of e = -J e_clock + n.
TEST(SodAuxiliary, ReinitialisationFromAClockDependentEstimateCarriesTheClockDoubt) {
  const astro::QnsElements obs0 = testing::observer_at_start();
  std::vector<Vec6> a_roe = testing::starling_a_roe_m();
  a_roe.resize(2);
  StateLayout layout{2, 0};
  layout.n_time_tag = 2;
  SodFilter filter(testing::j2_forces(), {}, {}, layout, SodOptions{});
  const InitialGuess g = testing::shifted_initial_guess(obs0, a_roe, 0.02, 30.0);
  MatrixXd P = MatrixXd::Zero(layout.size(), layout.size());
  P.topLeftCorner(g.P.rows(), g.P.cols()) = g.P;
  const int c = layout.time_tag_offset();
  P(c, c) = 0.05 * 0.05;
  P(c + 1, c + 1) = 1e-10;  // 10 ppm
  P(c, c + 1) = P(c + 1, c) = 0.5 * 0.05 * 1e-5;
  // The other target correlated with the clock, as bearings make it.
  const int other = layout.target_offset(0);
  P(other + 1, c) = P(c, other + 1) = 0.5 * std::sqrt(P(other + 1, other + 1)) * 0.05;
  VectorXd x0 = VectorXd::Zero(layout.size());
  x0.head(g.x.size()) = g.x;
  filter.initialize(kT0, x0, P);

  const int k = 1, off = layout.target_offset(k);
  const Vec6 roe = a_roe[1] / obs0.a_m;
  const Mat6 P_own = (Vec6() << 1e-12, 1e-8, 1e-11, 1e-11, 1e-11, 1e-11).finished().asDiagonal();
  MatrixXd J = MatrixXd::Zero(6, 2);
  J(1, 0) = -0.02 / 0.05 * 1.0;   // dlambda: 2 % of range per 0.05 s (2 v dt / rho at ~50 km)
  J(0, 0) = 1e-7;
  J(1, 1) = -300.0;               // per unit drift (s/s) over the batch
  filter.reinitialize_target(k, roe, P_own, J);
  const MatrixXd& Pn = filter.covariance();
  const MatrixXd Pcc = P.block(c, c, 2, 2);
  EXPECT_LT((Pn.block(off, off, 6, 6) - (P_own + J * Pcc * J.transpose())).norm(), 1e-15);
  EXPECT_LT((Pn.block(off, c, 6, 2) - (-J * Pcc)).norm(), 1e-18);
  // Correlated with the other target through the clock: -J P_clock,other.
  EXPECT_LT((Pn.block(off, other, 6, 6) - (-J * P.block(c, other, 2, 6))).norm(), 1e-18);
  EXPECT_NE(Pn(off + 1, other + 1), 0.0);
  EXPECT_LT((Pn - Pn.transpose()).norm(), 1e-18);
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<MatrixXd>(Pn).eigenvalues().minCoeff(), 0.0);
  EXPECT_EQ(filter.state().segment<6>(off), roe);
  // Against a Monte Carlo of the estimator's error -J e_clock + n.
  std::mt19937_64 rng(7);
  std::normal_distribution<double> N01;
  const Eigen::LLT<MatrixXd> Lc(Pcc);
  const Eigen::LLT<Mat6> Ln(P_own);
  Eigen::Vector2d s_ce = Eigen::Vector2d::Zero();
  double s_ll = 0.0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    Eigen::Vector2d z{N01(rng), N01(rng)};
    Vec6 w;
    for (int j = 0; j < 6; ++j) w[j] = N01(rng);
    const Eigen::Vector2d ec = Lc.matrixL() * z;
    const Vec6 e = -J * ec + Ln.matrixL() * w;
    s_ll += e[1] * e[1];
    s_ce += e[1] * ec;
  }
  EXPECT_NEAR(s_ll / n / Pn(off + 1, off + 1), 1.0, 0.05);
  EXPECT_NEAR(s_ce[0] / n / Pn(off + 1, c), 1.0, 0.05);
  // An empty J is the plain re-initialisation: no clock correlation.
  filter.reinitialize_target(k, roe, P_own, MatrixXd());
  EXPECT_EQ(filter.covariance().block(off, c, 6, 2).norm(), 0.0);
  EXPECT_THROW(filter.reinitialize_target(k, roe, P_own, MatrixXd::Zero(6, 1)), std::invalid_argument);
}

TEST(SodAuxiliary, TimeTagOffsetIsEstimatedFromBearings) {
  constexpr double kOffset_s = 0.5, kTol_s = 0.02;
  const AuxRun r = run_time_tag(kOffset_s, 1, 6, 7);
  std::printf("time-tag offset estimate %.4f s (1-sigma %.4f), truth %.2f\n", r.offset_s, r.offset_sigma_s, kOffset_s);
  EXPECT_NEAR(r.offset_s, kOffset_s, kTol_s);
  EXPECT_LT(std::abs(r.offset_s - kOffset_s), 3.0 * r.offset_sigma_s);
  for (int k = 0; k < 2; ++k)
    for (int i = 0; i < 6; ++i)
      EXPECT_LT(std::abs(r.err_a_roe_m[k][i]), 3.0 * r.sigma_a_roe_m[k][i]) << "target " << k << " roe " << i;
}

// A target's unknown 5 cm/s along-track burn after 2 orbits of convergence:
// health check 5 (the mean NIS of its last 20 bearings, gated ones included)
// fires within an orbit; inflating the target's covariance by that of an
// unknown manoeuvre (as the navigator does) brings every ROE back within 3 sigma.
TEST(SodHealth, NisWindowFlagsATargetBurnAndInflationRecovers) {
  const astro::QnsElements obs0 = testing::observer_at_start();
  std::vector<Vec6> a_roe = testing::starling_a_roe_m();
  a_roe.resize(2);
  Truth truth(kT0, obs0, a_roe);
  SodOptions o;
  o.health.nis_window = 20;
  o.health.nis_max_mean = chi2_quantile(40, 1.0 - 1e-4) / 20.0;
  SodFilter filter(testing::j2_forces(), {}, {}, StateLayout{2, 0}, o);
  const InitialGuess g = testing::shifted_initial_guess(obs0, a_roe, 0.02, 30.0);
  filter.initialize(kT0, g.x, g.P);
  std::mt19937_64 rng(11);
  const double sigma = 5.0 * astro::kArcsecToRad;
  const double period = astro::orbit_period_s(obs0.a_m);
  const int burn_step = static_cast<int>(2 * period / kStep_s), steps = static_cast<int>(7 * period / kStep_s);
  int flagged_step = -1, inflations = 0, false_alarms = 0;
  for (int s = 1; s <= steps; ++s) {
    truth.advance_to(kT0.plus_seconds(kStep_s * s));
    if (s == burn_step) truth.apply_target_dv(0, Vec3(0.0, 0.05, 0.0));
    ASSERT_TRUE(filter.update_gnss(truth.gnss(3.0, 0.01, true, &rng)).usable);
    for (int k = 0; k < 2; ++k) (void)filter.update_bearing(truth.bearing(k, sigma, sigma, &rng));
    const HealthReport h = filter.health();
    for (int k = 0; k < 2; ++k) {
      if (h.targets[k].condition != HealthCondition::kInconsistent) continue;
      if (k != 0 || s < burn_step) ++false_alarms;
      if (k == 0 && flagged_step < 0) flagged_step = s;
      filter.inflate_target_maneuver(k, std::clamp(0.02 * std::sqrt(filter.recent_mean_nis(k)), 0.02, 1.0),
                                     filter.recent_nis_span_s(k));
      ++inflations;
    }
  }
  std::printf("burn at step %d, flagged at step %d (%.2f orbits later), %d inflations, %d false alarms\n", burn_step,
              flagged_step, (flagged_step - burn_step) * kStep_s / period, inflations, false_alarms);
  EXPECT_EQ(false_alarms, 0);
  ASSERT_GE(flagged_step, burn_step);
  EXPECT_LT((flagged_step - burn_step) * kStep_s, period);
  const Vec6 err = filter.a_roe_m(0) - truth.a_roe_m(0), sig = filter.a_roe_sigma_m(0);
  for (int i = 0; i < 6; ++i) EXPECT_LT(std::abs(err[i]), 3.0 * sig[i]) << "roe " << i << " error " << err[i];
}

TEST(SodHealth, InflateTargetScalesItsBlockAndKeepsCorrelations) {
  StateLayout layout{2, 0};
  layout.ballistic = true;
  SodFilter f(testing::j2_forces(), {}, {}, layout);
  const int n = layout.size();
  MatrixXd A = MatrixXd::Random(n, n);
  MatrixXd P = A * A.transpose() * 1e-8 + MatrixXd::Identity(n, n) * 1e-8;
  VectorXd x = VectorXd::Zero(n);
  x.head<6>() = testing::observer_at_start().as_vector();
  x.segment<6>(6) = Roe::from_scaled_m(testing::starling_a_roe_m()[0], x[0]).as_vector();
  x.segment<6>(12) = Roe::from_scaled_m(testing::starling_a_roe_m()[1], x[0]).as_vector();
  f.initialize(kT0, x, P);
  f.inflate_target(1, 4.0);
  const MatrixXd& Q = f.covariance();
  EXPECT_NEAR(Q(12, 12), 4.0 * P(12, 12), 1e-12 * P(12, 12));
  EXPECT_NEAR(Q(12, 3), 2.0 * P(12, 3), 1e-9 * std::abs(P(12, 3)) + 1e-30);
  EXPECT_DOUBLE_EQ(Q(6, 6), P(6, 6));
  EXPECT_NEAR(Q(layout.ballistic_index(1), layout.ballistic_index(1)),
              4.0 * P(layout.ballistic_index(1), layout.ballistic_index(1)), 1e-20);
  EXPECT_DOUBLE_EQ(Q(layout.ballistic_index(0), layout.ballistic_index(0)),
                   P(layout.ballistic_index(0), layout.ballistic_index(0)));
  EXPECT_THROW(f.inflate_target(2, 2.0), std::invalid_argument);
  EXPECT_THROW(f.inflate_target(0, 0.5), std::invalid_argument);
}

// Drag world: the target's Cd A/m is 1.6 x the onboard nominal. The filter
// with a differential ballistic state estimates the excess and keeps every
// ROE within 3 sigma; its estimate of dB is within 3 sigma of the truth.
TEST(SodAuxiliary, DifferentialBallisticCoefficientIsEstimated) {
  const dynamics::ForceModel& drag_forces = j2_drag_forces();
  const dynamics::SpacecraftProperties nominal;
  dynamics::SpacecraftProperties heavy_drag = nominal;
  heavy_drag.cd = 1.6 * nominal.cd;
  const double dB_true = (heavy_drag.cd - nominal.cd) * nominal.drag_area_m2 / nominal.mass_kg;
  // Lower than Starling (450 km) so that the drag acts within a few orbits.
  astro::QnsElements obs = testing::observer_at_start();
  obs.a_m = astro::kRadiusEarth_m + 450e3;
  const Vec6 a_roe = testing::starling_a_roe_m()[0];
  astro::QnsElements tgt = astro::qns_from_roe(obs, Roe::from_scaled_m(a_roe, obs.a_m));
  dynamics::GveRk4Propagator p_obs(drag_forces, nominal), p_tgt(drag_forces, heavy_drag);

  StateLayout layout{1, 0};
  layout.ballistic = true;
  SodOptions o;
  const double B = nominal.cd * nominal.drag_area_m2 / nominal.mass_kg;
  o.q_ballistic_m4pkg2ps = std::pow(0.5 * B, 2) / 86400.0;
  SodFilter filter(drag_forces, nominal, nominal, layout, o);
  VectorXd x = VectorXd::Zero(layout.size());
  x.head<6>() = obs.as_vector();
  x.segment<6>(6) = astro::roe_from_qns(obs, tgt).as_vector();
  x[6 + 1] *= 1.01;
  MatrixXd P = MatrixXd::Zero(layout.size(), layout.size());
  P.topLeftCorner<6, 6>().diagonal() << 1.0, 1e-12, 1e-12, 1e-12, 1e-12, 1e-12;
  const Vec6 s_roe = (Vec6() << 10, 0.02 * std::abs(a_roe[1]), 10, 10, 10, 10).finished() / obs.a_m;
  P.block<6, 6>(6, 6) = s_roe.cwiseAbs2().asDiagonal();
  P(layout.ballistic_index(0), layout.ballistic_index(0)) = std::pow(B, 2);
  filter.initialize(kT0, x, P);

  std::mt19937_64 rng(3);
  std::normal_distribution<double> g(0.0, 1.0);
  const double sigma = 5.0 * astro::kArcsecToRad;
  TimeTT t = kT0;
  const int steps = static_cast<int>(8 * astro::orbit_period_s(obs.a_m) / kStep_s);
  for (int s = 1; s <= steps; ++s) {
    const TimeTT t1 = kT0.plus_seconds(kStep_s * s);
    obs = p_obs.propagate(obs, t, t1);
    tgt = p_tgt.propagate(tgt, t, t1);
    t = t1;
    GnssMeasurement gm;
    gm.t = t;
    gm.x_eci = astro::cartesian_from_qns(obs);
    for (int i = 0; i < 3; ++i) gm.x_eci.r_m[i] += 3.0 * g(rng);
    gm.sigma_r_m = 3.0;
    gm.sigma_v_mps = 0.01;
    ASSERT_TRUE(filter.update_gnss(gm).usable);
    const Vec3 los = astro::cartesian_from_qns(tgt).r_m - astro::cartesian_from_qns(obs).r_m;
    const Mat3 R = astro::R_v_from_eci(astro::cartesian_from_qns(obs), astro::Boresight::kMinusVelocity);
    BearingMeasurement m = bearing_measurement_from_unit_eci(t, 0, los.normalized(), sigma, R);
    m.angles.az_rad += sigma * g(rng);
    m.angles.el_rad += sigma * g(rng);
    (void)filter.update_bearing(m);
  }
  const int ib = layout.ballistic_index(0);
  const double dB = filter.state()[ib], dB_sigma = std::sqrt(filter.covariance()(ib, ib));
  const Vec6 err = filter.a_roe_m(0) - obs.a_m * astro::roe_from_qns(obs, tgt).as_vector();
  std::printf("dB estimate %.5f (1-sigma %.5f), truth %.5f m^2/kg; a*dlambda error %.1f m (1-sigma %.1f)\n", dB,
              dB_sigma, dB_true, err[1], filter.a_roe_sigma_m(0)[1]);
  EXPECT_LT(std::abs(dB - dB_true), 3.0 * dB_sigma);
  EXPECT_LT(dB_sigma, 0.5 * dB_true);  // observable: the state learned something
  for (int i = 0; i < 6; ++i) EXPECT_LT(std::abs(err[i]), 3.0 * filter.a_roe_sigma_m(0)[i]) << "roe " << i;
}

// The ballistic state's rates (Gauss's equations, near-circular) against the
// numerical propagator: a target whose ballistic coefficient is twice the
// nominal, flown by the filter as the nominal plus dB = B (no measurement,
// a covariance too small to matter), follows a direct propagation with the
// doubled drag over two orbits in every ROE, the relative eccentricity's
// drive by the day-night density bulge included.
TEST(SodAuxiliary, BallisticStateRatesFollowTheNumericalPropagator) {
  const dynamics::ForceModel& drag_forces = j2_drag_forces();
  const dynamics::SpacecraftProperties nominal;
  dynamics::SpacecraftProperties doubled = nominal;
  doubled.drag_area_m2 *= 2.0;
  const double B = nominal.cd * nominal.drag_area_m2 / nominal.mass_kg;
  astro::QnsElements obs = testing::observer_at_start();
  obs.a_m = astro::kRadiusEarth_m + 450e3;
  const Vec6 a_roe = testing::starling_a_roe_m()[0];
  const astro::QnsElements tgt0 = astro::qns_from_roe(obs, Roe::from_scaled_m(a_roe, obs.a_m));
  StateLayout layout{1, 0};
  layout.ballistic = true;
  SodOptions o;
  o.adaptive.enabled = false;
  o.q_target_a_roe_m2ps = Vec6::Zero();
  o.q_observer = Vec6::Zero();
  o.q_ballistic_m4pkg2ps = 0.0;
  SodFilter filter(drag_forces, nominal, nominal, layout, o);
  VectorXd x = VectorXd::Zero(layout.size());
  x.head<6>() = obs.as_vector();
  x.segment<6>(6) = astro::roe_from_qns(obs, tgt0).as_vector();
  x[layout.ballistic_index(0)] = B;
  VectorXd sigma = VectorXd::Constant(layout.size(), 1e-10);  // ~1 mm in a*ROE and the observer's angles
  sigma[StateLayout::kA] = 1e-3;
  sigma[layout.ballistic_index(0)] = 1e-6 * B;
  filter.initialize(kT0, x, MatrixXd(sigma.cwiseAbs2().asDiagonal()));
  const dynamics::GveRk4Propagator p_nominal(drag_forces, nominal, o.propagator), p_doubled(drag_forces, doubled, o.propagator);
  const int steps = static_cast<int>(2 * astro::orbit_period_s(obs.a_m) / kStep_s);
  const TimeTT t1 = kT0.plus_seconds(kStep_s * steps);
  for (int s = 1; s <= steps; ++s) ASSERT_TRUE(filter.time_update(kT0.plus_seconds(kStep_s * s)).usable);
  const astro::QnsElements obs1 = p_nominal.propagate(obs, kT0, t1);
  const Vec6 with_nominal = obs.a_m * astro::roe_from_qns(obs1, p_nominal.propagate(tgt0, kT0, t1)).as_vector();
  const Vec6 with_doubled = obs.a_m * astro::roe_from_qns(obs1, p_doubled.propagate(tgt0, kT0, t1)).as_vector();
  const Vec6 effect = with_doubled - with_nominal, modelled = filter.a_roe_m(0) - with_nominal;
  std::printf("a*ROE [da, dl, dex, dey, dix, diy] after 2 orbits, m: effect of doubling B ");
  for (int i = 0; i < 6; ++i) std::printf("%.3f ", effect[i]);
  std::printf("; the ballistic state's ");
  for (int i = 0; i < 6; ++i) std::printf("%.3f ", modelled[i]);
  std::printf("\n");
  // The bulge drives the relative eccentricity by a sizeable part of a*da's change.
  const double e_effect = std::hypot(effect[2], effect[3]);
  EXPECT_GT(e_effect, 0.05 * std::abs(effect[0]));
  constexpr double kRelTol = 0.05;  // first-order rates at the step's start over 60 s steps
  for (int i = 0; i < 6; ++i) {
    const double scale = i == 1 ? std::abs(effect[1]) : std::max(std::abs(effect[0]), e_effect);
    EXPECT_NEAR(modelled[i], effect[i], kRelTol * scale) << "roe " << i;
  }
  EXPECT_NEAR(std::hypot(modelled[2], modelled[3]), e_effect, kRelTol * e_effect);
}

// A target's along-track noise is the observer's along-track part in ROE
// units: da = dv_T 2/(n a), d(ex, ey) at half of it (u-averaged), none on
// dlambda, dix, diy (Gauss, M&G eq. 3.98).
TEST(SodProcessNoise, TargetAlongTrackNoiseThroughGaussEquations) {
  const double a = 6945e3, sigma = 2e-8, tau = 5760.0;
  const Vec6 q = target_along_track_process_noise(a, sigma, tau);
  const Vec6 q_obs = observer_process_noise_from_acceleration(a, 1.7, sigma, tau);
  EXPECT_NEAR(q[0] * a * a, q_obs[0], 1e-12 * q_obs[0]);
  EXPECT_DOUBLE_EQ(q[2], q[3]);
  EXPECT_NEAR(q[2], 0.5 * q[0], 1e-12 * q[0]);
  EXPECT_EQ(q[1], 0.0);
  EXPECT_EQ(q[4], 0.0);
  EXPECT_EQ(q[5], 0.0);
  EXPECT_THROW(target_along_track_process_noise(a, -1.0, tau), std::invalid_argument);
}

// Two targets at 450 km with ballistic states, the first estimated at
// dB = 2 B, the second at 0 (1-sigma B each, B the nominal Cd A/m): a time
// update to 60 s, a GNSS fix 5 m off in x, and the time update to 120 s at
// whose start the rates are set. x_seen, P_seen: what that adaptation saw.
struct BallisticRun {
  std::unique_ptr<SodFilter> filter;
  VectorXd x_seen;
  MatrixXd P_seen;
};
SodOptions block_unclamped_options(bool adaptive, bool targets) {
  SodOptions o;
  o.adaptive.enabled = adaptive;
  o.adaptive.targets = targets;
  o.adaptive.form = AdaptiveNoiseForm::kBlock;
  o.adaptive.average = AdaptiveNoiseAverage::kUnclamped;
  return o;
}
StateLayout two_ballistic_targets_layout() {
  StateLayout layout{2, 0};
  layout.ballistic = true;
  return layout;
}
astro::QnsElements observer_at_450_km() {
  astro::QnsElements obs = testing::observer_at_start();
  obs.a_m = astro::kRadiusEarth_m + 450e3;
  return obs;
}
BallisticRun run_two_ballistic_targets(const SodOptions& o, const StateLayout& layout, const astro::QnsElements& obs) {
  const dynamics::SpacecraftProperties nominal;
  const double B = nominal.cd * nominal.drag_area_m2 / nominal.mass_kg;
  BallisticRun r;
  r.filter = std::make_unique<SodFilter>(j2_drag_forces(), nominal, nominal, layout, o);
  VectorXd x = VectorXd::Zero(layout.size());
  x.head<6>() = obs.as_vector();
  for (int k = 0; k < 2; ++k) {
    x.segment<6>(layout.target_offset(k)) = Roe::from_scaled_m(testing::starling_a_roe_m()[k], obs.a_m).as_vector();
  }
  x[layout.ballistic_index(0)] = 2.0 * B;
  MatrixXd P = MatrixXd::Identity(layout.size(), layout.size()) * 1e-12;
  P(0, 0) = 100.0;
  P(layout.ballistic_index(0), layout.ballistic_index(0)) = P(layout.ballistic_index(1), layout.ballistic_index(1)) =
      B * B;
  r.filter->initialize(kT0, x, P);
  EXPECT_TRUE(r.filter->time_update(kT0.plus_seconds(60.0)).usable);
  GnssMeasurement gm;
  gm.t = kT0.plus_seconds(60.0);
  gm.x_eci = astro::cartesian_from_qns(astro::QnsElements::from_vector(r.filter->state().head<6>()));
  gm.x_eci.r_m[0] += 5.0;
  gm.sigma_r_m = 3.0;
  gm.sigma_v_mps = 0.01;
  EXPECT_TRUE(r.filter->update_gnss(gm).usable);
  r.x_seen = r.filter->state();
  r.P_seen = r.filter->covariance();
  EXPECT_TRUE(r.filter->time_update(kT0.plus_seconds(120.0)).usable);
  return r;
}

// The drag floor (docs/sod.md): a target estimated with a differential
// ballistic coefficient of twice the nominal Cd A/m gets, after an adaptive
// step, a process noise at least floor x nominal + the unmodelled drag's
// (density error x |dB| x the onboard drag per unit B, |dB| the estimate's
// magnitude less its own spread, sqrt(dB^2 - sigma_B^2)) in the Loewner
// order; a target with dB = 0 gets the same noise as without the floor, and
// so does every target when the option is 0. Without the adaptation the
// floor still holds (a budget, not an adaptation): per component the nominal
// rate, at least floor x nominal + D.
TEST(SodAdaptiveNoise, DragFloorFollowsTheEstimatedBallisticCoefficient) {
  const dynamics::ForceModel& drag_forces = j2_drag_forces();
  const dynamics::SpacecraftProperties nominal;
  const double B = nominal.cd * nominal.drag_area_m2 / nominal.mass_kg, error = 0.5;
  const StateLayout layout = two_ballistic_targets_layout();
  const astro::QnsElements obs = observer_at_450_km();
  VectorXd x_seen;  // the state and covariance the adaptation sees: after the update at 60 s
  MatrixXd P_seen;
  const auto run = [&](double density_error, bool adaptive = true, bool targets = true) {
    SodOptions o = block_unclamped_options(adaptive, targets);
    o.adaptive.drag_density_error = density_error;
    BallisticRun r = run_two_ballistic_targets(o, layout, obs);
    x_seen = r.x_seen;
    P_seen = r.P_seen;
    return std::move(r.filter);
  };
  const auto with = run(error), without = run(0.0);
  const MatrixXd& Q = with->process_noise_rate_matrix();
  const MatrixXd& Q0 = without->process_noise_rate_matrix();
  const astro::QnsElements o1 = astro::QnsElements::from_vector(x_seen.head<6>());
  const astro::StateVector xo = astro::cartesian_from_qns(o1);
  const double f_t = std::abs(
      (astro::R_rtn_from_eci(xo) * drag_forces.unit_ballistic_drag_eci(kT0.plus_seconds(60.0), xo))[1]);
  // Cannonball drag per unit B: 0.5 rho v^2 with rho of 1e-14 .. 1e-11 kg/m^3 at 450 km.
  EXPECT_GT(f_t, 0.5 * 1e-14 * 7.6e3 * 7.6e3);
  EXPECT_LT(f_t, 0.5 * 1e-11 * 7.7e3 * 7.7e3);
  const int ib = layout.ballistic_index(0);
  const double db = std::sqrt(x_seen[ib] * x_seen[ib] - P_seen(ib, ib));
  EXPECT_NEAR(db, std::sqrt(3.0) * B, 0.01 * B);  // 2 B estimated, 1-sigma B
  const Vec6 D = target_along_track_process_noise(o1.a_m, error * db * f_t, astro::orbit_period_s(o1.a_m));
  const int off0 = layout.target_offset(0), off1 = layout.target_offset(1);
  const Vec6 N = SodOptions{}.q_target_a_roe_m2ps / (obs.a_m * obs.a_m);  // the nominal at initialisation
  const Vec6 F_inv_sqrt = (SodOptions{}.adaptive.floor_factor * N + D).cwiseSqrt().cwiseInverse();
  const Eigen::SelfAdjointEigenSolver<Mat6> eig(F_inv_sqrt.asDiagonal() * Mat6(Q.block<6, 6>(off0, off0)) *
                                                F_inv_sqrt.asDiagonal());
  EXPECT_GE(eig.eigenvalues().minCoeff(), 1.0 - 1e-6);
  EXPECT_GT(Q(off0, off0), 10.0 * Q0(off0, off0));  // 2 B at 450 km: the floor dominates
  const double diff1 = (Q.block<6, 6>(off1, off1) - Q0.block<6, 6>(off1, off1)).cwiseAbs().maxCoeff();
  const double scale1 = Q0.block<6, 6>(off1, off1).cwiseAbs().maxCoeff();
  EXPECT_LT(diff1, 1e-9 * scale1);
  // The adaptation off (the states it sees are the same: nothing adapts before 60 s).
  const auto fixed = run(error, false), fixed0 = run(0.0, false);
  const MatrixXd& Qf = fixed->process_noise_rate_matrix();
  const MatrixXd& Qf0 = fixed0->process_noise_rate_matrix();
  const double floor = SodOptions{}.adaptive.floor_factor;
  for (int i = 0; i < 6; ++i) {
    EXPECT_NEAR(Qf(off0 + i, off0 + i), std::max(N[i], floor * N[i] + D[i]), 1e-9 * N.maxCoeff()) << i;
    EXPECT_DOUBLE_EQ(Qf(off1 + i, off1 + i), N[i]) << i;   // dB = 0: the nominal
    EXPECT_DOUBLE_EQ(Qf0(off0 + i, off0 + i), N[i]) << i;  // no floor: the nominal
  }
  EXPECT_GT(Qf(off0, off0), 10.0 * N[0]);  // 2 B at 450 km: the floor dominates a*da
  // Only the observer adapting (adaptive.targets false): the targets as without the adaptation, the
  // observer's block as with it (the blocks adapt separately).
  const auto obs_only = run(error, true, false);
  const MatrixXd& Qo = obs_only->process_noise_rate_matrix();
  EXPECT_EQ(Mat6(Qo.block<6, 6>(off0, off0)), Mat6(Qf.block<6, 6>(off0, off0)));
  EXPECT_EQ(Mat6(Qo.block<6, 6>(off1, off1)), Mat6(Qf.block<6, 6>(off1, off1)));
  EXPECT_EQ(Mat6(Qo.topLeftCorner<6, 6>()), Mat6(Q.topLeftCorner<6, 6>()));
  EXPECT_NE(Mat6(Qo.topLeftCorner<6, 6>()), Mat6(Qf.topLeftCorner<6, 6>()));  // the observer did adapt
}

// The ballistic walk from the density's day-to-day change (docs/sod.md, "The
// ballistic walk from the density's budget"): with no constant walk, a target
// estimated at dB = 2 B (1-sigma B) walks by change x sqrt(dB^2 - sigma_B^2)
// per day after an adaptive step, one estimated at 0 does not walk; the same
// with the adaptation off, and nothing walks when the option is 0.
TEST(SodAdaptiveNoise, BallisticWalkFollowsTheEstimatedBallisticCoefficient) {
  const dynamics::SpacecraftProperties nominal;
  const double B = nominal.cd * nominal.drag_area_m2 / nominal.mass_kg, change = 0.2;
  const StateLayout layout = two_ballistic_targets_layout();
  const astro::QnsElements obs = observer_at_450_km();
  const auto run = [&](double density_change, bool adaptive) {
    SodOptions o = block_unclamped_options(adaptive, false);
    o.adaptive.density_change_per_day = density_change;
    o.q_ballistic_m4pkg2ps = 0.0;
    return run_two_ballistic_targets(o, layout, obs);
  };
  const int ib0 = layout.ballistic_index(0), ib1 = layout.ballistic_index(1);
  for (const bool adaptive : {true, false}) {
    const BallisticRun with = run(change, adaptive);
    const double db = std::sqrt(with.x_seen[ib0] * with.x_seen[ib0] - with.P_seen(ib0, ib0));
    EXPECT_NEAR(db, std::sqrt(3.0) * B, 0.01 * B) << adaptive;
    const MatrixXd& Q = with.filter->process_noise_rate_matrix();
    EXPECT_NEAR(Q(ib0, ib0), std::pow(change * db, 2) / 86400.0, 1e-9 * std::pow(change * db, 2) / 86400.0)
        << adaptive;
    EXPECT_EQ(Q(ib1, ib1), 0.0) << adaptive;  // dB = 0: the true difference is not known to be other than 0
    EXPECT_EQ(run(0.0, adaptive).filter->process_noise_rate_matrix()(ib0, ib0), 0.0) << adaptive;
  }
}

// Each target flies its own uplinked nominal: a target with five times the
// drag area is propagated with it (the filter's mean follows a direct
// propagation of each body to the millimetre), while the shared-nominal
// constructor moves it as the first target by metres after 50 minutes.
TEST(SodFilter, EachTargetFliesItsOwnNominalProperties) {
  const dynamics::ForceModel& drag_forces = j2_drag_forces();
  const dynamics::SpacecraftProperties nominal;
  dynamics::SpacecraftProperties large = nominal;
  large.drag_area_m2 *= 5.0;
  astro::QnsElements obs = testing::observer_at_start();
  obs.a_m = astro::kRadiusEarth_m + 450e3;
  const StateLayout layout{2, 0};
  VectorXd x = VectorXd::Zero(layout.size());
  x.head<6>() = obs.as_vector();
  std::vector<Vec6> roe0(2);
  for (int k = 0; k < 2; ++k) {
    roe0[k] = Roe::from_scaled_m(testing::starling_a_roe_m()[k], obs.a_m).as_vector();
    x.segment<6>(layout.target_offset(k)) = roe0[k];
  }
  const MatrixXd P = MatrixXd::Identity(layout.size(), layout.size()) * 1e-20;
  const TimeTT t1 = kT0.plus_seconds(3000.0);
  const auto run = [&](SodFilter f) {
    f.initialize(kT0, x, P);
    EXPECT_TRUE(f.time_update(t1).usable);
    return VectorXd(f.state());
  };
  SodOptions o;
  o.adaptive.enabled = false;
  const VectorXd own = run(SodFilter(drag_forces, nominal, layout, std::vector<dynamics::SpacecraftProperties>{nominal, large},
                                     o));
  const VectorXd shared = run(SodFilter(drag_forces, nominal, nominal, layout, o));
  const dynamics::GveRk4Propagator p_nominal(drag_forces, nominal, o.propagator), p_large(drag_forces, large, o.propagator);
  const astro::QnsElements o1 = p_nominal.propagate(obs, kT0, t1);
  for (int k = 0; k < 2; ++k) {
    const auto& prop = k == 0 ? p_nominal : p_large;
    const Vec6 direct =
        astro::roe_from_qns(o1, prop.propagate(astro::qns_from_roe(obs, Roe::from_vector(roe0[k])), kT0, t1)).as_vector();
    const int off = layout.target_offset(k);
    EXPECT_LT(((own.segment<6>(off) - direct) * obs.a_m).cwiseAbs().maxCoeff(), 1e-3) << "target " << k;
  }
  const double moved_m = ((own.segment<6>(layout.target_offset(1)) - shared.segment<6>(layout.target_offset(1))) *
                          obs.a_m).cwiseAbs().maxCoeff();
  EXPECT_GT(moved_m, 1.0);
  EXPECT_LT(((own.segment<6>(layout.target_offset(0)) - shared.segment<6>(layout.target_offset(0))) * obs.a_m)
                .cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_THROW(SodFilter(drag_forces, nominal, layout, std::vector<dynamics::SpacecraftProperties>{nominal}, o),
               std::invalid_argument);
}

// The observer's own planned 10 cm/s along-track burn (executed 3 % long):
// applied in SOD with its execution error, every ROE stays within 3 sigma
// and no bearing is gated; without it, the targets' ROE (relative to the
// observer that moved) end far outside their covariance.
TEST(SodManeuver, PlannedObserverBurnKeepsTheTargetsConsistent) {
  constexpr int burn_step = 300;
  const auto run = [](bool apply) {
    const astro::QnsElements obs0 = testing::observer_at_start();
    std::vector<Vec6> a_roe = testing::starling_a_roe_m();
    a_roe.resize(2);
    Truth truth(kT0, obs0, a_roe);
    SodFilter filter(testing::j2_forces(), {}, {}, StateLayout{2, 0});
    const InitialGuess g = testing::shifted_initial_guess(obs0, a_roe, 0.01, 10.0);
    filter.initialize(kT0, g.x, g.P);
    std::mt19937_64 rng(5);
    const double sigma = 5.0 * astro::kArcsecToRad;
    const Vec3 dv(0.0, 0.1, 0.0);
    const int steps = 500;
    int gated_after = 0, gnss_flag_step = -1;
    for (int s = 1; s <= steps; ++s) {
      const TimeTT t = kT0.plus_seconds(kStep_s * s);
      if (s == burn_step) {
        truth.advance_to(t.plus_seconds(-30.0));
        truth.apply_observer_dv(1.03 * dv);
        if (apply) {
          const Mat3 P_dv = Mat3::Identity() * std::pow(0.05 * dv.norm(), 2);
          EXPECT_TRUE(filter.apply_observer_maneuver(truth.t(), dv, P_dv).usable);
        }
      }
      truth.advance_to(t);
      (void)filter.update_gnss(truth.gnss(3.0, 0.01, true, &rng));
      for (int k = 0; k < 2; ++k) {
        const UpdateSummary u = filter.update_bearing(truth.bearing(k, sigma, sigma, &rng));
        if (s >= burn_step && u.gated) ++gated_after;
      }
      if (gnss_flag_step < 0 && filter.health().filter.condition == HealthCondition::kInconsistent) gnss_flag_step = s;
    }
    double worst = 0.0;
    for (int k = 0; k < 2; ++k) {
      const Vec6 e = filter.a_roe_m(k) - truth.a_roe_m(k), sg = filter.a_roe_sigma_m(k);
      for (int i = 0; i < 6; ++i) worst = std::max(worst, std::abs(e[i]) / sg[i]);
    }
    std::printf("%s: worst |error| / sigma %.2f, %d bearings gated after the burn, GNSS window flagged at step %d\n",
                apply ? "applied" : "not applied", worst, gated_after, gnss_flag_step);
    return std::make_tuple(worst, gated_after, gnss_flag_step);
  };
  const auto [worst_with, gated_with, flag_with] = run(true);
  const auto [worst_without, gated_without, flag_without] = run(false);
  EXPECT_LT(worst_with, 3.0);
  EXPECT_EQ(gated_with, 0);
  EXPECT_EQ(flag_with, -1);  // no false alarm of the GNSS window
  EXPECT_GT(worst_without, 5.0);
  // Unplanned, the burn shows in the GNSS fixes within 20 minutes (health check 5, filter level).
  EXPECT_GE(flag_without, burn_step);
  EXPECT_LE(flag_without, burn_step + 20);
}

// The mean-shift test of the GNSS innovations (health.gnss_bias_window):
// while the model holds its statistic is chi2(6) (mean ~6, no alarm in 12 h
// of fixes at the navigator's threshold); an unplanned 5 cm/s along-track
// burn of the observer shows within 20 minutes, sooner than in the
// navigator's NIS window (5 x its quantile: sized for a world richer than the
// model, where that window misses such a burn: docs/sod.md).
TEST(SodManeuver, GnssMeanShiftTestFindsAnUnplannedObserverBurn) {
  constexpr int burn_step = 300, steps = 720;
  const auto run = [](bool burn) {
    const astro::QnsElements obs0 = testing::observer_at_start();
    std::vector<Vec6> a_roe = testing::starling_a_roe_m();
    a_roe.resize(1);
    Truth truth(kT0, obs0, a_roe);
    SodOptions o;
    o.health.gnss_bias_window = 10;
    o.health.gnss_bias_max = chi2_quantile(6, 1.0 - 1e-4 / 1440.0);
    o.health.gnss_nis_max_mean = 5.0 * chi2_quantile(60, 1.0 - 1e-4) / 10.0;  // the navigator's
    SodFilter filter(testing::j2_forces(), {}, {}, StateLayout{1, 0}, o);
    const InitialGuess g = testing::shifted_initial_guess(obs0, a_roe, 0.01, 10.0);
    filter.initialize(kT0, g.x, g.P);
    std::mt19937_64 rng(11);
    int bias_flag = -1, nis_flag = -1, n_stat = 0;
    double sum_stat = 0.0;
    for (int s = 1; s <= steps; ++s) {
      const TimeTT t = kT0.plus_seconds(kStep_s * s);
      if (burn && s == burn_step) {
        truth.advance_to(t.plus_seconds(-30.0));
        truth.apply_observer_dv(Vec3(0.0, 0.05, 0.0));
      }
      truth.advance_to(t);
      (void)filter.update_gnss(truth.gnss(3.0, 0.03, true, &rng));
      const double b = filter.recent_gnss_bias_statistic();
      if (std::isfinite(b) && s > 60 && s < burn_step) {
        sum_stat += b;
        ++n_stat;
      }
      if (bias_flag < 0 && std::isfinite(b) && b > o.health.gnss_bias_max) bias_flag = s;
      const double nis = filter.recent_mean_gnss_nis();
      if (nis_flag < 0 && std::isfinite(nis) && nis > o.health.gnss_nis_max_mean) nis_flag = s;
    }
    std::printf("%s: mean statistic before step %d %.2f (chi2(6): 6); mean-shift test flagged at step %d, NIS window "
                "at %d\n", burn ? "burn" : "no burn", burn_step, sum_stat / n_stat, bias_flag, nis_flag);
    return std::make_tuple(sum_stat / n_stat, bias_flag, nis_flag);
  };
  const auto [mean_quiet, flag_quiet, nis_quiet] = run(false);
  const auto [mean_burn, flag_burn, nis_burn] = run(true);
  EXPECT_GT(mean_quiet, 3.0);
  EXPECT_LT(mean_quiet, 9.0);
  EXPECT_EQ(flag_quiet, -1);
  EXPECT_EQ(nis_quiet, -1);
  EXPECT_GE(flag_burn, burn_step);
  EXPECT_LE(flag_burn, burn_step + 20);
  EXPECT_TRUE(nis_burn < 0 || flag_burn < nis_burn);  // sooner than the navigator's NIS window
  SodOptions bad;
  bad.health.gnss_bias_window = -1;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
  bad = {};
  bad.health.gnss_bias_max = 0.0;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
}

}  // namespace
}  // namespace artms::sod
