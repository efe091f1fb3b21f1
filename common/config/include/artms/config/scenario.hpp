// Scenario files (config/swarms/*.yaml): the swarm, its observers, crosslink,
// ARTMS tuning, maneuvers and injected faults. The schema is documented in
// config/swarms/SCHEMA.md; which processes exist follows from the scenario
// (see services(), below), not from code.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "artms/astro/elements.hpp"
#include "artms/astro/frames.hpp"
#include "artms/astro/time.hpp"
#include "artms/dynamics/forces.hpp"

namespace artms::config {

// One problem found in a scenario file: where, which field, what was expected.
struct Diagnostic {
  std::string file;
  int line = 0;    // 1-based; 0 when unknown
  int column = 0;  // 1-based; 0 when unknown
  std::string field;    // dotted path, e.g. "spacecraft[2].roe_m"
  std::string message;  // what is wrong and what was expected
  // "file:line:col: field: message" (":line:col" left out when line is 0,
  // "field: " when field is empty).
  [[nodiscard]] std::string format() const;
};

// Thrown by load_scenario with every problem found (not just the first).
class ScenarioError : public std::runtime_error {
 public:
  explicit ScenarioError(std::vector<Diagnostic> diagnostics);
  [[nodiscard]] const std::vector<Diagnostic>& diagnostics() const { return diagnostics_; }

 private:
  std::vector<Diagnostic> diagnostics_;
};

struct TimeWindow {
  astro::TimeTT start;
  astro::TimeTT end;  // end > start
};

// Initial orbit of a spacecraft: absolute Keplerian, absolute quasi-nonsingular
// (paper eq. 3), or ROE relative to a chief (paper eq. 4, a*droe in meters,
// a = the chief's semi-major axis), as Table 2 of the paper gives them.
// Elements are osculating at the scenario epoch.
struct InitialOrbit {
  enum class Kind { kKepler, kQns, kRelative } kind = Kind::kQns;
  astro::KeplerElements kepler;  // kKepler
  astro::QnsElements qns;        // kQns
  std::string chief;             // kRelative: id of another spacecraft
  astro::Vec6 a_droe_m = astro::Vec6::Zero();  // kRelative
  // kRelative: the ROE are osculating (default: relative to the chief's
  // osculating elements) or mean (relative to the chief's mean elements,
  // first-order J2 theory, common/dynamics/j2_mean.hpp; the deputy's
  // osculating state follows through the same map).
  bool mean_roe = false;
};

struct SpacecraftConfig {
  std::string id;  // e.g. "SV4"; [A-Za-z0-9_-]+
  InitialOrbit orbit;
  // What the world flies (truth service, renderer): spacecraft[].mass_kg ...
  dynamics::SpacecraftProperties properties;
  // The nominal values the ground uplinks for the onboard filter:
  // spacecraft[].onboard (default: SpacecraftProperties{}, whatever the truth).
  dynamics::SpacecraftProperties onboard_properties;
};

struct GnssConfig {
  bool enabled = true;
  double period_s = 60.0;
  double sigma_position_m = 3.0;     // 1-sigma per axis, white
  double sigma_velocity_mps = 0.03;  // 1-sigma per axis, white
  std::vector<TimeWindow> outages;   // no fix (valid = false) inside
};

struct CameraConfig {
  std::string model = "nst";  // camera model file stem in config/cameras/
  astro::Boresight boresight = astro::Boresight::kMinusVelocity;
  double cadence_s = 60.0;
  double pointing_error_deg = 0.0;  // 1-sigma, fixed per run
  double jitter_deg = 0.0;          // 1-sigma, per frame
  // Target photometry: nominal, or "flight-like" (targets beyond ~100 km
  // often lost in noise, as in the paper; docs/imaging_targets.md).
  bool flight_like = false;
  // The ground's time-tag correction, added onboard to every image time tag
  // (the paper's in-flight update: "user-specified time offsets for incoming
  // star tracker data"; -0.4 s on 05/08/24). 0: none.
  double time_tag_correction_s = 0.0;
  // The world's stars as the moving observer sees them: shifted by up to
  // ~26" by stellar aberration (the Earth's velocity about the Sun plus the
  // observer's orbital velocity). False only to study IMP without it.
  bool stellar_aberration = true;
};

// Ground a-priori knowledge uplinked to an observer (navigation mode 1):
// target ROE from a ground orbit determination `age_days` old, its errors
// following from that age (the SOD issue models them).
struct APrioriConfig {
  double age_days = 3.5;
};

struct ObserverConfig {
  std::string spacecraft;  // id of a spacecraft
  int mode = 1;            // navigation mode 1-4 (see SCHEMA.md); 0 = GNSS-only baseline
  CameraConfig camera;
  GnssConfig gnss;
  APrioriConfig apriori;
  // The spacecraft this observer navigates (the ground's telecommand; mode 2
  // gets no orbit for them). Empty: every other spacecraft.
  std::vector<std::string> targets;
  // Per target, an optional range window [min, max] in m for BOD's dlambda
  // samples (mode 2: how BOD tells identical unknown targets apart); {0, 0}:
  // tuning.bod.range_min_m / range_max_m.
  std::vector<std::array<double, 2>> target_ranges_m;
  // Per target id, optional: the 1-sigma of the short-periodic error the
  // onboard gravity field leaves in the target's osculating ROE, as a * ROE
  // [da, dlambda, dex, dey, dix, diy] in m (a ground budget,
  // tools/artms_swarm/relative_gravity_budget.py). The bearings cannot see
  // it, so it is not in the filter: it is added to the target's reported
  // covariance (docs/sod.md, "Unmodelled gravity in the thin directions").
  std::map<std::string, astro::Vec6> target_gravity_periodic_a_roe_m;
  // Navigation mode 4: the coarse ground orbit the observer starts from (no
  // GNSS afterwards). 1-sigma of its error, as a * (quasi-nonsingular ROE of
  // the true orbit relative to the uplinked one) [da, dlambda, dex, dey, dix,
  // diy] in m; the launcher draws the error (seeded) and uplinks the orbit with
  // this covariance. SCHEMA.md, observers[].coarse_orbit.
  astro::Vec6 coarse_orbit_sigma_a_roe_m = (astro::Vec6() << 20.0, 5000.0, 500.0, 500.0, 500.0, 500.0).finished();
  // Optional: the error itself (same units) instead of a draw, for a
  // scenario that reproduces a given degradation (the paper's 03/24/24 case).
  std::optional<astro::Vec6> coarse_orbit_error_a_roe_m;
};

struct LinkOutage {
  std::string from;  // spacecraft id or "*"
  std::string to;    // spacecraft id or "*"
  TimeWindow window;
};

struct CrosslinkConfig {
  bool enabled = true;
  double period_s = 60.0;
  double latency_s = 0.0;
  double max_range_m = 500e3;
  double loss_probability = 0.0;  // [0, 1]
  bool use_remote_gnss = false;   // paper's 02/05/24 anomaly: off by design
  std::vector<LinkOutage> outages;
};

// The paper's telecommand table, the parts later issues consume. Keys and
// defaults are in SCHEMA.md, each with the paper's value where it gives one.
struct ImpTuning {
  double detection_sigma = 5.0;      // threshold above background, in noise sigmas
  int dbscan_min_points = 3;         // n_D
  double dbscan_radius_px = 20.0;    // eps_D (SCHEMA.md: why 20)
  int dbscan_frames = 5;             // frames of unassigned candidates clustered
  // SOD-aided detection of untracked faint targets (matched-filter SNR in
  // the validity region, imp/aided_detection.hpp; not in the paper); 0: off.
  double aided_detection_snr = 5.5;
  // > 0: the aided threshold is set per search for this expected number of
  // noise peaks above it in the validity region (constant false-alarm rate,
  // imp::false_alarm_threshold_snr); 0: aided_detection_snr everywhere.
  double aided_false_alarms = 1e-4;
  // IMP aberrates the catalog by the observer's velocity (the Earth's from
  // the onboard Sun ephemeris plus its own orbit's) before solving the
  // attitude (imp::FrameProcessor::process); false: the catalog as it is.
  bool aberration_correction = true;
  // A detection's centroid 1-sigma from its source's expected signal (its
  // own shrunk towards its earlier detections', imp::SignalHistory: per SAMUS
  // track, and per target for single detections) instead of its own noisy
  // one; false: its own.
  bool signal_history = true;
  // > 1: an untracked target the aided search misses in this many
  // consecutive frames is searched for on their sum, shifted along its
  // predicted motion (imp::FrameProcessor::stacked_aided_candidate; not in
  // the paper); 0 or 1: off. At most 5 (the frames IMP keeps). Uplinks
  // written before the key read 0.
  int aided_stack_frames = 4;
};
struct BodTuning {
  bool enabled = true;               // BOD runs in modes 1-3 (paper: health check 1, re-initialisation)
  double period_s = 5400.0;          // 90 minutes (paper, "Flight Operations")
  int samples = 100;                 // along-track separation samples
  int max_iterations = 20;
  double range_min_m = 2e3;          // the dlambda samples: a|dlambda| in [range_min, range_max]
  double range_max_m = 200e3;        // (the camera's sensitivity)
  int min_measurements = 50;         // paper: batches of [50, 200] bearings
  int max_measurements = 200;
  double batch_orbits = 2.0;         // paper: over 1-2 orbits (the latest ones)
  double max_sigma_range_fraction = 0.3;  // uncertainty tolerance of a usable result
  double max_residual_arcsec = 15.0;      // post-fit RMS tolerance (a few times IMP's ~3")
  double check_chi2 = 50.0;          // health check 1: squared Mahalanobis distance (docs/bod.md: why not chi2(6) 99.9 % = 22.5)
  // Health check 1 takes a BOD estimate only when its post-fit RMS is at most
  // this times the RMS it should have (IMP's RMS 1-sigma of the batch's
  // bearings and BOD's own expected misfit of 2", in quadrature): beyond,
  // BOD's mean J2 model misses the target's motion (unmodelled drag, a
  // manoeuvre inside the batch) and its estimate is biased beyond its
  // covariance (docs/bod.md).
  double max_fit_ratio = 1.5;
  // After health check 5 flags a target, its first BOD batch made only of
  // later bearings re-initialises it when it confirms the manoeuvre: farther
  // than check_chi2 from SOD's estimate before the flag (docs/bod.md).
  bool reinit_after_check5 = true;
  // BOD corrects its mean J2 theory for what it misses of the onboard
  // numerical model (gravity beyond J2, drag, Sun, Moon) along the batch and
  // solves again (bod::Options::onboard_forces, docs/bod.md).
  bool model_correction = true;
};
struct SodTuning {
  double period_s = 60.0;
  double bearing_sigma_arcsec = 40.0;  // paper: 40" (20" was not robust)
  double eps_assign = 3.0;
  double eps_ambig = 6.0;
  int max_steps_without_update = 120;
  int max_large_residuals = 10;
  double underweighting = 0.5;        // beta of measurement underweighting (docs/sod.md)
  // > 0: underweight only while trace(P_zz - P_zx P^-1 P_xz) > this x trace R
  // too (a bearing nonlinear over the prior), unless the target's prior is a
  // guess (sod::SodOptions::bearing_underweighting_nonlinearity); 0: while
  // trace P_zz > trace R.
  double underweighting_nonlinearity = 0.0;
  bool adaptive_process_noise = true;  // paper: adaptive process noise estimation
  bool adaptive_targets = true;        // false: only the observer's own rates adapt (docs/sod.md)
  // Which entries adapt, and whether the recursion runs on the clamped rate
  // (sod::AdaptiveNoiseOptions, docs/sod.md "Adaptive process noise").
  enum class AdaptiveForm { kDiagonal, kBlock };
  enum class AdaptiveAverage { kClamped, kUnclamped };
  AdaptiveForm adaptive_form = AdaptiveForm::kDiagonal;
  AdaptiveAverage adaptive_average = AdaptiveAverage::kClamped;
  // The adaptation's time constant, s (sod::AdaptiveNoiseOptions::time_constant_s),
  // in (0, kMaxAdaptiveTimeConstantS].
  static constexpr double kMaxAdaptiveTimeConstantS = 30.0 * 86400.0;
  double adaptive_time_constant_s = 1170.0;
  double process_noise_scale = 1.0;   // times the nominal target process noise
  // The onboard density's expected relative error along the orbit: with the
  // ballistic states on, the differential drag it leaves unmodelled is the
  // floor of each target's adaptive process noise (0: off; docs/sod.md).
  double drag_density_error = 0.0;
  // Health check 5 (docs/sod.md): mean NIS of a target's last nis_window
  // bearings against the chi2(2 W)/W quantile at 1 - nis_false_alarm.
  int nis_window = 20;                // 0: off
  double nis_false_alarm = 1e-4;
  // Auxiliary states (paper, "System State"): the camera's time-tag offset
  // (and drift), and each target's differential ballistic coefficient.
  enum class TimeTagEstimation { kNone, kOffset, kOffsetAndDrift };
  TimeTagEstimation time_tag = TimeTagEstimation::kNone;
  double time_tag_sigma_s = 1.0;          // initial 1-sigma of the offset
  double time_tag_drift_sigma_ppm = 100.0;  // initial 1-sigma of the drift
  // One time-tag offset per other spacecraft of the swarm, estimated from the
  // bearings it broadcasts, with initial 1-sigma time_tag_senders_sigma_s.
  bool time_tag_senders = false;
  double time_tag_senders_sigma_s = 1.0;
  bool estimate_ballistic = false;
  // Initial 1-sigma of dB over the nominal Cd A/m: the effective dB is the
  // true one times the density's error, and Harris-Priester's mean table is
  // 2-4 x too thin at high solar activity (docs/sod.md).
  double ballistic_sigma_fraction = 2.0;
  // Its constant random walk per day over the nominal Cd A/m (docs/sod.md,
  // "The ballistic walk from the density's budget"). Unset: sigma_fraction.
  std::optional<double> ballistic_walk_fraction_per_day;
  double ballistic_walk() const { return ballistic_walk_fraction_per_day.value_or(ballistic_sigma_fraction); }
  // The density's relative change from day to day: dB walks by this x its
  // estimated |dB| per day on top of the walk above (0: off).
  double ballistic_density_change_per_day = 0.0;
  // The onboard model's unmodelled acceleration on the observer's own orbit
  // (1-sigma per RTN axis, m/s^2; correlated over one orbit): the observer's
  // process noise where it exceeds the built-in one (sod::
  // observer_process_noise_from_acceleration). 0: the built-in only (GNSS
  // corrects the orbit); mode 4 needs the budget (docs/sod.md).
  double observer_acceleration_sigma_mps2 = 0.0;
  // A remote observer's bearing of another target (a line of sight between
  // two bodies other than this observer): kConsiderObserver updates the
  // relative orbits only and keeps the observer's own orbit as a consider
  // parameter (sod::SodOptions::target_to_target_consider_observer,
  // docs/sod.md); kUpdateObserver updates every state.
  enum class TargetLines { kConsiderObserver, kUpdateObserver };
  TargetLines target_lines = TargetLines::kConsiderObserver;
};
struct ArtmsTuning {
  ImpTuning imp;
  BodTuning bod;
  SodTuning sod;
};

struct ManeuverConfig {
  std::string spacecraft;
  astro::TimeTT epoch;
  astro::Vec3 dv_rtn_mps = astro::Vec3::Zero();
  // Planned by the ground: uplinked to the spacecraft's own observer, whose
  // SOD applies it in its time update; the truth executes it with a
  // magnitude error of 1-sigma execution_sigma_fraction and a pointing error
  // of the same size in radians (drawn with the run's seed).
  bool planned = false;
  double execution_sigma_fraction = 0.0;
};

// Injected faults per observer (empty observer = all observers).
struct FaultConfig {
  std::string observer;
  double frame_dropout_probability = 0.0;  // [0, 1)
  double time_tag_offset_s = 0.0;
  double time_tag_drift_ppm = 0.0;
  // The clock's residual after the ground's correction: per seed, the
  // offset and the drift each get a normal draw of these 1-sigmas
  // (`time_tag_offset_sigma_s`, `time_tag_drift_sigma_ppm`; 0: none). The
  // drawn values are kept apart from the file's, and the camera's tags err
  // by the sums (time_tag_offset_total_s, time_tag_drift_total_ppm).
  double time_tag_offset_sigma_s = 0.0;
  double time_tag_drift_sigma_ppm = 0.0;
  double time_tag_offset_drawn_s = 0.0;
  double time_tag_drift_drawn_ppm = 0.0;
  [[nodiscard]] double time_tag_offset_total_s() const { return time_tag_offset_s + time_tag_offset_drawn_s; }
  [[nodiscard]] double time_tag_drift_total_ppm() const { return time_tag_drift_ppm + time_tag_drift_drawn_ppm; }
};

struct Scenario {
  std::string name;         // e.g. "starling-pse"
  std::string description;
  std::string source_path;  // file it was loaded from
  astro::TimeTT epoch;      // the run's epoch: epoch_nominal + epoch_offset_s
  double duration_s = 0.0;
  double step_s = 60.0;     // lock-step period of the clock
  std::uint64_t seed = 1;
  // `epoch_window`: the run's epoch is drawn from the seed in
  // [epoch_nominal, epoch_nominal + epoch_window_s), in whole seconds, and
  // every instant the file gives (maneuvers, outages, space weather days)
  // moves with it. The orbits stay where they are in inertial space and the
  // Sun moves by at most ~1 deg a day, but the Earth turns under them: each
  // seed of a campaign flies over its own part of the geopotential the
  // onboard model truncates (docs/sod.md, "One world or many"). 0: the
  // epoch as given (epoch_offset_s = 0).
  astro::TimeTT epoch_nominal;
  double epoch_window_s = 0.0;
  double epoch_offset_s = 0.0;
  static constexpr double kMaxEpochWindowS = 30.0 * 86400.0;
  // `phase_window_deg`: the orbit phase drawn from the seed, an angle in
  // [0, phase_window_deg) added to the mean argument of latitude (the mean
  // anomaly of Keplerian elements) of every spacecraft whose orbit the file
  // gives in absolute elements; relative orbits follow their chiefs, so the
  // formation is the same. Each seed then starts at its own point of the
  // orbit: the latitudes it flies at a given time since the epoch (the zonal
  // gravity the onboard model truncates), the star fields behind its
  // targets and the Sun's phase differ (docs/sod.md, "One world or many").
  // 0: the orbits as given.
  double phase_window_deg = 0.0;
  double phase_offset_deg = 0.0;
  // The world's forces (truth service, renderer) and the onboard model the
  // uplink carries (SOD's propagator). No block, or a single `force_model`
  // block, means both (the paper's onboard model by default);
  // `force_model: {truth: ..., onboard: ...}` sets them apart, keys left out
  // on the truth side defaulting to ForceModelOptions::flight_like_truth(),
  // on the onboard side to the paper's. Space weather counts its days from
  // the epoch and draws from the seed.
  dynamics::ForceModelOptions force_model;
  dynamics::ForceModelOptions onboard_force_model;
  // Same forces on both sides (the atmosphere's parameters only where drag is on).
  [[nodiscard]] bool force_models_agree() const;
  std::vector<SpacecraftConfig> spacecraft;
  std::vector<ObserverConfig> observers;
  CrosslinkConfig crosslink;
  ArtmsTuning tuning;
  std::vector<ManeuverConfig> maneuvers;
  std::vector<FaultConfig> faults;

  [[nodiscard]] const SpacecraftConfig& spacecraft_by_id(const std::string& id) const;
  // Initial ECI state of every spacecraft at the epoch (relative orbits
  // resolved through their chiefs with the exact inverse of eq. 4).
  [[nodiscard]] astro::StateVector initial_state_eci(const std::string& id) const;
  // Orbit period of the first observer's spacecraft (for --orbits N).
  [[nodiscard]] double reference_period_s() const;
};

// Loads and validates a scenario. Every problem is collected and thrown
// together as a ScenarioError (syntax errors, wrong types, missing required
// fields, unknown keys, out-of-range values, unknown or duplicate ids).
Scenario load_scenario(const std::string& path);
// Sets the run's seed and what is drawn from it when a scenario is loaded:
// the space weather's day-to-day variation, the epoch within epoch_window_s,
// the orbit phase within phase_window_deg and the faults' clock residuals. Every process applies the launcher's --seed through it.
void set_seed(Scenario& s, std::uint64_t seed);
// Sets epoch_window_s and draws the epoch again; std::invalid_argument
// outside [0, Scenario::kMaxEpochWindowS].
void set_epoch_window(Scenario& s, double window_s);
// Sets phase_window_deg and draws the orbit phase again; std::invalid_argument
// outside [0, 360].
void set_phase_window(Scenario& s, double window_deg);
// The delta-v the truth executes for s.maneuvers[index]: the planned one
// with its execution error (ManeuverConfig::execution_sigma_fraction) drawn
// from the scenario seed; the commanded one for an unplanned maneuver.
astro::Vec3 executed_maneuver_dv(const Scenario& s, std::size_t index);
// The same checks, returning the diagnostics instead of throwing (empty =
// valid). For `artms-swarm validate`.
std::vector<Diagnostic> validate_scenario_file(const std::string& path);

// The processes a scenario runs, in start order, as the launcher and the
// truth service (lock-step registration) both need them:
// "truth", "camera-renderer", "crosslink-emulator", "observer-<id>"..., "recorder".
std::vector<std::string> services(const Scenario& s);

}  // namespace artms::config
