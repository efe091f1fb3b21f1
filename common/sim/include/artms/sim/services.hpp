// The swarm's ground-side logic as plain objects stepped in lock step over
// plain messages (bus/messages.hpp), with no DDS inside: the truth world
// (clock master), the camera renderer, the crosslink emulator and the
// recorder. services/*/main.cpp wire them to DDS; artms-swarm --in-process
// steps the same objects in one process (DESIGN.md section 2). Only the
// recorder writes files (the run folder is its output).
//
// Lock-step contract (DESIGN.md section 3): at tick k the truth states and
// GNSS fixes of t_k are known to everybody; anything else written at step k
// is used at step k + 1 at the earliest. Each object below is written so that
// its outputs do not depend on whether an input written at step k arrived
// during step k or at step k + 1.
#pragma once

#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "artms/bus/messages.hpp"
#include "artms/config/scenario.hpp"
#include "artms/dynamics/forces.hpp"
#include "artms/io/oem.hpp"
#include "artms/render/frame_setup.hpp"
#include "artms/truth_propagator/cowell.hpp"

namespace artms::sim {

// Truth: every spacecraft integrated with the CVODE truth propagator and the
// scenario's maneuvers; truth states (with the body attitude) and noisy GNSS
// fixes at each navigation step.
class Truth {
 public:
  Truth(const config::Scenario& sc, std::shared_ptr<const dynamics::ForceModel> forces, std::string source);
  // Navigation steps 0..steps(); the tick steps() + 1 only closes the run.
  [[nodiscard]] std::int64_t steps() const { return steps_; }
  [[nodiscard]] bus::Tick tick(std::int64_t k) const;
  // The event that opens the run (stamped at the epoch).
  [[nodiscard]] bus::Event started() const;
  struct StepOutput {
    std::vector<bus::TruthState> states;
    std::vector<bus::GnssFix> gnss;
  };
  // States and fixes of navigation step k (k <= steps()).
  StepOutput step(std::int64_t k);

 private:
  struct GnssChannel {
    std::string spacecraft;
    config::GnssConfig cfg;
    std::mt19937_64 rng;
  };
  const config::Scenario& sc_;
  std::shared_ptr<const dynamics::ForceModel> forces_;
  std::string source_;
  std::vector<std::pair<std::string, truth::CowellPropagator>> props_;
  std::map<std::string, astro::Boresight> boresight_;
  std::vector<GnssChannel> gnss_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  std::int64_t steps_;
};

// Camera renderer: every observer's frames at its cadence, from truth.
class CameraRenderer {
 public:
  CameraRenderer(const config::Scenario& sc, std::string source);
  [[nodiscard]] std::vector<std::string> observers() const;
  struct StepOutput {
    std::vector<bus::FrameTruth> truths;  // evaluation only
    std::vector<bus::CameraFrame> frames;
    std::vector<bus::Event> events;
  };
  // The truth states of this tick (others are ignored).
  StepOutput step(const bus::Tick& tick, const std::vector<bus::TruthState>& states);
  // One line per observer for the process log.
  [[nodiscard]] std::vector<std::string> summary() const;

 private:
  struct Channel {
    std::string id;
    std::unique_ptr<render::FrameSetup> setup;
    std::size_t rendered = 0, dropped = 0, excluded = 0;
  };
  const config::Scenario& sc_;
  bus::EventSink events_;
  std::vector<Channel> channels_;
};

// Crosslink emulator: link states (disabled, outage windows, range from
// truth), random loss per (broadcast, link), latency; one outcome per
// (broadcast, link). Two phases per step: links() decides the link states
// (the DDS service moves its relay writers between partitions), relay()
// then decides every relay that is due.
class Crosslink {
 public:
  Crosslink(const config::Scenario& sc, std::string source);
  struct Link {
    std::string from, to;
    bool up_at_epoch = false;
  };
  [[nodiscard]] const std::vector<Link>& links() const { return links_; }
  struct LinkChange {
    std::size_t link = 0;
    bool up = false;
  };
  struct LinkOutput {
    std::vector<LinkChange> changes;  // links whose state changed (apply before relay())
    std::vector<bus::LinkState> states;
    std::vector<bus::Event> events;
  };
  // Broadcasts received (any sent before this tick; later ones wait) and the
  // link states at this tick.
  LinkOutput links(const bus::Tick& tick, const std::vector<bus::TruthState>& states,
                   std::vector<bus::IslBroadcast> broadcasts);
  struct Relay {
    std::size_t link = 0;
    bool down = false;  // written into the down partition: lost in transport
    bus::IslBroadcast msg;
  };
  struct RelayOutput {
    std::vector<Relay> relays;
    std::vector<bus::IslOutcome> outcomes;
    std::vector<bus::Event> events;
  };
  // Relays due now: released (t_sent + latency reached, and sent at an
  // earlier step), in (release, sent, link, arrival) order; at the last
  // navigation step every remaining one is decided. receiver_present(link):
  // is the receiving process there (false: "no_receiver").
  RelayOutput relay(const bus::Tick& tick, const std::function<bool(std::size_t)>& receiver_present);
  [[nodiscard]] std::string summary() const;

 private:
  struct Pending {
    std::int64_t release_ns;
    std::size_t order;
    std::size_t link;
    std::shared_ptr<const bus::IslBroadcast> msg;
  };
  const config::Scenario& sc_;
  bus::EventSink events_;
  std::vector<Link> links_;
  std::vector<std::mt19937_64> rng_;
  std::vector<std::string> down_reason_;
  std::vector<bool> announced_;
  std::vector<double> range_;
  std::map<std::string, Eigen::Vector3d> pos_;
  std::vector<Pending> pending_;
  std::size_t arrivals_ = 0;
  std::int64_t latency_ns_;
  astro::TimeTT t_end_;
  std::size_t delivered_ = 0, dropped_ = 0;
};

// Recorder: the run folder (DESIGN.md section 8): truth.oem, nav/, gnss.csv,
// isl.csv, links.csv, events.log, frames.csv, imp/<observer>/, bod/ (the BOD
// attempts of every observer in navigation mode 1, 2 or 3; the files exist,
// header only, when no attempt was made). Samples are buffered and written
// in (time, source, arrival) order once every sample stamped before a time
// is known (flush). Malformed samples (unknown observer, unknown code,
// non-finite numbers where numbers are required) are counted in rejected().
class Recorder {
 public:
  Recorder(const config::Scenario& sc, const std::string& out_dir);
  ~Recorder();
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;
  void add(const bus::TruthState& m);
  void add(const bus::GnssFix& m);
  void add(const bus::NavTelemetry& m);
  void add(const bus::Event& m);
  void add(const bus::LinkState& m);
  void add(const bus::FrameTruth& m);
  void add(const bus::ImpReport& m);
  void add(const bus::IslOutcome& m);
  // Stamped with its estimation epoch t_est (behind the clock): written at
  // the first flush after it arrived, the same in both run modes.
  void add(const bus::BodAttempt& m);
  // Writes everything stamped before t_limit (IMP measurements two hours
  // behind: SAMUS decides them late); everything with kAll.
  static constexpr std::int64_t kAll = std::numeric_limits<std::int64_t>::max();
  void flush(std::int64_t t_limit);
  // At a tick: flush before its time (everything at the final tick), and at
  // the final tick write truth.oem.
  void on_tick(const bus::Tick& tick);
  // Flushes everything and writes truth.oem (a run that stopped early keeps
  // what was recorded).
  void finish();
  [[nodiscard]] std::size_t rejected() const { return rejected_; }

 private:
  class Sink;
  const config::Scenario& sc_;
  std::map<std::string, std::unique_ptr<Sink>> nav_, imp_attitude_, imp_meas_, bod_, bod_curves_;
  std::unique_ptr<Sink> targets_, gnss_, isl_, links_, events_, frames_;
  io::OemStreamWriter truth_;
  std::size_t rejected_ = 0;
  bool finished_ = false;
};

}  // namespace artms::sim
