// artms-camera-renderer: renders every observer's NST-like frames at its
// cadence, in lock step, from truth (DESIGN.md section 2). The rendering is
// sim::CameraRenderer (common/sim); this file wires it to DDS: camera frames
// go out in one partition per observer (each observer receives only its own
// 2.6 MB frames), frame truth for evaluation only.
#include <malloc.h>

#include <cstdio>

#include "artms/runtime/runtime.hpp"
#include "artms/runtime/wire.hpp"
#include "artms/sim/services.hpp"

namespace {

using namespace artms;

int run(const runtime::ServiceOptions& opt) {
  const config::Scenario sc = runtime::load_for_service(opt);
  const runtime::Topology topo = runtime::topology(sc);
  sim::CameraRenderer renderer(sc, opt.name);
  dds::Participant participant(dds::domain_from_environment());
  runtime::TopicSet topics(participant);
  runtime::LockStepClient clock(participant, topics, opt.name, opt.step_timeout_s);
  dds::Reader<artms_msg_TruthState> truth_reader(participant, topics.truth_state, runtime::data_qos());
  dds::Writer<artms_msg_FrameTruth> truth_writer(participant, topics.frame_truth, runtime::data_qos());
  runtime::EventLog events(participant, topics, opt.name);
  std::map<std::string, std::unique_ptr<dds::Writer<artms_msg_CameraFrame>>> frame_writers;
  std::vector<dds::MatchExpectation> expect = {
      {"event writer", events.writer().handle(), true, topo.readers_of_topic.at("event")},
      {"frame_truth writer", truth_writer.handle(), true, topo.readers_of_topic.at("frame_truth")},
      {"truth_state reader", truth_reader.handle(), false, 1}};
  for (const auto& id : renderer.observers()) {
    auto& w = frame_writers[id];
    w = std::make_unique<dds::Writer<artms_msg_CameraFrame>>(participant, topics.camera_frame, runtime::frame_qos(id));
    expect.push_back({"camera_frame writer for " + id, w->handle(), true, 1});
  }
  clock.announce_ready(participant, expect, 60.0);

  while (auto tick = clock.wait_tick()) {
    const auto out = renderer.step(runtime::from_wire(*tick), runtime::take_all<bus::TruthState>(truth_reader));
    for (const auto& ft : out.truths) runtime::write(truth_writer, ft);
    for (const auto& f : out.frames) runtime::write(*frame_writers.at(f.observer), f);
    events.publish(out.events);
    std::vector<dds_entity_t> writers = {events.writer().handle(), truth_writer.handle()};
    for (auto& [id, w] : frame_writers) writers.push_back(w->handle());
    for (auto w : writers) dds::detail::wait_for_acks(w, opt.step_timeout_s);
    clock.done(tick->step);
    if (tick->final_step) {
      for (const auto& line : renderer.summary()) std::fprintf(stderr, "[%s] %s\n", opt.name.c_str(), line.c_str());
      return 0;
    }
  }
  return runtime::g_stop_requested ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  // Every frame allocates and frees buffers of several MB (a 1280 x 1024
  // float image is 5.2 MB). glibc raises its mmap threshold after such a
  // free, after which these buffers stay in the heap and the resident size
  // drifts by 5-15 MB from run to run although nothing is kept (the soak's
  // growth check saw -5 % to +14 %). A fixed 1 MB threshold maps them and
  // returns them on free.
  mallopt(M_MMAP_THRESHOLD, 1 << 20);
  return runtime::run_service(argc, argv, "artms-camera-renderer",
                              "Camera renderer: NST-like 1280x1024 12-bit frames for every observer at its cadence, from\n"
                              "truth (stars, faint stars, targets, noise, hot pixels, eclipse, exclusions, drop-outs,\n"
                              "time-tag faults); publishes camera frames and frame truth.",
                              run);
}
