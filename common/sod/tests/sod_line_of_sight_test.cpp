// Multi-observer lines of sight (SodFilter::update_line_of_sight): the same
// update as update_bearing for observer -> target; a dry run leaves the
// filter alone; target -> target bearings (a remote observer that is itself a
// target) and bearings from an external remote observer close the loop.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include "artms/sod/sod_filter.hpp"
#include "sod_scenario.hpp"

namespace artms::sod {
namespace {

using testing::j2_forces;
using testing::observer_at_start;
using testing::shifted_initial_guess;
using testing::starling_a_roe_m;
using testing::Truth;
using L = LineOfSightMeasurement;

const TimeTT kT0 = astro::tt_from_utc_string("2024-05-08T00:00:00Z");

SodFilter make_filter(int n_targets) {
  return SodFilter(j2_forces(), dynamics::SpacecraftProperties{}, dynamics::SpacecraftProperties{},
                   StateLayout{n_targets, 0}, SodOptions{});
}

// Target 0's true line of sight to target 1 at kT0.
L first_to_second(const Truth& truth, double sigma_arcsec) {
  L m;
  m.t = kT0;
  m.from = 0;
  m.to = 1;
  m.los_eci = truth.target_eci(1).r_m - truth.target_eci(0).r_m;
  m.sigma_rad = sigma_arcsec * astro::kArcsecToRad;
  return m;
}

TEST(SodLineOfSight, ObserverToTargetMatchesUpdateBearing) {
  auto a_roe = starling_a_roe_m();
  a_roe.resize(2);
  Truth truth(kT0, observer_at_start(), a_roe);
  const auto g = shifted_initial_guess(observer_at_start(), a_roe, 0.05, 100.0);
  SodFilter f1 = make_filter(2), f2 = make_filter(2);
  f1.initialize(kT0, g.x, g.P);
  f2.initialize(kT0, g.x, g.P);
  const double s = 20 * astro::kArcsecToRad;
  const auto b = truth.bearing(0, s, 0.0, nullptr);
  const auto u1 = f1.update_bearing(b);
  L m;
  m.t = kT0;
  m.from = L::kObserver;
  m.to = 0;
  m.los_eci = truth.target_eci(0).r_m - truth.observer_eci().r_m;
  m.sigma_rad = s;
  const auto u2 = f2.update_line_of_sight(m);
  ASSERT_TRUE(u1.usable && u2.usable) << u1.why << " / " << u2.why;
  // The angles are formed in different frames (camera vs line of sight), so
  // the nonlinear updates agree closely but not to rounding.
  EXPECT_NEAR(u1.nis, u2.nis, 1e-3 * std::max(1.0, u1.nis));
  EXPECT_LT((f1.a_roe_m(0) - f2.a_roe_m(0)).cwiseAbs().maxCoeff(), 1e-2);  // m, of a 2.5 km correction
  EXPECT_LT((f1.a_roe_m(1) - f2.a_roe_m(1)).cwiseAbs().maxCoeff(), 1e-2);
  EXPECT_LT((f1.a_roe_sigma_m(0) - f2.a_roe_sigma_m(0)).cwiseAbs().maxCoeff(), 1e-3);
}

TEST(SodLineOfSight, DryRunLeavesTheFilterAlone) {
  auto a_roe = starling_a_roe_m();
  a_roe.resize(2);
  Truth truth(kT0, observer_at_start(), a_roe);
  const auto g = shifted_initial_guess(observer_at_start(), a_roe, 0.05, 100.0);
  SodFilter f = make_filter(2);
  f.initialize(kT0, g.x, g.P);
  L m = first_to_second(truth, 20.0);
  const Eigen::VectorXd x0 = f.state();
  const Eigen::MatrixXd P0 = f.covariance();
  const auto s = f.update_line_of_sight(m, true);
  EXPECT_FALSE(s.usable);
  EXPECT_TRUE(std::isfinite(s.mahalanobis));
  EXPECT_EQ(f.state(), x0);
  EXPECT_EQ(f.covariance(), P0);
  EXPECT_EQ(f.counters(1).accepted, 0);
  // An impossible body is refused with a reason.
  m.to = 5;
  EXPECT_FALSE(f.update_line_of_sight(m).usable);
}

TEST(SodLineOfSight, RemoteBearingsBetweenTargetsAndFromAnExternalObserverConverge) {
  // Target 0 observes target 1 (a remote observer that is also a target),
  // and an external observer (in the state of nobody, position known to 20 m)
  // observes target 0; the local observer sees nothing but GNSS. The remote
  // lines of sight alone must bring both a*dlambda errors well below the
  // initial 5 % within 6 orbits.
  auto a_roe = starling_a_roe_m();
  a_roe.resize(2);
  Truth truth(kT0, observer_at_start(), a_roe);
  auto ext = starling_a_roe_m()[2];  // a third spacecraft, not in the filter
  Truth ext_truth(kT0, observer_at_start(), {ext});
  const auto g = shifted_initial_guess(observer_at_start(), a_roe, 0.05, 100.0);
  SodFilter f = make_filter(2);
  f.initialize(kT0, g.x, g.P);
  const double s = 5 * astro::kArcsecToRad;
  const Vec6 err0 = f.a_roe_m(0) - truth.a_roe_m(0), err1 = f.a_roe_m(1) - truth.a_roe_m(1);
  int used = 0;
  for (int k = 1; k <= 6 * 95; ++k) {
    const TimeTT t = kT0.plus_seconds(60.0 * k);
    truth.advance_to(t);
    ext_truth.advance_to(t);
    ASSERT_TRUE(f.update_gnss(truth.gnss(2.0, 0.01, false, nullptr)).usable);
    L a;
    a.t = t;
    a.from = 0;
    a.to = 1;
    a.los_eci = truth.target_eci(1).r_m - truth.target_eci(0).r_m;
    a.sigma_rad = s;
    used += f.update_line_of_sight(a).usable ? 1 : 0;
    L b;
    b.t = t;
    b.from = L::kExternal;
    b.from_r_eci_m = ext_truth.target_eci(0).r_m;
    b.from_P_r_m2 = Mat3::Identity() * 400.0;
    b.to = 0;
    b.los_eci = truth.target_eci(0).r_m - b.from_r_eci_m;
    b.sigma_rad = s;
    used += f.update_line_of_sight(b).usable ? 1 : 0;
  }
  const Vec6 e0 = f.a_roe_m(0) - truth.a_roe_m(0), e1 = f.a_roe_m(1) - truth.a_roe_m(1);
  std::printf("remote LOS: %d used; a*dlambda error %.0f -> %.0f m and %.0f -> %.0f m\n", used, err0[1], e0[1],
              err1[1], e1[1]);
  EXPECT_GT(used, 1000);
  EXPECT_LT(std::abs(e0[1]), 0.4 * std::abs(err0[1]));
  EXPECT_LT(std::abs(e1[1]), 0.2 * std::abs(err1[1]));
  for (int i = 0; i < 6; ++i) {
    EXPECT_LT(std::abs(e0[i]), 3.0 * f.a_roe_sigma_m(0)[i] + 1.0) << i;
    EXPECT_LT(std::abs(e1[i]), 3.0 * f.a_roe_sigma_m(1)[i] + 1.0) << i;
  }
}

TEST(SodLineOfSight, TargetToTargetLineKeepsTheObserverAsAConsiderParameter) {
  // SodOptions::target_to_target_consider_observer: a line of sight between
  // two targets updates their relative orbits and leaves the observer's
  // orbit and its covariance block as they were (Schmidt-Kalman); its
  // posterior covariance is no smaller than the full update's. Lines of
  // sight that involve the observer still update it. The observer's orbit is
  // uncertain by kilometres here (mode 4's coarse orbit).
  auto a_roe = starling_a_roe_m();
  a_roe.resize(2);
  Truth truth(kT0, observer_at_start(), a_roe);
  auto g = shifted_initial_guess(observer_at_start(), a_roe, 0.05, 100.0);
  const double a = observer_at_start().a_m;
  g.P.diagonal().head<6>() << 50.0 * 50.0, std::pow(500.0 / a, 2), std::pow(500.0 / a, 2), std::pow(2000.0 / a, 2),
      std::pow(2000.0 / a, 2), std::pow(3000.0 / a, 2);
  SodOptions consider;
  consider.target_to_target_consider_observer = true;
  SodFilter full = make_filter(2);
  SodFilter cons(j2_forces(), dynamics::SpacecraftProperties{}, dynamics::SpacecraftProperties{}, StateLayout{2, 0},
                 consider);
  full.initialize(kT0, g.x, g.P);
  cons.initialize(kT0, g.x, g.P);
  const L m = first_to_second(truth, 5.0);
  const auto uf = full.update_line_of_sight(m), uc = cons.update_line_of_sight(m);
  ASSERT_TRUE(uf.usable && uc.usable) << uf.why << " / " << uc.why;
  EXPECT_NEAR(uf.nis, uc.nis, 1e-12 * std::max(1.0, uf.nis));  // same prediction
  // The observer: untouched by the consider update, moved by the full one.
  EXPECT_EQ(cons.state().head<6>(), g.x.head<6>());
  // In metres (a, and a times the angles): the full update shrinks the
  // observer's covariance, the consider update leaves it exactly.
  Eigen::VectorXd to_m = Eigen::VectorXd::Constant(static_cast<Eigen::Index>(g.x.size()), a);
  to_m[0] = 1.0;
  const Eigen::MatrixXd S = to_m.asDiagonal();
  const Eigen::MatrixXd P0 = S * g.P * S, Pc = S * cons.covariance() * S, Pf = S * full.covariance() * S;
  EXPECT_EQ(Pc.topLeftCorner(6, 6), P0.topLeftCorner(6, 6));
  EXPECT_LT(Pf.topLeftCorner(6, 6).trace(), 0.99 * P0.topLeftCorner(6, 6).trace());
  // The relative orbits learn in both; the consider posterior is the larger.
  const int n = static_cast<int>(g.x.size());
  EXPECT_LT(Pc.bottomRightCorner(n - 6, n - 6).trace(), 0.99 * P0.bottomRightCorner(n - 6, n - 6).trace());
  const Eigen::MatrixXd D = Pc - Pf;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (D + D.transpose()));
  EXPECT_GT(eig.eigenvalues().minCoeff(), -1e-9 * Pf.diagonal().maxCoeff());
  // Observer -> target: the observer is updated as before.
  L own = m;
  own.from = L::kObserver;
  own.to = 0;
  own.los_eci = truth.target_eci(0).r_m - truth.observer_eci().r_m;
  ASSERT_TRUE(cons.update_line_of_sight(own).usable);
  EXPECT_NE(cons.state().head<6>(), g.x.head<6>());
}

TEST(SodLineOfSight, ARemoteObserversClockOffsetIsEstimatedAndKeptOutOfTheOrbits) {
  // Target 0 is also an observer. When its camera tags its images 0.5 s
  // late, its lines of sight to target 1 and to this observer show the bodies
  // as they were 0.5 s before the tag (the formation turned by n dt = 113").
  // This observer's own bearings (tags right) and GNSS come every minute, 8
  // orbits. With a clock state for the sender (StateLayout::n_remote_clock)
  // the offset is found to 0.02 s within 6 orbits and the relative orbits end
  // where the same filter ends when the sender's tags are right; taken as
  // right, the late lines are refused by the gate (or, let through, would
  // turn the formation).
  auto a_roe = starling_a_roe_m();
  a_roe.resize(2);
  const auto g = shifted_initial_guess(observer_at_start(), a_roe, 0.05, 100.0);
  const double s = 5 * astro::kArcsecToRad;
  struct Run {
    Vec6 err[2], sigma[2];
    double dt_6_orbits = 0.0, sigma_dt = 0.0;
    int used = 0, gated = 0;
  };
  const auto run = [&](double late_s, bool clock) {
    StateLayout layout{2, 0};
    layout.n_remote_clock = clock ? 1 : 0;
    SodFilter f(j2_forces(), {}, {}, layout, SodOptions{});
    const int n = layout.size();
    Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
    x.head(g.x.size()) = g.x;
    Eigen::MatrixXd P = Eigen::MatrixXd::Identity(n, n);  // the clock: 1 s
    P.topLeftCorner(g.x.size(), g.x.size()) = g.P;
    f.initialize(kT0, x, P);
    Truth truth(kT0, observer_at_start(), a_roe), seen(kT0, observer_at_start(), a_roe);
    Run r;
    for (int k = 1; k <= 8 * 95; ++k) {
      const TimeTT t = kT0.plus_seconds(60.0 * k);
      truth.advance_to(t);
      seen.advance_to(t.plus_seconds(-late_s));
      EXPECT_TRUE(f.update_gnss(truth.gnss(2.0, 0.01, false, nullptr)).usable);
      for (int j = 0; j < 2; ++j) f.update_bearing(truth.bearing(j, s, 0.0, nullptr));
      for (const int to : {1, L::kObserver}) {
        L m;
        m.t = t;
        m.from = 0;
        m.to = to;
        m.los_eci = (to == 1 ? seen.target_eci(1).r_m : seen.observer_eci().r_m) - seen.target_eci(0).r_m;
        m.sigma_rad = s;
        m.sender_clock = clock ? 0 : -1;
        const auto u = f.update_line_of_sight(m);
        r.used += u.usable ? 1 : 0;
        r.gated += u.gated ? 1 : 0;
      }
      if (clock && k == 6 * 95) {
        r.dt_6_orbits = f.state()[layout.remote_clock_index(0)];
        r.sigma_dt = std::sqrt(f.covariance()(n - 1, n - 1));
      }
    }
    for (int j = 0; j < 2; ++j) {
      r.err[j] = f.a_roe_m(j) - truth.a_roe_m(j);
      r.sigma[j] = f.a_roe_sigma_m(j);
    }
    return r;
  };
  const Run late = run(0.5, true), right = run(0.0, true), plain = run(0.5, false);
  std::printf("remote clock: offset %.4f s (1-sigma %.4f) after 6 orbits; remote lines used %d, refused %d; "
              "without the clock state used %d, refused %d\n",
              late.dt_6_orbits, late.sigma_dt, late.used, late.gated, plain.used, plain.gated);
  EXPECT_NEAR(late.dt_6_orbits, 0.5, 0.02);
  EXPECT_LT(late.sigma_dt, 0.02);
  EXPECT_NEAR(right.dt_6_orbits, 0.0, 0.02);
  EXPECT_GT(late.used, 1400);  // of 1520
  for (int j = 0; j < 2; ++j) {
    const Vec6 d = (late.err[j] - right.err[j]).cwiseQuotient(right.sigma[j]);
    std::printf("target %d: a*dlambda error %.1f m (1-sigma %.1f) with the late sender, %.1f m (%.1f) with its tags "
                "right\n", j, late.err[j][1], late.sigma[j][1], right.err[j][1], right.sigma[j][1]);
    EXPECT_LT(d.cwiseAbs().maxCoeff(), 0.1) << j;
  }
  EXPECT_GT(plain.gated, plain.used);
  // A clock index the layout does not have is refused with a reason.
  SodFilter f = make_filter(2);
  f.initialize(kT0, g.x, g.P);
  L bad = first_to_second(Truth(kT0, observer_at_start(), a_roe), 5.0);
  bad.sender_clock = 0;
  const auto u = f.update_line_of_sight(bad);
  EXPECT_FALSE(u.usable);
  EXPECT_EQ(u.why, "sender clock index out of range");
}

TEST(SodUnderweighting, LimitsTheCollapseOfAWidePriorAndIsValidated) {
  // A stale prior (5 % in a*dlambda, 100 m elsewhere) and a 2" bearing: with
  // beta = 0.5 the posterior 1-sigma of every ROE stays above what the plain
  // update gives, and the options reject a negative beta.
  auto a_roe = starling_a_roe_m();
  a_roe.resize(2);
  Truth truth(kT0, observer_at_start(), a_roe);
  const auto g = shifted_initial_guess(observer_at_start(), a_roe, 0.05, 100.0);
  SodOptions plain, under;
  under.bearing_underweighting = 0.5;
  SodFilter f0(j2_forces(), {}, {}, StateLayout{2, 0}, plain), f1(j2_forces(), {}, {}, StateLayout{2, 0}, under);
  f0.initialize(kT0, g.x, g.P);
  f1.initialize(kT0, g.x, g.P);
  const auto b = truth.bearing(0, 2 * astro::kArcsecToRad, 0.0, nullptr);
  ASSERT_TRUE(f0.update_bearing(b).usable);
  ASSERT_TRUE(f1.update_bearing(b).usable);
  for (int i = 0; i < 6; ++i) EXPECT_GT(f1.a_roe_sigma_m(0)[i], f0.a_roe_sigma_m(0)[i] * (1.0 - 1e-9)) << i;
  EXPECT_GT((f1.a_roe_sigma_m(0).array() / f0.a_roe_sigma_m(0).array()).maxCoeff(), 1.1);
  SodOptions bad;
  bad.bearing_underweighting = -1.0;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
}

TEST(SodUnderweighting, NonlinearityGradesTheUnderweightingOfABearingLinearOverItsPrior) {
  // The statistic trace(P_zz - P_zx P^-1 P_xz) / trace R is the part of the
  // predicted bearing spread that no linear map of the state explains. A
  // prior known to 0.05 % in a*dlambda and 2 m elsewhere still spreads the
  // bearing beyond a 2" noise (the spread rule underweights it) but is
  // linear over it; a 1 % / 20 m prior is not. A prior made a guess (by an
  // inflation) is confirmed by a bearing whose spread is within its noise
  // (here a 1-degree one); the a-priori of initialize() is not a guess.
  auto a_roe = starling_a_roe_m();
  a_roe.resize(1);
  Truth truth(kT0, observer_at_start(), a_roe);
  const auto precise = truth.bearing(0, 2 * astro::kArcsecToRad, 0.0, nullptr);
  const auto coarse = truth.bearing(0, 3600 * astro::kArcsecToRad, 0.0, nullptr);
  const auto update = [&](double dlambda_frac, double other_m, double kappa, bool confirm) {
    SodOptions o;
    o.bearing_underweighting = 0.5;
    o.bearing_underweighting_nonlinearity = kappa;
    SodFilter f(j2_forces(), {}, {}, StateLayout{1, 0}, o);
    const auto g = shifted_initial_guess(observer_at_start(), a_roe, dlambda_frac, other_m);
    f.initialize(kT0, g.x, g.P);
    if (!confirm) f.inflate_target(0, 1.0);  // a guessed prior: the spread rule until confirmed
    EXPECT_TRUE(f.prior_unconfirmed(0) != confirm);
    if (confirm) {
      const UpdateSummary c = f.update_bearing(coarse);
      EXPECT_TRUE(c.usable) << c.why;
      EXPECT_FALSE(c.underweighted);
      EXPECT_FALSE(f.prior_unconfirmed(0));
    }
    const UpdateSummary u = f.update_bearing(precise);
    EXPECT_TRUE(u.usable) << u.why;
    return std::make_pair(u, f.a_roe_sigma_m(0));
  };
  const auto [tight_spread, sig_spread] = update(0.0005, 2.0, 0.0, true);
  const auto [tight_guess, sig_guess] = update(0.0005, 2.0, 0.01, false);
  const auto [tight_nl, sig_nl] = update(0.0005, 2.0, 0.01, true);
  const auto [wide_nl, sig_wide] = update(0.01, 20.0, 0.01, true);
  const auto [wider_nl, sig_wider] = update(0.02, 40.0, 0.01, true);
  std::printf("nonlinearity / R: tight prior %.2e, wide %.3g, twice as wide %.3g\n", tight_nl.nonlinearity,
              wide_nl.nonlinearity, wider_nl.nonlinearity);
  EXPECT_EQ(tight_spread.underweighting, 0.5);
  EXPECT_EQ(tight_guess.underweighting, 0.5);  // a guessed prior: the spread rule
  EXPECT_LT(tight_nl.nonlinearity, 1e-3);
  // Graded: beta min(1, Omega / kappa), a tenth of beta at most for the linear bearing.
  EXPECT_NEAR(tight_nl.underweighting, 0.5 * tight_nl.nonlinearity / 0.01, 1e-12);
  EXPECT_LT(tight_nl.underweighting, 0.05);
  EXPECT_GT(wide_nl.nonlinearity, 0.01);
  EXPECT_EQ(wide_nl.underweighting, 0.5);
  // Second order in the prior's spread: twice the spread, ~16 times the statistic.
  EXPECT_GT(wider_nl.nonlinearity / wide_nl.nonlinearity, 8.0);
  EXPECT_LT(wider_nl.nonlinearity / wide_nl.nonlinearity, 32.0);
  // Released, the linear bearing gets the plain update: a tighter posterior.
  EXPECT_LT(sig_nl.cwiseQuotient(sig_spread).minCoeff(), 0.95);
  // Inflation, re-initialisation and a manoeuvre of the observer make the prior a guess again.
  SodOptions o;
  o.bearing_underweighting = 0.5;
  o.bearing_underweighting_nonlinearity = 0.01;
  SodFilter f(j2_forces(), {}, {}, StateLayout{1, 0}, o);
  const auto g = shifted_initial_guess(observer_at_start(), a_roe, 0.0005, 2.0);
  f.initialize(kT0, g.x, g.P);
  EXPECT_FALSE(f.prior_unconfirmed(0));
  const auto confirm = [&] {
    ASSERT_TRUE(f.update_bearing(coarse).usable);
    ASSERT_FALSE(f.prior_unconfirmed(0));
  };
  confirm();
  f.inflate_target(0, 4.0);
  EXPECT_TRUE(f.prior_unconfirmed(0));
  confirm();
  f.inflate_target_maneuver(0, 0.01, 0.0);
  EXPECT_TRUE(f.prior_unconfirmed(0));
  confirm();
  ASSERT_TRUE(f.apply_observer_maneuver(kT0, astro::Vec3::Zero(), astro::Mat3::Identity() * 1e-6).usable);
  EXPECT_TRUE(f.prior_unconfirmed(0));
  confirm();
  f.reinitialize_target(0, g.x.segment<6>(6), g.P.block<6, 6>(6, 6));
  EXPECT_TRUE(f.prior_unconfirmed(0));
  EXPECT_THROW((void)f.prior_unconfirmed(1), std::invalid_argument);
  SodOptions bad;
  bad.bearing_underweighting_nonlinearity = -0.1;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
}

}  // namespace
}  // namespace artms::sod
