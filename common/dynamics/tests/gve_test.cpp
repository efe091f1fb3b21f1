#include "artms/dynamics/gve.hpp"

#include <gtest/gtest.h>

#include <limits>
#include <random>

#include "artms/testing/testing.hpp"

namespace artms::dynamics {
namespace {

using artms::testing::IsNearJacobian;
using astro::StateVector;

// The GVE are the exact time derivative of the osculating elements:
// d(alpha)/dt = d(alpha)/dx * x_dot with x_dot = [v; -mu r/r^3 + d].
// Checked against a numerical Jacobian of qns_from_cartesian.
TEST(Gve, MatrixEqualsDerivativeOfOsculatingElements) {
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> ua(6.7e6, 8e6), ue(0.0, 0.05), ui(0.2, 2.9),
      uang(0.0, astro::kTwoPi), ud(-1e-4, 1e-4);
  const double gm = astro::kGmEarth_m3ps2;
  for (int k = 0; k < 200; ++k) {
    const double e = k % 5 == 0 ? 1e-9 : ue(rng), w = uang(rng);
    const QnsElements oe{ua(rng), e * std::cos(w), e * std::sin(w), ui(rng), uang(rng), uang(rng)};
    const StateVector x = astro::cartesian_from_qns(oe, gm);
    const Vec3 d_rtn(ud(rng), ud(rng), ud(rng));
    const Vec3 d_eci = astro::R_rtn_from_eci(x).transpose() * d_rtn;
    Vec6 xdot;
    xdot << x.v_mps, -gm * x.r_m / std::pow(x.r_m.norm(), 3) + d_eci;
    // Directional derivative of the elements along x_dot (central difference in time).
    const double h = 1e-2;  // s
    const auto alpha_at = [&](double s) {
      const QnsElements q = astro::qns_from_cartesian(StateVector::from_stacked(x.stacked() + s * xdot), gm);
      return q.as_vector();
    };
    Vec6 num = (alpha_at(h) - alpha_at(-h)) / (2 * h);
    num[4] = astro::wrap_pi(alpha_at(h)[4] - alpha_at(-h)[4]) / (2 * h);
    num[5] = astro::wrap_pi(alpha_at(h)[5] - alpha_at(-h)[5]) / (2 * h);
    const Vec6 ana = qns_rates(oe, d_rtn, gm);
    // Perturbation part only (the mean motion dominates u_dot).
    Vec6 kepler = Vec6::Zero();
    kepler[5] = astro::mean_motion_radps(oe.a_m, gm);
    const Vec6 num_pert = num - kepler, ana_pert = ana - kepler;
    const Mat63 G = gve_matrix(oe, gm);
    for (int i = 0; i < 6; ++i) {
      // Size of this element's perturbation rate: |G_i| |d|.
      const double typical = G.row(i).norm() * d_rtn.norm();
      // Rounding noise of the central difference: a few ulps of the element over 2h.
      const double magnitude = i == 0 ? oe.a_m : (i == 1 || i == 2 ? 1.0 : astro::kTwoPi);
      const double noise = 8.0 * std::numeric_limits<double>::epsilon() * magnitude / (2.0 * h);
      EXPECT_NEAR(ana_pert[i], num_pert[i], 1e-4 * typical + noise)
          << "element " << i << " case " << k << " e=" << e;
    }
  }
}

TEST(Gve, RegularAtZeroEccentricity) {
  const QnsElements oe{7e6, 0.0, 0.0, 1.7, 0.3, 1.1};
  const Mat63 G = gve_matrix(oe);
  EXPECT_TRUE(G.allFinite());
  const QnsElements oe2{7e6, 1e-12, 0.0, 1.7, 0.3, 1.1};
  EXPECT_LT((gve_matrix(oe2) - G).cwiseAbs().maxCoeff(), 1e-9 * G.cwiseAbs().maxCoeff());
}

TEST(Gve, TwoBodyPropagationIsExact) {
  const ForceModel forces = ForceModel::load(ForceModelOptions::parse("two-body"), ARTMS_DATA_DIR);
  const GveRk4Propagator prop(forces, SpacecraftProperties{});
  const QnsElements oe0{6945e3, 0.0007, 0.0014, 1.735, -2.66, -0.73};
  const astro::TimeTT t0 = astro::tt_from_utc_string("2024-02-05T00:00:00Z");
  const QnsElements oe1 = prop.propagate(oe0, t0, t0.plus_seconds(86400.0));
  EXPECT_NEAR(oe1.a_m, oe0.a_m, 1e-6);
  EXPECT_NEAR(oe1.ex, oe0.ex, 1e-15);
  // 1e-10 rad = 0.7 mm along track after 15 orbits (rounding of ~2900 steps).
  EXPECT_NEAR(astro::wrap_pi(oe1.u_rad - oe0.u_rad - astro::mean_motion_radps(oe0.a_m) * 86400.0),
              0.0, 1e-10);
  // Backwards returns to the start.
  const QnsElements back = prop.propagate(oe1, t0.plus_seconds(86400.0), t0);
  EXPECT_NEAR(astro::wrap_pi(back.u_rad - oe0.u_rad), 0.0, 1e-10);
}

TEST(Gve, ManeuverIsAppliedAtItsEpoch) {
  const ForceModel forces = ForceModel::load(ForceModelOptions::parse("two-body"), ARTMS_DATA_DIR);
  const GveRk4Propagator prop(forces, SpacecraftProperties{});
  const QnsElements oe0{6945e3, 0.0, 0.0, 1.735, 0.5, 0.0};
  const astro::TimeTT t0 = astro::tt_from_utc_string("2024-02-05T00:00:00Z");
  // A tangential burn of 1 m/s raises a by 2 a dv / v (Gauss).
  const QnsElements oe1 =
      prop.propagate(oe0, t0, t0.plus_seconds(1000.0), {{t0.plus_seconds(100.0), Vec3(0, 1.0, 0)}});
  const double v = std::sqrt(astro::kGmEarth_m3ps2 / oe0.a_m);
  EXPECT_NEAR(oe1.a_m - oe0.a_m, 2.0 * oe0.a_m / v, 0.01 * 2.0 * oe0.a_m / v);
}

TEST(Gve, RejectsBadOptions) {
  const ForceModel forces = ForceModel::load(ForceModelOptions::parse("two-body"), ARTMS_DATA_DIR);
  EXPECT_THROW(GveRk4Propagator(forces, SpacecraftProperties{}, GvePropagatorOptions{0.0}),
               std::invalid_argument);
}

}  // namespace
}  // namespace artms::dynamics
