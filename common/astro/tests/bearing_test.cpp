#include "artms/astro/bearing.hpp"

#include <gtest/gtest.h>

#include <random>

#include "artms/astro/roe.hpp"
#include "artms/testing/testing.hpp"

namespace artms::astro {
namespace {

using artms::testing::IsNearJacobian;
using artms::testing::numerical_jacobian;

constexpr double kJacobianRelTol = 1e-7;

TEST(Bearing, Equation2Definitions) {
  // Along the boresight: both angles zero.
  const Bearing b0 = bearing_from_los(Vec3(0, 0, 5e4));
  EXPECT_DOUBLE_EQ(b0.az_rad, 0.0);
  EXPECT_DOUBLE_EQ(b0.el_rad, 0.0);
  // +y_V gives positive azimuth, +x_V positive elevation.
  EXPECT_NEAR(bearing_from_los(Vec3(0, 1, 1)).az_rad, kPi / 4, 1e-15);
  EXPECT_NEAR(bearing_from_los(Vec3(1, 0, 1)).el_rad, kPi / 4, 1e-15);
  EXPECT_THROW(bearing_from_los(Vec3::Zero()), std::invalid_argument);
}

TEST(Bearing, UnitLineOfSightInvertsEquation2) {
  std::mt19937 rng(2);
  std::normal_distribution<double> n(0, 1);
  for (int k = 0; k < 1000; ++k) {
    Vec3 los(n(rng), n(rng), std::abs(n(rng)) + 0.1);
    const Vec3 u = unit_los_from_bearing(bearing_from_los(los));
    EXPECT_LT((u - los.normalized()).norm(), 1e-14);
  }
}

TEST(Bearing, JacobianWrtLineOfSightMatchesNumerical) {
  std::mt19937 rng(4);
  std::normal_distribution<double> n(0, 1);
  for (int k = 0; k < 500; ++k) {
    const Vec3 los = 1e5 * Vec3(0.2 * n(rng), 0.2 * n(rng), 1.0 + 0.1 * n(rng));
    const auto f = [](const Vec3& l) { return bearing_from_los(l).as_vector(); };
    const Mat23 num = numerical_jacobian<2, 3>(f, los, Vec3::Constant(1e-3));
    EXPECT_THAT(bearing_jacobian_los(los), IsNearJacobian(num, kJacobianRelTol));
  }
  EXPECT_THROW(bearing_jacobian_los(Vec3(0, 1, 0)), std::domain_error);
}

TEST(Bearing, JacobianChainedToEciPositionsMatchesNumerical) {
  const StateVector obs{Vec3(6.9e6, 1e5, -2e5), Vec3(-100, 1500, 7400)};
  const Mat3 R = R_v_from_eci(obs, Boresight::kMinusVelocity);
  const Vec3 r_t = obs.r_m - 80e3 * obs.v_mps.normalized() + Vec3(300, -500, 800);
  const auto f_t = [&](const Vec3& rt) { return bearing_from_eci(obs.r_m, rt, R).as_vector(); };
  const Mat23 num_t = numerical_jacobian<2, 3>(f_t, r_t, Vec3::Constant(1.0));
  const Mat23 J_t = bearing_jacobian_target_eci(obs.r_m, r_t, R);
  EXPECT_THAT(J_t, IsNearJacobian(num_t, kJacobianRelTol));
  const auto f_o = [&](const Vec3& ro) { return bearing_from_eci(ro, r_t, R).as_vector(); };
  const Mat23 num_o = numerical_jacobian<2, 3>(f_o, obs.r_m, Vec3::Constant(1.0));
  EXPECT_THAT(Mat23(-J_t), IsNearJacobian(num_o, kJacobianRelTol));
}

TEST(Bearing, JacobianChainedToRoeMatchesNumerical) {
  // PSE formation, SV2 seen from SV4 with the camera anti-velocity.
  const double a = 6943e3;
  const Vec6 roe = (Vec6() << 23, -52266, -471, -523, 35, 1811).finished() / a;
  const Mat3 R_v_from_rtn = R_v_from_w(Boresight::kMinusVelocity);  // circular: W = RTN
  for (double u : {0.0, 0.7, 2.1, 4.0}) {
    const auto f = [&](const Vec6& x) {
      return bearing_from_los(R_v_from_rtn * rtn_from_roe_linear(Roe::from_vector(x), a, u).r_m)
          .as_vector();
    };
    const Mat26 num = numerical_jacobian<2, 6>(f, roe, Vec6::Constant(1e-8));
    EXPECT_THAT(bearing_jacobian_roe_linear(roe, a, u, R_v_from_rtn),
                IsNearJacobian(num, kJacobianRelTol));
  }
}

}  // namespace
}  // namespace artms::astro
