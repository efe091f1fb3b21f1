// Batch Orbit Determination (paper, "Batch Orbit Determination"; Koenig and
// D'Amico 2020): the relative orbit of one target from a batch of bearing
// angles and a coarse estimate of the observer's orbit, with no a-priori of
// the target.
//
// State per target (paper): estimated x_est = [a, da, dex, dey, dix, diy],
// known a-priori x_prior = [ex, ey, i, RAAN, u] (the observer's mean elements
// at the estimation epoch t_est). The weakly observable dlambda is sampled:
// for each user-set sample, x_est starts from a = the observer's a and all
// other ROE zero and is refined by iterative batch least squares,
//   dz = z_meas - z_model(x(t_est), t),  dz = S_est dx_est,  x_est += dx_est,
// until dx_est is below a threshold or an iteration limit. The sample with
// the smallest residual wins; R_vbs comes from its post-fit residuals and
//   P_est = Y*_est (N R_vbs + Y_prior P_prior Y_prior^T) Y*_est^T
// (paper; N R_vbs read as the block diagonal of the N per-bearing R_vbs).
//
// Dynamics: the analytic J2 mean model of common/dynamics (mean elements
// under secular J2, the J2 STM of the mean ROE) with the first-order
// mean-to-osculating conversion, so that the modelled lines of sight carry
// the short-period J2 motion of both spacecraft (docs/bod.md). Where the
// caller gives its numerical force model (Options::onboard_forces), a usable
// solution is corrected for what the mean theory misses of it and solved
// again (docs/bod.md, "Model correction").
//
// Where the paper is silent (docs/bod.md): bearings are the camera-frame
// angles of eq. (2); residuals are unweighted (radians); the samples are
// log-spaced in range a|dlambda|, with the sign of dlambda from the mean
// along-track component of the measured lines of sight; each sample starts
// from the previous sample's solution scaled to the new range (the same
// converged result, fewer iterations); the chosen dlambda is refined by a
// parabola through the residual curve around its minimum; the covariance
// of all seven states (dlambda included) is the paper's formula at that
// solution with N R_vbs generalised to residuals correlated in time
// (Newey-West; the mean model's misfit of the world is not white).
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "artms/astro/elements.hpp"
#include "artms/astro/frames.hpp"
#include "artms/astro/roe.hpp"
#include "artms/astro/time.hpp"
#include "artms/dynamics/forces.hpp"
#include "artms/dynamics/j2_mean.hpp"

namespace artms::bod {

using Mat5 = Eigen::Matrix<double, 5, 5>;
using Mat7 = Eigen::Matrix<double, 7, 7>;

// One bearing of the batch: the measured unit line of sight observer ->
// target (ECI) and the attitude of its frame (the camera frame V in which
// the bearing angles of eq. 2 are formed).
struct Measurement {
  astro::TimeTT t;
  astro::Vec3 u_eci = astro::Vec3::UnitZ();
  astro::Mat3 R_v_from_eci = astro::Mat3::Identity();
};

// The observer's coarse orbit at the estimation epoch: mean quasi-nonsingular
// elements and the covariance of x_prior = [ex, ey, i, RAAN, u].
struct ObserverPrior {
  astro::TimeTT t_est;
  astro::QnsElements mean;
  Mat5 P_prior = Mat5::Zero();
};

struct Options {
  // dlambda samples: `samples` ranges a|dlambda|, log-spaced in [range_min_m,
  // range_max_m] (the camera's sensitivity: a target beyond range_max_m is
  // too faint, one closer than range_min_m too bright or too fast).
  double range_min_m = 2e3;
  double range_max_m = 200e3;
  int samples = 100;
  int max_iterations = 10;
  double convergence_m = 0.01;  // |dx_est| (meters: a and a*ROE) that ends the iteration
  int min_measurements = 50;
  int max_measurements = 200;   // a longer batch is thinned evenly
  // The residual curve is "flat" (range unobservable) when chi2 rises by less
  // than this over the samples either side of its minimum.
  double min_curve_rise_chi2 = 4.0;
  // Tolerances of a usable result (paper: "within state and uncertainty tolerances").
  double max_residual_rms_rad = 15.0 * 4.84813681109536e-6;  // post-fit RMS of a bearing angle
  double max_a_da_m = 1000.0;                                 // |a da|
  double max_sigma_range_fraction = 0.3;                      // sigma(a dlambda) / (a |dlambda|)
  double max_sigma_a_da_m = 200.0;                            // sigma(a da)
  // The mean J2 model's own error over a batch, 1-sigma in a*da, a*dex,
  // a*dey, a*dix, a*diy (meters), added to P: residuals cannot show the part
  // of a model error that the fit absorbs (docs/bod.md: the first-order
  // theory against a numerically integrated world, 10x10 gravity + drag +
  // Sun + Moon, 20 batches: mean NEES 131 without, 6.5 with 0.7 m).
  double model_sigma_m = 0.7;
  // The same for the range, a fraction of a|dlambda|: the range rests on the
  // curvature of the bearings over the batch, which ~1 arcsec of systematic
  // error (the model, IMP's centroids and attitude) moves by ~1 % at 50 km
  // (docs/bod.md).
  double model_sigma_range_fraction = 0.01;
  // Both floors also hold for a solution corrected for the onboard model
  // (onboard_forces). Its errors in a flight-like world are smaller
  // (BodStudy.DISABLED_ModelErrorFloorsWithTheCorrection: range error /
  // 1-sigma RMS 0.35 at 52 km with these floors, 0.91 with 0.3 %), but a
  // target whose drag the correction misses (the world sweep's Cd x 3, with
  // the observer's properties for the target) biases it by 3-4.7 % of range:
  // with 0.3 % and 0.4 m, health check 1 re-initialised SOD from such a
  // batch (docs/bod.md, "Model correction"; target_properties below).
  dynamics::J2Constants j2;
  // The onboard numerical force model (SOD's), or null for the paper's BOD
  // alone. When set, a usable solution is corrected for what the mean J2
  // theory misses of that model (gravity beyond J2, drag, Sun, Moon): both
  // spacecraft are propagated numerically from the solution over the batch,
  // the difference of their bearings from the mean theory's is taken off the
  // measured ones, and the batch is solved again with its samples within
  // [range / correction_window, range * correction_window] (docs/bod.md,
  // "Model correction"). Not owned; must outlive the call.
  const dynamics::ForceModel* onboard_forces = nullptr;
  dynamics::SpacecraftProperties onboard_properties;  // the observer's (the uplink's nominal values)
  // The target's, where the observer knows them (SOD's nominal with its
  // estimated differential ballistic coefficient); else onboard_properties.
  std::optional<dynamics::SpacecraftProperties> target_properties;
  double correction_window = 1.3;
  // Throws std::invalid_argument naming the field.
  void validate() const;
};

enum class Verdict {
  kUsable = 0,
  kTooFewMeasurements = 1,
  kBadInput = 2,            // non-finite measurement, epoch, or elements outside the mean model
  kNotConverged = 3,        // no sample converged
  kMinimumAtEdge = 4,       // range outside [range_min_m, range_max_m]
  kFlatResidualCurve = 5,   // range unobservable
  kOutsideTolerances = 6,   // state or uncertainty tolerances
};
const char* to_string(Verdict v);

struct Sample {
  double a_dlambda_m = 0.0;
  double residual_rms_rad = 0.0;  // RMS of all bearing-angle residuals
  double chi2 = 0.0;              // sum of squared residuals / R_vbs of the winner
  int iterations = 0;
  bool converged = false;
};

struct Result {
  Verdict verdict = Verdict::kBadInput;
  std::string why;  // empty when usable
  [[nodiscard]] bool usable() const { return verdict == Verdict::kUsable; }
  astro::TimeTT t_est;
  int measurements = 0;
  int iterations = 0;              // of the refined solution
  double residual_rms_rad = 0.0;   // post-fit
  Eigen::Matrix2d R_vbs = Eigen::Matrix2d::Zero();
  // Variance of a dlambda with the residuals' autocorrelation over that
  // with white residuals (the paper's formula): how much the mean model's
  // misfit, correlated in time, weakens the batch.
  double correlation_inflation = 1.0;
  double a_observer_m = 0.0;       // refined mean semi-major axis of the observer
  double sigma_a_observer_m = 0.0;
  astro::Roe roe_mean;             // the target's mean ROE at t_est
  astro::Mat6 P_roe_mean = astro::Mat6::Zero();  // dimensionless, [da, dlambda, dex, dey, dix, diy]
  double range_m = 0.0;            // a0 |dlambda| (the along-track separation)
  double sigma_range_m = 0.0;      // sigma(a dlambda)
  int best_sample = -1;
  std::vector<Sample> curve;       // the residual curve, in sample order (of the measured bearings)
  // Model correction (Options::onboard_forces): RMS of the bearing
  // corrections taken off the measured angles, and the range before them
  // (0 and range_m when no correction was made).
  double model_correction_rms_rad = 0.0;
  double uncorrected_range_m = 0.0;
  // One line for the event log.
  [[nodiscard]] std::string brief() const;
};

// The batch with its precomputed observer trajectory and linearisations,
// exposed for the tests (the sensitivity matrix against numerical
// derivatives). x = [a (m), a0 da, a0 dlambda, a0 dex, a0 dey, a0 dix, a0 diy]
// (meters, a0 the prior's a): all seven, dlambda included.
class BatchModel {
 public:
  using Vec7 = Eigen::Matrix<double, 7, 1>;
  BatchModel(std::vector<Measurement> batch, const ObserverPrior& prior, const dynamics::J2Constants& j2);
  [[nodiscard]] int size() const { return static_cast<int>(m_.size()); }
  [[nodiscard]] double a0_m() const { return prior_.mean.a_m; }
  // Measured bearing angles [az, el] of measurement j.
  [[nodiscard]] Eigen::Vector2d measured(int j) const { return m_[static_cast<std::size_t>(j)].z; }
  // Modelled angles of measurement j and, optionally, d angles / d x (2x7).
  [[nodiscard]] Eigen::Vector2d modelled(int j, const Vec7& x, Eigen::Matrix<double, 2, 7>* S = nullptr) const;
  // The same through the full nonlinear chain (mean propagation of both
  // spacecraft, mean-to-osculating conversion of each, Cartesian), with the
  // observer's prior elements perturbed by d_prior ([ex, ey, i, RAAN, u]):
  // what the linearised model approximates, and Y_prior by differences.
  [[nodiscard]] Eigen::Vector2d modelled_exact(int j, const Vec7& x,
                                               const Eigen::Matrix<double, 5, 1>& d_prior) const;
  // Unit along-track direction of the observer at measurement j (ECI).
  [[nodiscard]] astro::Vec3 along_track(int j) const { return m_[static_cast<std::size_t>(j)].t_hat; }
  [[nodiscard]] astro::Vec3 measured_los(int j) const { return m_[static_cast<std::size_t>(j)].u_eci; }

 private:
  struct Precomputed {
    double dt_s = 0.0;
    Eigen::Vector2d z = Eigen::Vector2d::Zero();
    astro::Vec3 u_eci = astro::Vec3::Zero();
    astro::Mat3 R_v = astro::Mat3::Identity();
    astro::Vec6 chief_osc = astro::Vec6::Zero();   // observer's osculating elements at t_j (a0)
    astro::Vec6 dosc_da = astro::Vec6::Zero();     // their derivative in the observer's a
    astro::Vec3 r_o = astro::Vec3::Zero();         // observer position at t_j (a0)
    astro::Vec3 dro_da = astro::Vec3::Zero();
    // Mean element differences at t_j from the mean ROE at t_est (eq. 4
    // inverted, after the J2 STM), and the osculating differences from the
    // mean ones: D at the observer, D' its derivative in u (the deputy's
    // differences use D at the midpoint, D + D' du / 2).
    Eigen::Matrix<double, 6, 6> EPhi = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 6> D = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 6> dD_du = Eigen::Matrix<double, 6, 6>::Zero();
    // d r / d osc elements at the observer, and its derivative in u: the
    // target's is Jr + du dJr_du (first order in the phase difference du).
    Eigen::Matrix<double, 3, 6> Jr = Eigen::Matrix<double, 3, 6>::Zero();
    Eigen::Matrix<double, 3, 6> dJr_du = Eigen::Matrix<double, 3, 6>::Zero();
    Eigen::Matrix<double, 6, 6> DEPhi = Eigen::Matrix<double, 6, 6>::Zero();
    astro::Vec3 t_hat = astro::Vec3::UnitY();      // along-track
  };
  std::vector<Precomputed> m_;
  ObserverPrior prior_;
  dynamics::J2Constants j2_;
};

// The batch least squares over the dlambda samples. The batch needs no
// particular order; measurements at the same time as another are kept.
Result solve(const std::vector<Measurement>& batch, const ObserverPrior& prior, const Options& options = {});

}  // namespace artms::bod
