// Navigation mode 1 of one observer (paper, "Navigation Modes" and
// "Sequential Orbit Determination"): SOD (sod::SodFilter) over the observer's
// absolute elements and the ROE of every target, initialised from the first
// GNSS fix and the uplinked ground a-priori, updated with the observer's GNSS
// fixes and with the bearings IMP decided.
//
// Timing: SAMUS decides measurements n_scan frames late, so the filter runs
// behind the clock: events (GNSS fixes, bearings) are queued and processed in
// time order up to a safe time (the latest decided frame, or the clock minus
// max_lag_s; in mode 3 also at least remote_hold_s behind the clock, so
// remote bearings arrive in time); a bearing older than the filter epoch when it arrives (the first
// measurements of a track that DBSCAN just started) is counted late and
// skipped. Telemetry at a step is the filter state predicted to the step time.
//
// Tracks and targets: a SAMUS track is bound to the SOD target whose
// unscented prediction (samus.hpp) fits its measurements best, once
// association_min_measurements of them give a mean squared Mahalanobis
// distance below association_limit_d2(n) (the chi-square test of its n
// bearings, 2 n degrees of freedom) and the second best target is at least
// association_ambiguity times worse; until then its bearings only serve the
// association.
//
// BOD (paper, "Batch Orbit Determination"; bod::solve): every
// tuning.bod.period the bearings of every SAMUS track over the latest
// tuning.bod.batch_orbits orbits (at least min_measurements) are solved
// for a relative orbit. A usable result of a bound track is health check (1)
// for its target (squared Mahalanobis distance to SOD above check_chi2:
// the target is re-initialised from BOD). A usable result of an unbound
// track initialises a target that has no estimate yet (navigation mode 2,
// no a-priori; the first such target in the uplink's order), or else goes
// to the target without a bound track it is nearest to: check (1) again, or
// when BOD knows the range better than SOD (an a-priori too poor to bind
// the track), SOD is refined from BOD; the track is then bound to it.
//
// Health (the paper's four checks, sod::SodFilter::health): a target failing
// (3) large residuals or (4) valid range is re-initialised from its most
// recent BOD estimate, else from the ground a-priori (along-track drift
// applied to either); (2) is applied to the filter as a whole (a sparsely seen target
// keeps its estimate, as in the paper's SV3 case), and a filter failing (2) or
// (4) is re-initialised from the next GNSS fix and the a-priori.
//
// Navigation mode 3 adds the bearings other observers broadcast over the ISL
// (paper, "Sequential Orbit Determination"): a remote bearing j is assigned to
// body k (one of the targets, or this observer itself) when sigma_jk <=
// eps_assign, sigma_lk >= eps_ambig for every other bearing l of the same
// sender and epoch, and sigma_jp >= eps_ambig for every other body p, where
// sigma is the Mahalanobis distance of the innovation; the sender's position
// is this filter's estimate when the sender is one of its targets, else the
// sender's broadcast orbit (propagated to the bearing's time) with its
// covariance in the innovation covariance. A remote orbit is never used as a
// measurement (the paper's 02/05/24 anomaly, fixed by design).
#pragma once

#include <Eigen/Geometry>
#include <deque>
#include <functional>
#include <map>
#include <set>
#include <tuple>
#include <optional>
#include <string>
#include <vector>

#include "artms/bod/bod.hpp"
#include "artms/bus/messages.hpp"
#include "artms/config/uplink.hpp"
#include "artms/imp/samus.hpp"
#include "artms/sod/sod_filter.hpp"

namespace artms::fsw {

struct NavigatorOptions {
  double max_lag_s = 600.0;
  // Navigation mode 3: the filter stays at least this far behind the clock,
  // so that a remote bearing reaches the queue before the filter passes its
  // epoch. < 0: from the uplink, the oldest a remote bearing can be when it
  // arrives: the sender's SAMUS decision lag (a track DBSCAN starts reports
  // measurements up to dbscan_frames + n_scan frames old, at the swarm's
  // longest cadence) + one ISL period + the link latency + two steps (the
  // sender holds a frame one step, the receiver takes a relayed broadcast at
  // the step after the emulator relayed it).
  double remote_hold_s = -1.0;
  int association_min_measurements = 3;
  // A track is bound to a target when the mean squared Mahalanobis distance
  // of its n bearings (2 n degrees of freedom) to the target's prediction is
  // below chi2_quantile(2 n, association_confidence) / n, a test a right
  // binding fails with probability 1 - association_confidence (7.56 for
  // n = 3 at 0.999, 5.51 for n = 6; sod::chi2_quantile), and below
  // association_max_d2. A fixed
  // limit of 16 bound IT seed 17's SV2 (orbit phase +138.2 deg) to a track
  // that had swapped to SV3, at a mean d2 of 8.29 over 3 bearings (a chance
  // of 4e-4 for a right binding): SV3's bearings pulled SV2's estimate
  // beyond 5 sigma while it was reported healthy (docs/sod.md, stop 58).
  double association_confidence = 0.999;
  // The upper bound of the binding limit above, and the limit of each
  // bearing of a held track (one joined across a gap since it was bound).
  double association_max_d2 = 16.0;
  double association_ambiguity = 4.0;
  // A bound track is unbound after this many successive gated bearings
  // (fewer than the health check's max_large_residuals).
  int unbind_after_gated = 3;
  double aided_max_dlambda_fraction = 0.02;  // SOD-aided SAMUS once a*dlambda 1-sigma < 2 % of range
  double direct_gate_chi2 = 9.21;            // 2 dof, 99 %: single detections of untracked targets
  double direct_max_sigma_rad = 300.0 * 4.84813681109536e-6;  // widest validity region (RSS 1-sigma) used
  // A single detection that no frame could check (its inertial direction
  // off the sensors of the frames IMP keeps before it and of the next frame,
  // or no next frame) is fused only when its validity region was at most
  // this wide (RSS 1-sigma). A faint star of
  // V 6.6-9 (2.7 per deg^2 over the sky, 8.9e3 per sr; the renderer's
  // faint-star counts) falls in the 99 % region (area pi 9.21 w^2 / 2) with
  // probability 1.28e5 w^2: 4.3 % at 120", 27 % at 300". In IT seed 9 (orbit
  // phase drawn) three such stars 25-31 px from SV3, in frames whose next
  // delivered frame had turned away, were fused while its a-priori put the
  // region ~30 px wide (docs/sod.md, "Faint stars taken for a target").
  double direct_unverified_max_sigma_rad = 120.0 * 4.84813681109536e-6;
  // A local bearing of a target whose predicted pixel lies this close to
  // another target's is left out: within ~6 px (5 PSF sigmas of the NST)
  // the other spot's light pulls its centroid (a spot 3 x as bright: 0.2 px
  // at 5 px, AidedDetection.ABrighterSpotPullsTheCentroidAtFivePixelsNotAtEight);
  // 2 px more for the error of the predicted pixels (docs/sod.md, "The
  // orbit phase"). With the uplinked fx. 0 disables.
  double blend_separation_px = 8.0;
  // No SOD-aided search, and no single detection assigned, for a target the
  // onboard model puts in the Earth's umbra: its estimate and every sigma
  // point of the validity region's unscented transform in the shadow cone
  // (the onboard Sun ephemeris and dynamics::sunlit_fraction, the ones SRP
  // uses). An unlit target is not seen, so whatever the search finds there
  // is a false alarm: IT seed 36 with the orbit phase drawn took a noise peak
  // 12.65 px from an eclipsed SV2 and was starved for 16 h after it
  // (docs/sod.md, "A defect, IT seed 36").
  bool skip_eclipsed_targets = true;
  // A target that had bearings and has had none for lost_after_steps filter
  // steps, while an unbound IMP track is unambiguously nearest its prediction
  // (mean d2 in [lost_min_d2, lost_max_d2)), is suspect: its covariance is inflated so
  // that the track can be bound again (a target's unknown manoeuvre: the
  // track SAMUS starts after the jump; issue 17).
  int lost_after_steps = 10;
  double lost_min_d2 = 100.0;  // far beyond association_max_d2: a jump, not a slightly off prediction
  double lost_max_d2 = 1e7;
  // The own-clock check (with tuning.sod.time_tag.senders): when at least
  // two senders' clocks are known (1-sigma <= clock_known_s) and all appear
  // off by the same amount (each beyond clock_min_offset_s and 5 sigma, of
  // one sign, spread within half their mean), this observer's own camera
  // clock is the likelier culprit: its time-tag correction takes the
  // offset and its relative orbits start again (docs/sod.md).
  double clock_known_s = 0.02;
  double clock_min_offset_s = 0.02;
};

// The binding limit on a track's mean squared Mahalanobis distance over its
// n bearings (NavigatorOptions::association_confidence).
double association_limit_d2(const NavigatorOptions& options, int n);

// SOD's options from the uplinked telecommands, as the navigator builds its
// filter (artms-sod-replay uses the same function).
sod::SodOptions sod_options(const config::SodTuning& tuning);
// The same, with the onboard model's expected error on the observer's own
// orbit (tuning.observer_acceleration_sigma_mps2, an unmodelled acceleration
// correlated over one orbit) as its process noise where that exceeds the
// built-in one.
sod::SodOptions sod_options(const config::SodTuning& tuning, const astro::QnsElements& observer);
// SOD's state layout for n_targets targets and the auxiliary states the
// tuning enables (camera time tag, differential ballistic coefficients and,
// with time_tag_senders, the clocks of n_senders remote observers).
sod::StateLayout sod_layout(const config::SodTuning& tuning, int n_targets, int n_senders = 0);
// Each target's uplinked nominal properties, in the order of target_ids (the
// filter propagates target k with the k-th).
std::vector<dynamics::SpacecraftProperties> target_nominal_properties(const config::ObserverUplink& up,
                                                                      const std::vector<std::string>& target_ids);
// The auxiliary states' initial variances (their uplinked 1-sigma), in the
// layout's auxiliary order.
Eigen::VectorXd auxiliary_prior_variance(const config::SodTuning& tuning, const sod::StateLayout& layout);
// BOD's options from the uplinked telecommands.
bod::Options bod_options(const config::BodTuning& tuning);

// The oldest a remote bearing can be when it arrives (NavigatorOptions::
// remote_hold_s < 0): the sender's SAMUS decision lag (dbscan_frames + n_scan
// frames at the swarm's longest cadence) + one ISL period + latency + two steps.
double remote_bearing_max_age_s(const config::ObserverUplink& up);

// What arrives over the inter-satellite link from another observer (paper,
// "Sequential Orbit Determination": remote bearings are fused, the remote
// observer's orbit uncertainty accounted for).
struct RemoteBearing {
  astro::TimeTT t;
  std::string track;  // the sender's track label (e.g. "SV2-3"), stable per object
  Eigen::Vector3d u_eci = Eigen::Vector3d::UnitZ();
  double sigma_rad = 0.0;
};
struct RemoteBroadcast {
  std::string sender;
  std::uint32_t seq = 0;  // the sender's broadcast sequence number
  astro::TimeTT t;
  astro::StateVector x_eci;                                         // sender's absolute orbit estimate
  Eigen::Matrix<double, 6, 6> P_rv = Eigen::Matrix<double, 6, 6>::Zero();
  int source = 0;               // 0 none, 1 SOD, 2 GNSS, 3 ground
  bool reinitialising = false;
  std::vector<RemoteBearing> bearings;  // since the sender's previous broadcast
};

struct TargetReport {
  std::string id;
  astro::Vec6 roe = astro::Vec6::Zero();
  astro::Mat6 P_roe = astro::Mat6::Zero();
  std::uint32_t local_measurements = 0;
  std::uint32_t remote_measurements = 0;
  // Every bearing update of this target so far (local and remote, fused or
  // refused by the gate): the sum of their normalised innovation squares
  // (2 degrees of freedom each) and how many (NIS consistency, summary.json).
  double bearing_nis_sum = 0.0;
  std::uint32_t bearing_updates = 0;
  int health = 0;  // 0 healthy, 1 suspect (bus::TargetEstimate::health)
};

struct NavReport {
  bool valid = false;
  int health = 2;  // 0 healthy, 1 re-initialising, 2 no solution
  astro::StateVector x_eci;
  Eigen::Matrix<double, 6, 6> P_rv = Eigen::Matrix<double, 6, 6>::Zero();
  std::vector<TargetReport> targets;
};

class Navigator {
 public:
  Navigator(const config::ObserverUplink& up, const dynamics::ForceModel& forces, NavigatorOptions options = {});

  void add_gnss(const sod::GnssMeasurement& m);
  // A broadcast received over the ISL (navigation mode 3 fuses its bearings;
  // other modes count it only).
  void add_remote(const RemoteBroadcast& b);
  [[nodiscard]] std::size_t remote_broadcasts() const { return remote_broadcasts_; }
  [[nodiscard]] std::size_t remote_assigned() const { return remote_assigned_; }
  [[nodiscard]] std::size_t remote_unassigned() const { return remote_unassigned_; }
  [[nodiscard]] std::size_t remote_late() const { return remote_late_; }
  [[nodiscard]] std::size_t remote_repeated() const { return remote_repeated_; }  // duplicates dropped
  // A bearing released by SAMUS: time tag, track, unit line of sight (ECI),
  // the attitude of its frame and the track's segment
  // (TrackedMeasurement::segment).
  void add_bearing(astro::TimeTT t, int track, const Eigen::Vector3d& u_eci, const Eigen::Quaterniond& q_cam_from_eci,
                   double imp_sigma_rad, int segment = 1);
  // Processes queued events up to t_safe (and at most up to t_now - max_lag_s
  // behind). samus supplies the tracking plane for association.
  void advance(astro::TimeTT t_safe, astro::TimeTT t_now, const imp::Samus& samus);
  // Everything queued (end of run).
  void finish(const imp::Samus& samus);
  [[nodiscard]] NavReport report(astro::TimeTT t) const;
  [[nodiscard]] const NavigatorOptions& options() const { return opt_; }
  // SOD-aided assignment of single detections (paper: "target state
  // estimates from SOD are propagated into the current epoch to provide
  // predicted track measurements ... a validity region around the
  // prediction, computed via an unscented transform"): for every target with
  // no active bound track (a faint, rarely detected one), the candidate of
  // this frame inside the 99 % validity region of its predicted measurement,
  // if exactly one is, is that target's. Returns each assignment with the
  // width of its validity region; the caller queues the ones it confirms with
  // add_direct (the observer first checks that the candidate is not a faint
  // star, by looking at its inertial direction in the frames before and the
  // next one).
  // Candidates a SAMUS track took (`taken`) are skipped, and so is a
  // candidate that lies within the ambiguity distance (eps_ambig) of another
  // target's prediction.
  struct DirectAssignment {
    int candidate = -1;             // index in `candidates`
    int target = -1;                // index in the uplinked a-priori
    double region_sigma_rad = 0.0;  // the validity region's RSS 1-sigma
  };
  std::vector<DirectAssignment> assign_untracked(astro::TimeTT t, const std::vector<imp::Candidate>& candidates,
                                                 const std::vector<int>& taken, const astro::StateVector& observer_eci,
                                                 const imp::Samus& samus);
  // A single detection of target `target` (index) confirmed by the caller.
  void add_direct(astro::TimeTT t, int target, const Eigen::Vector3d& u_eci, const Eigen::Quaterniond& q_cam_from_eci,
                  double imp_sigma_rad);
  // Validity regions in pixels of the targets assign_untracked would
  // consider (no active bound track) in the frame tagged t, for SOD-aided
  // detection (imp::FrameProcessor::aided_candidate): the unscented
  // transform of the filter state through pixel_of (a unit line of sight,
  // ECI, to a pixel of this frame; nullopt off the sensor).
  struct PixelRegion {
    int target = -1;
    Eigen::Vector2d px = Eigen::Vector2d::Zero();
    Eigen::Matrix2d cov_px2 = Eigen::Matrix2d::Identity();
  };
  using PixelOf = std::function<std::optional<Eigen::Vector2d>(const Eigen::Vector3d&)>;
  [[nodiscard]] std::vector<PixelRegion> untracked_regions(astro::TimeTT t, const PixelOf& pixel_of) const;
  // True when (t, u_eci) was assigned by assign_untracked: SAMUS may later
  // release the same candidate in a track (DBSCAN clusters it), and it must
  // not be fused, nor broadcast, twice.
  [[nodiscard]] bool direct_assigned(astro::TimeTT t, const Eigen::Vector3d& u_eci) const;
  // SOD-aided SAMUS: predictions at t for tracks bound to converged targets.
  [[nodiscard]] std::vector<imp::TargetPrediction> predictions(astro::TimeTT t, const imp::Samus& samus) const;

  // Events for the event log, drained by the caller.
  std::vector<std::string> take_messages() { return std::exchange(messages_, {}); }
  [[nodiscard]] std::size_t late_measurements() const { return late_; }
  // Added to a local bearing's time tag (the uplinked correction and what the
  // own-clock check found).
  [[nodiscard]] double time_tag_correction_s() const { return time_tag_correction_s_; }
  // Local bearings left out because another target was predicted within
  // NavigatorOptions::blend_separation_px.
  [[nodiscard]] std::size_t blended_measurements() const { return blended_; }
  // Bearing updates of target k so far (local and remote, fused or refused
  // by the gate): a change means its predictions since then come from
  // another estimate (the stacked aided search restarts its stack).
  [[nodiscard]] std::uint32_t target_bearing_updates(int k) const {
    return k >= 0 && static_cast<std::size_t>(k) < nis_n_.size() ? nis_n_[static_cast<std::size_t>(k)] : 0;
  }
  // Per frame and target: aided searches not run because the target was
  // predicted in the Earth's umbra (NavigatorOptions::skip_eclipsed_targets).
  [[nodiscard]] std::size_t eclipsed_searches_skipped() const { return eclipsed_skipped_; }
  // Local bearings the gate refused, and those of tracks not bound to a
  // target (they served the association only).
  [[nodiscard]] std::size_t refused_measurements() const { return refused_; }
  [[nodiscard]] std::size_t association_measurements() const { return association_; }
  [[nodiscard]] bool initialised() const { return filter_.has_value(); }
  [[nodiscard]] std::size_t bod_attempts() const { return bod_attempts_; }
  // Every BOD attempt since the last call, for telemetry (bod/<observer>.csv).
  std::vector<bus::BodAttempt> take_bod_records() { return std::exchange(bod_records_, {}); }
  [[nodiscard]] std::size_t bod_usable() const { return bod_usable_; }

 private:
  // What a queued event is (processed in (time, kind, track) order).
  enum class EventKind : std::uint8_t {
    kGnss = 0,            // a GNSS fix
    kTrackBearing = 1,    // a bearing of a SAMUS track
    kDirectBearing = 2,   // a single detection assigned by SOD's prediction
    kRemoteBearing = 3,   // a bearing received over the ISL
  };
  struct Event {
    astro::TimeTT t;
    EventKind kind = EventKind::kGnss;
    sod::GnssMeasurement gnss;
    int track = -1;   // kTrackBearing: SAMUS track; kDirectBearing: target index; kRemoteBearing: sender index
    int segment = 1;  // kTrackBearing: the track's segment (TrackedMeasurement::segment)
    Eigen::Vector3d u_eci = Eigen::Vector3d::Zero();
    Eigen::Quaterniond q_cam_from_eci = Eigen::Quaterniond::Identity();
    double imp_sigma_rad = 0.0;
    // kRemoteBearing: the sender (index into senders_) and its position estimate at t.
    astro::Vec3 sender_r_eci_m = astro::Vec3::Zero();
    astro::Mat3 sender_P_r_m2 = astro::Mat3::Zero();
    astro::Vec3 sender_v_eci_mps = astro::Vec3::Zero();
    double correction_s = 0.0;  // local bearings: the time-tag correction in their t
    bool sender_position_valid = false;
    // kRemoteBearing: which silence of the sender's link it follows (LinkWatch) and
    // the broadcast's number after it (0: not after a silence).
    int gap = 0;
    int since_gap = 0;
    std::uint32_t seq = 0;  // kRemoteBearing: the sender's broadcast sequence number
    bool direct = false;    // kTrackBearing: the same candidate was assigned as kDirectBearing (fused once only)
  };
  struct LinkWatch {
    std::optional<astro::TimeTT> last;  // the latest broadcast received
    int gap = 0;                        // silences seen so far
    int since_gap = 0;                  // broadcasts since the latest silence (0: none yet)
    int reported_gap = 0;               // the latest silence after which fusion resumed
    int reported_since = 0;             // the earliest broadcast after it reported fused
  };
  struct Association {
    std::vector<double> d2_sum;
    // Per target, the bearings of this track it had no usable prediction
    // for (no estimate yet, or no plane prediction): such a target could own
    // the track.
    std::vector<int> unpredicted;
    int n = 0;
    int target = -1;
    astro::TimeTT first;  // the first bearing of the association under way
    astro::TimeTT last;
    int gated_in_row = 0;  // successive bearings of the bound track refused by the gate
    int segment = 0;       // the track's segment when it was bound (or joined again)
    int held = 0;          // bearings after a join across a gap still to fit the bound target alone
  };

  // A bearing of a SAMUS track kept for BOD (the latest batch_orbits orbits).
  struct TrackBearing {
    astro::TimeTT t;
    Eigen::Vector3d u_eci = Eigen::Vector3d::UnitZ();
    Eigen::Quaterniond q_cam_from_eci = Eigen::Quaterniond::Identity();
    int segment = 1;
    double sigma_rad = 0.0;  // IMP's 1-sigma of the bearing
  };
  // A BOD estimate: the target's mean ROE and covariance at t, with the
  // observer's mean elements they are relative to.
  struct BodEstimate {
    astro::TimeTT t;
    astro::QnsElements observer_mean;
    astro::Vec6 roe_mean = astro::Vec6::Zero();
    astro::Mat6 P_mean = astro::Mat6::Zero();
  };
  // The same as SOD holds a target: osculating ROE and covariance.
  struct OsculatingRoe {
    astro::Vec6 roe = astro::Vec6::Zero();
    astro::Mat6 P = astro::Mat6::Zero();  // with the camera clock's doubt (J P_clock J^T) when clock_J is set
    // A BOD estimate's sensitivity to the time tags SOD gave its batch
    // (6 x n_time_tag, empty without a time-tag state), and its covariance
    // without the clock's doubt (SodFilter::reinitialize_target).
    Eigen::MatrixXd clock_J;
    astro::Mat6 P_without_clock = astro::Mat6::Zero();
  };

  const config::ObserverUplink& up_;
  const dynamics::ForceModel& forces_;
  NavigatorOptions opt_;
  sod::SodOptions sod_opt_;
  std::vector<std::string> target_ids_;
  // Every other spacecraft of the swarm: the order of the remote clock states.
  std::vector<std::string> sender_clock_ids_;
  double time_tag_correction_s_ = 0.0;  // the uplinked one, plus what the own-clock check found
  // Each target's a-priori as mean ROE at the first initialisation (restart_estimate).
  std::vector<std::optional<BodEstimate>> apriori_mean_;
  std::optional<sod::SodFilter> filter_;
  bool reinit_pending_ = false;
  double a_observer_m_ = 6.9e6;  // for the a-priori drift; set from the first GNSS fix
  std::vector<Event> queue_;
  std::map<int, Association> tracks_;
  std::vector<std::uint32_t> local_;
  std::size_t late_ = 0;
  std::size_t blended_ = 0;
  mutable std::size_t eclipsed_skipped_ = 0;  // counted in untracked_regions (const)
  std::size_t refused_ = 0;
  std::size_t association_ = 0;
  std::size_t remote_broadcasts_ = 0;
  bool fuse_remote_ = false;             // navigation modes 3 and 4
  bool angles_only_ = false;             // navigation mode 4: no GNSS, the absolute orbit from bearings
  std::vector<std::string> senders_;
  std::map<std::string, LinkWatch> links_;
  // Remote bearings already queued, (sender, t, track label): a sender
  // repeats its recent bearings after a silence of its links (fsw::Observer).
  std::set<std::tuple<std::string, std::int64_t, std::string>> remote_seen_;
  std::size_t remote_repeated_ = 0;
  std::deque<std::pair<astro::TimeTT, Eigen::Vector3d>> direct_;
  std::uint64_t version_ = 0;  // bumped whenever queued events change filter_
  mutable std::optional<sod::SodFilter> predicted_;
  mutable astro::TimeTT predicted_t_;
  mutable std::uint64_t predicted_version_ = 0;
  mutable bool predicted_usable_ = false;  // kDirectBearing assignments of the last hours
  const dynamics::GveRk4Propagator onboard_;
  std::size_t remote_assigned_ = 0, remote_unassigned_ = 0, remote_late_ = 0;
  std::vector<std::uint32_t> remote_;
  std::vector<double> nis_sum_;      // per target: sum of bearing-update NIS
  std::vector<std::uint32_t> nis_n_;  // per target: bearing updates counted
  void record_nis(int k, const sod::UpdateSummary& s);
  std::vector<std::string> messages_;
  // BOD.
  bod::Options bod_opt_;
  std::vector<bool> has_estimate_;  // false: no a-priori and no BOD yet (mode 2); left out of everything
  std::vector<std::optional<BodEstimate>> last_bod_;
  std::map<int, std::deque<TrackBearing>> history_;
  std::optional<astro::TimeTT> next_bod_;
  std::optional<astro::TimeTT> next_aux_report_;
  // The observer's own planned maneuvers (uplink), in time order; the next
  // one not yet applied to the filter.
  std::vector<config::ObserverUplink::PlannedManeuver> planned_;
  std::size_t next_planned_ = 0;
  // Applies the planned maneuvers due before t (the filter moves to each).
  void apply_planned_maneuvers(astro::TimeTT t);
  // Hourly event with the auxiliary states' estimates (time tag, drag).
  void report_aux();
  // SOD's estimate of the camera's time-tag offset at t (0 without the state).
  [[nodiscard]] double time_tag_offset_at(astro::TimeTT t) const;
  // When a frame tagged `tag` was taken: the tag plus the uplinked
  // correction, less SOD's estimated offset. IMP's predictions
  // (predictions, assign_untracked, untracked_regions) are made there.
  [[nodiscard]] astro::TimeTT image_time(astro::TimeTT tag) const;
  // True when target k's estimate in f and every sigma point of its
  // unscented transform lie in the Earth's umbra at t (image time).
  [[nodiscard]] bool predicted_eclipsed(const sod::SodFilter& f, int k, astro::TimeTT t) const;
  // The same from [observer QNS; target ROE] and its covariance (12).
  [[nodiscard]] bool in_umbra(const Eigen::VectorXd& mean, const Eigen::MatrixXd& P, astro::TimeTT t) const;
  std::size_t bod_attempts_ = 0, bod_usable_ = 0;
  std::vector<bus::BodAttempt> bod_records_;
  // Per target: its bound track's bearings were refused by the gate and none
  // has fitted since (telemetry health 1, "suspect").
  std::vector<bool> suspect_;
  std::vector<astro::TimeTT> last_fit_t_;  // filter epoch of each target's latest accepted bearing
  // Per target: when health check 5 first flagged it (an unknown manoeuvre)
  // since its latest (re-)initialisation. The first usable BOD batch of its
  // track made only of later bearings confirms the manoeuvre and
  // re-initialises it, or refutes it (pre_flag_ below; issue 16).
  std::vector<std::optional<astro::TimeTT>> manoeuvre_flagged_;
  // Per target: SOD's estimate at that flag, before check 5's inflation, as
  // mean ROE; the first BOD batch after the flag re-initialises the target
  // only when it is farther from this than check 1's threshold (BOD
  // confirms the manoeuvre) and clears the flag when it is not.
  std::vector<std::optional<BodEstimate>> pre_flag_;
  // SOD's estimate of target k now as mean ROE (nullopt when the mean model
  // refuses its elements).
  [[nodiscard]] std::optional<BodEstimate> sod_mean_estimate(int k) const;
  // Squared Mahalanobis distance between a BOD estimate b at t (osculating)
  // and pre_flag_[k] carried to t; +inf when there is none.
  [[nodiscard]] double pre_flag_distance2(int k, const OsculatingRoe& b, astro::TimeTT t) const;
  void set_suspect(int k, bool on, const std::string& why);
  void run_bod(astro::TimeTT t_est);
  // Adds to a usable BOD estimate its sensitivity to the camera clock SOD
  // estimates and that doubt to its covariance (throws when the shifted
  // batch is not usable).
  void add_clock_doubt(OsculatingRoe& b, const std::vector<bod::Measurement>& batch,
                       const bod::ObserverPrior& prior, const bod::Options& options) const;
  // BOD's options for a batch of target k (-1: not known): its model
  // correction propagates the target as SOD does, with SOD's nominal
  // properties and its estimated differential ballistic coefficient.
  [[nodiscard]] bod::Options bod_options_for_target(int k) const;
  // A BOD estimate at t (its mean ROE carried by the J2 STM) as osculating
  // ROE relative to the observer's osculating elements observer_osc at t
  // (what SOD estimates), the covariance through the same maps.
  [[nodiscard]] static OsculatingRoe osculating_at(const BodEstimate& b, astro::TimeTT t,
                                                   const astro::QnsElements& observer_osc);
  // Health check (1): squared Mahalanobis distance between b and SOD's target k.
  [[nodiscard]] double bod_distance2(int k, const OsculatingRoe& b) const;
  // Binds SAMUS track `track` to target k at t (in the segment its latest bearing had).
  void bind_track(int track, int k, astro::TimeTT t);
  void set_target_from_bod(int k, int track, const OsculatingRoe& b, astro::TimeTT t, const std::string& why);
  // What target k restarts from at t (the observer's osculating elements
  // then): its latest BOD estimate, else the a-priori (drifted to t); false
  // when it has neither (mode 2).
  // Target k's uplinked range window (observer targets[].range_km), if any.
  [[nodiscard]] std::optional<std::array<double, 2>> range_window(int k) const;
  bool restart_estimate(int k, astro::TimeTT t, const astro::QnsElements& observer_osc, astro::Vec6& roe,
                        astro::Mat6& P) const;

  static Event bearing_event(astro::TimeTT t, EventKind kind, int track, const Eigen::Vector3d& u_eci,
                             const Eigen::Quaterniond& q_cam_from_eci, double imp_sigma_rad);
  void process(const Event& e, const imp::Samus& samus);
  // The filter predicted to t (time update from its epoch), shared by the
  // report, SAMUS predictions and single-detection assignment of one step or
  // frame; recomputed when t or the filter changes. nullptr when the time
  // update is not usable (unless even_if_unusable: then the state as far as
  // it got, as the report has always used).
  [[nodiscard]] const sod::SodFilter* predicted_to(astro::TimeTT t, bool even_if_unusable = false) const;
  // Every queued event with t <= limit, in time order.
  void process_until(astro::TimeTT limit, const imp::Samus& samus);
  // Remote bearings of one sender at one epoch: the paper's three
  // assignment conditions on the Mahalanobis distances sigma_jk, then the
  // updates.
  void process_remote(const std::vector<Event>& group);
  void initialise(const sod::GnssMeasurement& g);
  void initialise_angles_only();  // mode 4: the uplinked coarse orbit, or the own estimate after a failure
  void initialise_at(astro::TimeTT t0, const astro::QnsElements& observer, Eigen::Matrix<double, 6, 6> P_observer_qns,
                     const std::string& from);
  [[nodiscard]] astro::Roe apriori_at(int k, astro::TimeTT t, const astro::QnsElements& observer_osc) const;
  // Its covariance carried along the same drift: Phi P Phi^T, Phi the J2 STM of mean ROE.
  [[nodiscard]] astro::Mat6 apriori_covariance_at(int k, astro::TimeTT t, const astro::QnsElements& observer_osc) const;
  void check_health();
  // The own-clock check (NavigatorOptions::clock_known_s); true when it corrected the clock.
  bool check_own_clock();
  // Is target k predicted (filter f, time-updated to t) within
  // blend_separation_px of another target? count: a bearing left out for it.
  bool blended(sod::SodFilter& f, int k, astro::TimeTT t, bool count = true);
  // The filter's bearing 1-sigma: sod.bearing_sigma_arcsec, or IMP's own when 0.
  [[nodiscard]] double bearing_sigma(double imp_sigma_rad) const;
  // A track bearing against every target's prediction at its image time:
  // squared Mahalanobis distances in the tracking plane (1e6 without a
  // prediction, counted in unpredicted when given). False when SOD cannot
  // be predicted there.
  bool association_d2(sod::SodFilter& f, const imp::Samus& samus, const Event& e, std::vector<double>& d2,
                      std::vector<int>* unpredicted) const;
  // Unscented prediction of target k's tracking-plane coordinates from the
  // filter state (at the filter epoch).
  // The target's predicted tracking-plane position at the filter's epoch,
  // projected with the observer's RTN frame at the filter's epoch or, when
  // given, at plane_t (the frame's time tag SAMUS projects its candidates
  // at, when the filter was predicted to the image time as SOD knows it).
  bool predict_plane(const sod::SodFilter& f, int k, const imp::Samus& samus, imp::TargetPrediction& out,
                     std::optional<astro::TimeTT> plane_t = std::nullopt) const;
  // A target has an active bound SAMUS track (its last bearing < 30 min before t).
  [[nodiscard]] bool tracked(int k, astro::TimeTT t) const;
};

}  // namespace artms::fsw
