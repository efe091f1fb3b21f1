// artms-truth: the truth service and clock master (DESIGN.md sections 2, 3).
// The truth world is sim::Truth (common/sim); this file wires it to DDS and
// drives the lock-step clock: states and GNSS fixes of step k are written
// and acknowledged, then tick k goes out, and the next step waits until
// every service reported step k done.
#include <chrono>
#include <thread>

#include "artms/io/paths.hpp"
#include "artms/runtime/runtime.hpp"
#include "artms/runtime/wire.hpp"
#include "artms/sim/services.hpp"

namespace {

using namespace artms;

int run(const runtime::ServiceOptions& opt) {
  const config::Scenario sc = runtime::load_for_service(opt);
  const runtime::Topology topo = runtime::topology(sc);
  sim::Truth world(sc, std::make_shared<const dynamics::ForceModel>(dynamics::ForceModel::load(sc.force_model, io::data_dir())),
                   opt.name);
  dds::Participant participant(dds::domain_from_environment());
  runtime::TopicSet topics(participant);
  dds::Writer<artms_msg_ClockTick> tick_writer(participant, topics.clock_tick, runtime::clock_qos());
  dds::Writer<artms_msg_TruthState> state_writer(participant, topics.truth_state, runtime::data_qos());
  dds::Writer<artms_msg_GnssFix> gnss_writer(participant, topics.gnss_fix, runtime::data_qos());
  dds::Reader<artms_msg_StepDone> done_reader(participant, topics.step_done, runtime::step_done_qos());
  dds::WaitSet waitset(participant);
  waitset.attach(done_reader.handle());
  runtime::EventLog events(participant, topics, opt.name);

  // Start-up: every writer sees its readers, then every service is ready.
  const auto& rt = topo.readers_of_topic;
  dds::wait_for_matches(participant,
                        {{"clock_tick writer", tick_writer.handle(), true, rt.at("clock_tick")},
                         {"truth_state writer", state_writer.handle(), true, rt.at("truth_state")},
                         {"gnss_fix writer", gnss_writer.handle(), true, rt.at("gnss_fix")},
                         {"event writer", events.writer().handle(), true, rt.at("event")}},
                        60.0, &runtime::g_stop_requested);

  std::map<std::string, std::int64_t> last_done;
  for (const auto& s : topo.services) {
    if (s != opt.name) last_done[s] = -2;
  }
  const auto wait_all_done = [&](std::int64_t step, double timeout_s) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    for (;;) {
      done_reader.take_each([&](const artms_msg_StepDone& d) {
        const std::string who = dds::to_string(d.service, sizeof d.service);
        auto it = last_done.find(who);
        if (it == last_done.end()) return;
        if (d.status != 0) {
          throw std::runtime_error("service " + who + " reported failure at step " + std::to_string(d.step));
        }
        it->second = std::max(it->second, d.step);
      });
      std::string missing;
      for (const auto& [who, s] : last_done) {
        if (s < step) missing += (missing.empty() ? "" : ", ") + who;
      }
      if (missing.empty()) return;
      if (runtime::g_stop_requested) throw std::runtime_error("stop requested");
      const double left = std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count();
      if (left <= 0.0) {
        throw std::runtime_error("no answer within " + std::to_string(static_cast<int>(timeout_s)) + " s for step " +
                                 std::to_string(step) + " from: " + missing);
      }
      waitset.wait(std::min(left, 0.5));
    }
  };
  wait_all_done(-1, 60.0);
  events.publish({world.started()});

  const auto wall_start = std::chrono::steady_clock::now();
  for (std::int64_t k = 0; k <= world.steps() + 1; ++k) {
    const bus::Tick tick = world.tick(k);
    if (!tick.final_step) {
      const sim::Truth::StepOutput out = world.step(k);
      for (const auto& s : out.states) runtime::write(state_writer, s);
      for (const auto& f : out.gnss) runtime::write(gnss_writer, f);
      // Everything stamped <= t is in every reader's cache before the tick.
      for (auto* w : {static_cast<dds::Entity*>(&state_writer), static_cast<dds::Entity*>(&gnss_writer),
                      static_cast<dds::Entity*>(&events.writer())}) {
        if (!dds::detail::wait_for_acks(w->handle(), opt.step_timeout_s)) {
          throw std::runtime_error("a reader did not acknowledge data of step " + std::to_string(k));
        }
      }
    }
    if (opt.rate > 0.0 && !tick.final_step) {
      // Real-time-scaled mode: tick k no earlier than its wall-clock time.
      const auto due = wall_start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                        std::chrono::duration<double>(static_cast<double>(k) * sc.step_s / opt.rate));
      std::this_thread::sleep_until(due);
    }
    artms_msg_ClockTick m{};
    m.step = tick.step;
    m.t_tt_ns = tick.t_tt_ns;
    m.final_step = tick.final_step;
    tick_writer.write(m);
    wait_all_done(k, opt.step_timeout_s);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return runtime::run_service(argc, argv, "artms-truth",
                              "Truth service and clock master: propagates every spacecraft (SUNDIALS CVODE), publishes\n"
                              "truth states and GNSS fixes, and drives the lock-step clock.",
                              run);
}
