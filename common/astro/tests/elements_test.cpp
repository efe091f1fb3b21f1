#include "artms/astro/elements.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "artms/testing/testing.hpp"

namespace artms::astro {
namespace {

using artms::testing::load_json;
using artms::testing::test_data_path;

constexpr double kVallado_mu_m3ps2 = 398600.4418e9;

TEST(Kepler, Vallado21KeplersEquation) {
  const auto j = load_json(test_data_path("vallado_examples.json"))["ex2_1_kepler_equation"];
  const double E = eccentric_from_mean_anomaly(j["M_deg"].get<double>() * kDegToRad, j["e"]);
  EXPECT_NEAR(E * kRadToDeg, j["expected_E_deg"].get<double>(), j["tol_deg"].get<double>());
}

TEST(Kepler, AnomalyConversionsInvertEachOther) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> ue(0.0, 0.95), ua(-10.0, 10.0);
  for (int k = 0; k < 5000; ++k) {
    const double e = ue(rng), M = ua(rng);
    const double E = eccentric_from_mean_anomaly(M, e);
    EXPECT_NEAR(mean_from_eccentric_anomaly(E, e), M, 1e-12);
    const double nu = true_from_mean_anomaly(M, e);
    EXPECT_NEAR(mean_from_true_anomaly(nu, e), M, 1e-11);
  }
}

TEST(Kepler, Vallado25CartesianToElements) {
  const auto j = load_json(test_data_path("vallado_examples.json"))["ex2_5_rv2coe"];
  const auto& ex = j["expected"];
  StateVector x;
  for (int k = 0; k < 3; ++k) {
    x.r_m[k] = j["r_km"][k].get<double>() * 1e3;
    x.v_mps[k] = j["v_kms"][k].get<double>() * 1e3;
  }
  const KeplerElements oe = kepler_from_cartesian(x, kVallado_mu_m3ps2);
  EXPECT_NEAR(oe.a_m / 1e3, ex["a_km"].get<double>(), 0.01);
  EXPECT_NEAR(oe.e, ex["e"].get<double>(), 1e-5);
  EXPECT_NEAR(oe.i_rad * kRadToDeg, ex["i_deg"].get<double>(), 0.01);
  EXPECT_NEAR(oe.raan_rad * kRadToDeg, ex["raan_deg"].get<double>(), 0.01);
  EXPECT_NEAR(oe.argp_rad * kRadToDeg, ex["argp_deg"].get<double>(), 0.01);
  EXPECT_NEAR(true_from_mean_anomaly(oe.M_rad, oe.e) * kRadToDeg, ex["nu_deg"].get<double>(),
              0.01);
}

TEST(Kepler, Vallado26ElementsToCartesian) {
  const auto j = load_json(test_data_path("vallado_examples.json"))["ex2_6_coe2rv"];
  KeplerElements oe;
  oe.e = j["e"];
  oe.a_m = j["p_km"].get<double>() * 1e3 / (1.0 - oe.e * oe.e);
  oe.i_rad = j["i_deg"].get<double>() * kDegToRad;
  oe.raan_rad = j["raan_deg"].get<double>() * kDegToRad;
  oe.argp_rad = j["argp_deg"].get<double>() * kDegToRad;
  oe.M_rad = mean_from_true_anomaly(j["nu_deg"].get<double>() * kDegToRad, oe.e);
  const StateVector x = cartesian_from_kepler(oe, kVallado_mu_m3ps2);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(x.r_m[k] / 1e3, j["expected_r_km"][k].get<double>(), 1e-3);
    EXPECT_NEAR(x.v_mps[k] / 1e3, j["expected_v_kms"][k].get<double>(), 1e-6);
  }
}

// Cartesian -> elements -> Cartesian closes to 1e-9 relative, singular
// geometries included (circular, equatorial, retrograde equatorial).
TEST(Kepler, RoundTripIncludingSingularCases) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ua(6.6e6, 4.3e7), ue(0.0, 0.7), ui(0.0, kPi),
      uang(0.0, kTwoPi);
  for (int k = 0; k < 4000; ++k) {
    KeplerElements oe{ua(rng), ue(rng), ui(rng), uang(rng), uang(rng), uang(rng)};
    if (k % 4 == 1) oe.e = 0.0;
    if (k % 5 == 2) oe.i_rad = 0.0;
    if (k % 7 == 3) oe.i_rad = kPi;
    const StateVector x = cartesian_from_kepler(oe);
    const StateVector y = cartesian_from_kepler(kepler_from_cartesian(x));
    EXPECT_LT((y.r_m - x.r_m).norm() / x.r_m.norm(), 1e-9);
    EXPECT_LT((y.v_mps - x.v_mps).norm() / x.v_mps.norm(), 1e-9);
    const StateVector z = cartesian_from_qns(qns_from_cartesian(x));
    EXPECT_LT((z.r_m - x.r_m).norm() / x.r_m.norm(), 1e-9);
    EXPECT_LT((z.v_mps - x.v_mps).norm() / x.v_mps.norm(), 1e-9);
  }
}

TEST(Kepler, ElementRoundTripNonSingular) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> ua(6.6e6, 4.3e7), ue(0.001, 0.7), ui(0.01, kPi - 0.01),
      uang(0.0, kTwoPi);
  for (int k = 0; k < 2000; ++k) {
    const KeplerElements oe{ua(rng), ue(rng), ui(rng), uang(rng), uang(rng), uang(rng)};
    const KeplerElements back = kepler_from_cartesian(cartesian_from_kepler(oe));
    EXPECT_NEAR(back.a_m / oe.a_m, 1.0, 1e-11);
    EXPECT_NEAR(back.e, oe.e, 1e-11);
    EXPECT_NEAR(back.i_rad, oe.i_rad, 1e-11);
    EXPECT_NEAR(wrap_pi(back.raan_rad - oe.raan_rad), 0.0, 1e-10);
    EXPECT_NEAR(wrap_pi(back.argp_rad - oe.argp_rad), 0.0, 1e-8);
    EXPECT_NEAR(wrap_pi(back.M_rad - oe.M_rad), 0.0, 1e-8);
  }
}

TEST(Qns, MeanArgumentOfLatitudeIsContinuousAtZeroEccentricity) {
  // The same physical orbit with e = 0 and e = 1e-12: u agrees, ex, ey ~ 0.
  const QnsElements q0{6.9e6, 0.0, 0.0, 1.7, 0.5, 2.0};
  const QnsElements q1{6.9e6, 1e-12, -1e-12, 1.7, 0.5, 2.0};
  const QnsElements b0 = qns_from_cartesian(cartesian_from_qns(q0));
  const QnsElements b1 = qns_from_cartesian(cartesian_from_qns(q1));
  EXPECT_NEAR(b0.u_rad, 2.0, 1e-12);
  EXPECT_NEAR(b1.u_rad, 2.0, 1e-11);
  EXPECT_NEAR(b1.ex, 1e-12, 1e-14);
  EXPECT_NEAR(b1.ey, -1e-12, 1e-14);
}

TEST(Kepler, RejectsNonElliptical) {
  EXPECT_THROW(cartesian_from_kepler({7e6, 1.0, 0, 0, 0, 0}), std::invalid_argument);
  EXPECT_THROW(cartesian_from_kepler({-7e6, 0.1, 0, 0, 0, 0}), std::invalid_argument);
  const StateVector escape{Vec3(7e6, 0, 0), Vec3(0, 11000.0, 0)};
  EXPECT_THROW(kepler_from_cartesian(escape), std::invalid_argument);
  EXPECT_THROW(eccentric_from_mean_anomaly(1.0, 1.2), std::invalid_argument);
}

TEST(Kepler, PeriodAndMeanMotion) {
  // GEO: period ~ one sidereal day for a = 42164.17 km.
  EXPECT_NEAR(orbit_period_s(42164.17e3), 86164.09, 1.0);
  EXPECT_NEAR(mean_motion_radps(6945e3) * orbit_period_s(6945e3), kTwoPi, 1e-12);
}

}  // namespace
}  // namespace artms::astro
