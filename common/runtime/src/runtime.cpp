#include "artms/runtime/runtime.hpp"
#include "artms/runtime/wire.hpp"

#include <CLI/CLI.hpp>
#include <malloc.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <iostream>

#include "artms/io/duration.hpp"

namespace artms::runtime {

std::atomic<bool> g_stop_requested{false};

namespace {
void on_signal(int) { g_stop_requested.store(true); }
}  // namespace

void install_signal_handlers() {
  struct sigaction sa{};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

TopicSet::TopicSet(const dds::Participant& p)
    : clock_tick(p, &artms_msg_ClockTick_desc, "artms_clock_tick"),
      step_done(p, &artms_msg_StepDone_desc, "artms_step_done"),
      truth_state(p, &artms_msg_TruthState_desc, "artms_truth_state"),
      gnss_fix(p, &artms_msg_GnssFix_desc, "artms_gnss_fix"),
      camera_frame(p, &artms_msg_CameraFrame_desc, "artms_camera_frame"),
      frame_truth(p, &artms_msg_FrameTruth_desc, "artms_frame_truth"),
      isl_broadcast(p, &artms_msg_IslBroadcast_desc, "artms_isl_broadcast"),
      nav_telemetry(p, &artms_msg_NavTelemetry_desc, "artms_nav_telemetry"),
      link_state(p, &artms_msg_LinkState_desc, "artms_link_state"),
      event(p, &artms_msg_Event_desc, "artms_event"),
      imp_report(p, &artms_msg_ImpReport_desc, "artms_imp_report"),
      isl_relay(p, &artms_msg_IslBroadcast_desc, "artms_isl_relay"),
      isl_outcome(p, &artms_msg_IslOutcome_desc, "artms_isl_outcome"),
      bod_attempt(p, &artms_msg_BodAttempt_desc, "artms_bod_attempt") {}

dds::QosProfile clock_qos() { return {true, true, 1, 0, {}}; }
dds::QosProfile step_done_qos() { return {true, true, 1, 0, {}}; }
dds::QosProfile data_qos() { return {true, false, 0, 0, {}}; }
dds::QosProfile frame_qos(const std::string& observer) {
  return {true, false, 4, 0, {"frames-" + observer}};
}

dds::QosProfile isl_tx_qos() { return {true, false, 0, 0, {"isl-tx"}}; }
dds::QosProfile isl_relay_writer_qos(const std::string& from, const std::string& to, bool up, double lifespan_s) {
  return {true, false, 0, static_cast<std::int64_t>(std::llround(lifespan_s * 1e9)),
          {up ? "isl-" + from + "-" + to : std::string("isl-down")}};
}
dds::QosProfile isl_relay_reader_qos(const std::string& me) { return {true, false, 0, 0, {"isl-*-" + me}}; }

Topology topology(const config::Scenario& s) {
  Topology t;
  t.services = config::services(s);
  const int n = static_cast<int>(t.services.size());
  int gnss_readers = 1;  // recorder
  for (const auto& o : s.observers) gnss_readers += o.gnss.enabled ? 1 : 0;
  t.readers_of_topic = {
      {"clock_tick", n - 1},            // every service but truth
      {"step_done", 1},                 // truth
      {"truth_state", 3},               // camera renderer, crosslink emulator, recorder
      {"gnss_fix", gnss_readers},       // observers with GNSS, recorder
      {"nav_telemetry", 1},             // recorder
      {"frame_truth", 1},               // recorder (evaluation only)
      {"imp_report", 1},                // recorder
      {"link_state", 1},                // recorder
      {"event", 1},                     // recorder
      {"isl_broadcast", 1},             // crosslink emulator (partition isl-tx)
      {"isl_outcome", 1},               // recorder
      {"bod_attempt", 1},               // recorder (BOD telemetry)
  };
  for (const auto& [from, to] : config::isl_links(s)) {
    t.isl_relay_readers[from + "->" + to] = config::isl_link_up_at_epoch(s, from, to) ? 1 : 0;
  }
  return t;
}

LockStepClient::LockStepClient(const dds::Participant& p, const TopicSet& topics,
                               std::string service_name, double step_timeout_s)
    : name_(std::move(service_name)),
      step_timeout_s_(step_timeout_s),
      tick_reader_(p, topics.clock_tick, clock_qos()),
      done_writer_(p, topics.step_done, step_done_qos()),
      waitset_(p) {
  waitset_.attach(tick_reader_.handle());
}

void LockStepClient::announce_ready(const dds::Participant& p,
                                    std::vector<dds::MatchExpectation> expected, double timeout_s) {
  expected.push_back({"clock_tick reader", tick_reader_.handle(), false, 1});
  expected.push_back({"step_done writer", done_writer_.handle(), true, 1});
  try {
    dds::wait_for_matches(p, expected, timeout_s, &g_stop_requested);
  } catch (const std::exception& e) {
    throw std::runtime_error(name_ + ": " + e.what());
  }
  done(-1, 0);
}

std::optional<artms_msg_ClockTick> LockStepClient::wait_tick() {
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::duration<double>(step_timeout_s_);
  for (;;) {
    std::optional<artms_msg_ClockTick> next;
    tick_reader_.take_each([&](const artms_msg_ClockTick& t) {
      if (t.step > last_step_) next = t;
    });
    if (next) {
      last_step_ = next->step;
      return next;
    }
    if (g_stop_requested) return std::nullopt;
    const double left =
        std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count();
    if (left <= 0.0) {
      timed_out_ = true;
      return std::nullopt;
    }
    waitset_.wait(std::min(left, 0.5));  // wake periodically to see stop requests
  }
}

void LockStepClient::done(std::int64_t step, int status) {
  artms_msg_StepDone d{};
  dds::copy_string(d.service, sizeof d.service, name_);
  d.step = step;
  d.status = status;
  done_writer_.write(d);
}

EventLog::EventLog(const dds::Participant& p, const TopicSet& topics, std::string source)
    : source_(std::move(source)), writer_(p, topics.event, data_qos()) {}

void EventLog::emit(std::int64_t t, int severity, const std::string& text) {
  publish({{source_, t, static_cast<bus::Severity>(severity), text}});
}

void EventLog::publish(const std::vector<bus::Event>& events) {
  // The wire bounds the strings (runtime::write); stderr shows them whole.
  for (const auto& e : events) {
    write(writer_, e);
    std::fprintf(stderr, "[%s] %s: %s\n", e.source.c_str(), bus::to_string(e.severity), e.text.c_str());
  }
}

std::optional<ServiceOptions> parse_service_options(int argc, char** argv, const std::string& app_name,
                                                    const std::string& description, int* exit_code) {
  CLI::App app{description, app_name};
  ServiceOptions o;
  std::string duration;
  std::string epoch_window;
  double phase_window_deg = 0.0;
  std::uint64_t seed = 0;
  auto* scen = app.add_option("--scenario", o.scenario_path, "scenario YAML file");
  auto* up = app.add_option("--uplink", o.uplink_path,
                            "observer uplink file (JSON written by the launcher; observers only)");
  scen->excludes(up);
  app.require_option(1, 0);
  app.add_option("--out", o.out_dir, "run folder")->required();
  app.add_option("--name", o.name, "service name (as in the scenario's process list)")->required();
  auto* dur = app.add_option("--duration", duration, "override the scenario duration (6h, 1d, ...)");
  auto* sd = app.add_option("--seed", seed, "override the scenario seed");
  auto* ew = app.add_option("--epoch-window", epoch_window,
                            "override the scenario's epoch_window (the run's epoch drawn from the seed within it)");
  auto* pw = app.add_option("--phase-window-deg", phase_window_deg,
                            "override the scenario's phase_window_deg (the orbit phase drawn from the seed within it)");
  app.add_option("--rate", o.rate, "0 = lock-step as fast as possible; X = X times real time");
  app.add_option("--step-timeout", o.step_timeout_s, "seconds to wait for a step before giving up")
      ->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    *exit_code = app.exit(e);
    return std::nullopt;
  }
  if (dur->count() > 0) o.duration_s = io::parse_duration_s(duration);
  if (sd->count() > 0) o.seed = seed;
  if (ew->count() > 0) o.epoch_window_s = io::parse_duration_s(epoch_window);
  if (pw->count() > 0) o.phase_window_deg = phase_window_deg;
  return o;
}

int run_service(int argc, char** argv, const std::string& app, const std::string& description,
                const std::function<int(const ServiceOptions&)>& body) {
  int code = 0;
  const auto opt = parse_service_options(argc, argv, app, description, &code);
  if (!opt) return code;
  install_signal_handlers();
  // Frame-sized buffers (2.6 MB frames, 5 MB float images) are mapped and
  // unmapped per use: glibc's dynamic mmap threshold would otherwise serve
  // them from the heap after the first free, and the heap fragments over a
  // long run (the resident memory of the camera renderer grew 11 % between
  // hours 6 and 24 of the soak). A fixed threshold turns the dynamic one off.
  mallopt(M_MMAP_THRESHOLD, 256 * 1024);
  try {
    return body(*opt);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "[%s] error: %s\n", opt->name.c_str(), e.what());
    return 1;
  }
}

config::Scenario load_for_service(const ServiceOptions& o) {
  if (o.scenario_path.empty()) throw std::invalid_argument(o.name + " needs --scenario");
  config::Scenario s = config::load_scenario(o.scenario_path);
  if (o.duration_s) s.duration_s = *o.duration_s;
  if (o.epoch_window_s) config::set_epoch_window(s, *o.epoch_window_s);
  if (o.phase_window_deg) config::set_phase_window(s, *o.phase_window_deg);
  if (o.seed) config::set_seed(s, *o.seed);
  return s;
}

}  // namespace artms::runtime
