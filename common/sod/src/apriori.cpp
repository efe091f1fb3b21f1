#include "artms/sod/apriori.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <stdexcept>
#include <string>

#include "artms/astro/elements.hpp"
#include "artms/astro/roe.hpp"
#include "artms/dynamics/j2_mean.hpp"

namespace artms::sod {

void AprioriErrorModel::validate() const {
  const auto check = [](double v, const char* name) {
    if (!std::isfinite(v) || v < 0.0)
      throw std::invalid_argument(std::string("AprioriErrorModel.") + name +
                                  ": must be finite and >= 0");
  };
  check(sigma_a_da0_m, "sigma_a_da0_m");
  check(sigma_a_dlambda0_m, "sigma_a_dlambda0_m");
  check(sigma_a_de0_m, "sigma_a_de0_m");
  check(sigma_a_di0_m, "sigma_a_di0_m");
  check(sigma_a_da_rate_mpd, "sigma_a_da_rate_mpd");
  check(sigma_a_de_rate_mpd, "sigma_a_de_rate_mpd");
  check(sigma_a_di_rate_mpd, "sigma_a_di_rate_mpd");
}

AprioriRoe apriori_from_age(double age_days, double a_observer_m, const AprioriErrorModel& model) {
  model.validate();
  if (!std::isfinite(age_days) || age_days < 0.0)
    throw std::invalid_argument("apriori_from_age: age_days must be finite and >= 0");
  if (!std::isfinite(a_observer_m) || a_observer_m <= 0.0)
    throw std::invalid_argument("apriori_from_age: a_observer_m must be positive");
  const double t = age_days * astro::kSecondsPerDay;
  const double n = astro::mean_motion_radps(a_observer_m);
  const double s_da0 = model.sigma_a_da0_m;
  const double s_dadot = model.sigma_a_da_rate_mpd / astro::kSecondsPerDay;  // m/s
  // [a da, a dlambda] = A [a da0, a dadot] + [0, a dlambda0]
  const double k0 = -1.5 * n * t, k1 = -0.75 * n * t * t;
  AprioriRoe out;
  astro::Mat6& P = out.P_a_roe_m2;
  P(0, 0) = s_da0 * s_da0 + s_dadot * s_dadot * t * t;
  P(1, 1) = model.sigma_a_dlambda0_m * model.sigma_a_dlambda0_m + k0 * k0 * s_da0 * s_da0 +
            k1 * k1 * s_dadot * s_dadot;
  P(0, 1) = P(1, 0) = k0 * s_da0 * s_da0 + k1 * t * s_dadot * s_dadot;
  const double de_days = model.sigma_a_de_rate_mpd * age_days;
  const double di_days = model.sigma_a_di_rate_mpd * age_days;
  P(2, 2) = P(3, 3) = model.sigma_a_de0_m * model.sigma_a_de0_m + de_days * de_days;
  P(4, 4) = P(5, 5) = model.sigma_a_di0_m * model.sigma_a_di0_m + di_days * di_days;
  out.sigma_a_roe_m = P.diagonal().cwiseSqrt();
  out.P_roe = P / (a_observer_m * a_observer_m);
  return out;
}

astro::Vec6 draw_apriori_error_a_roe_m(const AprioriRoe& apriori, std::mt19937_64& rng) {
  // Symmetric square root: valid also when a sigma is zero (P semi-definite).
  const Eigen::SelfAdjointEigenSolver<astro::Mat6> es(apriori.P_a_roe_m2);
  const astro::Vec6 sd = es.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  std::normal_distribution<double> g(0.0, 1.0);
  astro::Vec6 w;
  for (int i = 0; i < 6; ++i) w[i] = g(rng);
  return es.eigenvectors() * sd.asDiagonal() * w;
}

astro::Vec6 apriori_roe_drifted(const astro::Vec6& roe, double a_observer_m, double dt_s) {
  const double a = a_observer_m;
  const double n = std::sqrt(astro::kGmEarth_m3ps2 / (a * a * a));
  astro::Vec6 out = roe;
  out[1] += -1.5 * n * roe[0] * dt_s;
  return out;
}

astro::Mat6 apriori_covariance_drifted(const astro::Mat6& P_roe, double a_observer_m, double dt_s) {
  const double n = std::sqrt(astro::kGmEarth_m3ps2 / std::pow(a_observer_m, 3));
  astro::Mat6 Phi = astro::Mat6::Identity();
  Phi(1, 0) = -1.5 * n * dt_s;
  return Phi * P_roe * Phi.transpose();
}

astro::Vec6 apriori_roe_drifted(const astro::Vec6& roe, const astro::QnsElements& observer_mean, double dt_s) {
  return dynamics::roe_stm_j2(observer_mean, dt_s) * roe;
}

astro::Mat6 apriori_covariance_drifted(const astro::Mat6& P_roe, const astro::QnsElements& observer_mean, double dt_s) {
  const astro::Mat6 Phi = dynamics::roe_stm_j2(observer_mean, dt_s);
  return Phi * P_roe * Phi.transpose();
}

namespace {
astro::QnsElements mean_or_osculating(const astro::QnsElements& osc) {
  try {
    return dynamics::mean_from_osculating(osc);
  } catch (const std::exception&) {
    return osc;
  }
}
}  // namespace

astro::Vec6 apriori_roe_at(const astro::Vec6& roe, const astro::QnsElements& observer_osc, double dt_s) {
  return dt_s == 0.0 ? roe : apriori_roe_drifted(roe, mean_or_osculating(observer_osc), dt_s);
}

astro::Mat6 apriori_covariance_at(const astro::Mat6& P_roe, const astro::QnsElements& observer_osc, double dt_s) {
  return dt_s == 0.0 ? P_roe : apriori_covariance_drifted(P_roe, mean_or_osculating(observer_osc), dt_s);
}

}  // namespace artms::sod

namespace artms::sod {

namespace {
// The orbit x displaced by the ROE a_roe_m / a (the deputy of x at those ROE).
astro::StateVector displaced(const astro::QnsElements& chief, const astro::Vec6& a_roe_m) {
  return astro::cartesian_from_qns(astro::qns_from_roe(chief, astro::Roe::from_vector(a_roe_m / chief.a_m)));
}
}  // namespace

astro::Mat6 coarse_orbit_covariance_rv(const astro::StateVector& x_eci, const astro::Vec6& sigma_a_roe_m) {
  if (!sigma_a_roe_m.allFinite() || (sigma_a_roe_m.array() <= 0.0).any()) {
    throw std::invalid_argument("coarse_orbit_covariance_rv: every 1-sigma must be finite and > 0");
  }
  const astro::QnsElements chief = astro::qns_from_cartesian(x_eci);
  astro::Mat6 J;
  for (int i = 0; i < 6; ++i) {
    astro::Vec6 d = astro::Vec6::Zero();
    d[i] = 1.0;  // 1 m of a*ROE
    const astro::StateVector p = displaced(chief, d), m = displaced(chief, -d);
    J.col(i) << (p.r_m - m.r_m) / 2.0, (p.v_mps - m.v_mps) / 2.0;
  }
  return J * sigma_a_roe_m.cwiseAbs2().asDiagonal() * J.transpose();
}

CoarseOrbit draw_coarse_orbit(const astro::StateVector& truth_eci, const astro::Vec6& sigma_a_roe_m,
                              std::mt19937_64& rng) {
  std::normal_distribution<double> n01(0.0, 1.0);
  astro::Vec6 e;
  for (int i = 0; i < 6; ++i) e[i] = sigma_a_roe_m[i] * n01(rng);
  return coarse_orbit_with_error(truth_eci, sigma_a_roe_m, e);
}

CoarseOrbit coarse_orbit_with_error(const astro::StateVector& truth_eci, const astro::Vec6& sigma_a_roe_m,
                                    const astro::Vec6& error_a_roe_m) {
  CoarseOrbit c;
  c.error_a_roe_m = error_a_roe_m;
  c.x_eci = displaced(astro::qns_from_cartesian(truth_eci), -error_a_roe_m);
  c.P_rv = coarse_orbit_covariance_rv(c.x_eci, sigma_a_roe_m);
  return c;
}

}  // namespace artms::sod
