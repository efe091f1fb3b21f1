// The messages between the swarm's processes as plain C++ structs
// (DESIGN.md section 4; idl/artms.idl is their DDS form) and the codes they
// carry. The onboard software (common/fsw) and the truth, renderer, crosslink
// and recorder logic (common/sim) are stepped over these structs; only
// common/runtime converts them to and from DDS (runtime/wire.hpp), and the
// in-process runner hands them over directly.
//
// Bounded strings: the IDL bounds identifiers to 31 characters, reasons to
// 63 and event texts to 255; `bounded()` applies the same bound, so that a
// run folder does not depend on whether a message crossed DDS.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace artms::bus {

// IDL string bounds (characters, without the terminator).
inline constexpr std::size_t kIdChars = 31;
inline constexpr std::size_t kReasonChars = 63;
inline constexpr std::size_t kShortReasonChars = 31;
inline constexpr std::size_t kEventTextChars = 255;
inline std::string bounded(std::string s, std::size_t chars) {
  if (s.size() > chars) s.resize(chars);
  return s;
}

// Navigation telemetry: filter health (NavTelemetry::health).
enum class Health : std::uint8_t { kHealthy = 0, kReinitialising = 1, kNoSolution = 2 };
// Where an absolute orbit comes from (NavTelemetry::source, IslBroadcast::source).
// kSodAnglesOnly: SOD without GNSS (navigation mode 4, bearings only).
enum class SolutionSource : std::uint8_t { kNone = 0, kSod = 1, kGnss = 2, kGround = 3, kSodAnglesOnly = 4 };
inline constexpr std::uint8_t kMaxSolutionSource = 4;
// IMP's verdict on a frame (ImpReport::status; attitude.csv's status column).
enum class FrameStatus : std::uint8_t { kOk = 0, kNoDetections = 1, kNotIdentified = 2, kCorrupt = 3, kEnd = 4 };
// Event severity (Event::severity; events.log).
enum class Severity : std::uint8_t { kInfo = 0, kWarning = 1, kError = 2 };

inline const char* to_string(Health h) {
  switch (h) {
    case Health::kHealthy: return "healthy";
    case Health::kReinitialising: return "reinitialising";
    case Health::kNoSolution: return "no_solution";
  }
  return "unknown";
}
inline const char* to_string(SolutionSource s) {
  switch (s) {
    case SolutionSource::kNone: return "none";
    case SolutionSource::kSod: return "sod";
    case SolutionSource::kGnss: return "gnss";
    case SolutionSource::kGround: return "ground";
    case SolutionSource::kSodAnglesOnly: return "sod_angles_only";
  }
  return "unknown";
}
// The words of attitude.csv's status column.
inline const char* to_string(FrameStatus s) {
  switch (s) {
    case FrameStatus::kOk: return "ok";
    case FrameStatus::kNoDetections: return "no_detections";
    case FrameStatus::kNotIdentified: return "not_identified";
    case FrameStatus::kCorrupt: return "corrupt";
    case FrameStatus::kEnd: return "end";
  }
  return "unknown";
}
// The words of events.log.
inline const char* to_string(Severity s) {
  switch (s) {
    case Severity::kInfo: return "info";
    case Severity::kWarning: return "warning";
    case Severity::kError: return "error";
  }
  return "error";
}

// IMP measurement track ids (ImpMeasurement::track_id, measurements.csv):
// >= 0 a SAMUS track, -1 an untracked candidate, <= -2 a single detection
// SOD assigned to the target of index -2 - id in the uplinked a-priori.
inline constexpr int kUntracked = -1;
inline constexpr int single_detection_track(int target_index) { return -2 - target_index; }
inline constexpr bool is_single_detection(int track_id) { return track_id <= -2; }
inline constexpr int single_detection_target(int track_id) { return -2 - track_id; }

struct Tick {
  std::int64_t step = 0;
  std::int64_t t_tt_ns = 0;
  bool final_step = false;
};

struct TruthState {
  std::string spacecraft;
  std::int64_t t_tt_ns = 0;
  std::array<double, 3> r_eci_m{}, v_eci_mps{};
  std::array<double, 4> q_body_from_eci{};  // [w, x, y, z]
};

struct GnssFix {
  std::string spacecraft;
  std::int64_t t_tt_ns = 0;
  bool valid = false;
  std::array<double, 3> r_eci_m{}, v_eci_mps{};
  double sigma_position_m = 0.0;
  double sigma_velocity_mps = 0.0;
};

struct CameraFrame {
  std::string observer, camera;
  std::uint32_t frame_seq = 0;
  std::int64_t time_tag_tt_ns = 0;  // may carry the injected offset and drift
  std::uint16_t width = 0, height = 0;
  std::uint8_t bit_depth = 0;
  std::vector<std::uint16_t> pixels;
};

struct TargetPixel {
  std::string target;
  double x_px = 0.0, y_px = 0.0, vmag = 0.0, range_m = 0.0;
  bool visible = false;
  std::string reason;
};

struct FrameTruth {
  std::string observer;
  std::uint32_t frame_seq = 0;
  std::int64_t t_tt_ns = 0;
  std::int64_t time_tag_tt_ns = 0;
  bool dropped = false;
  std::string exclusion;  // "none", "sun exclusion", ...
  std::array<double, 4> q_cam_from_eci{};
  std::uint32_t stars_used = 0;
  std::vector<TargetPixel> targets;
};

struct BearingMeasurement {
  std::int64_t t_tt_ns = 0;
  std::string track;
  std::array<double, 3> u_eci{};
  double sigma_rad = 0.0;
};

struct ImpMeasurement {
  std::uint32_t frame_seq = 0;
  std::int64_t t_tt_ns = 0;  // the frame's time tag
  std::int32_t track_id = kUntracked;
  double x_px = 0.0, y_px = 0.0;
  std::array<double, 3> u_eci{};
  double az_rad = 0.0, el_rad = 0.0;  // eq. (2) in the camera frame
  double sigma_rad = 0.0;
};

struct ImpReport {
  std::string observer;
  std::uint32_t frame_seq = 0;
  std::int64_t t_tt_ns = 0;
  FrameStatus status = FrameStatus::kOk;
  std::array<double, 4> q_cam_from_eci{};
  std::uint32_t stars_matched = 0;
  double residual_arcsec = 0.0;
  double attitude_sigma_arcsec = 0.0;
  std::uint32_t candidates = 0, hot_pixels_removed = 0, uncatalogued_stars_removed = 0;
  std::vector<ImpMeasurement> measurements;  // released by SAMUS at this frame
};

struct IslBroadcast {
  std::string sender;
  std::int64_t t_tt_ns = 0;
  std::uint32_t broadcast_seq = 0;
  std::array<double, 3> r_eci_m{}, v_eci_mps{};
  std::array<double, 36> covariance_rv{};
  std::uint8_t source = 0;  // SolutionSource; raw, since a forged one is checked by the receiver
  bool reinitialising = false;
  std::vector<BearingMeasurement> measurements;
  std::string receiver;             // relay only
  std::int64_t t_relayed_tt_ns = 0;  // relay only: the emulator's step that relayed it
};

struct IslOutcome {
  std::string sender, receiver;
  std::uint32_t broadcast_seq = 0;
  std::int64_t t_sent_tt_ns = 0;
  std::int64_t t_tt_ns = 0;  // when the emulator decided
  bool delivered = false;
  std::string reason;
  std::uint8_t source = 0;
  std::uint32_t measurements = 0;
  double range_m = 0.0;
};

struct TargetEstimate {
  std::string target;
  std::array<double, 6> roe{};
  std::array<double, 36> covariance_roe{};
  std::uint32_t local_measurements = 0, remote_measurements = 0;
  double bearing_nis_sum = 0.0;      // sum of the NIS of every bearing update so far
  std::uint32_t bearing_updates = 0;  // how many
  // This target's estimate: healthy, or suspect (kReinitialising: its bound
  // track's bearings were refused by the gate and none has fitted since; it
  // stays so until one fits or BOD or the a-priori re-initialises it).
  Health health = Health::kHealthy;
};

struct NavTelemetry {
  std::string observer;
  std::int64_t t_tt_ns = 0;
  std::uint8_t mode = 0;
  Health health = Health::kNoSolution;
  SolutionSource source = SolutionSource::kNone;
  std::array<double, 3> r_eci_m{}, v_eci_mps{};
  std::array<double, 36> covariance_rv{};
  std::uint32_t frames_received = 0;
  std::vector<TargetEstimate> targets;
  std::uint32_t isl_sent = 0, isl_received = 0, isl_rejected = 0;
};

struct LinkState {
  std::string from_id, to_id;
  std::int64_t t_tt_ns = 0;
  bool up = false;
  std::string reason;
};

// One BOD attempt (fsw::Navigator; paper, "Batch Orbit Determination"):
// the batch, the residual curve over the dlambda samples, the chosen
// estimate (mean ROE at t_est, a*ROE meters, with its covariance), the
// verdict and what the navigator did with it.
inline constexpr std::size_t kMaxBodSamples = 256;
enum class BodVerdict : std::uint8_t {
  kUsable = 0,
  kTooFewMeasurements = 1,
  kBadInput = 2,
  kNotConverged = 3,
  kMinimumAtEdge = 4,
  kFlatResidualCurve = 5,
  kOutsideTolerances = 6,
};
inline constexpr std::uint8_t kMaxBodVerdict = 6;
// The words of bod/<observer>.csv's verdict_name column.
inline const char* to_string(BodVerdict v) {
  switch (v) {
    case BodVerdict::kUsable: return "usable";
    case BodVerdict::kTooFewMeasurements: return "too_few_measurements";
    case BodVerdict::kBadInput: return "bad_input";
    case BodVerdict::kNotConverged: return "not_converged";
    case BodVerdict::kMinimumAtEdge: return "minimum_at_edge";
    case BodVerdict::kFlatResidualCurve: return "flat_residual_curve";
    case BodVerdict::kOutsideTolerances: return "outside_tolerances";
  }
  return "unknown";
}
struct BodSample {
  double a_dlambda_m = 0.0;
  double residual_rms_rad = 0.0;
  double chi2 = 0.0;
  bool converged = false;
};
struct BodAttempt {
  std::string observer;
  std::uint32_t attempt = 0;       // 1, 2, ... per observer
  std::int64_t t_est_tt_ns = 0;    // estimation epoch
  std::int32_t track = -1;         // the SAMUS track
  std::string target;              // the target it went to ("" when none)
  BodVerdict verdict = BodVerdict::kBadInput;
  std::string why;                 // empty when usable (bounded kReasonChars... kEventTextChars)
  std::string action;              // what the navigator did (bounded kEventTextChars)
  std::uint32_t measurements = 0;
  std::uint32_t iterations = 0;
  double residual_rms_rad = 0.0;
  double correlation_inflation = 1.0;
  double model_correction_rms_rad = 0.0;  // BOD's correction for the onboard model (0: none)
  double uncorrected_range_m = 0.0;       // the range before it
  double a_observer_m = 0.0;
  double range_m = 0.0;
  double sigma_range_m = 0.0;
  std::array<double, 6> a_roe_mean_m{};      // [da, dlambda, dex, dey, dix, diy] * a
  std::array<double, 36> covariance_a_roe_m2{};  // row-major
  double mahalanobis2 = -1.0;      // health check 1 against SOD (< 0: not compared)
  std::vector<BodSample> curve;    // at most kMaxBodSamples
};

struct Event {
  std::string source;
  std::int64_t t_tt_ns = 0;
  Severity severity = Severity::kInfo;
  std::string text;
};

// Events of one component, stamped and bounded as they go on the wire.
class EventSink {
 public:
  explicit EventSink(std::string source) : source_(bounded(std::move(source), kIdChars)) {}
  void info(std::int64_t t_tt_ns, const std::string& text) { add(t_tt_ns, Severity::kInfo, text); }
  void warning(std::int64_t t_tt_ns, const std::string& text) { add(t_tt_ns, Severity::kWarning, text); }
  void error(std::int64_t t_tt_ns, const std::string& text) { add(t_tt_ns, Severity::kError, text); }
  void add(std::int64_t t_tt_ns, Severity s, const std::string& text) {
    events_.push_back({source_, t_tt_ns, s, bounded(text, kEventTextChars)});
  }
  std::vector<Event> take() { return std::exchange(events_, {}); }
  [[nodiscard]] const std::string& source() const { return source_; }

 private:
  std::string source_;
  std::vector<Event> events_;
};

}  // namespace artms::bus
