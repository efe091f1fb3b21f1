#include "artms/sod/sod_filter.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <functional>
#include <sstream>
#include <stdexcept>

namespace artms::sod {

namespace {

using astro::QnsElements;
using astro::Roe;

void require(bool ok, const std::string& field, const std::string& expected) {
  if (!ok) throw std::invalid_argument("SodOptions." + field + ": " + expected);
}

bool is_finite_positive(double v) { return std::isfinite(v) && v > 0.0; }

// Scaled unscented transform weights (Wan & van der Merwe 2000, eq. 15).
void ukf_weights(int n, const SodOptions& o, double& gamma, VectorXd& wm, VectorXd& wc) {
  const double lambda = o.ukf_alpha * o.ukf_alpha * (n + o.ukf_kappa) - n;
  gamma = std::sqrt(n + lambda);
  wm = VectorXd::Constant(2 * n + 1, 0.5 / (n + lambda));
  wc = wm;
  wm[0] = lambda / (n + lambda);
  wc[0] = wm[0] + (1.0 - o.ukf_alpha * o.ukf_alpha + o.ukf_beta);
}

// Sigma point j (j >= 1) is built from column (j - 1) % n of chol(P).
int column_of(int j, int n) { return (j - 1) % n; }

bool symmetric_positive_definite(const MatrixXd& P) {
  if (!P.allFinite()) return false;
  if ((P - P.transpose()).cwiseAbs().maxCoeff() >
      1e-9 * std::max(1e-300, P.diagonal().cwiseAbs().maxCoeff()))
    return false;
  const Eigen::LLT<MatrixXd> llt(P);
  return llt.info() == Eigen::Success;
}

}  // namespace

// ---------------------------------------------------------------- options

void SodOptions::validate() const {
  require(std::isfinite(propagator.step_s) && propagator.step_s > 0.0, "propagator.step_s",
          "must be positive and finite");
  require(std::isfinite(ukf_alpha) && ukf_alpha > 0.0 && ukf_alpha <= 1.0, "ukf_alpha",
          "must be in (0, 1]");
  require(std::isfinite(ukf_beta) && ukf_beta >= 0.0, "ukf_beta", "must be >= 0");
  require(std::isfinite(ukf_kappa), "ukf_kappa", "must be finite");
  for (int i = 0; i < 6; ++i) {
    require(std::isfinite(q_observer[i]) && q_observer[i] >= 0.0,
            "q_observer[" + std::to_string(i) + "]", "must be finite and >= 0");
    require(std::isfinite(q_target_a_roe_m2ps[i]) && q_target_a_roe_m2ps[i] >= 0.0,
            "q_target_a_roe_m2ps[" + std::to_string(i) + "]", "must be finite and >= 0");
  }
  require(std::isfinite(q_aux) && q_aux >= 0.0, "q_aux", "must be finite and >= 0");
  require(std::isfinite(q_time_tag_offset_s2ps) && q_time_tag_offset_s2ps >= 0.0, "q_time_tag_offset_s2ps",
          "must be finite and >= 0");
  require(std::isfinite(q_time_tag_drift_ps) && q_time_tag_drift_ps >= 0.0, "q_time_tag_drift_ps",
          "must be finite and >= 0");
  require(std::isfinite(q_ballistic_m4pkg2ps) && q_ballistic_m4pkg2ps >= 0.0, "q_ballistic_m4pkg2ps",
          "must be finite and >= 0");
  require(health.nis_window >= 0, "health.nis_window", "must be >= 0 (0 disables)");
  require(std::isfinite(health.nis_max_mean) && health.nis_max_mean > 0.0, "health.nis_max_mean",
          "must be finite and > 0");
  require(health.gnss_nis_window >= 0, "health.gnss_nis_window", "must be >= 0 (0 disables)");
  require(std::isfinite(health.gnss_nis_max_mean) && health.gnss_nis_max_mean > 0.0, "health.gnss_nis_max_mean",
          "must be finite and > 0");
  require(health.gnss_bias_window >= 0, "health.gnss_bias_window", "must be >= 0 (0 disables)");
  require(std::isfinite(health.gnss_bias_max) && health.gnss_bias_max > 0.0, "health.gnss_bias_max",
          "must be finite and > 0");
  require(std::isfinite(adaptive.time_constant_s) && adaptive.time_constant_s > 0.0, "adaptive.time_constant_s",
          "must be finite and > 0");
  require(std::isfinite(adaptive.floor_factor) && adaptive.floor_factor >= 0.0 &&
              adaptive.floor_factor <= 1.0,
          "adaptive.floor_factor", "must be in [0, 1]");
  require(std::isfinite(adaptive.ceiling_factor) && adaptive.ceiling_factor >= 1.0,
          "adaptive.ceiling_factor", "must be finite and >= 1");
  require(std::isfinite(adaptive.drag_density_error) && adaptive.drag_density_error >= 0.0 &&
              adaptive.drag_density_error <= 10.0,
          "adaptive.drag_density_error", "must be in [0, 10]");
  require(std::isfinite(adaptive.density_change_per_day) && adaptive.density_change_per_day >= 0.0 &&
              adaptive.density_change_per_day <= 10.0,
          "adaptive.density_change_per_day", "must be in [0, 10]");
  require(bearing_gate_mahalanobis > 0.0, "bearing_gate_mahalanobis", "must be > 0 (inf disables)");
  require(bearing_underweighting >= 0.0 && std::isfinite(bearing_underweighting), "bearing_underweighting", "must be >= 0");
  require(bearing_underweighting_nonlinearity >= 0.0 && std::isfinite(bearing_underweighting_nonlinearity),
          "bearing_underweighting_nonlinearity", "must be >= 0");
  require(gnss_gate_mahalanobis > 0.0, "gnss_gate_mahalanobis", "must be > 0 (inf disables)");
  require(health.bod_max_mahalanobis > 0.0, "health.bod_max_mahalanobis", "must be > 0");
  require(health.bod_max_relative > 0.0, "health.bod_max_relative", "must be > 0");
  require(health.max_steps_without_update >= 1, "health.max_steps_without_update", "must be >= 1");
  require(health.max_large_residuals >= 1, "health.max_large_residuals", "must be >= 1");
  require(health.large_residual_mahalanobis > 0.0, "health.large_residual_mahalanobis",
          "must be > 0");
  require(is_finite_positive(health.min_a_m) && health.max_a_m > health.min_a_m,
          "health.min_a_m", "must be positive and below health.max_a_m");
  require(health.max_e > 0.0 && health.max_e < 1.0, "health.max_e", "must be in (0, 1)");
  require(health.max_a_roe_m > 0.0, "health.max_a_roe_m", "must be > 0");
}

Vec6 observer_process_noise_from_acceleration(double a_m, double i_rad, double sigma_acc_mps2, double tau_s) {
  if (!(a_m > 0.0) || !(sigma_acc_mps2 >= 0.0) || !(tau_s >= 0.0)) {
    throw std::invalid_argument("observer_process_noise_from_acceleration: a > 0, sigma >= 0 and tau >= 0 expected");
  }
  const double n = std::sqrt(astro::kGmEarth_m3ps2 / (a_m * a_m * a_m));
  const double q_v = 2.0 * sigma_acc_mps2 * sigma_acc_mps2 * tau_s;
  const double na2 = std::pow(n * a_m, 2);
  const double s2 = std::max(std::pow(std::sin(i_rad), 2), 1e-6);
  Vec6 q;
  q << std::pow(2.0 / n, 2) * q_v, 2.5 / na2 * q_v, 2.5 / na2 * q_v, 0.5 / na2 * q_v, 0.5 / (na2 * s2) * q_v,
      4.0 / na2 * q_v;
  return q;
}

Vec6 target_along_track_process_noise(double a_m, double sigma_acc_mps2, double tau_s) {
  if (!(a_m > 0.0) || !(sigma_acc_mps2 >= 0.0) || !(tau_s >= 0.0)) {
    throw std::invalid_argument("target_along_track_process_noise: a > 0, sigma >= 0 and tau >= 0 expected");
  }
  const double n = std::sqrt(astro::kGmEarth_m3ps2 / (a_m * a_m * a_m));
  const double q_v = 2.0 * sigma_acc_mps2 * sigma_acc_mps2 * tau_s;
  const double na2 = std::pow(n * a_m, 2);
  Vec6 q;
  q << 4.0 / na2 * q_v, 0.0, 2.0 / na2 * q_v, 2.0 / na2 * q_v, 0.0, 0.0;
  return q;
}

double chi2_quantile(int dof, double p) {
  if (dof < 1) throw std::invalid_argument("chi2_quantile: dof must be >= 1");
  if (!(p > 0.0 && p < 1.0)) throw std::invalid_argument("chi2_quantile: p must be in (0, 1)");
  // Standard normal quantile z(p) by bisection on 0.5 erfc(-z / sqrt 2) = p.
  double lo = -40.0, hi = 40.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (0.5 * std::erfc(-mid / std::sqrt(2.0)) < p ? lo : hi) = mid;
  }
  const double z = 0.5 * (lo + hi), k = dof, c = 2.0 / (9.0 * k);
  return k * std::pow(std::max(0.0, 1.0 - c + z * std::sqrt(c)), 3);
}

BearingMeasurement bearing_measurement_from_unit_eci(TimeTT t, int target, const Vec3& los_eci,
                                                     double sigma_rad, const Mat3& R_v_from_eci) {
  BearingMeasurement m;
  m.t = t;
  m.target = target;
  m.angles = astro::bearing_from_los(R_v_from_eci * los_eci);
  m.sigma_az_rad = m.sigma_el_rad = sigma_rad;
  m.R_v_from_eci = R_v_from_eci;
  return m;
}

std::string UpdateSummary::brief_report() const {
  std::ostringstream s;
  s << (target < 0 ? std::string("gnss") : "bearing target " + std::to_string(target)) << ": "
    << (usable ? "accepted" : (gated ? "gated" : "unusable"));
  if (std::isfinite(mahalanobis)) s << ", Mahalanobis " << mahalanobis << ", NIS " << nis;
  if (!why.empty()) s << " (" << why << ")";
  return s.str();
}

std::string_view to_string(HealthCondition c) {
  switch (c) {
    case HealthCondition::kHealthy: return "healthy";
    case HealthCondition::kBodDisagreement: return "bod_disagreement";
    case HealthCondition::kNoMeasurementUpdate: return "no_measurement_update";
    case HealthCondition::kLargeResiduals: return "large_residuals";
    case HealthCondition::kOutOfRange: return "out_of_range";
    case HealthCondition::kInconsistent: return "inconsistent";
  }
  return "unknown";
}

bool HealthReport::healthy() const {
  if (!filter.healthy()) return false;
  for (const auto& t : targets)
    if (!t.healthy()) return false;
  return true;
}

// ---------------------------------------------------------------- filter

struct SodFilter::MeasurementModel {
  std::function<VectorXd(const VectorXd&)> h;
  // Sigma points from chol(P) columns >= cutoff leave h unchanged.
  int cutoff = 0;
  // Components of z that are angles (residuals wrapped).
  std::vector<bool> angle;
  double underweighting = 0.0;  // beta (SodOptions::bearing_underweighting)
  double nonlinearity = 0.0;    // SodOptions::bearing_underweighting_nonlinearity
  // The first `consider` states are consider parameters (Schmidt-Kalman):
  // their gain rows are zero.
  int consider = 0;
};

SodFilter::SodFilter(const dynamics::ForceModel& forces,
                     const dynamics::SpacecraftProperties& observer_sc,
                     const dynamics::SpacecraftProperties& target_sc, StateLayout layout,
                     SodOptions options)
    : SodFilter(forces, observer_sc, layout,
                std::vector<dynamics::SpacecraftProperties>(static_cast<std::size_t>(std::max(layout.n_targets, 0)),
                                                            target_sc),
                std::move(options)) {}

SodFilter::SodFilter(const dynamics::ForceModel& forces,
                     const dynamics::SpacecraftProperties& observer_sc,
                     StateLayout layout, const std::vector<dynamics::SpacecraftProperties>& target_sc,
                     SodOptions options)
    : observer_prop_(forces, observer_sc, options.propagator),
      gm_m3ps2_(forces.gm_m3ps2()),
      layout_(layout),
      options_(std::move(options)),
      forces_(forces) {
  options_.validate();
  if (layout_.n_targets < 1) throw std::invalid_argument("StateLayout.n_targets: must be >= 1");
  if (static_cast<int>(target_sc.size()) != layout_.n_targets)
    throw std::invalid_argument("SodFilter: need one target's properties per target (" +
                                std::to_string(layout_.n_targets) + "), got " + std::to_string(target_sc.size()));
  target_props_.reserve(target_sc.size());
  for (const auto& sc : target_sc) target_props_.emplace_back(forces, sc, options_.propagator);
  if (layout_.n_aux < 0) throw std::invalid_argument("StateLayout.n_aux: must be >= 0");
  if (layout_.n_time_tag < 0 || layout_.n_time_tag > 2)
    throw std::invalid_argument("StateLayout.n_time_tag: must be 0, 1 or 2");
  if (layout_.n_remote_clock < 0) throw std::invalid_argument("StateLayout.n_remote_clock: must be >= 0");
  const int n = layout_.size();
  require(n + options_.ukf_kappa > 0.0, "ukf_kappa", "n + ukf_kappa must be > 0 (n = state size)");
  ukf_weights(n, options_, gamma_, wm_, wc_);
  counters_.assign(layout_.n_targets, {});
  bod_status_.assign(layout_.n_targets, {});
  last_bod_.assign(layout_.n_targets, std::nullopt);
  recent_nis_.assign(layout_.n_targets, std::vector<double>(static_cast<std::size_t>(options_.health.nis_window), 0.0));
  recent_nis_t_.assign(layout_.n_targets, std::vector<TimeTT>(static_cast<std::size_t>(options_.health.nis_window)));
  recent_nis_count_.assign(layout_.n_targets, 0);
  gnss_nis_.assign(static_cast<std::size_t>(options_.health.gnss_nis_window), 0.0);
  gnss_white_rtn_.assign(static_cast<std::size_t>(options_.health.gnss_bias_window), Vec6::Zero());
}

VectorXd SodFilter::make_state(const QnsElements& observer, const std::vector<Roe>& roe,
                               const VectorXd& aux) const {
  if (static_cast<int>(roe.size()) != layout_.n_targets)
    throw std::invalid_argument("SodFilter::make_state: need one ROE per target");
  const int n_aux_all = layout_.size() - layout_.aux_offset();
  if (aux.size() != 0 && aux.size() != n_aux_all)
    throw std::invalid_argument("SodFilter::make_state: aux has the wrong size");
  VectorXd x = VectorXd::Zero(layout_.size());
  x.segment<6>(0) = observer.as_vector();
  for (int k = 0; k < layout_.n_targets; ++k) x.segment<6>(layout_.target_offset(k)) = roe[k].as_vector();
  if (aux.size() > 0) x.tail(n_aux_all) = aux;
  return x;
}

void SodFilter::initialize(TimeTT t, const VectorXd& x, const MatrixXd& P) {
  const int n = layout_.size();
  if (x.size() != n || P.rows() != n || P.cols() != n)
    throw std::invalid_argument("SodFilter::initialize: x and P must have layout().size() = " +
                                std::to_string(n) + " rows");
  if (!x.allFinite()) throw std::invalid_argument("SodFilter::initialize: x is not finite");
  if (!symmetric_positive_definite(P))
    throw std::invalid_argument("SodFilter::initialize: P is not symmetric positive definite");
  if (!(x[StateLayout::kA] > 0.0)) throw std::invalid_argument("SodFilter::initialize: a <= 0");
  t_ = t;
  x_ = x;
  wrap_state(x_);
  P_ = 0.5 * (P + P.transpose());
  // Nominal process noise in state units (targets through the observer's a).
  q_nominal_.resize(n);
  q_nominal_.head<6>() = options_.q_observer;
  const double a2 = x_[StateLayout::kA] * x_[StateLayout::kA];
  for (int k = 0; k < layout_.n_targets; ++k)
    q_nominal_.segment<6>(layout_.target_offset(k)) = options_.q_target_a_roe_m2ps / a2;
  if (layout_.n_aux > 0) q_nominal_.segment(layout_.aux_offset(), layout_.n_aux).setConstant(options_.q_aux);
  if (layout_.n_time_tag > 0) q_nominal_[layout_.time_tag_offset()] = options_.q_time_tag_offset_s2ps;
  if (layout_.n_time_tag > 1) q_nominal_[layout_.time_tag_drift()] = options_.q_time_tag_drift_ps;
  if (layout_.ballistic)
    q_nominal_.segment(layout_.ballistic_offset(), layout_.n_targets).setConstant(options_.q_ballistic_m4pkg2ps);
  if (layout_.n_remote_clock > 0)
    q_nominal_.segment(layout_.remote_clock_offset(), layout_.n_remote_clock).setConstant(options_.q_time_tag_offset_s2ps);
  q_ = q_nominal_;
  Q_rate_ = q_nominal_.asDiagonal();
  Q_average_ = Q_rate_;
  pending_dxdx_ = MatrixXd::Zero(n, n);
  pending_ = false;
  pending_dt_s_ = 0.0;
  counters_.assign(layout_.n_targets, {});
  bod_status_.assign(layout_.n_targets, {});
  last_bod_.assign(layout_.n_targets, std::nullopt);
  steps_without_update_ = 0;
  consecutive_large_gnss_ = 0;
  rejected_total_ = 0;
  recent_nis_count_.assign(layout_.n_targets, 0);
  prior_unconfirmed_.assign(layout_.n_targets, 0);  // a modelled a-priori, not a guess
  gnss_nis_count_ = 0;
  gnss_white_count_ = 0;
  initialized_ = true;
}

VectorXd SodFilter::state_difference(const VectorXd& a, const VectorXd& b) const {
  VectorXd d = a - b;
  for (int i = 0; i < d.size(); ++i)
    if (layout_.is_angle(i)) d[i] = astro::wrap_pi(d[i]);
  return d;
}

void SodFilter::wrap_state(VectorXd& x) const {
  x[StateLayout::kU] = astro::wrap_two_pi(x[StateLayout::kU]);
  x[StateLayout::kRaan] = astro::wrap_pi(x[StateLayout::kRaan]);
  for (int k = 0; k < layout_.n_targets; ++k) {
    const int i = layout_.target_offset(k) + StateLayout::kDlambda;
    x[i] = astro::wrap_pi(x[i]);
  }
}

bool SodFilter::sigma_points(MatrixXd& X) const {
  const int n = layout_.size();
  const Eigen::LLT<MatrixXd> llt(P_);
  if (llt.info() != Eigen::Success) return false;
  const MatrixXd L = llt.matrixL();
  if (!L.allFinite()) return false;
  X.resize(n, 2 * n + 1);
  X.col(0) = x_;
  for (int c = 0; c < n; ++c) {
    X.col(1 + c) = x_ + gamma_ * L.col(c);
    X.col(1 + n + c) = x_ - gamma_ * L.col(c);
  }
  return true;
}

VectorXd SodFilter::drag_floor_rates() const {
  // The drag floor of each target (docs/sod.md, "The drag floor") and its
  // ballistic walk from the density's day-to-day change, in the nominal's units.
  const AdaptiveNoiseOptions& o = options_.adaptive;
  VectorXd floor_add = VectorXd::Zero(layout_.size());
  if (!has_drag_budget() || !layout_.ballistic || layout_.n_targets == 0) return floor_add;
  const QnsElements obs = QnsElements::from_vector(x_.head<6>());
  // The onboard drag per unit B at the observer: only the floor needs it.
  double f_t = 0.0, period_s = 0.0;
  if (o.drag_density_error > 0.0) {
    const astro::StateVector xo = astro::cartesian_from_qns(obs, gm_m3ps2_);
    f_t = std::abs((astro::R_rtn_from_eci(xo) * forces_.unit_ballistic_drag_eci(t_, xo))[1]);
    period_s = astro::orbit_period_s(obs.a_m);
  }
  for (int k = 0; k < layout_.n_targets; ++k) {
    // |dB| estimated without the estimate's own spread: E[dB^2] = dB_true^2 + sigma_B^2.
    const int ib = layout_.ballistic_index(k);
    const double db = std::sqrt(std::max(x_[ib] * x_[ib] - P_(ib, ib), 0.0));
    if (o.drag_density_error > 0.0) {
      const double sigma = o.drag_density_error * db * f_t;
      floor_add.segment<6>(layout_.target_offset(k)) = target_along_track_process_noise(obs.a_m, sigma, period_s);
    }
    floor_add[ib] = std::pow(o.density_change_per_day * db, 2) / 86400.0;
  }
  return floor_add;
}

void SodFilter::adapt_process_noise() {
  const AdaptiveNoiseOptions& o = options_.adaptive;
  if (o.enabled && !pending_) {
    pending_dxdx_.setZero();
    return;
  }
  const double floor = o.floor_factor, ceiling = o.ceiling_factor;
  const VectorXd floor_add = drag_floor_rates();
  // A rate that does not adapt: the nominal, at least the drag floor (a
  // budget of the onboard model, not an adaptation).
  const VectorXd budget = q_nominal_.cwiseMax(floor * q_nominal_ + floor_add);
  if (!o.enabled) {
    pending_dxdx_.setZero();
    pending_ = false;
    pending_dt_s_ = 0.0;
    if (has_drag_budget()) {
      q_ = budget;
      Q_rate_ = q_.asDiagonal();
    }
    return;
  }
  // docs/sod.md, "Adaptive process noise": the corrections weigh 1/tau
  // whatever the interval; an unclamped average outside the clamp relaxes
  // towards the rate over the time they span.
  const double tau = o.time_constant_s, keep = std::exp(-pending_dt_s_ / tau);
  pending_dt_s_ = 0.0;
  const bool unclamped = o.average == AdaptiveNoiseAverage::kUnclamped;
  const int n = layout_.size();
  std::vector<char> in_block(n, 0);
  if (o.form == AdaptiveNoiseForm::kBlock) {
    std::vector<int> blocks{0};
    if (o.targets) {
      for (int k = 0; k < layout_.n_targets; ++k) blocks.push_back(layout_.target_offset(k));
    }
    for (const int off : blocks) {
      const Vec6 nominal = q_nominal_.segment<6>(off);
      if (!(nominal.minCoeff() > 0.0)) continue;  // adapts per component below
      // In the nominal's units, N^-1/2 A N^-1/2, the clamp acts on eigenvalues.
      const Vec6 s = nominal.cwiseSqrt(), s_inv = s.cwiseInverse();
      const Mat6 Q_prev = Q_rate_.block<6, 6>(off, off);
      const Mat6 A_prev = unclamped ? Mat6(Q_average_.block<6, 6>(off, off)) : Q_prev;
      const Mat6 A = keep * A_prev + (1.0 - keep) * Q_prev + pending_dxdx_.block<6, 6>(off, off) / tau;
      Mat6 M = s_inv.asDiagonal() * A * s_inv.asDiagonal();
      M = 0.5 * (M + M.transpose());
      const Eigen::SelfAdjointEigenSolver<Mat6> eig(M);
      if (eig.info() != Eigen::Success || !eig.eigenvalues().allFinite()) continue;
      const Mat6& V = eig.eigenvectors();
      const auto rebuild = [&](double lo, double hi) -> Mat6 {
        const Vec6 lambda = eig.eigenvalues().cwiseMax(lo).cwiseMin(hi);
        return s.asDiagonal() * (V * lambda.asDiagonal() * V.transpose()) * s.asDiagonal();
      };
      Mat6 R = rebuild(floor, ceiling);
      const Vec6 extra = floor_add.segment<6>(off);
      if (extra.maxCoeff() > 0.0) {
        // R >= floor N + D in the Loewner order: clamp in the floor's own units.
        const Vec6 f = (floor * nominal + extra).cwiseSqrt(), f_inv = f.cwiseInverse();
        Mat6 G = f_inv.asDiagonal() * R * f_inv.asDiagonal();
        G = 0.5 * (G + G.transpose());
        const Eigen::SelfAdjointEigenSolver<Mat6> eg(G);
        if (eg.info() == Eigen::Success && eg.eigenvalues().allFinite()) {
          const Vec6 mu = eg.eigenvalues().cwiseMax(1.0);
          R = f.asDiagonal() * (eg.eigenvectors() * mu.asDiagonal() * eg.eigenvectors().transpose()) * f.asDiagonal();
        }
      }
      Q_rate_.block<6, 6>(off, off) = R;
      Q_average_.block<6, 6>(off, off) = unclamped ? rebuild(-ceiling, ceiling) : R;
      for (int i = off; i < off + 6; ++i) in_block[i] = 1;
    }
  }
  std::vector<char> on_budget(n, 0);  // target components that do not adapt
  if (!o.targets) {
    for (int k = 0; k < layout_.n_targets; ++k) {
      for (int i = layout_.target_offset(k); i < layout_.target_offset(k) + 6; ++i) on_budget[i] = 1;
    }
  }
  for (int i = 0; i < n; ++i) {
    if (in_block[i]) continue;
    if (on_budget[i]) {
      Q_rate_(i, i) = Q_average_(i, i) = budget[i];
      continue;
    }
    const double a_prev = unclamped ? Q_average_(i, i) : Q_rate_(i, i);
    const double a = keep * a_prev + (1.0 - keep) * Q_rate_(i, i) + pending_dxdx_(i, i) / tau;
    const double lo = floor * q_nominal_[i] + floor_add[i];
    Q_rate_(i, i) = std::clamp(a, lo, std::max(lo, ceiling * q_nominal_[i]));
    Q_average_(i, i) = unclamped ? std::clamp(a, -ceiling * q_nominal_[i], ceiling * q_nominal_[i]) : Q_rate_(i, i);
  }
  q_ = Q_rate_.diagonal();
  pending_dxdx_.setZero();
  pending_ = false;
}

TimeUpdateSummary SodFilter::time_update(TimeTT t) {
  TimeUpdateSummary s;
  if (!begin_time_update(t, s)) return s;
  const int n = layout_.size(), m = 2 * n + 1;
  MatrixXd X;
  if (!sigma_points(X)) {
    s.why = "covariance not positive definite before the time update";
    return s;
  }
  MatrixXd Y = X;  // auxiliary states stay constant
  try {
    // Observer: only sigma points from columns 0..5 move it.
    std::vector<QnsElements> obs0(m), obs1(m);
    for (int j = 0; j < m; ++j) {
      obs0[j] = QnsElements::from_vector(X.col(j).head<6>());
      if (j == 0 || column_of(j, n) < 6) {
        obs1[j] = observer_prop_.propagate(obs0[j], t_, t);
        ++s.propagations;
      } else {
        obs1[j] = obs1[0];
      }
      Y.col(j).head<6>() = obs1[j].as_vector();
    }
    // Target k: only columns before the end of its block move it.
    for (int k = 0; k < layout_.n_targets; ++k) {
      const int off = layout_.target_offset(k), end = off + StateLayout::kBlock;
      QnsElements tgt_mean1;
      for (int j = 0; j < m; ++j) {
        QnsElements tgt1;
        if (j == 0 || column_of(j, n) < end) {
          const QnsElements tgt0 =
              astro::qns_from_roe(obs0[j], Roe::from_vector(X.col(j).segment<6>(off)));
          tgt1 = target_props_[static_cast<std::size_t>(k)].propagate(tgt0, t_, t);
          ++s.propagations;
          if (j == 0) tgt_mean1 = tgt1;
        } else {
          tgt1 = tgt_mean1;
        }
        Y.col(j).segment<6>(off) = astro::roe_from_qns(obs1[j], tgt1).as_vector();
      }
    }
  } catch (const std::exception& e) {
    s.why = std::string("propagation of a sigma point failed: ") + e.what();
    return s;
  }
  apply_aux_dynamics(X, Y, s.dt_s);
  VectorXd mean;
  MatrixXd P;
  mean_and_covariance(Y, mean, P);
  finish_time_update(t, mean, std::move(P), s);
  return s;
}

TimeUpdateSummary SodFilter::predict_linearised(TimeTT t) {
  TimeUpdateSummary s;
  if (!begin_time_update(t, s)) return s;
  const int n = layout_.size();
  VectorXd x = x_;
  MatrixXd Phi = MatrixXd::Identity(n, n);
  try {
    const QnsElements o0 = QnsElements::from_vector(x_.head<6>());
    const QnsElements o1 = observer_prop_.propagate(o0, t_, t);
    ++s.propagations;
    x.head<6>() = o1.as_vector();
    const double n_rad = std::sqrt(gm_m3ps2_ / std::pow(o0.a_m, 3));
    Phi(StateLayout::kU, StateLayout::kA) = -1.5 * n_rad / o0.a_m * s.dt_s;
    for (int k = 0; k < layout_.n_targets; ++k) {
      const int off = layout_.target_offset(k);
      const Vec6 roe0 = x_.segment<6>(off);
      const QnsElements tgt1 = target_props_[static_cast<std::size_t>(k)].propagate(astro::qns_from_roe(o0, Roe::from_vector(roe0)), t_, t);
      ++s.propagations;
      const Vec6 roe1 = astro::roe_from_qns(o1, tgt1).as_vector();
      x.segment<6>(off) = roe1;
      // The target's block by differences over its 1-sigma (statistical
      // linearisation, as the sigma points would see it): the osculating
      // ROE's short-period J2 terms couple a dlambda known to hundreds of
      // metres into the other ROE at the metre level, which a Keplerian or
      // mean-J2 map leaves out of the thin directions of P.
      for (int i = 0; i < 6; ++i) {
        const double h = std::max(std::sqrt(std::max(P_(off + i, off + i), 0.0)), 1e-9);
        Vec6 roe0_h = roe0;
        roe0_h[i] += h;
        const QnsElements tgt1_h = target_props_[static_cast<std::size_t>(k)].propagate(astro::qns_from_roe(o0, Roe::from_vector(roe0_h)), t_, t);
        ++s.propagations;
        Vec6 d = astro::roe_from_qns(o1, tgt1_h).as_vector() - roe1;
        d[StateLayout::kDlambda] = astro::wrap_pi(d[StateLayout::kDlambda]);
        Phi.block<6, 1>(off, off + i) = d / h;
      }
    }
  } catch (const std::exception& e) {
    s.why = std::string("propagation of the mean failed: ") + e.what();
    return s;
  }
  // The auxiliary dynamics are linear: their map is applied to the identity.
  const MatrixXd I = MatrixXd::Identity(n, n);
  MatrixXd A = I;
  apply_aux_dynamics(I, A, s.dt_s);
  Phi = (A - I) + Phi;
  const VectorXd x_aux = x_;
  MatrixXd Y = x;
  apply_aux_dynamics(x_aux, Y, s.dt_s);
  MatrixXd P = Phi * P_ * Phi.transpose();
  finish_time_update(t, Y.col(0), std::move(P), s);
  return s;
}

// Shared by both predictions: nothing to do at dt = 0; the adaptive noise of
// the last update (true: go on).
bool SodFilter::begin_time_update(TimeTT t, TimeUpdateSummary& s) {
  if (!initialized_) {
    s.why = "filter not initialised";
    return false;
  }
  s.dt_s = astro::seconds_between(t_, t);
  if (s.dt_s == 0.0) {
    s.usable = true;
    return false;
  }
  adapt_process_noise();
  return true;
}

// Q |dt| added, the prediction stored, the step counted.
void SodFilter::finish_time_update(TimeTT t, const VectorXd& mean, MatrixXd P, TimeUpdateSummary& s) {
  if (options_.adaptive.form == AdaptiveNoiseForm::kBlock) P += Q_rate_ * std::abs(s.dt_s);
  else P.diagonal() += q_ * std::abs(s.dt_s);
  if (!store(mean, P)) {
    s.why = "predicted covariance not positive definite (or state not finite)";
    return;
  }
  t_ = t;
  pending_dt_s_ += std::abs(s.dt_s);
  ++steps_without_update_;
  for (auto& c : counters_) ++c.steps_without_update;
  s.usable = true;
}

void SodFilter::apply_aux_dynamics(const MatrixXd& X, MatrixXd& Y, double dt_s) const {
  const int m = static_cast<int>(X.cols());
  // Time-tag offset with drift: offset(t + dt) = offset(t) + drift dt.
  if (layout_.n_time_tag > 1) {
    Y.row(layout_.time_tag_offset()) += dt_s * X.row(layout_.time_tag_drift());
  }
  if (!layout_.ballistic) return;
  // Differential drag of target k beyond the onboard nominal: a ballistic
  // coefficient dB_k more than the nominal adds dB_k f(B = 1), f = (f_R, f_T,
  // f_N) in the observer's RTN frame, at the observer's mean position (the
  // targets are within ~1000 km: same density to first order). Its rates on
  // the ROE are Gauss's variational equations for a near-circular orbit
  // (docs/sod.md, "The ballistic state's rates"):
  //   d(da)/dt = 2 f_T / (n a),            d(dlambda)/dt = -2 f_R / (n a),
  //   d(dex)/dt = (sin u f_R + 2 cos u f_T) / (n a),
  //   d(dey)/dt = (-cos u f_R + 2 sin u f_T) / (n a),
  //   d(dix)/dt = cos u f_N / (n a),       d(diy)/dt = sin u f_N / (n a).
  // The eccentricity terms carry the density's variation along the orbit (the
  // day-night bulge): with a constant density they average out over an orbit,
  // with the bulge they drive the relative eccentricity secularly.
  const QnsElements obs = QnsElements::from_vector(x_.head<6>());
  const astro::StateVector xo = astro::cartesian_from_qns(obs, gm_m3ps2_);
  const Vec3 f = astro::R_rtn_from_eci(xo) * forces_.unit_ballistic_drag_eci(t_, xo);
  const double n = std::sqrt(gm_m3ps2_ / std::pow(obs.a_m, 3)), na = n * obs.a_m;
  const double cu = std::cos(obs.u_rad), su = std::sin(obs.u_rad);
  Vec6 rate;  // per unit dB, 1/s
  rate << 2.0 * f[1] / na, -2.0 * f[0] / na, (su * f[0] + 2.0 * cu * f[1]) / na,
      (-cu * f[0] + 2.0 * su * f[1]) / na, cu * f[2] / na, su * f[2] / na;
  for (int k = 0; k < layout_.n_targets; ++k) {
    const int off = layout_.target_offset(k), ib = layout_.ballistic_index(k);
    for (int j = 0; j < m; ++j) Y.block<6, 1>(off, j) += rate * (X(ib, j) * dt_s);
  }
}

void SodFilter::mean_and_covariance(const MatrixXd& Y, VectorXd& mean, MatrixXd& P) const {
  // Weighted mean about the central point (angles wrapped), then covariance.
  const int n = static_cast<int>(Y.rows()), m = static_cast<int>(Y.cols());
  mean = Y.col(0);
  for (int j = 1; j < m; ++j) mean += wm_[j] * state_difference(Y.col(j), Y.col(0));
  P = MatrixXd::Zero(n, n);
  for (int j = 0; j < m; ++j) {
    const VectorXd d = state_difference(Y.col(j), mean);
    P.noalias() += wc_[j] * d * d.transpose();
  }
}

bool SodFilter::store(VectorXd x, MatrixXd P) {
  P = 0.5 * (P + P.transpose());
  if (!x.allFinite() || !symmetric_positive_definite(P)) return false;
  wrap_state(x);
  x_ = std::move(x);
  P_ = std::move(P);
  return true;
}

bool SodFilter::advance_to(TimeTT t, UpdateSummary& s) {
  if (t == t_) return true;
  const TimeUpdateSummary tu = time_update(t);
  if (!tu.usable) s.why = "time update to the measurement epoch failed: " + tu.why;
  return tu.usable;
}

UpdateSummary SodFilter::unscented_update(const MeasurementModel& model, const VectorXd& z,
                                          const MatrixXd& R, double gate, int target, bool dry_run) {
  UpdateSummary s;
  s.target = target;
  const int n = layout_.size(), m = 2 * n + 1, nz = static_cast<int>(z.size());
  const auto wrap_z = [&](VectorXd d) {
    for (int i = 0; i < nz; ++i)
      if (model.angle[i]) d[i] = astro::wrap_pi(d[i]);
    return d;
  };
  MatrixXd X;
  if (!sigma_points(X)) {
    s.why = "covariance not positive definite before the measurement update";
    return s;
  }
  MatrixXd Z(nz, m);
  try {
    Z.col(0) = model.h(X.col(0));
    for (int j = 1; j < m; ++j)
      Z.col(j) = column_of(j, n) < model.cutoff ? model.h(X.col(j)) : VectorXd(Z.col(0));
  } catch (const std::exception& e) {
    s.why = std::string("measurement model failed at a sigma point: ") + e.what();
    return s;
  }
  VectorXd z_mean = Z.col(0);
  for (int j = 1; j < m; ++j) z_mean += wm_[j] * wrap_z(Z.col(j) - Z.col(0));
  MatrixXd Pzz = MatrixXd::Zero(nz, nz);
  MatrixXd Pxz = MatrixXd::Zero(n, nz);
  for (int j = 0; j < m; ++j) {
    const VectorXd dz = wrap_z(Z.col(j) - z_mean);
    const VectorXd dx = state_difference(X.col(j), x_);
    Pzz.noalias() += wc_[j] * dz * dz.transpose();
    Pxz.noalias() += wc_[j] * dx * dz.transpose();
  }
  const double beta = model.underweighting;
  const bool wide = Pzz.trace() > R.trace();
  // The nonlinearity (an n x n factorisation) only where it can decide.
  if (beta > 0.0 && wide && model.nonlinearity > 0.0) {
    const Eigen::LDLT<MatrixXd> ldlt_p(P_);
    const MatrixXd omega = Pzz - Pxz.transpose() * ldlt_p.solve(Pxz);
    s.nonlinearity = omega.trace() / R.trace();
  }
  const bool target_bearing = target >= 0 && target < layout_.n_targets && !dry_run;
  const bool unconfirmed = target_bearing && prior_unconfirmed_[static_cast<std::size_t>(target)] != 0;
  // Graded by the nonlinearity: beta min(1, Omega / kappa), so that the gain
  // varies continuously with the prior (a hard threshold flipped on state
  // differences far below the 1-sigma, docs/sod.md "Underweighting").
  // A statistic that could not be computed (NaN) takes the whole beta.
  const double ratio = s.nonlinearity / model.nonlinearity;
  const double graded = (model.nonlinearity <= 0.0 || unconfirmed || !std::isfinite(ratio))
                            ? 1.0
                            : std::clamp(ratio, 0.0, 1.0);
  s.underweighting = beta > 0.0 && wide ? beta * graded : 0.0;
  s.underweighted = s.underweighting > 0.0;
  if (target_bearing && !wide) prior_unconfirmed_[static_cast<std::size_t>(target)] = 0;
  MatrixXd S = (1.0 + s.underweighting) * Pzz + R;
  S = 0.5 * (S + S.transpose());
  s.prefit_residual = wrap_z(z - z_mean);
  const Eigen::LLT<MatrixXd> llt_s(S);
  if (llt_s.info() != Eigen::Success || !S.allFinite()) {
    s.why = "innovation covariance not positive definite";
    return s;
  }
  s.nis = s.prefit_residual.dot(llt_s.solve(s.prefit_residual));
  s.mahalanobis = std::sqrt(s.nis);
  if (dry_run) {
    s.why = "dry run";
    return s;
  }

  if (target >= 0 && options_.health.nis_window > 0) {
    auto& ring = recent_nis_[static_cast<std::size_t>(target)];
    int& count = recent_nis_count_[static_cast<std::size_t>(target)];
    ring[static_cast<std::size_t>(count % options_.health.nis_window)] = s.nis;
    recent_nis_t_[static_cast<std::size_t>(target)][static_cast<std::size_t>(count % options_.health.nis_window)] = t_;
    ++count;
  }
  if (target < 0 && options_.health.gnss_nis_window > 0) {
    gnss_nis_[static_cast<std::size_t>(gnss_nis_count_ % options_.health.gnss_nis_window)] = s.nis;
    ++gnss_nis_count_;
  }
  if (target < 0 && options_.health.gnss_bias_window > 0) {
    // The innovation and its covariance in the predicted fix's RTN frame, whitened.
    astro::StateVector predicted;
    predicted.r_m = z_mean.head<3>();
    predicted.v_mps = z_mean.tail<3>();
    const Mat3 R_rtn = astro::R_rtn_from_eci(predicted);
    MatrixXd T = MatrixXd::Zero(6, 6);
    T.topLeftCorner<3, 3>() = R_rtn;
    T.bottomRightCorner<3, 3>() = R_rtn;
    const MatrixXd S_rtn = T * S * T.transpose();
    const Eigen::LLT<MatrixXd> llt_rtn(0.5 * (S_rtn + S_rtn.transpose()));
    if (llt_rtn.info() == Eigen::Success) {
      const VectorXd w = llt_rtn.matrixL().solve(T * s.prefit_residual);
      gnss_white_rtn_[static_cast<std::size_t>(gnss_white_count_ % options_.health.gnss_bias_window)] = w;
      ++gnss_white_count_;
    }
  }
  // Health check (3): successive large pre-fit residuals (gated ones included).
  int& large = target >= 0 ? counters_[target].consecutive_large_residuals : consecutive_large_gnss_;
  large = s.mahalanobis > options_.health.large_residual_mahalanobis ? large + 1 : 0;

  if (s.mahalanobis > gate) {
    s.gated = true;
    s.why = "innovation Mahalanobis distance above the gate";
    ++rejected_total_;
    if (target >= 0) ++counters_[target].rejected;
    return s;
  }
  MatrixXd K = llt_s.solve(Pxz.transpose()).transpose();  // Pxz S^-1
  MatrixXd P_post;
  if (model.consider > 0) {
    // Schmidt-Kalman: P+ = P - K Pxz^T - Pxz K^T + K S K^T with the consider
    // rows of K zero (Joseph form of a suboptimal gain; the other blocks are
    // those of the optimal update, the consider block unchanged).
    K.topRows(model.consider).setZero();
    const MatrixXd KPzx = K * Pxz.transpose();
    P_post = P_ - KPzx - KPzx.transpose() + K * S * K.transpose();
  } else {
    P_post = P_ - K * S * K.transpose();
  }
  const VectorXd dx = K * s.prefit_residual;
  if (!store(x_ + dx, P_post)) {
    s.why = "posterior covariance not positive definite (or state not finite)";
    return s;
  }
  try {
    s.postfit_residual = wrap_z(z - model.h(x_));
  } catch (const std::exception&) {
    s.postfit_residual = VectorXd::Constant(nz, kNaN);
  }
  // Covariance matching (docs/sod.md): dx dx^T - K S K^T, its diagonal or its spacecraft blocks.
  if (options_.adaptive.form == AdaptiveNoiseForm::kBlock) {
    pending_dxdx_ += dx * dx.transpose() - K * S * K.transpose();
  } else {
    pending_dxdx_.diagonal() += dx.cwiseAbs2() - (K * S * K.transpose()).diagonal();
  }
  pending_ = true;
  steps_without_update_ = 0;
  if (target >= 0) {
    counters_[target].steps_without_update = 0;
    ++counters_[target].accepted;
  }
  s.usable = true;
  return s;
}

UpdateSummary SodFilter::update_bearing(const BearingMeasurement& meas) {
  UpdateSummary s;
  s.target = meas.target;
  if (meas.target < 0 || meas.target >= layout_.n_targets) {
    s.why = "target index out of range";
    return s;
  }
  if (!is_finite_positive(meas.sigma_az_rad) || !is_finite_positive(meas.sigma_el_rad) ||
      !meas.R_v_from_eci.allFinite() || !std::isfinite(meas.angles.az_rad) ||
      !std::isfinite(meas.angles.el_rad)) {
    s.why = "measurement angles, sigmas or attitude not finite/positive";
    return s;
  }
  if (!advance_to(meas.t, s)) return s;
  const int off = layout_.target_offset(meas.target);
  const double gm = gm_m3ps2_;
  const Mat3 R = meas.R_v_from_eci;
  MeasurementModel model;
  model.cutoff = layout_.n_time_tag > 0 ? layout_.time_tag_offset() + 1 : off + StateLayout::kBlock;
  model.angle = {true, true};
  model.underweighting = options_.bearing_underweighting;
  model.nonlinearity = options_.bearing_underweighting_nonlinearity;
  const int i_dt = layout_.n_time_tag > 0 ? layout_.time_tag_offset() : -1;
  model.h = [off, gm, R, i_dt](const VectorXd& x) -> VectorXd {
    const QnsElements obs = QnsElements::from_vector(x.head<6>());
    const QnsElements tgt = astro::qns_from_roe(obs, Roe::from_vector(x.segment<6>(off)));
    const astro::StateVector so = astro::cartesian_from_qns(obs, gm), st = astro::cartesian_from_qns(tgt, gm);
    // A time tag late by dt: the image saw both spacecraft at t - dt (first order).
    const double dt = i_dt >= 0 ? x[i_dt] : 0.0;
    return astro::bearing_from_eci(so.r_m - dt * so.v_mps, st.r_m - dt * st.v_mps, R).as_vector();
  };
  const Eigen::Vector2d r(meas.sigma_az_rad * meas.sigma_az_rad,
                          meas.sigma_el_rad * meas.sigma_el_rad);
  return unscented_update(model, meas.angles.as_vector(), MatrixXd(r.asDiagonal()),
                          options_.bearing_gate_mahalanobis, meas.target);
}

UpdateSummary SodFilter::update_line_of_sight(const LineOfSightMeasurement& meas, bool dry_run) {
  using L = LineOfSightMeasurement;
  UpdateSummary s;
  const auto body_ok = [&](int b, bool external_ok) {
    return b == L::kObserver || (external_ok && b == L::kExternal) || (b >= 0 && b < layout_.n_targets);
  };
  if (!body_ok(meas.from, true) || !body_ok(meas.to, false) || meas.from == meas.to) {
    s.why = "body index out of range";
    return s;
  }
  s.target = meas.to >= 0 ? meas.to : meas.from;
  if (!is_finite_positive(meas.sigma_rad) || !meas.los_eci.allFinite() || !(meas.los_eci.norm() > 0.0) ||
      !meas.from_r_eci_m.allFinite() || !meas.from_v_eci_mps.allFinite() || !meas.from_P_r_m2.allFinite()) {
    s.why = "line of sight, sigma or remote position not finite/positive";
    return s;
  }
  if (meas.sender_clock < -1 || meas.sender_clock >= layout_.n_remote_clock) {
    s.why = "sender clock index out of range";
    return s;
  }
  if (!advance_to(meas.t, s)) return s;
  // Angles in a frame whose z is the measured line of sight.
  const Vec3 z = meas.los_eci.normalized();
  const Vec3 x = z.unitOrthogonal();
  Mat3 R_v;
  R_v.row(0) = x.transpose();
  R_v.row(1) = z.cross(x).transpose();
  R_v.row(2) = z.transpose();
  const double gm = gm_m3ps2_;
  const StateLayout lay = layout_;
  const auto state_of = [gm, lay](const VectorXd& xs, int body) -> astro::StateVector {
    const QnsElements obs = QnsElements::from_vector(xs.head<6>());
    if (body == L::kObserver) return astro::cartesian_from_qns(obs, gm);
    return astro::cartesian_from_qns(astro::qns_from_roe(obs, Roe::from_vector(xs.segment<6>(lay.target_offset(body)))), gm);
  };
  MeasurementModel model;
  const int hi = std::max(meas.from, meas.to);
  model.cutoff = hi >= 0 ? layout_.target_offset(hi) + StateLayout::kBlock : StateLayout::kBlock;
  model.angle = {true, true};
  model.underweighting = options_.bearing_underweighting;
  model.nonlinearity = options_.bearing_underweighting_nonlinearity;
  if (options_.target_to_target_consider_observer && meas.from >= 0 && meas.to >= 0) {
    model.consider = StateLayout::kBlock;
  }
  const int from = meas.from, to = meas.to;
  const Vec3 r_ext = meas.from_r_eci_m, v_ext = meas.from_v_eci_mps;
  const int i_clock = meas.sender_clock >= 0 ? layout_.remote_clock_index(meas.sender_clock) : -1;
  if (i_clock >= 0) model.cutoff = i_clock + 1;
  model.h = [=](const VectorXd& xs) -> VectorXd {
    // The sender's image saw both bodies at t - dt (first order in its clock's offset dt).
    const double dt = i_clock >= 0 ? xs[i_clock] : 0.0;
    const astro::StateVector b = state_of(xs, to);
    Vec3 a = r_ext - dt * v_ext;
    if (from != L::kExternal) {
      const astro::StateVector sa = state_of(xs, from);
      a = sa.r_m - dt * sa.v_mps;
    }
    return astro::bearing_from_eci(a, b.r_m - dt * b.v_mps, R_v).as_vector();
  };
  MatrixXd Rm = MatrixXd::Identity(2, 2) * meas.sigma_rad * meas.sigma_rad;
  if (from == L::kExternal) {
    const astro::Mat23 J = astro::bearing_jacobian_target_eci(r_ext, state_of(x_, to).r_m, R_v);
    Rm += J * meas.from_P_r_m2 * J.transpose();
  }
  const astro::Bearing zb = astro::bearing_from_los(R_v * z);
  return unscented_update(model, zb.as_vector(), Rm, options_.bearing_gate_mahalanobis, s.target, dry_run);
}

UpdateSummary SodFilter::update_gnss(const GnssMeasurement& meas) {
  UpdateSummary s;
  if (!is_finite_positive(meas.sigma_r_m) || !is_finite_positive(meas.sigma_v_mps) ||
      !meas.x_eci.stacked().allFinite()) {
    s.why = "GNSS state or sigmas not finite/positive";
    return s;
  }
  if (!advance_to(meas.t, s)) return s;
  const double gm = gm_m3ps2_;
  MeasurementModel model;
  model.cutoff = StateLayout::kBlock;
  model.angle.assign(6, false);
  model.h = [gm](const VectorXd& x) -> VectorXd {
    return astro::cartesian_from_qns(QnsElements::from_vector(x.head<6>()), gm).stacked();
  };
  VectorXd r(6);
  r << Vec3::Constant(meas.sigma_r_m * meas.sigma_r_m),
      Vec3::Constant(meas.sigma_v_mps * meas.sigma_v_mps);
  return unscented_update(model, meas.x_eci.stacked(), MatrixXd(r.asDiagonal()), options_.gnss_gate_mahalanobis,
                          -1);
}

TimeUpdateSummary SodFilter::apply_observer_maneuver(TimeTT t, const Vec3& dv_rtn_mps, const Mat3& P_dv) {
  TimeUpdateSummary s;
  if (!initialized_) {
    s.why = "filter not initialised";
    return s;
  }
  if (!dv_rtn_mps.allFinite() || !P_dv.allFinite()) {
    s.why = "maneuver delta-v or covariance not finite";
    return s;
  }
  if (t != t_) {
    s = time_update(t);
    if (!s.usable) return s;
  }
  const double gm = gm_m3ps2_;
  const StateLayout lay = layout_;
  const auto burn = [gm, lay](const VectorXd& x, const Vec3& dv) {
    VectorXd y = x;
    const QnsElements obs0 = QnsElements::from_vector(x.head<6>());
    const QnsElements obs1 =
        astro::qns_from_cartesian(dynamics::apply_maneuver(astro::cartesian_from_qns(obs0, gm), dv), gm);
    y.head<6>() = obs1.as_vector();
    for (int k = 0; k < lay.n_targets; ++k) {
      const int off = lay.target_offset(k);
      const QnsElements tgt = astro::qns_from_roe(obs0, Roe::from_vector(x.segment<6>(off)));
      y.segment<6>(off) = astro::roe_from_qns(obs1, tgt).as_vector();
    }
    return y;
  };
  const int n = layout_.size(), m = 2 * n + 1;
  MatrixXd X;
  if (!sigma_points(X)) {
    s.why = "covariance not positive definite before the maneuver";
    return s;
  }
  MatrixXd Y(n, m);
  for (int j = 0; j < m; ++j) Y.col(j) = burn(X.col(j), dv_rtn_mps);
  VectorXd mean;
  MatrixXd P;
  mean_and_covariance(Y, mean, P);
  // Execution error: central differences of the map by the delta-v (1 mm/s).
  MatrixXd J(n, 3);
  for (int i = 0; i < 3; ++i) {
    Vec3 h = Vec3::Zero();
    h[i] = 1e-3;
    J.col(i) = state_difference(burn(x_, dv_rtn_mps + h), burn(x_, dv_rtn_mps - h)) / 2e-3;
  }
  P += J * P_dv * J.transpose();
  if (!store(mean, P)) {
    s.why = "covariance after the maneuver not positive definite (or state not finite)";
    return s;
  }
  prior_unconfirmed_.assign(layout_.n_targets, 1);
  s.usable = true;
  return s;
}

// ---------------------------------------------------------------- health

BodComparison SodFilter::check_bod(int target, const BodEstimate& bod) {
  BodComparison c;
  if (target < 0 || target >= layout_.n_targets) {
    c.why = "target index out of range";
    return c;
  }
  if (std::abs(astro::seconds_between(t_, bod.t)) > 1e-3) {
    c.why = "BOD epoch differs from the filter epoch; time_update() to it first";
    return c;
  }
  if (!bod.roe.allFinite() || !symmetric_positive_definite(bod.P_roe)) {
    c.why = "BOD estimate not finite or its covariance not positive definite";
    return c;
  }
  const int off = layout_.target_offset(target);
  Vec6 d = x_.segment<6>(off) - bod.roe;
  d[StateLayout::kDlambda] = astro::wrap_pi(d[StateLayout::kDlambda]);
  const Mat6 S = P_.block<6, 6>(off, off) + bod.P_roe;
  const Eigen::LLT<Mat6> llt(S);
  if (llt.info() != Eigen::Success) {
    c.why = "P_sod + P_bod not positive definite";
    return c;
  }
  c.mahalanobis = std::sqrt(d.dot(llt.solve(d)));
  c.relative_distance = d.norm() / std::max(bod.roe.norm(), 1e-12);
  c.disagrees = c.mahalanobis > options_.health.bod_max_mahalanobis ||
                c.relative_distance > options_.health.bod_max_relative;
  c.usable = true;
  last_bod_[target] = bod;
  HealthStatus& st = bod_status_[target];
  if (c.disagrees) {
    std::ostringstream why;
    why << "SOD differs from BOD: Mahalanobis " << c.mahalanobis << " (max "
        << options_.health.bod_max_mahalanobis << "), relative " << c.relative_distance << " (max "
        << options_.health.bod_max_relative << ")";
    st = {HealthCondition::kBodDisagreement, why.str()};
  } else {
    st = {};
  }
  return c;
}

HealthReport SodFilter::health() const {
  HealthReport r;
  r.targets.assign(layout_.n_targets, {});
  const HealthOptions& h = options_.health;
  if (!initialized_) {
    r.filter = {HealthCondition::kOutOfRange, "filter not initialised"};
    return r;
  }
  // (4) for the whole filter: finite, positive definite, observer in range.
  const double a = x_[StateLayout::kA];
  const double e = std::hypot(x_[StateLayout::kEx], x_[StateLayout::kEy]);
  if (!x_.allFinite() || !P_.allFinite()) {
    r.filter = {HealthCondition::kOutOfRange, "state or covariance not finite"};
  } else if (Eigen::LLT<MatrixXd>(P_).info() != Eigen::Success) {
    r.filter = {HealthCondition::kOutOfRange, "covariance not positive definite"};
  } else if (a < h.min_a_m || a > h.max_a_m) {
    r.filter = {HealthCondition::kOutOfRange,
                "observer a = " + std::to_string(a) + " m outside [min_a_m, max_a_m]"};
  } else if (e >= h.max_e) {
    r.filter = {HealthCondition::kOutOfRange, "observer e = " + std::to_string(e) + " >= max_e"};
  } else if (steps_without_update_ > h.max_steps_without_update) {
    // (2) for the filter: no measurement of any kind accepted.
    r.filter = {HealthCondition::kNoMeasurementUpdate,
                std::to_string(steps_without_update_) + " steps without a measurement update"};
  } else if (consecutive_large_gnss_ > h.max_large_residuals) {
    r.filter = {HealthCondition::kLargeResiduals,
                std::to_string(consecutive_large_gnss_) + " successive large GNSS residuals"};
  } else if (const double nis = recent_mean_gnss_nis(); std::isfinite(nis) && nis > h.gnss_nis_max_mean) {
    std::ostringstream why;
    why.precision(3);
    why << "mean NIS " << nis << " of the last " << h.gnss_nis_window << " GNSS fixes above " << h.gnss_nis_max_mean;
    r.filter = {HealthCondition::kInconsistent, why.str()};
  } else if (const double b = recent_gnss_bias_statistic(); std::isfinite(b) && b > h.gnss_bias_max) {
    std::ostringstream why;
    why.precision(3);
    why << "the last " << h.gnss_bias_window << " GNSS innovations keep one sign (W |mean whitened innovation|^2 "
        << b << " above " << h.gnss_bias_max << ")";
    r.filter = {HealthCondition::kInconsistent, why.str()};
  }
  for (int k = 0; k < layout_.n_targets; ++k) {
    const Vec6 a_roe = a * x_.segment<6>(layout_.target_offset(k));
    const TargetCounters& c = counters_[k];
    HealthStatus& st = r.targets[k];
    if (!a_roe.allFinite()) {
      st = {HealthCondition::kOutOfRange, "ROE not finite"};
    } else if (a_roe.cwiseAbs().maxCoeff() > h.max_a_roe_m) {
      st = {HealthCondition::kOutOfRange, "|a*ROE| = " + std::to_string(a_roe.cwiseAbs().maxCoeff()) +
                                              " m above max_a_roe_m"};
    } else if (!bod_status_[k].healthy()) {
      st = bod_status_[k];  // (1)
    } else if (c.consecutive_large_residuals > h.max_large_residuals) {
      st = {HealthCondition::kLargeResiduals,
            std::to_string(c.consecutive_large_residuals) + " successive large bearing residuals"};
    } else if (c.steps_without_update > h.max_steps_without_update) {
      st = {HealthCondition::kNoMeasurementUpdate,
            std::to_string(c.steps_without_update) + " steps without a bearing update"};
    } else if (const double nis = recent_mean_nis(k); std::isfinite(nis) && nis > h.nis_max_mean) {
      std::ostringstream why;
      why.precision(3);
      why << "mean NIS " << nis << " of the last " << h.nis_window << " bearings above " << h.nis_max_mean;
      st = {HealthCondition::kInconsistent, why.str()};
    }
  }
  return r;
}

void SodFilter::reinitialize_target(int target, const Vec6& roe, const Mat6& P_roe) {
  if (target < 0 || target >= layout_.n_targets)
    throw std::invalid_argument("SodFilter::reinitialize_target: target index out of range");
  if (!roe.allFinite() || !symmetric_positive_definite(P_roe))
    throw std::invalid_argument(
        "SodFilter::reinitialize_target: ROE not finite or P_roe not symmetric positive definite");
  const int off = layout_.target_offset(target);
  x_.segment<6>(off) = roe;
  wrap_state(x_);
  P_.middleRows<6>(off).setZero();
  P_.middleCols<6>(off).setZero();
  P_.block<6, 6>(off, off) = 0.5 * (P_roe + P_roe.transpose());
  // The corrections since the last adaptation were made to the replaced
  // estimate: they say nothing of the process noise of the new one.
  pending_dxdx_.middleRows<6>(off).setZero();
  pending_dxdx_.middleCols<6>(off).setZero();
  counters_[target] = {};
  bod_status_[target] = {};
  recent_nis_count_[static_cast<std::size_t>(target)] = 0;
  prior_unconfirmed_[static_cast<std::size_t>(target)] = 1;
}

void SodFilter::reinitialize_target(int target, const Vec6& roe, const Mat6& P_roe, const Eigen::MatrixXd& clock_J) {
  const int n = layout_.n_time_tag;
  if (n == 0 || clock_J.size() == 0) {
    reinitialize_target(target, roe, P_roe);
    return;
  }
  if (clock_J.rows() != 6 || clock_J.cols() != n || !clock_J.allFinite())
    throw std::invalid_argument("SodFilter::reinitialize_target: clock_J must be finite, 6 x n_time_tag");
  reinitialize_target(target, roe, P_roe);  // the target's old correlations gone
  const int off = layout_.target_offset(target);
  const MatrixXd cross = -clock_J * P_.middleRows(layout_.time_tag_offset(), n);  // 6 x N, zero in the target's columns
  P_.middleRows<6>(off) = cross;
  P_.middleCols<6>(off) = cross.transpose();
  const Mat6 P_clock = clock_J * P_.block(layout_.time_tag_offset(), layout_.time_tag_offset(), n, n) *
                       clock_J.transpose();
  P_.block<6, 6>(off, off) = 0.5 * (P_roe + P_roe.transpose()) + 0.5 * (P_clock + P_clock.transpose());
}

void SodFilter::inflate_target(int target, double factor) {
  if (target < 0 || target >= layout_.n_targets)
    throw std::invalid_argument("SodFilter::inflate_target: target index out of range");
  if (!std::isfinite(factor) || factor < 1.0)
    throw std::invalid_argument("SodFilter::inflate_target: factor must be finite and >= 1");
  VectorXd scale = VectorXd::Ones(layout_.size());
  scale.segment<6>(layout_.target_offset(target)).setConstant(std::sqrt(factor));
  if (layout_.ballistic) scale[layout_.ballistic_index(target)] = std::sqrt(factor);
  P_ = scale.asDiagonal() * P_ * scale.asDiagonal();
  recent_nis_count_[static_cast<std::size_t>(target)] = 0;
  prior_unconfirmed_[static_cast<std::size_t>(target)] = 1;
  counters_[target].consecutive_large_residuals = 0;
}

void SodFilter::inflate_target_maneuver(int target, double sigma_dv_mps, double since_s) {
  if (target < 0 || target >= layout_.n_targets)
    throw std::invalid_argument("SodFilter::inflate_target_maneuver: target index out of range");
  if (!is_finite_positive(sigma_dv_mps) || !std::isfinite(since_s) || since_s < 0.0)
    throw std::invalid_argument("SodFilter::inflate_target_maneuver: sigma_dv_mps must be > 0, since_s >= 0");
  const double a = x_[StateLayout::kA], u = x_[StateLayout::kU];
  const double n = std::sqrt(gm_m3ps2_ / (a * a * a));
  // a * dROE = G dv_RTN (near-circular), rows [da, dlambda, dex, dey, dix, diy].
  Eigen::Matrix<double, 6, 3> G = Eigen::Matrix<double, 6, 3>::Zero();
  G(0, 1) = 2.0 / n;
  G(1, 0) = -2.0 / n;
  G(2, 0) = std::sin(u) / n;
  G(2, 1) = 2.0 * std::cos(u) / n;
  G(3, 0) = -std::cos(u) / n;
  G(3, 1) = 2.0 * std::sin(u) / n;
  G(4, 2) = std::cos(u) / n;
  G(5, 2) = std::sin(u) / n;
  // Drift of a*dlambda since the burn: -1.5 n (a da) tau = -3 dv_T tau, with
  // tau uniform in [0, since]: the mean in G, the spread as extra variance.
  const double tau_mean = 0.5 * since_s, tau_var = since_s * since_s / 12.0;
  G(1, 1) = -3.0 * tau_mean;
  Mat6 Q = sigma_dv_mps * sigma_dv_mps * G * G.transpose();
  Q(1, 1) += 9.0 * sigma_dv_mps * sigma_dv_mps * tau_var;
  const int off = layout_.target_offset(target);
  P_.block<6, 6>(off, off) += Q / (a * a);
  P_ = 0.5 * (P_ + P_.transpose());
  recent_nis_count_[static_cast<std::size_t>(target)] = 0;
  prior_unconfirmed_[static_cast<std::size_t>(target)] = 1;
  counters_[target].consecutive_large_residuals = 0;
}

void SodFilter::inflate_auxiliary(int index, double add_variance) {
  if (index < layout_.aux_offset() || index >= layout_.size())
    throw std::invalid_argument("SodFilter::inflate_auxiliary: index outside the auxiliary block");
  if (!std::isfinite(add_variance) || add_variance < 0.0)
    throw std::invalid_argument("SodFilter::inflate_auxiliary: variance must be finite and >= 0");
  P_(index, index) += add_variance;
}

void SodFilter::shift_auxiliary(int index, double delta) {
  if (index < layout_.aux_offset() || index >= layout_.size())
    throw std::invalid_argument("SodFilter::shift_auxiliary: index outside the auxiliary block");
  if (!std::isfinite(delta)) throw std::invalid_argument("SodFilter::shift_auxiliary: delta must be finite");
  x_[index] += delta;
}

double SodFilter::recent_mean_gnss_nis() const {
  const int w = options_.health.gnss_nis_window;
  if (w <= 0 || gnss_nis_count_ < w) return kNaN;
  double sum = 0.0;
  for (double v : gnss_nis_) sum += v;
  return sum / w;
}

double SodFilter::recent_gnss_bias_statistic() const {
  const int w = options_.health.gnss_bias_window;
  if (w <= 0 || gnss_white_count_ < w) return kNaN;
  Vec6 sum = Vec6::Zero();
  for (const Vec6& v : gnss_white_rtn_) sum += v;
  return sum.squaredNorm() / w;  // W |sum / W|^2
}

void SodFilter::clear_gnss_nis() {
  gnss_nis_count_ = 0;
  gnss_white_count_ = 0;
}

double SodFilter::recent_nis_span_s(int target) const {
  const int w = options_.health.nis_window;
  if (!std::isfinite(recent_mean_nis(target))) return kNaN;
  const auto& ts = recent_nis_t_[static_cast<std::size_t>(target)];
  const int c = recent_nis_count_[static_cast<std::size_t>(target)];
  const TimeTT oldest = ts[static_cast<std::size_t>(c % w)];
  return astro::seconds_between(oldest, t_);
}

double SodFilter::recent_mean_nis(int target) const {
  const int w = options_.health.nis_window;
  if (target < 0 || target >= layout_.n_targets || w <= 0 || recent_nis_count_[static_cast<std::size_t>(target)] < w)
    return kNaN;
  const auto& ring = recent_nis_[static_cast<std::size_t>(target)];
  double sum = 0.0;
  for (double v : ring) sum += v;
  return sum / w;
}

bool SodFilter::reinitialize_target_from_bod(int target) {
  if (target < 0 || target >= layout_.n_targets || !last_bod_[target]) return false;
  reinitialize_target(target, last_bod_[target]->roe, last_bod_[target]->P_roe);
  return true;
}

void SodFilter::reinitialize_observer(const QnsElements& observer, const Mat6& P) {
  if (!observer.as_vector().allFinite() || !symmetric_positive_definite(P))
    throw std::invalid_argument(
        "SodFilter::reinitialize_observer: elements not finite or P not symmetric positive definite");
  x_.head<6>() = observer.as_vector();
  wrap_state(x_);
  P_.topRows<6>().setZero();
  P_.leftCols<6>().setZero();
  P_.topLeftCorner<6, 6>() = 0.5 * (P + P.transpose());
  steps_without_update_ = 0;
  consecutive_large_gnss_ = 0;
  prior_unconfirmed_.assign(layout_.n_targets, 1);
}

bool SodFilter::prior_unconfirmed(int target) const {
  if (target < 0 || target >= layout_.n_targets)
    throw std::invalid_argument("SodFilter::prior_unconfirmed: target index out of range");
  return prior_unconfirmed_[static_cast<std::size_t>(target)] != 0;
}

// ---------------------------------------------------------------- accessors

double SodFilter::nees(const VectorXd& x_true) const {
  if (x_true.size() != x_.size()) throw std::invalid_argument("SodFilter::nees: wrong state size");
  const Eigen::LLT<MatrixXd> llt(P_);
  if (llt.info() != Eigen::Success) return kNaN;
  const VectorXd d = state_difference(x_, x_true);
  return d.dot(llt.solve(d));
}

QnsElements SodFilter::observer() const { return QnsElements::from_vector(x_.head<6>()); }

Roe SodFilter::roe(int target) const {
  return Roe::from_vector(x_.segment<6>(layout_.target_offset(target)));
}

Vec6 SodFilter::a_roe_m(int target) const {
  return x_[StateLayout::kA] * x_.segment<6>(layout_.target_offset(target));
}

Vec6 SodFilter::a_roe_sigma_m(int target) const {
  const int off = layout_.target_offset(target);
  return x_[StateLayout::kA] * P_.diagonal().segment<6>(off).cwiseSqrt();
}

const TargetCounters& SodFilter::counters(int target) const {
  if (target < 0 || target >= layout_.n_targets)
    throw std::invalid_argument("SodFilter::counters: target index out of range");
  return counters_[target];
}

}  // namespace artms::sod
