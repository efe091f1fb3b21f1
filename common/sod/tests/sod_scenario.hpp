// Closed-loop scenario for the SOD tests: truth from the same GVE-RK4
// propagator (J2), an observer in a ~500 km, 97.6 deg near-circular orbit and
// Starling-like targets, and simulated bearings and GNSS.
#pragma once

#include <random>
#include <vector>

#include "artms/astro/bearing.hpp"
#include "artms/astro/roe.hpp"
#include "artms/dynamics/gve.hpp"
#include "artms/sod/sod_filter.hpp"

namespace artms::sod::testing {

using astro::QnsElements;
using astro::Roe;

inline const dynamics::ForceModel& j2_forces() {
  static const dynamics::ForceModel f =
      dynamics::ForceModel::load(dynamics::ForceModelOptions::parse("j2"), ARTMS_DATA_DIR);
  return f;
}

inline QnsElements observer_at_start() {
  using astro::kDegToRad;
  return {astro::kRadiusEarth_m + 500e3, 2e-4, 9e-4, 97.6 * kDegToRad, 30.0 * kDegToRad, 0.3};
}

// a*ROE (m): Starling-like, one target behind (-50 km) and one ahead (+80 km).
inline std::vector<Vec6> starling_a_roe_m() {
  return {(Vec6() << 2.0, -50e3, 300.0, -200.0, 250.0, 400.0).finished(),
          (Vec6() << -3.0, 80e3, -400.0, 250.0, -300.0, 350.0).finished(),
          (Vec6() << 1.0, 30e3, 200.0, 300.0, 200.0, -250.0).finished()};
}

// Truth: every spacecraft propagated with the onboard propagator itself.
class Truth {
 public:
  Truth(TimeTT t0, const QnsElements& observer, const std::vector<Vec6>& a_roe_m)
      : prop_(j2_forces(), dynamics::SpacecraftProperties{}), t_(t0), obs_(observer) {
    for (const Vec6& ar : a_roe_m)
      tgt_.push_back(astro::qns_from_roe(observer, Roe::from_scaled_m(ar, observer.a_m)));
  }
  void advance_to(TimeTT t) {
    obs_ = prop_.propagate(obs_, t_, t);
    for (auto& q : tgt_) q = prop_.propagate(q, t_, t);
    t_ = t;
  }
  // An impulsive manoeuvre of the observer (delta-v in its RTN frame).
  void apply_observer_dv(const Vec3& dv_rtn_mps) {
    obs_ = astro::qns_from_cartesian(dynamics::apply_maneuver(astro::cartesian_from_qns(obs_), dv_rtn_mps));
  }
  // An impulsive manoeuvre of target k (delta-v in its RTN frame).
  void apply_target_dv(int k, const Vec3& dv_rtn_mps) {
    tgt_[k] = astro::qns_from_cartesian(dynamics::apply_maneuver(astro::cartesian_from_qns(tgt_[k]), dv_rtn_mps));
  }
  [[nodiscard]] TimeTT t() const { return t_; }
  [[nodiscard]] const QnsElements& observer() const { return obs_; }
  [[nodiscard]] Roe roe(int k) const { return astro::roe_from_qns(obs_, tgt_[k]); }
  [[nodiscard]] Vec6 a_roe_m(int k) const { return obs_.a_m * roe(k).as_vector(); }
  [[nodiscard]] int n_targets() const { return static_cast<int>(tgt_.size()); }
  [[nodiscard]] VectorXd state() const {
    VectorXd x(6 + 6 * n_targets());
    x.head<6>() = obs_.as_vector();
    for (int k = 0; k < n_targets(); ++k) x.segment<6>(6 + 6 * k) = roe(k).as_vector();
    return x;
  }
  [[nodiscard]] astro::StateVector observer_eci() const { return astro::cartesian_from_qns(obs_); }
  [[nodiscard]] astro::StateVector target_eci(int k) const {
    return astro::cartesian_from_qns(tgt_[k]);
  }
  // Camera looking at target k: anti-velocity for targets behind, else +velocity.
  [[nodiscard]] Mat3 camera(int k) const {
    return astro::R_v_from_eci(observer_eci(), roe(k).dlambda < 0.0
                                                   ? astro::Boresight::kMinusVelocity
                                                   : astro::Boresight::kPlusVelocity);
  }
  [[nodiscard]] BearingMeasurement bearing(int k, double sigma_rad, double noise_rad,
                                           std::mt19937_64* rng) const {
    BearingMeasurement m;
    m.t = t_;
    m.target = k;
    m.R_v_from_eci = camera(k);
    m.angles = astro::bearing_from_eci(observer_eci().r_m, target_eci(k).r_m, m.R_v_from_eci);
    if (rng != nullptr && noise_rad > 0.0) {
      std::normal_distribution<double> g(0.0, noise_rad);
      m.angles.az_rad += g(*rng);
      m.angles.el_rad += g(*rng);
    }
    m.sigma_az_rad = m.sigma_el_rad = sigma_rad;
    return m;
  }
  [[nodiscard]] GnssMeasurement gnss(double sigma_r_m, double sigma_v_mps, bool noisy,
                                     std::mt19937_64* rng) const {
    GnssMeasurement m;
    m.t = t_;
    m.x_eci = observer_eci();
    if (noisy && rng != nullptr) {
      std::normal_distribution<double> gr(0.0, sigma_r_m), gv(0.0, sigma_v_mps);
      for (int i = 0; i < 3; ++i) {
        m.x_eci.r_m[i] += gr(*rng);
        m.x_eci.v_mps[i] += gv(*rng);
      }
    }
    m.sigma_r_m = sigma_r_m;
    m.sigma_v_mps = sigma_v_mps;
    return m;
  }

 private:
  dynamics::GveRk4Propagator prop_;
  TimeTT t_;
  QnsElements obs_;
  std::vector<QnsElements> tgt_;
};

// Initial estimate: a*dlambda off by `dlambda_frac` of itself, the other a*ROE
// off by +-`other_m`; observer off by a few meters. Covariance: the errors as
// 1-sigma (diagonal).
struct InitialGuess {
  VectorXd x;
  MatrixXd P;
};
inline InitialGuess shifted_initial_guess(const QnsElements& observer,
                                          const std::vector<Vec6>& a_roe_m, double dlambda_frac,
                                          double other_m) {
  const int n_t = static_cast<int>(a_roe_m.size());
  const int n = 6 + 6 * n_t;
  InitialGuess g;
  g.x.resize(n);
  g.P = MatrixXd::Zero(n, n);
  const double a = observer.a_m;
  Vec6 obs = observer.as_vector();
  const Vec6 obs_err = (Vec6() << 5.0, 5e-6, -5e-6, 2e-6, -2e-6, 1e-6).finished();
  const Vec6 obs_sig = (Vec6() << 10.0, 1e-5, 1e-5, 5e-6, 5e-6, 3e-6).finished();
  g.x.head<6>() = obs + obs_err;
  g.P.diagonal().head<6>() = obs_sig.cwiseAbs2();
  for (int k = 0; k < n_t; ++k) {
    Vec6 err;
    const double s = k % 2 == 0 ? 1.0 : -1.0;
    err << s * other_m, dlambda_frac * a_roe_m[k][1], -s * other_m, s * other_m, s * other_m,
        -s * other_m;
    Vec6 sig = Vec6::Constant(other_m);
    sig[1] = std::abs(dlambda_frac * a_roe_m[k][1]);
    g.x.segment<6>(6 + 6 * k) = (a_roe_m[k] + err) / a;
    g.P.diagonal().segment<6>(6 + 6 * k) = (sig / a).cwiseAbs2();
  }
  return g;
}

}  // namespace artms::sod::testing
