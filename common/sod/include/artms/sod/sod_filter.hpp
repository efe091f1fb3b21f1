// Sequential Orbit Determination (paper, "Sequential Orbit Determination";
// Sullivan & D'Amico 2020): an unscented Kalman filter on the observer's
// absolute elements and the ROE of N targets (state_layout.hpp), with the
// nonlinear GVE-RK4 dynamics (gve.hpp), the nonlinear bearing model (paper
// eq. 2) and GNSS position/velocity of the observer, adaptive process noise,
// Mahalanobis gating and the paper's four health checks. Equations: docs/sod.md.
//
// Units: state as in state_layout.hpp (SI, ROE dimensionless); times TT.
// Failures at run time (a Cholesky that fails, a measurement the model cannot
// evaluate) come back as summaries with usable = false and a reason; the
// state and covariance are then left as they were. Bad options or inputs at
// set-up throw std::invalid_argument naming the field.
#pragma once

#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "artms/astro/bearing.hpp"
#include "artms/astro/elements.hpp"
#include "artms/astro/roe.hpp"
#include "artms/dynamics/gve.hpp"
#include "artms/sod/state_layout.hpp"

namespace artms::sod {

using astro::Mat3;
using astro::Mat6;
using astro::TimeTT;
using astro::Vec3;
using astro::Vec6;
using Eigen::MatrixXd;
using Eigen::VectorXd;

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
inline constexpr double kInf = std::numeric_limits<double>::infinity();

// Adaptive process noise (Sullivan, Koenig & D'Amico 2017; Stacey & D'Amico
// 2018), covariance matching on the state correction dx = K nu, in time:
// the corrections C = sum (dx dx^T - K S K^T) weigh 1/tau, and an average
// outside the clamp relaxes towards the rate applied over the time h noise
// was added since the last adaptation:
//   A_k = e^(-h/tau) A_{k-1} + (1 - e^(-h/tau)) Q_{k-1} + C / tau,   Q_k = A_k clamped
// to [floor_factor, ceiling_factor] x the nominal (docs/sod.md, "Adaptive
// process noise"). The form says which entries adapt; the average whether
// the recursion runs on the clamped Q (A = Q) or on its own unclamped A.
enum class AdaptiveNoiseForm {
  kDiagonal,  // one rate per state component (the paper's)
  kBlock,     // a 6x6 rate per spacecraft (observer, each target), clamped in the Loewner order
};
enum class AdaptiveNoiseAverage {
  kClamped,    // A = Q: the recursion runs on the clamped value
  kUnclamped,  // A kept within +-ceiling x the nominal; only the Q applied is clamped
};
struct AdaptiveNoiseOptions {
  bool enabled = true;
  // false: only the observer's own block (and the auxiliary states) adapt;
  // each target keeps its nominal rate, at least the drag floor. The
  // corrections estimate the observer's rate (GNSS fixes it every step) but
  // not a target's (docs/sod.md, "What one adaptation knows").
  bool targets = true;
  AdaptiveNoiseForm form = AdaptiveNoiseForm::kDiagonal;
  AdaptiveNoiseAverage average = AdaptiveNoiseAverage::kClamped;
  // tau, s: the corrections' gain 1/tau; e^(-60/tau) = 0.95, the former
  // per-step forgetting at the scenarios' 60 s cadence, however the time
  // updates split it.
  double time_constant_s = 1170.0;
  double floor_factor = 0.1;
  double ceiling_factor = 100.0;
  // The onboard density's expected relative error along the orbit (0: off).
  // A target whose differential ballistic coefficient is estimated at dB^
  // (1-sigma sigma_B) has sqrt(max(dB^2 - sigma_B^2, 0)) x this x the onboard
  // drag per unit B of unmodelled along-track acceleration; its ROE rate
  // (Gauss, correlated over one orbit) is added to the floor of the target's
  // adaptive process noise (docs/sod.md, "The drag floor").
  double drag_density_error = 0.0;
  // The onboard density's expected relative change from day to day (0: off).
  // The effective dB is the true difference of the two Cd A/m times the
  // density's error, so it walks by this x sqrt(max(dB^2 - sigma_B^2, 0)) per
  // day; added to the floor of each target's ballistic rate (docs/sod.md,
  // "The ballistic walk from the density's budget").
  double density_change_per_day = 0.0;
};

// Thresholds of the paper's four health checks.
struct HealthOptions {
  // (1) SOD versus the latest BOD estimate of a target: Mahalanobis distance
  // of the ROE difference with P_sod + P_bod, and the difference's norm
  // relative to the BOD ROE norm (a*ROE). Either one above its threshold fails.
  double bod_max_mahalanobis = 6.0;
  double bod_max_relative = 0.2;
  // (2) successive time updates without an accepted measurement update
  // (per target for bearings, and for the filter for any measurement).
  int max_steps_without_update = 180;
  // (3) successive measurement updates whose pre-fit residual has a
  // Mahalanobis distance above large_residual_mahalanobis.
  int max_large_residuals = 10;
  double large_residual_mahalanobis = 3.0;
  // (4) valid range: observer a in [min_a_m, max_a_m], e below max_e, every
  // |a_o * ROE| component below max_a_roe_m, everything finite, P positive definite.
  double min_a_m = astro::kRadiusEarth_m + 100e3;
  double max_a_m = 50000e3;
  double max_e = 0.1;
  double max_a_roe_m = 2000e3;
  // (5) consistency (not in the paper; Bar-Shalom et al. 2001, section 5.4):
  // the mean NIS of a target's last nis_window bearings (gated ones included)
  // above nis_max_mean, the chi2(2 W)/W quantile the navigator sets from its
  // false-alarm probability. The filter is then over-confident or wrong about
  // that target (a manoeuvre, a model error, a wrong time tag). 0 disables.
  int nis_window = 20;
  double nis_max_mean = 4.0;
  // The same for the observer: the mean NIS of the last gnss_nis_window GNSS
  // fixes (6 dof each) above gnss_nis_max_mean (chi2(6 W)/W quantile): the
  // observer's orbit left its model (an unplanned maneuver). 0 disables.
  int gnss_nis_window = 10;
  double gnss_nis_max_mean = 10.1;
  // And a persistent offset of the observer's GNSS innovations: each rotated
  // into the predicted RTN frame and whitened (w = L^-1 nu, S = L L^T), the
  // mean of the last gnss_bias_window of them; W |mean w|^2 is chi2(6) while
  // the model holds (a GLR test for a mean shift; Willsky and Jones 1976).
  // A filter absorbs an unplanned burn over tens of minutes, so its mean NIS
  // hardly rises while its innovations keep one sign for that long.
  // Above gnss_bias_max the observer's orbit left its model. 0 disables.
  int gnss_bias_window = 0;
  double gnss_bias_max = 43.3;  // chi2(6) at 1 - 1e-7
};

struct SodOptions {
  dynamics::GvePropagatorOptions propagator;  // RK4 step (30 s, paper)
  // Scaled unscented transform (Wan & van der Merwe 2000):
  // lambda = ukf_alpha^2 (n + ukf_kappa) - n; the sigma points sit at
  // +-sqrt(n + lambda) columns of chol(P).
  double ukf_alpha = 1.0;
  double ukf_beta = 2.0;
  double ukf_kappa = 0.0;
  // Nominal process noise as a white-noise rate (variance per second), added
  // as Q = diag(q) dt. Observer: state units^2 / s (m^2/s for a, rad^2/s for
  // angles, 1/s for ex, ey). Targets: (a_o * ROE) m^2/s, converted to the
  // dimensionless state with the observer's a at initialisation.
  Vec6 q_observer = (Vec6() << 4e-5, 2e-18, 2e-18, 2e-18, 2e-18, 1e-16).finished();
  Vec6 q_target_a_roe_m2ps = (Vec6() << 2e-6, 2e-4, 2e-6, 2e-6, 2e-6, 2e-6).finished();
  double q_aux = 0.0;  // per generic auxiliary state, state units^2 / s
  // Random walks of the named auxiliary states (StateLayout): camera
  // time-tag offset (s^2/s) and drift ((s/s)^2/s), differential ballistic
  // coefficient ((m^2/kg)^2/s).
  double q_time_tag_offset_s2ps = 0.0;
  double q_time_tag_drift_ps = 0.0;
  double q_ballistic_m4pkg2ps = 0.0;
  AdaptiveNoiseOptions adaptive;
  // Measurements whose innovation Mahalanobis distance sqrt(nu^T S^-1 nu)
  // exceeds these are rejected (counted, state untouched). kInf disables.
  double bearing_gate_mahalanobis = 5.0;
  // Measurement underweighting (Lear; Zanetti and D'Souza 2013): while the
  // predicted bearing spread P_zz exceeds the measurement noise R, the
  // innovation covariance is S = (1 + beta) P_zz + R instead of P_zz + R, so
  // that one bearing cannot collapse a wide, nonlinear prior (a stale
  // a-priori, a target seen for the first time). 0 disables.
  double bearing_underweighting = 0.0;
  // When > 0 (kappa), a bearing whose spread exceeds its noise is
  // underweighted in proportion to how nonlinear it is over the prior:
  // beta min(1, Omega / kappa), with Omega = trace(P_zz - P_zx P^-1 P_xz) /
  // trace(R), the part of the spread that no linear map of the state
  // explains (the statistical linearisation's error) against the noise;
  // except while the target's prior is a guess (after an inflation, a
  // re-initialisation, a manoeuvre of the observer, until a bearing's spread
  // falls within its noise: prior_unconfirmed()), when the whole beta
  // applies. 0: the whole beta whenever the spread exceeds the noise.
  double bearing_underweighting_nonlinearity = 0.0;
  double gnss_gate_mahalanobis = 6.0;
  // A line of sight between two targets (another observer's bearing of a
  // third spacecraft) updates the relative orbits only: the observer's own
  // orbit enters it as a consider parameter (Schmidt-Kalman update: its
  // uncertainty is in the innovation covariance and the cross-covariances,
  // its estimate and variance are left as they were). Such a line of sight
  // fixes the observer's orbit plane only through the ranges of the targets
  // (to first order a rotation of the observer's plane is matched by the
  // targets' relative inclination vectors), and taking that from bearings
  // while the ranges converge made mode 4 over-confident (docs/sod.md).
  bool target_to_target_consider_observer = false;
  HealthOptions health;

  // Throws std::invalid_argument naming the offending field.
  void validate() const;
};

// The observer's process noise (SodOptions::q_observer units: QNS element
// variance rates, order a, ex, ey, i, RAAN, u) of an unmodelled acceleration
// with 1-sigma sigma_acc per RTN axis and correlation time tau, seen as white
// noise of PSD q_v = 2 sigma^2 tau on the velocity and mapped through Gauss's
// variational equations of a near-circular orbit (Montenbruck & Gill 2000,
// eq. 3.98; u-averaged): da = (2/n) dv_T; d(ex, ey) = (2 cos u dv_T + sin u
// dv_R)/(n a) -> 2.5/(n a)^2; di = cos u dv_N/(n a) -> 0.5/(n a)^2;
// dRAAN = sin u dv_N/(n a sin i) -> 0.5/(n a sin i)^2; du = -2 dv_R/(n a) -> 4/(n a)^2.
// Throws std::invalid_argument for a non-positive a or a negative sigma or tau.
Vec6 observer_process_noise_from_acceleration(double a_m, double i_rad, double sigma_acc_mps2, double tau_s);

// A target's ROE process noise (variance rates of the dimensionless ROE, order
// da, dlambda, dex, dey, dix, diy) of an unmodelled differential along-track
// acceleration with 1-sigma sigma_acc and correlation time tau: q_v = 2
// sigma^2 tau through the same Gauss equations, da = (2/n) dv_T / a;
// d(ex, ey) = 2 (cos u, sin u) dv_T / (n a) -> 2/(n a)^2 each; dlambda, dix,
// diy take none directly. Throws std::invalid_argument as above.
Vec6 target_along_track_process_noise(double a_m, double sigma_acc_mps2, double tau_s);

// Quantile of the chi-square distribution with `dof` degrees of freedom at
// probability p (Wilson & Hilferty 1931 cube-root normal approximation; within
// 0.5 % of the exact quantile for dof >= 10 and p in [0.9, 1 - 1e-6]).
// Throws std::invalid_argument for dof < 1 or p outside (0, 1).
double chi2_quantile(int dof, double p);

// Bearing angles of paper eq. (2) to target `target`, measured in the camera
// frame V whose attitude R_v_from_eci comes with the measurement.
struct BearingMeasurement {
  TimeTT t;
  int target = 0;
  astro::Bearing angles;
  double sigma_az_rad = 0.0;
  double sigma_el_rad = 0.0;
  Mat3 R_v_from_eci = Mat3::Identity();
};
// From an inertial unit line of sight (ECI) observer -> target: the angles it
// makes in the frame R_v_from_eci (identity: angles in ECI components).
BearingMeasurement bearing_measurement_from_unit_eci(TimeTT t, int target, const Vec3& los_eci,
                                                     double sigma_rad,
                                                     const Mat3& R_v_from_eci = Mat3::Identity());

// A bearing taken by another body (multi-observer fusion, paper "Sequential
// Orbit Determination"): the unit line of sight (ECI) from body `from` to
// body `to`, where a body is kObserver (this filter's observer) or a target
// index. A remote observer that is not in the state is kExternal: its
// position estimate (from its ISL broadcast) and covariance enter the
// innovation covariance through the bearing Jacobian, R = sigma^2 I + J P J^T.
// The angles are formed in a frame whose z axis is the measured line of sight
// (no singularity).
struct LineOfSightMeasurement {
  static constexpr int kObserver = -1;
  static constexpr int kExternal = -2;
  TimeTT t;
  int from = kExternal;
  int to = 0;
  Vec3 from_r_eci_m = Vec3::Zero();    // kExternal only
  Vec3 from_v_eci_mps = Vec3::Zero();  // kExternal only, with sender_clock
  Mat3 from_P_r_m2 = Mat3::Zero();     // kExternal only
  // The sender's camera clock: index j of StateLayout::remote_clock_index, or
  // -1 when its time tags are taken as right. With j the image saw both
  // bodies at t - dt_j.
  int sender_clock = -1;
  Vec3 los_eci = Vec3::UnitZ();
  double sigma_rad = 0.0;
};

// GNSS navigation solution of the observer: ECI position and velocity.
struct GnssMeasurement {
  TimeTT t;
  astro::StateVector x_eci;
  double sigma_r_m = 0.0;
  double sigma_v_mps = 0.0;
};

struct TimeUpdateSummary {
  bool usable = false;
  std::string why;
  double dt_s = 0.0;
  int propagations = 0;  // calls of GveRk4Propagator::propagate
};

struct UpdateSummary {
  bool usable = false;  // state and covariance were updated
  bool gated = false;   // rejected by the Mahalanobis gate
  std::string why;
  int target = -1;      // -1 for GNSS
  VectorXd prefit_residual;   // z - h(x-), angles wrapped to (-pi, pi]
  VectorXd postfit_residual;  // z - h(x+), when usable
  double nis = kNaN;          // nu^T S^-1 nu
  // trace(P_zz - P_zx P^-1 P_xz) / trace(R): the predicted measurement's
  // spread that no linear map of the state explains, against the noise.
  // Computed only where it decides the underweighting (beta > 0,
  // trace P_zz > trace R, bearing_underweighting_nonlinearity > 0); NaN else.
  double nonlinearity = kNaN;
  double underweighting = 0.0;  // the beta applied: S = (1 + beta) P_zz + R
  bool underweighted = false;   // underweighting > 0
  double mahalanobis = kNaN;  // sqrt(nis)
  [[nodiscard]] std::string brief_report() const;
};

enum class HealthCondition {
  kHealthy,
  kBodDisagreement,      // (1)
  kNoMeasurementUpdate,  // (2)
  kLargeResiduals,       // (3)
  kOutOfRange,           // (4), also non-finite or non-positive-definite
  kInconsistent,         // (5) normalised innovations too large
};
std::string_view to_string(HealthCondition c);

struct HealthStatus {
  HealthCondition condition = HealthCondition::kHealthy;
  std::string reason;
  [[nodiscard]] bool healthy() const { return condition == HealthCondition::kHealthy; }
};

struct HealthReport {
  HealthStatus filter;                // observer block and whole-filter checks
  std::vector<HealthStatus> targets;  // one per target
  [[nodiscard]] bool healthy() const;
};

// A BOD estimate of one target's ROE (dimensionless) at the filter's epoch.
struct BodEstimate {
  TimeTT t;
  Vec6 roe = Vec6::Zero();
  Mat6 P_roe = Mat6::Zero();
};

struct BodComparison {
  bool usable = false;
  std::string why;
  double mahalanobis = kNaN;
  double relative_distance = kNaN;
  bool disagrees = false;
};

struct TargetCounters {
  int steps_without_update = 0;
  int consecutive_large_residuals = 0;
  int accepted = 0;
  int rejected = 0;
};

class SodFilter {
 public:
  // forces must outlive the filter. Throws std::invalid_argument for bad
  // options or a layout without targets.
  // Every target propagated with the same nominal properties target_sc.
  SodFilter(const dynamics::ForceModel& forces, const dynamics::SpacecraftProperties& observer_sc,
            const dynamics::SpacecraftProperties& target_sc, StateLayout layout,
            SodOptions options = {});
  // Target k propagated with its own nominal properties target_sc[k]
  // (layout.n_targets of them; its ballistic state, if any, adds to its own
  // nominal).
  SodFilter(const dynamics::ForceModel& forces, const dynamics::SpacecraftProperties& observer_sc,
            StateLayout layout, const std::vector<dynamics::SpacecraftProperties>& target_sc,
            SodOptions options = {});

  // Sets epoch, mean and covariance (layout().size()). Throws
  // std::invalid_argument for a wrong size, non-finite values or a P that is
  // not symmetric positive definite. Also resets counters and process noise.
  void initialize(TimeTT t, const VectorXd& x, const MatrixXd& P);
  // Stacks an observer and target ROE (and aux, may be empty) into a state.
  [[nodiscard]] VectorXd make_state(const astro::QnsElements& observer,
                                    const std::vector<astro::Roe>& roe,
                                    const VectorXd& aux = VectorXd()) const;

  // Propagates every sigma point with the GVE-RK4 dynamics to t and adds
  // Q = diag(q) |dt|. Sigma points that differ from the mean only in later
  // blocks reuse the mean's propagation (Stacey & D'Amico 2018).
  TimeUpdateSummary time_update(TimeTT t);
  // A cheap prediction for telemetry and IMP's predictions over short
  // horizons (never the filter's own time update): the mean through the same
  // GVE-RK4 dynamics (one trajectory per body), the covariance through the
  // observer's Keplerian drift (du/da = -1.5 n / a), each target's 6x6 block by
  // differences of the same propagation over its 1-sigma (six more target
  // trajectories each) and the auxiliary states' linear dynamics, plus Q |dt|.
  TimeUpdateSummary predict_linearised(TimeTT t);
  // Unscented measurement updates; each propagates to the measurement epoch
  // first when it differs from epoch().
  UpdateSummary update_bearing(const BearingMeasurement& m);
  UpdateSummary update_gnss(const GnssMeasurement& m);
  // Line of sight between bodies (remote observers). With dry_run the
  // innovation and its Mahalanobis distance are computed (after the time
  // update to m.t) but the state, covariance and counters are left alone:
  // the assignment test of remote measurements.
  UpdateSummary update_line_of_sight(const LineOfSightMeasurement& m, bool dry_run = false);

  // The observer's own planned impulsive maneuver (delta-v in its RTN frame)
  // at t, with the covariance of its execution error: the filter moves to t,
  // every sigma point's observer gets the delta-v and its targets' ROE are
  // recomputed against the new observer orbit (the targets did not move);
  // P += J P_dv J^T with J the derivative of that map by the delta-v.
  TimeUpdateSummary apply_observer_maneuver(TimeTT t, const Vec3& dv_rtn_mps, const Mat3& P_dv);

  // Health check (1): compares a BOD estimate (at epoch()) with the target's
  // block and stores the result for health() and reinitialize_target_from_bod().
  BodComparison check_bod(int target, const BodEstimate& bod);
  // All four checks on the current estimate.
  [[nodiscard]] HealthReport health() const;

  // Covariance inflation of one target (rows and columns of its ROE block and
  // of its ballistic state scaled by sqrt(factor), correlations kept): the
  // answer to check (5), a fading memory of the bearings that no longer fit.
  // Clears the target's NIS window. Throws std::invalid_argument for a bad
  // target or a factor that is not finite and >= 1.
  void inflate_target(int target, double factor);
  // Additive inflation for an unknown impulsive manoeuvre of the target, of
  // 1-sigma sigma_dv_mps per RTN axis, made up to since_s seconds ago: the
  // covariance of the ROE jump through the near-circular control matrix
  // (D'Amico 2010, eq. 2.38) at the observer's current u, plus the along-track
  // drift -3 dv_T tau it caused since (tau uniform in [0, since_s]). Clears
  // the target's NIS window. Throws std::invalid_argument for a bad target or
  // a sigma that is not finite and positive.
  void inflate_target_maneuver(int target, double sigma_dv_mps, double since_s);
  // Adds variance to one auxiliary state (its cross-covariances kept).
  // Throws std::invalid_argument for an index outside the auxiliary block or
  // a variance that is not finite and >= 0.
  void inflate_auxiliary(int index, double add_variance);
  // Adds delta to the auxiliary state `index` (a change of its reference, as
  // when the navigator moves a clock offset into its own time-tag correction).
  void shift_auxiliary(int index, double delta);
  // Mean NIS of the last health.gnss_nis_window GNSS fixes (NaN until full),
  // and clearing that window (after the navigator answered check 5).
  [[nodiscard]] double recent_mean_gnss_nis() const;
  // W |mean w|^2 of the last health.gnss_bias_window whitened RTN GNSS
  // innovations (NaN until full); cleared with the NIS window.
  [[nodiscard]] double recent_gnss_bias_statistic() const;
  void clear_gnss_nis();
  // Time span of the target's NIS window (s; NaN until full).
  [[nodiscard]] double recent_nis_span_s(int target) const;
  // Mean NIS of the target's last health.nis_window bearings (NaN until full).
  [[nodiscard]] double recent_mean_nis(int target) const;

  // Re-initialisation: replaces a target's block with the given mean (ROE,
  // dimensionless) and covariance, clears its cross-covariances and counters.
  // Throws std::invalid_argument if P_roe is not symmetric positive definite.
  void reinitialize_target(int target, const Vec6& roe, const Mat6& P_roe);
  // The same for an estimate made with the camera's time tags as this filter
  // knows them (BOD's batch): its error is -J e_clock + n, with J = d roe /
  // d(time shift) of the estimator (6 x n_time_tag: a uniform shift of 1 s,
  // and one of 1 s per second of (t - epoch) for the drift), e_clock this
  // filter's clock error and n the estimator's own error of covariance
  // P_roe. Its cross-covariances are -J P_clock,* and its covariance P_roe +
  // J P_clock J^T: the clock's doubt enters the target without being counted
  // twice. An empty J (or no time-tag state) is the overload above.
  void reinitialize_target(int target, const Vec6& roe, const Mat6& P_roe, const Eigen::MatrixXd& clock_J);
  // From the latest estimate passed to check_bod(); false if there is none.
  bool reinitialize_target_from_bod(int target);
  void reinitialize_observer(const astro::QnsElements& observer, const Mat6& P);
  // True from the target's re-initialisation or inflation, or a manoeuvre or
  // re-initialisation of the observer, until one of the target's bearings
  // has a predicted spread within its noise (trace P_zz <= trace R): while
  // true, the spread alone decides the underweighting
  // (SodOptions::bearing_underweighting_nonlinearity). False after
  // initialize(): its covariance is a modelled a-priori, not a guess.
  [[nodiscard]] bool prior_unconfirmed(int target) const;

  // Normalised estimation error squared (x^ - x)^T P^-1 (x^ - x), angles
  // wrapped; NaN if P is not positive definite. x_true has layout().size().
  [[nodiscard]] double nees(const VectorXd& x_true) const;
  // a - b with the angle components of the layout wrapped to (-pi, pi].
  [[nodiscard]] VectorXd state_difference(const VectorXd& a, const VectorXd& b) const;

  [[nodiscard]] const StateLayout& layout() const { return layout_; }
  [[nodiscard]] const SodOptions& options() const { return options_; }
  [[nodiscard]] TimeTT epoch() const { return t_; }
  [[nodiscard]] const VectorXd& state() const { return x_; }
  [[nodiscard]] const MatrixXd& covariance() const { return P_; }
  [[nodiscard]] astro::QnsElements observer() const;
  [[nodiscard]] astro::Roe roe(int target) const;
  // a_o * ROE and its 1-sigma, meters.
  [[nodiscard]] Vec6 a_roe_m(int target) const;
  [[nodiscard]] Vec6 a_roe_sigma_m(int target) const;
  // Current (adapted) process noise rate q, state units^2 / s.
  [[nodiscard]] const VectorXd& process_noise_rate() const { return q_; }
  [[nodiscard]] const MatrixXd& process_noise_rate_matrix() const { return Q_rate_; }
  [[nodiscard]] const TargetCounters& counters(int target) const;
  [[nodiscard]] int steps_without_update() const { return steps_without_update_; }
  [[nodiscard]] int rejected_total() const { return rejected_total_; }
  // UKF weights (mean, covariance) for the 2n+1 sigma points.
  [[nodiscard]] const VectorXd& weights_mean() const { return wm_; }
  [[nodiscard]] const VectorXd& weights_covariance() const { return wc_; }

 private:
  struct MeasurementModel;
  UpdateSummary unscented_update(const MeasurementModel& model, const VectorXd& z,
                                 const MatrixXd& R, double gate, int target, bool dry_run = false);
  [[nodiscard]] bool sigma_points(MatrixXd& X) const;
  void wrap_state(VectorXd& x) const;
  // Symmetrises P, checks x finite and P positive definite, wraps and keeps
  // both; false (nothing changed) otherwise.
  bool store(VectorXd x, MatrixXd P);
  bool begin_time_update(TimeTT t, TimeUpdateSummary& s);
  void finish_time_update(TimeTT t, const VectorXd& mean, MatrixXd P, TimeUpdateSummary& s);
  // Time update to a measurement epoch; false with s.why set on failure.
  bool advance_to(TimeTT t, UpdateSummary& s);
  void adapt_process_noise();
  // Each target's drag floor rate (docs/sod.md, "The drag floor") and its
  // ballistic walk (density_change_per_day); zero without either or without
  // ballistic states.
  [[nodiscard]] Eigen::VectorXd drag_floor_rates() const;
  [[nodiscard]] bool has_drag_budget() const {
    return options_.adaptive.drag_density_error > 0.0 || options_.adaptive.density_change_per_day > 0.0;
  }
  // Dynamics of the named auxiliary states over dt on propagated sigma points
  // Y (columns of X before the step): time-tag drift, differential drag.
  void apply_aux_dynamics(const MatrixXd& X, MatrixXd& Y, double dt_s) const;
  // Unscented mean (about the central point, angles wrapped) and covariance of
  // the transformed sigma points Y.
  void mean_and_covariance(const MatrixXd& Y, VectorXd& mean, MatrixXd& P) const;

  dynamics::GveRk4Propagator observer_prop_;
  std::vector<dynamics::GveRk4Propagator> target_props_;  // one per target
  double gm_m3ps2_;
  StateLayout layout_;
  SodOptions options_;
  double gamma_ = 0.0;
  VectorXd wm_, wc_;

  TimeTT t_;
  VectorXd x_;
  MatrixXd P_;
  VectorXd q_nominal_, q_;  // q_: the diagonal of Q_rate_
  MatrixXd Q_rate_;         // process noise rate added in the time update (Q = Q_rate_ |dt|)
  MatrixXd Q_average_;      // the adaptive recursion's A (= Q_rate_ with the clamped average)
  MatrixXd pending_dxdx_;   // sum of dx dx^T - K S K^T since the last time update
  bool pending_ = false;
  double pending_dt_s_ = 0.0;  // time propagated since the last adaptation
  bool initialized_ = false;

  const dynamics::ForceModel& forces_;
  std::vector<TargetCounters> counters_;
  std::vector<std::vector<double>> recent_nis_;  // ring buffers, health.nis_window each
  std::vector<std::vector<TimeTT>> recent_nis_t_;
  std::vector<int> recent_nis_count_;
  std::vector<char> prior_unconfirmed_;  // per target, see prior_unconfirmed()
  std::vector<double> gnss_nis_;
  int gnss_nis_count_ = 0;
  std::vector<Vec6> gnss_white_rtn_;  // ring buffer, health.gnss_bias_window
  int gnss_white_count_ = 0;
  std::vector<HealthStatus> bod_status_;
  std::vector<std::optional<BodEstimate>> last_bod_;
  int steps_without_update_ = 0;
  int consecutive_large_gnss_ = 0;
  int rejected_total_ = 0;
};

}  // namespace artms::sod
