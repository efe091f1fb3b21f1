// artms-recorder: records every topic of a run into the run folder
// (DESIGN.md section 8). The files and their order are sim::Recorder
// (common/sim); this file drains every reader into it at each tick.
// Everything stamped before tick k has been acknowledged by the time tick k
// arrives, so flushing what is stamped before it gives the same files
// whatever the arrival order.
#include <cstdio>

#include "artms/runtime/runtime.hpp"
#include "artms/runtime/wire.hpp"
#include "artms/sim/services.hpp"

namespace {

using namespace artms;

template <typename Wire>
void drain(dds::Reader<Wire>& r, sim::Recorder& rec) {
  r.take_each([&](const Wire& m) { rec.add(runtime::from_wire(m)); });
}

int run(const runtime::ServiceOptions& opt) {
  const config::Scenario sc = runtime::load_for_service(opt);
  sim::Recorder rec(sc, opt.out_dir);
  dds::Participant participant(dds::domain_from_environment());
  runtime::TopicSet topics(participant);
  runtime::LockStepClient clock(participant, topics, opt.name, opt.step_timeout_s);
  const auto q = runtime::data_qos();
  dds::Reader<artms_msg_TruthState> truth_reader(participant, topics.truth_state, q);
  dds::Reader<artms_msg_GnssFix> gnss_reader(participant, topics.gnss_fix, q);
  dds::Reader<artms_msg_NavTelemetry> nav_reader(participant, topics.nav_telemetry, q);
  dds::Reader<artms_msg_Event> event_reader(participant, topics.event, q);
  dds::Reader<artms_msg_LinkState> link_reader(participant, topics.link_state, q);
  dds::Reader<artms_msg_IslOutcome> isl_reader(participant, topics.isl_outcome, q);
  dds::Reader<artms_msg_FrameTruth> frame_truth_reader(participant, topics.frame_truth, q);
  dds::Reader<artms_msg_ImpReport> imp_reader(participant, topics.imp_report, q);
  dds::Reader<artms_msg_BodAttempt> bod_reader(participant, topics.bod_attempt, q);
  const auto drain_all = [&]() {
    drain(truth_reader, rec);
    drain(gnss_reader, rec);
    drain(nav_reader, rec);
    drain(event_reader, rec);
    drain(link_reader, rec);
    drain(frame_truth_reader, rec);
    drain(imp_reader, rec);
    drain(isl_reader, rec);
    drain(bod_reader, rec);
  };

  clock.announce_ready(participant, {}, 60.0);
  while (auto tick = clock.wait_tick()) {
    drain_all();
    rec.on_tick(runtime::from_wire(*tick));
    if (tick->final_step) {
      if (rec.rejected() > 0) std::fprintf(stderr, "[%s] rejected %zu malformed samples\n", opt.name.c_str(), rec.rejected());
      clock.done(tick->step);
      return 0;
    }
    clock.done(tick->step);
  }
  // Stopped (signal) or timed out: keep what was recorded.
  drain_all();
  rec.finish();
  std::fprintf(stderr, "[%s] stopped early; run folder holds what was recorded\n", opt.name.c_str());
  return clock.timed_out() ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  return runtime::run_service(argc, argv, "artms-recorder",
                              "Records every topic of a run into the run folder (truth.oem, nav/, gnss.csv, isl.csv,\n"
                              "links.csv, events.log, frames.csv, imp/, bod/), deterministically ordered.",
                              run);
}
