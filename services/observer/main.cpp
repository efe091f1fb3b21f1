// artms-observer: one ARTMS process per observing spacecraft. The onboard
// software is fsw::Observer (common/fsw); this file only wires DDS to it:
// each tick, what arrived (its GNSS fixes, its camera frames, the ISL relays
// addressed to it) goes in, and what it wrote (IMP telemetry, navigation
// telemetry, its ISL broadcast, BOD attempts, events) goes out. It never
// reads truth.
#include <cstdio>

#include "artms/fsw/observer.hpp"
#include "artms/io/paths.hpp"
#include "artms/runtime/runtime.hpp"
#include "artms/runtime/wire.hpp"

namespace {

using namespace artms;

int run(const runtime::ServiceOptions& opt) {
  // The observer knows only what the ground uplinked: never the scenario
  // (which holds the true orbits).
  if (opt.uplink_path.empty()) throw std::invalid_argument("artms-observer needs --uplink FILE");
  fsw::Observer observer(fsw::load_observer_setup(opt.uplink_path, io::data_dir()), opt.name);
  if (opt.name != "observer-" + observer.id()) {
    throw std::invalid_argument("service name " + opt.name + " does not match the uplink's observer " + observer.id());
  }
  const std::string& me = observer.id();
  dds::Participant participant(dds::domain_from_environment());
  runtime::TopicSet topics(participant);
  runtime::LockStepClient clock(participant, topics, opt.name, opt.step_timeout_s);
  dds::Reader<artms_msg_GnssFix> gnss_reader(participant, topics.gnss_fix, runtime::data_qos());
  // Only this observer's frames: the renderer writes them in partition frames-<id>.
  dds::Reader<artms_msg_CameraFrame> frame_reader(participant, topics.camera_frame, runtime::frame_qos(me));
  dds::Writer<artms_msg_NavTelemetry> nav_writer(participant, topics.nav_telemetry, runtime::data_qos());
  runtime::EventLog events(participant, topics, opt.name);
  dds::Writer<artms_msg_ImpReport> imp_writer(participant, topics.imp_report, runtime::data_qos());
  dds::Writer<artms_msg_BodAttempt> bod_writer(participant, topics.bod_attempt, runtime::data_qos());
  // Inter-satellite link: broadcasts go to the crosslink emulator (partition
  // isl-tx); what it relays to this observer arrives in isl-<sender>-<me>.
  dds::Writer<artms_msg_IslBroadcast> isl_writer(participant, topics.isl_broadcast, runtime::isl_tx_qos());
  dds::Reader<artms_msg_IslBroadcast> relay_reader(participant, topics.isl_relay, runtime::isl_relay_reader_qos(me));
  // Readers of what the observer writes: the recorder only (runtime::topology).
  clock.announce_ready(participant,
                       {{"nav_telemetry writer", nav_writer.handle(), true, 1},
                        {"event writer", events.writer().handle(), true, 1},
                        {"imp_report writer", imp_writer.handle(), true, 1},
                        {"bod_attempt writer", bod_writer.handle(), true, 1},
                        {"gnss_fix reader", gnss_reader.handle(), false, observer.uplink().observer.gnss.enabled ? 1 : 0},
                        {"camera_frame reader", frame_reader.handle(), false, 1},
                        // The emulator reads every broadcast; relay writers
                        // match only while their link is up (the emulator
                        // waits for those), so none is required here.
                        {"isl_broadcast writer", isl_writer.handle(), true, 1}},
                       60.0);

  while (auto tick = clock.wait_tick()) {
    fsw::ObserverInputs in;
    in.gnss = runtime::take_all<bus::GnssFix>(gnss_reader);
    in.relays = runtime::take_all<bus::IslBroadcast>(relay_reader);
    in.frames = runtime::take_all<bus::CameraFrame>(frame_reader);
    const fsw::ObserverOutputs out = observer.step(runtime::from_wire(*tick), std::move(in));
    for (const auto& r : out.imp) runtime::write(imp_writer, r);
    if (out.isl) runtime::write(isl_writer, *out.isl);
    if (out.nav) runtime::write(nav_writer, *out.nav);
    for (const auto& b : out.bod) runtime::write(bod_writer, b);
    events.publish(out.events);
    for (dds::Entity* w : {static_cast<dds::Entity*>(&nav_writer), static_cast<dds::Entity*>(&events.writer()),
                           static_cast<dds::Entity*>(&imp_writer), static_cast<dds::Entity*>(&isl_writer),
                           static_cast<dds::Entity*>(&bod_writer)}) {
      dds::detail::wait_for_acks(w->handle(), opt.step_timeout_s);
    }
    clock.done(tick->step);
    if (tick->final_step) {
      std::fprintf(stderr, "[%s] %s\n", opt.name.c_str(), observer.isl_summary().c_str());
      return 0;
    }
  }
  if (clock.timed_out()) {
    std::fprintf(stderr, "[%s] error: no clock tick within %.0f s (is truth running?)\n", opt.name.c_str(),
                 opt.step_timeout_s);
    return 1;
  }
  return runtime::g_stop_requested ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  return runtime::run_service(argc, argv, "artms-observer",
                              "One ARTMS observer process (the onboard software of one spacecraft: IMP -> SOD on its\n"
                              "own frames, GNSS fixes and the ISL).",
                              run);
}
