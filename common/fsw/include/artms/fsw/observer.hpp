// The onboard software of one observing spacecraft (paper, "ARTMS"): IMP
// (frame processing, SAMUS tracking, SOD-aided detection) -> SOD (Navigator),
// its GNSS fallback and the inter-satellite link, as one plain object built
// from what the ground uplinked and stepped in lock step over plain messages
// (bus/messages.hpp). No DDS and no file I/O inside: services/observer wires
// it to DDS, artms-swarm --in-process steps it directly, tests step it alone.
//
// Lock-step contract (DESIGN.md section 3), which makes the outputs
// independent of when within a step an input arrived:
// - GNSS fixes stamped <= t are used at the tick of time t;
// - a camera frame rendered at t_f = epoch + frame_seq * cadence is held and
//   processed at the first tick after t_f;
// - a relayed ISL broadcast is consumed at the first tick after the step that
//   relayed it (t_relayed < t), in (relay time, sender, sequence) order;
// - at the final tick (which only closes the run) nothing is processed.
#pragma once

#include <Eigen/Geometry>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "artms/bus/messages.hpp"
#include "artms/config/uplink.hpp"
#include "artms/dynamics/forces.hpp"
#include "artms/dynamics/gve.hpp"
#include "artms/fsw/navigator.hpp"
#include "artms/imp/aided_detection.hpp"
#include "artms/imp/frame_processor.hpp"
#include "artms/imp/samus.hpp"

namespace artms::fsw {

// Everything the observer is built from: the uplink, the onboard star
// catalog it names, and the onboard force model (the observer's own, never
// the truth's). load_observer_setup reads them from files.
struct ObserverSetup {
  config::ObserverUplink uplink;
  std::vector<imp::CatalogStar> star_catalog;  // the one uplink.star_catalog_file names (IMP off when none is)
  std::shared_ptr<const dynamics::ForceModel> forces;
};
// Reads the uplink (JSON), the star catalog it names (beside it) and the
// force model's data files from data_dir. Throws naming the file and line.
ObserverSetup load_observer_setup(const std::string& uplink_path, const std::string& data_dir);
// The uplinked onboard star catalog: catalog_id,ux_eci,uy_eci,uz_eci[,vmag].
std::vector<imp::CatalogStar> read_star_catalog(const std::string& path);
// The onboard identification catalog: the file's stars down to this visual
// magnitude (the uplinked file holds fainter ones for the blend check).
inline constexpr double kStarIdVmagLimit = 6.5;

// IMP exactly as the observer builds it from the uplinked calibration and
// telecommands (artms-imp and artms-sod-replay use the same functions).
imp::Intrinsics intrinsics_from(const config::CameraCalibration& c);
imp::FrameProcessorOptions frame_processor_options(const config::CameraCalibration& c,
                                                   const config::ImpTuning& imp_tuning);
imp::SamusOptions samus_options(const config::CameraCalibration& c, const config::ImpTuning& imp_tuning);
imp::AidedDetectionOptions aided_detection_options(const config::CameraCalibration& c,
                                                   const config::ImpTuning& imp_tuning);

// What reached the observer since its previous step.
struct ObserverInputs {
  std::vector<bus::GnssFix> gnss;         // any spacecraft's; the observer keeps its own
  std::vector<bus::CameraFrame> frames;   // this observer's
  std::vector<bus::IslBroadcast> relays;  // relayed to this observer
};
// What it wrote during the step, in the order written.
struct ObserverOutputs {
  std::vector<bus::ImpReport> imp;
  std::optional<bus::NavTelemetry> nav;
  std::optional<bus::IslBroadcast> isl;
  std::vector<bus::BodAttempt> bod;  // BOD attempts of this step (telemetry)
  std::vector<bus::Event> events;
};

class Observer {
 public:
  // `source` names the event source (the service name, "observer-<id>").
  Observer(ObserverSetup setup, std::string source);
  Observer(const Observer&) = delete;
  Observer& operator=(const Observer&) = delete;

  ObserverOutputs step(const bus::Tick& tick, ObserverInputs in);

  [[nodiscard]] const std::string& id() const { return me_; }
  [[nodiscard]] const config::ObserverUplink& uplink() const { return setup_.uplink; }
  [[nodiscard]] bool imp_on() const { return processor_.has_value(); }
  [[nodiscard]] const Navigator* navigator() const { return navigator_ ? &*navigator_ : nullptr; }
  // One line for the process log at the end of the run.
  [[nodiscard]] std::string isl_summary() const;
  // Counters (telemetry and tests).
  struct Counters {
    std::uint32_t frames_received = 0;
    std::size_t frames_rejected = 0;
    std::size_t gnss_rejected = 0;
    std::size_t measurements_released = 0;
    std::uint32_t aided_detections = 0;
    std::uint32_t aided_stacked = 0;  // of them, found on stacked frames (tuning.imp.aided_stack_frames)
    std::uint32_t direct_refused_star = 0;
    std::uint32_t direct_refused_stacked_star = 0;  // a source at the direction in the stack of other frames
    std::uint32_t direct_blended_stacked = 0;       // a neighbour within the blend radius in that stack
    std::uint32_t direct_refused_unverified = 0;
    std::uint32_t isl_sent = 0, isl_received = 0, isl_rejected = 0;
  };
  [[nodiscard]] const Counters& counters() const { return n_; }

 private:
  struct Fix {
    astro::TimeTT t;
    astro::StateVector x;
    double sigma_r = 0.0, sigma_v = 0.0;
  };
  static constexpr int kFaintStarFramesBefore = 4;  // frames IMP keeps for the faint-star check
  // The stacked check of a single detection (FrameProcessor::stacked_sky,
  // over the next frame and the kept ones): a source at its direction with
  // stacked nu >= kStackedStarSnr (noise alone: 0.13 %) is a faint star; a
  // neighbour within the blend radius above the annulus threshold for
  // kStackedNeighbourFalseAlarms makes it a blend (blend_sigma_px added).
  static constexpr double kStackedStarSnr = 3.0;
  static constexpr double kStackedNeighbourFalseAlarms = 0.01;
  struct PendingDirect {
    std::uint32_t frame_seq;
    std::int64_t t_ns;
    int target;
    imp::Candidate c;
    Eigen::Quaterniond q_cam_from_eci;
    double region_sigma_rad = 0.0;  // its validity region's RSS 1-sigma
    bool checked_before = false;    // a frame before saw no source at its direction
  };
  struct IslIn {
    std::int64_t t_relayed_ns = 0;
    std::string sender;
    std::uint32_t seq = 0;
    RemoteBroadcast rb;
    std::string why;  // non-empty: rejected
  };

  void take_gnss(const std::vector<bus::GnssFix>& fixes, astro::TimeTT t);
  void take_relays(std::vector<bus::IslBroadcast> relays, astro::TimeTT t);
  void handle_frame(const bus::CameraFrame& f, astro::TimeTT t, ObserverOutputs& out);
  void flush_imp(astro::TimeTT t, ObserverOutputs& out);
  // A pending single detection no frame before nor the next could check:
  // usable only from a narrow validity region; counts the refusal otherwise.
  bool unverified_direct_usable(const PendingDirect& p);
  // A detection's 1-sigma from its source's expected signal (h: its track's
  // or its target's history; tuning.imp.signal_history), then its signal
  // added to h. Aided and saturated detections keep theirs.
  void expected_signal_sigma(imp::SignalHistory& h, imp::Candidate& c, std::int64_t t_ns);
  [[nodiscard]] bus::NavTelemetry navigation(astro::TimeTT t) const;
  void broadcast(astro::TimeTT t, const bus::NavTelemetry& nav, ObserverOutputs& out);
  // A relayed broadcast checked field by field; "" when valid.
  std::string check_relay(const bus::IslBroadcast& b, RemoteBroadcast& rb) const;
  void keep_for_isl(std::int64_t t_ns, int track, const Eigen::Vector3d& u_eci, double sigma_rad);
  void report_measurement(std::vector<bus::ImpMeasurement>& out, std::uint32_t frame_seq, std::int64_t t_ns,
                          int track, const imp::Candidate& c);
  void drain_navigator(std::int64_t t_ns);

  ObserverSetup setup_;
  const config::ObserverUplink& up_;
  std::string me_;
  bus::EventSink events_;
  dynamics::GveRk4Propagator onboard_;
  // IMP (paper, "Image Processing"): the uplinked sensor calibration and
  // star catalog, SAMUS tuned by the uplinked telecommands.
  imp::Intrinsics K_;
  std::optional<imp::StarIdCatalog> catalog_;
  std::optional<imp::FrameProcessor> processor_;
  std::optional<imp::Samus> samus_;
  imp::AidedDetectionOptions aided_options_;
  std::vector<std::uint16_t> decoded_;  // frame pixels in DN (camera calibration dn_shift_bits undone)
  std::map<int, imp::ForcedPhotometry> forced_;  // per target index: forced photometry at its prediction
  // Per target index: its predicted pixels in the latest frames whose aided
  // search found nothing there ("none"), most recent first, for the stacked
  // aided search (FrameProcessor::stacked_aided_candidate).
  std::map<int, std::vector<imp::FrameProcessor::StackedPrediction>> unseen_;
  // Per target index: its bearing updates when its stack began
  // (Navigator::target_bearing_updates): the stacked frames' predictions
  // must come from one estimate, or the offset they share is not the last
  // frame's (an earlier prediction's error, larger, pulls the bearing
  // towards that earlier estimate).
  std::map<int, std::uint32_t> unseen_updates_;
  // The stacked frames span at most this long (the prediction's error taken
  // as the same over them).
  static constexpr double kMaxStackSpanS = 600.0;
  std::map<int, imp::SignalHistory> track_signal_;   // per SAMUS track id: its released detections' signals
  std::map<int, imp::SignalHistory> target_signal_;  // per target index: its single detections' signals
  std::optional<Navigator> navigator_;
  int n_scan_;

  std::deque<std::int64_t> frame_times_ns_;                   // time tags of frames given to SAMUS
  std::map<std::uint32_t, Eigen::Quaterniond> frame_attitude_;  // recent frames' q_cam_from_eci
  std::deque<bus::CameraFrame> held_frames_;
  std::vector<PendingDirect> pending_direct_;
  std::optional<Fix> last_fix_;
  std::optional<astro::TimeTT> gnss_outage_since_;  // the first invalid fix of the outage under way
  bool announced_ = false;
  bool samus_flushed_ = false;

  // ISL: bearings decided since the last broadcast, the repeat window.
  std::vector<bus::BearingMeasurement> isl_bearings_;
  std::optional<astro::TimeTT> last_broadcast_;
  std::map<std::string, std::uint32_t> isl_received_from_;
  std::map<std::string, astro::TimeTT> isl_last_heard_;  // sender -> its latest broadcast received
  std::deque<bus::BearingMeasurement> isl_recent_;       // broadcast within the repeat window
  bool isl_repeat_pending_ = false;
  double isl_repeat_window_s_;
  std::vector<IslIn> isl_in_;  // taken, waiting for a later step

  Counters n_;
};

}  // namespace artms::fsw
