// SAMUS: Spacecraft Angles-only MUltitarget tracking System (paper, "Image
// Processing"; Kruger and D'Amico 2021). Chains measurement candidates of
// successive frames into target tracks without a-priori relative orbit
// knowledge, needing only a coarse observer orbit. docs/imp_samus.md has the
// full description; in short:
//
//  * Tracking plane. Each candidate's line of sight is expressed in the
//    observer's RTN frame (from the coarse orbit) and projected
//    gnomonically on the plane normal to a reference direction d (the
//    camera boresight in RTN at the first frame): p = (v.e1, v.e2) / v.d,
//    e1 along R projected on the plane, e2 = d x e1. For a camera along
//    -/+T these are the paper's elevation and azimuth to first order.
//  * Motion model, paper eq. (9): per axis
//      p_k = (r_o / a_o) (c0 + c1 cos u_o + c2 sin u_o),
//    i.e. x1 - x2 cos(u - x3) and x4 + x5 sin(u - x6) rewritten linearly, fitted by
//    weighted linear least squares to the track's last fit_window
//    measurements, with a weak zero-mean prior (harmonic_prior_rad) on c1,
//    c2 so that a short arc extrapolates like a straight line instead of a
//    free quadratic. The prediction's variance h^T N^-1 h feeds the gate.
//  * Hypotheses. Each track keeps up to max_branches hypotheses (which
//    candidate, or none, it took in each frame) scored by cumulative cost;
//    each frame every hypothesis spawns one child per candidate that passes
//    the five kinematic rules plus a missed-detection child; the cheapest
//    max_branches survive; a hypothesis disagreeing with the best one on a
//    frame n_scan frames back is pruned (N-scan), and measurements that old
//    in the best hypothesis of a confirmed track are released.
//  * Rules (hypotheses failing one are not formed): 1) rate below
//    max_rate_radps; 2) consistent speed (ratio <= max_speed_ratio); 3) no
//    acute angle between successive displacements; 4) consistent turning
//    direction; 5) within gate_sigma of the prediction. Rules 2-4 apply only
//    to displacements larger than significance_sigma measurement sigmas.
//  * Cost of an assignment (lower is better; weights in SamusOptions): the
//    squared normalised distance to the prediction, the normalised fit
//    residual after adding it, speed change, direction change, brightness
//    change; a miss costs miss_cost.
//  * Initiation: DBSCAN (n_D = dbscan_min_points within eps_D =
//    dbscan_radius_rad) on the unassigned candidates of the last
//    dbscan_frames frames; a cluster with n_D distinct frames whose chain
//    passes rules 1-3 and fits eq. (9) starts a tentative track.
//  * Eclipse joining: when a tentative track reaches confirm_measurements,
//    eq. (9) is fitted to it together with every lost track (gap <=
//    join_max_gap_s); compatible pairs (chi-square per degree of freedom <=
//    join_max_chi2) are taken by least residual, and the new track inherits
//    the old identity.
//  * SOD-aided mode: for a track with a TargetPrediction (SOD's predicted
//    measurement and covariance from an unscented transform), the rules are
//    replaced by a Mahalanobis gate on that prediction (aided_gate_chi2) and
//    the Mahalanobis distance squared replaces the prediction, speed and
//    direction terms of the cost (fit and brightness terms stay).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "artms/astro/elements.hpp"
#include "artms/imp/frame_processor.hpp"

namespace artms::imp {

struct SamusOptions {
  double max_rate_radps = 2.0e-4;       // rule 1 (~0.7 deg/min; stars move ~4 deg/min)
  double max_speed_ratio = 4.0;         // rule 2
  double significance_sigma = 4.0;      // rules 2-4: displacements above this many sigmas
  double min_turn_sine = 0.2;           // rule 4: only turns sharper than this count
  double gate_sigma = 5.0;              // rule 5
  double model_floor_rad = 15.0 * 4.84813681109536e-6;  // eq. (9) model error added to each sigma
  double harmonic_prior_rad = 0.1;      // weak prior on c1, c2
  int fit_window = 8;                   // measurements in the eq. (9) fit (see docs: model error)
  int max_branches = 4;                 // hypotheses kept per track
  int n_scan = 2;                       // frames before a measurement is decided
  double miss_cost = 12.0;
  // Cost weights: prediction distance^2, fit chi^2/dof, |log speed ratio|,
  // 1 - cos(direction change), |log brightness ratio|.
  double w_prediction = 1.0, w_fit = 1.0, w_speed = 2.0, w_direction = 2.0, w_brightness = 1.0;
  // Initiation (DBSCAN; the scenario's imp.dbscan_* keys).
  int dbscan_min_points = 3;
  double dbscan_radius_rad = 20.0 / 5660.0;  // 20 NST pixels (config SCHEMA.md)
  int dbscan_frames = 5;
  double init_max_chi2 = 4.0;           // eq. (9) fit of a new cluster, per degree of freedom
  int confirm_measurements = 6;
  double lost_after_s = 900.0;          // no measurement for this long: track lost
  double join_max_gap_s = 4.0 * 3600.0;
  double join_max_chi2 = 4.0;
  int join_window = 20;                 // measurements of the lost track in the joint fit
  double aided_gate_chi2 = 13.8;        // 2 dof, 99.9 %
  void validate() const;  // throws std::invalid_argument naming the field
};

struct TrackerInput {
  std::int64_t frame = 0;  // caller's frame number (output only)
  astro::TimeTT t;         // the frame's time tag (TT)
  astro::StateVector observer_eci;  // coarse observer orbit estimate at t
  Eigen::Vector3d boresight_eci = Eigen::Vector3d::UnitZ();
  std::vector<Candidate> candidates;
};

// SOD-aided tracking: predicted tracking-plane coordinates of a track's next
// measurement with covariance (from an unscented transform of the target
// state covariance; Samus::unscented_prediction() does it).
struct TargetPrediction {
  int track_id = -1;
  Eigen::Vector2d p = Eigen::Vector2d::Zero();
  Eigen::Matrix2d cov = Eigen::Matrix2d::Identity();
};

struct TrackedMeasurement {
  std::int64_t frame = 0;
  astro::TimeTT t;  // its frame's time tag, exactly as given in TrackerInput
  int track_id = -1;
  int candidate = -1;  // index into that frame's candidates
  Candidate c;
  int segment = 1;  // the track's segments (1 + joins across gaps) when this measurement was released
};

struct TrackInfo {
  int track_id = -1;
  std::int64_t first_frame = 0, last_frame = 0;
  int measurements = 0;
  int segments = 1;  // 1 + eclipse joins
  bool confirmed = false;
  bool lost = false;
  double fit_rms_rad = 0.0;
};

struct SamusFrameSummary {
  int candidates = 0;
  int assigned = 0;         // candidates taken by any hypothesis of an active track
  std::vector<int> taken;   // their indices (into the frame's candidates)
  int tracks_started = 0;
  int tracks_joined = 0;
  int tracks_dropped = 0;   // tentative tracks lost before confirmation
  std::vector<TrackedMeasurement> released;  // decided measurements, time order
};

class Samus {
 public:
  explicit Samus(SamusOptions options = {});
  SamusFrameSummary process(const TrackerInput& in, std::span<const TargetPrediction> aided = {});
  // End of data: releases every pending measurement of confirmed tracks.
  std::vector<TrackedMeasurement> flush();
  [[nodiscard]] std::vector<TrackInfo> tracks() const;
  // The time tag of the oldest measurement a later frame may still release:
  // the first undecided one of every active track (a tentative track's
  // first), and the initiation pool's oldest candidate (it may start a track
  // whose first measurements it is). nullopt when nothing is held.
  [[nodiscard]] std::optional<astro::TimeTT> oldest_undecided() const;
  // Tracking-plane coordinates of a line of sight (ECI) for an observer state;
  // false when the plane is not set yet or the direction is behind it.
  bool plane_coordinates(const Eigen::Vector3d& u_eci, const astro::StateVector& observer_eci,
                         Eigen::Vector2d& p) const;
  // Eq. (9) prediction of a track at an observer state (nullopt: unknown track).
  [[nodiscard]] bool predict(int track_id, const astro::StateVector& observer_eci, Eigen::Vector2d& p,
                             Eigen::Matrix2d& cov) const;
  // SOD-aided mode: the unscented transform (symmetric sigma points,
  // weights 1/(2n), no centre point) of a target state (mean, covariance) through
  // los_eci (state -> line of sight, ECI) and the tracking plane. false if a
  // sigma point falls behind the plane or the covariance is not positive
  // definite.
  bool unscented_prediction(int track_id, const Eigen::VectorXd& mean, const Eigen::MatrixXd& cov,
                            const std::function<Eigen::Vector3d(const Eigen::VectorXd&)>& los_eci,
                            const astro::StateVector& observer_eci, TargetPrediction& out) const;

  struct Meas {
    std::int64_t seq = 0;  // internal frame counter
    std::int64_t frame = 0;
    astro::TimeTT t;
    double t_s = 0.0;      // t in seconds since J2000 (the kinematic rules' arithmetic)
    int candidate = -1;
    Eigen::Vector2d p;     // tracking plane
    double sigma = 0.0;    // per axis, incl. model floor
    double ra = 1.0;       // r_o / a_o
    double u = 0.0;        // u_o
    Candidate c;
  };

 private:
  struct Branch {
    std::vector<Meas> meas;
    double cost = 0.0;
  };
  struct Family {
    int id = -1;
    std::vector<Branch> branches;  // best first
    bool confirmed = false;
    bool lost = false;
    int segments = 1;
    std::size_t released = 0;       // measurements of branches[0] already released
    std::int64_t created_seq = 0;
  };
  struct Pending {
    std::int64_t seq;
    Meas m;
  };

  SamusOptions opt_;
  bool plane_set_ = false;
  Eigen::Vector3d d_rtn_, e1_rtn_, e2_rtn_;
  std::int64_t seq_ = 0;
  int next_id_ = 0;
  std::vector<Family> families_;
  std::vector<Pending> unassigned_;  // recent unassigned candidates (initiation pool)
  std::vector<TrackInfo> retired_;   // lost beyond the joining window

  [[nodiscard]] TrackInfo info_of(const Family& f) const;

  void release(Family& f, std::int64_t upto_seq, std::vector<TrackedMeasurement>& out) const;
  void try_joins(SamusFrameSummary& s);
};

// Eq. (9) fit of measurements: returns chi-square per degree of freedom and
// fills the coefficient vectors (per axis c0, c1, c2) and the inverse normal
// matrix. Exposed for tests and the documentation.
struct Eq9Fit {
  bool usable = false;
  Eigen::Vector3d c_x = Eigen::Vector3d::Zero(), c_y = Eigen::Vector3d::Zero();
  Eigen::Matrix3d N_inv = Eigen::Matrix3d::Zero();  // covariance of c per axis (unit-sigma weights applied)
  double chi2_per_dof = 0.0;
  double rms_rad = 0.0;
};
Eq9Fit fit_eq9(std::span<const Samus::Meas> meas, double harmonic_prior_rad);

}  // namespace artms::imp
