// What every swarm process shares: topic names and QoS (DESIGN.md section 4),
// the expected topology of a scenario (who reads what, so that start-up waits
// for every match before step 0), and the lock-step protocol (section 3).
#pragma once

#include <atomic>
#include <functional>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "artms.h"
#include "artms/bus/messages.hpp"
#include "artms/config/links.hpp"
#include "artms/config/scenario.hpp"
#include "artms/dds/dds.hpp"

namespace artms::runtime {

// Topic names and QoS. Reliable everywhere; the clock and step-done topics
// are transient-local (a late reader still sees the current tick / "ready").
struct TopicSet {
  explicit TopicSet(const dds::Participant& p);
  dds::Topic clock_tick, step_done, truth_state, gnss_fix, camera_frame, frame_truth,
      isl_broadcast, nav_telemetry, link_state, event, imp_report, isl_relay, isl_outcome, bod_attempt;
};
dds::QosProfile clock_qos();      // reliable, transient-local, keep last 1
dds::QosProfile step_done_qos();  // reliable, transient-local, keep last 1 per service
dds::QosProfile data_qos();       // reliable, volatile, keep all
// Camera frames: reliable, keep last 4, in the partition "frames-<observer>"
// so that each observer receives only its own frames.
dds::QosProfile frame_qos(const std::string& observer);
// Inter-satellite link (docs/runtime.md, "Crosslink"). Observers write their
// broadcasts in partition "isl-tx" (read by the crosslink emulator only); the
// emulator relays each to each receiver through one writer per directed
// link, in partition "isl-<from>-<to>" while the link is up and "isl-down"
// while it is down (no reader is ever in "isl-down": the match disappears);
// an observer reads the relay topic in "isl-*-<me>". Relay writers carry a
// lifespan (stale messages expire).
dds::QosProfile isl_tx_qos();
dds::QosProfile isl_relay_writer_qos(const std::string& from, const std::string& to, bool up, double lifespan_s);
dds::QosProfile isl_relay_reader_qos(const std::string& me);
// Link states: config/links.hpp.

// Number of readers each writer of a service must see before the run starts.
// Derived from the scenario (services(), observers, GNSS flags).
struct Topology {
  std::vector<std::string> services;            // lock-step participants (truth first)
  std::map<std::string, int> readers_of_topic;  // topic name -> number of reader processes
  // ISL relay writers of the crosslink emulator, "FROM->TO" -> readers it
  // must match before step 0: 1 if the link is up at the epoch (from the
  // initial states), 0 if it starts down.
  std::map<std::string, int> isl_relay_readers;
};
Topology topology(const config::Scenario& s);

// Process-wide stop flag set by SIGINT/SIGTERM (install_signal_handlers).
extern std::atomic<bool> g_stop_requested;
void install_signal_handlers();

// The lock-step client side (every service but truth).
class LockStepClient {
 public:
  LockStepClient(const dds::Participant& p, const TopicSet& topics, std::string service_name,
                 double step_timeout_s);
  // Waits until `writers` have their expected matches (and the clock reader
  // has matched truth), then announces ready (StepDone step -1). Throws
  // std::runtime_error naming what did not match within the timeout.
  void announce_ready(const dds::Participant& p, std::vector<dds::MatchExpectation> expected,
                      double timeout_s);
  // Next tick, or nullopt if a stop was requested or no tick came within the
  // step timeout (then timed_out() says which).
  std::optional<artms_msg_ClockTick> wait_tick();
  [[nodiscard]] bool timed_out() const { return timed_out_; }
  // Reports that step `step` is finished (after the caller waited for acks).
  void done(std::int64_t step, int status = 0);
  const std::string& name() const { return name_; }

 private:
  std::string name_;
  double step_timeout_s_;
  dds::Reader<artms_msg_ClockTick> tick_reader_;
  dds::Writer<artms_msg_StepDone> done_writer_;
  dds::WaitSet waitset_;
  std::int64_t last_step_ = -1;
  bool timed_out_ = false;
};

// Writes an event on the events topic and to stderr.
class EventLog {
 public:
  EventLog(const dds::Participant& p, const TopicSet& topics, std::string source);
  void info(std::int64_t t_tt_ns, const std::string& text) { emit(t_tt_ns, 0, text); }
  void warning(std::int64_t t_tt_ns, const std::string& text) { emit(t_tt_ns, 1, text); }
  void error(std::int64_t t_tt_ns, const std::string& text) { emit(t_tt_ns, 2, text); }
  // Events a library object produced (bus::EventSink), written and echoed.
  void publish(const std::vector<bus::Event>& events);
  dds::Writer<artms_msg_Event>& writer() { return writer_; }

 private:
  void emit(std::int64_t t, int severity, const std::string& text);
  std::string source_;
  dds::Writer<artms_msg_Event> writer_;
};

// Options every service binary takes (the launcher passes them).
struct ServiceOptions {
  std::string scenario_path;  // every service but the observers
  std::string uplink_path;    // observers: what the ground uplinked (no truth)
  std::string out_dir;
  std::string name;
  std::optional<double> duration_s;
  std::optional<std::uint64_t> seed;
  std::optional<double> epoch_window_s;    // overrides the scenario's epoch_window
  std::optional<double> phase_window_deg;  // overrides the scenario's phase_window_deg
  double rate = 0.0;             // 0 = as fast as possible (lock-step only)
  double step_timeout_s = 120.0;
};
// Parses the common options with CLI11 (plus --help). Returns nullopt after
// printing help or an error (exit code in *exit_code).
std::optional<ServiceOptions> parse_service_options(int argc, char** argv, const std::string& app,
                                                    const std::string& description,
                                                    int* exit_code);
// The whole main() of a service: parses the common options, installs the
// signal handlers, runs `body` and turns an exception into a named error and
// exit code 1.
int run_service(int argc, char** argv, const std::string& app, const std::string& description,
                const std::function<int(const ServiceOptions&)>& body);
// Loads the scenario with the overrides applied (duration, epoch and phase windows, seed).
config::Scenario load_for_service(const ServiceOptions& o);

}  // namespace artms::runtime
