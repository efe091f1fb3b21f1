// artms-camera-renderer: renders every observer's NST-like frames at its
// cadence, in lock step, from truth (DESIGN.md section 2), and publishes
// camera frames (one DDS partition per observer, so each observer receives
// only its own 2.6 MB frames) and frame truth (evaluation only).
#include <cstdio>
#include <map>

#include "artms/render/frame_setup.hpp"
#include "artms/runtime/runtime.hpp"

namespace {

using namespace artms;

struct ObserverChannel {
  std::string id;
  std::unique_ptr<render::FrameSetup> setup;
  std::unique_ptr<dds::Writer<artms_msg_CameraFrame>> writer;
  std::size_t rendered = 0, dropped = 0, excluded = 0;
};

int run(const runtime::ServiceOptions& opt) {
  const config::Scenario sc = runtime::load_for_service(opt);
  const runtime::Topology topo = runtime::topology(sc);
  dds::Participant participant(dds::domain_from_environment());
  runtime::TopicSet topics(participant);
  runtime::LockStepClient clock(participant, topics, opt.name, opt.step_timeout_s);
  dds::Reader<artms_msg_TruthState> truth_reader(participant, topics.truth_state, runtime::data_qos());
  dds::Writer<artms_msg_FrameTruth> truth_writer(participant, topics.frame_truth, runtime::data_qos());
  runtime::EventLog events(participant, topics, opt.name);
  std::vector<ObserverChannel> channels;
  std::vector<dds::MatchExpectation> expect = {
      {"event writer", events.writer().handle(), true, topo.readers_of_topic.at("event")},
      {"frame_truth writer", truth_writer.handle(), true, topo.readers_of_topic.at("frame_truth")},
      {"truth_state reader", truth_reader.handle(), false, 1}};
  for (const auto& o : sc.observers) {
    ObserverChannel c;
    c.id = o.spacecraft;
    c.setup = std::make_unique<render::FrameSetup>(
        render::make_frame_setup(sc, o.spacecraft, "", o.camera.flight_like, false));
    c.writer = std::make_unique<dds::Writer<artms_msg_CameraFrame>>(participant, topics.camera_frame,
                                                                    runtime::frame_qos(o.spacecraft));
    expect.push_back({"camera_frame writer for " + o.spacecraft, c.writer->handle(), true, 1});
    channels.push_back(std::move(c));
  }
  clock.announce_ready(participant, expect, 60.0);

  artms_msg_CameraFrame frame{};
  std::vector<std::uint16_t> pixels;
  while (auto tick = clock.wait_tick()) {
    const astro::TimeTT t{tick->t_tt_ns};
    std::map<std::string, astro::StateVector> states;
    truth_reader.take_each([&](const artms_msg_TruthState& m) {
      if (m.t_tt_ns != tick->t_tt_ns) return;
      states[dds::to_string(m.spacecraft, sizeof m.spacecraft)] = {
          astro::Vec3(m.r_eci_m[0], m.r_eci_m[1], m.r_eci_m[2]),
          astro::Vec3(m.v_eci_mps[0], m.v_eci_mps[1], m.v_eci_mps[2])};
    });
    const double since = astro::seconds_between(sc.epoch, t);
    for (auto& c : channels) {
      if (tick->final_step) break;
      const double cadence = c.setup->camera_config.cadence_s;
      const double phase = std::fmod(since, cadence);
      if (phase > 1e-6 && cadence - phase > 1e-6) continue;
      if (!states.count(c.id)) {
        events.error(t.ns_since_j2000, "no truth state for observer " + c.id + " at this step");
        continue;
      }
      imaging::RenderRequest req;
      req.observer = c.id;
      req.frame_index = static_cast<std::uint64_t>(std::llround(since / cadence));
      req.t = t;
      req.observer_eci = states.at(c.id);
      for (const auto& [id, x] : states) {
        if (id != c.id) req.targets.push_back({id, x.r_m});
      }
      req.q_cam_from_eci = c.setup->attitude(req.observer_eci, req.frame_index);
      const imaging::RenderedFrame f = c.setup->renderer.render(req);
      ++c.rendered;
      artms_msg_FrameTruth ft{};
      dds::copy_string(ft.observer, sizeof ft.observer, c.id);
      ft.frame_seq = static_cast<std::uint32_t>(req.frame_index);
      ft.t_tt_ns = t.ns_since_j2000;
      ft.time_tag_tt_ns = f.time_tag.ns_since_j2000;
      ft.dropped = f.dropped;
      dds::copy_string(ft.exclusion, sizeof ft.exclusion, f.exclusion.excluded ? f.exclusion.reason : "none");
      const auto q = astro::wxyz_from_quaternion(req.q_cam_from_eci);
      for (int i = 0; i < 4; ++i) ft.q_cam_from_eci[i] = q[static_cast<std::size_t>(i)];
      ft.stars_used = static_cast<std::uint32_t>(f.stars.size());
      std::vector<artms_msg_TargetPixel> tp(f.targets.size());
      for (std::size_t k = 0; k < f.targets.size(); ++k) {
        dds::copy_string(tp[k].target, sizeof tp[k].target, f.targets[k].id);
        tp[k].x_px = f.targets[k].x_px;
        tp[k].y_px = f.targets[k].y_px;
        tp[k].vmag = f.targets[k].vmag;
        tp[k].range_m = f.targets[k].range_m;
        tp[k].visible = f.targets[k].visible;
        dds::copy_string(tp[k].reason, sizeof tp[k].reason, f.targets[k].reason);
      }
      ft.targets._buffer = tp.data();
      ft.targets._length = ft.targets._maximum = static_cast<std::uint32_t>(tp.size());
      ft.targets._release = false;
      truth_writer.write(ft);
      if (f.exclusion.excluded) ++c.excluded;
      if (f.dropped) {
        ++c.dropped;
        continue;
      }
      dds::copy_string(frame.observer, sizeof frame.observer, c.id);
      dds::copy_string(frame.camera, sizeof frame.camera, c.setup->camera_config.model);
      frame.frame_seq = ft.frame_seq;
      frame.time_tag_tt_ns = f.time_tag.ns_since_j2000;
      frame.width = static_cast<std::uint16_t>(f.width);
      frame.height = static_cast<std::uint16_t>(f.height);
      frame.bit_depth = static_cast<std::uint8_t>(c.setup->renderer.camera().bit_depth);
      pixels = f.pixels;
      frame.pixels._buffer = pixels.data();
      frame.pixels._length = frame.pixels._maximum = static_cast<std::uint32_t>(pixels.size());
      frame.pixels._release = false;
      c.writer->write(frame);
    }
    std::vector<dds_entity_t> writers = {events.writer().handle(), truth_writer.handle()};
    for (auto& c : channels) writers.push_back(c.writer->handle());
    for (auto w : writers) dds::detail::wait_for_acks(w, opt.step_timeout_s);
    clock.done(tick->step);
    if (tick->final_step) {
      for (const auto& c : channels) {
        std::fprintf(stderr, "[%s] %s: %zu frames rendered, %zu dropped, %zu excluded\n", opt.name.c_str(),
                     c.id.c_str(), c.rendered, c.dropped, c.excluded);
      }
      return 0;
    }
  }
  return runtime::g_stop_requested ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  return runtime::run_service(argc, argv, "artms-camera-renderer",
                              "Camera renderer: NST-like 1280x1024 12-bit frames for every observer at its cadence, from\n"
      "truth (stars, faint stars, targets, noise, hot pixels, eclipse, exclusions, drop-outs,\n"
      "time-tag faults); publishes camera frames and frame truth.",
                              run);
}
