// artms-crosslink-emulator: PLACEHOLDER process. It joins the lock-step clock and consumes
// truth states so that the swarm has its full process list; the real
// service replaces this file in a later issue (see README.md).
#include <cstdio>

#include "artms/runtime/runtime.hpp"

namespace {

using namespace artms;

int run(const runtime::ServiceOptions& opt) {
  const config::Scenario sc = runtime::load_for_service(opt);
  const runtime::Topology topo = runtime::topology(sc);
  dds::Participant participant(dds::domain_from_environment());
  runtime::TopicSet topics(participant);
  runtime::LockStepClient clock(participant, topics, opt.name, opt.step_timeout_s);
  dds::Reader<artms_msg_TruthState> truth_reader(participant, topics.truth_state, runtime::data_qos());
  runtime::EventLog events(participant, topics, opt.name);
  clock.announce_ready(participant,
                       {{"event writer", events.writer().handle(), true, topo.readers_of_topic.at("event")},
                        {"truth_state reader", truth_reader.handle(), false, 1}},
                       60.0);
  std::size_t states = 0;
  bool announced = false;
  while (auto tick = clock.wait_tick()) {
    if (!announced) {
      announced = true;
      events.info(tick->t_tt_ns, "placeholder service: consumes truth, produces nothing yet");
    }
    states += static_cast<std::size_t>(truth_reader.take_each([](const artms_msg_TruthState&) {}));
    dds::detail::wait_for_acks(events.writer().handle(), opt.step_timeout_s);
    clock.done(tick->step);
    if (tick->final_step) return 0;
  }
  return runtime::g_stop_requested ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  return runtime::run_service(argc, argv, "artms-crosslink-emulator",
                              "Crosslink emulator (placeholder until the crosslink issue): joins the lock-step clock and\nconsumes truth states; the inter-satellite link is not emulated yet.",
                              run);
}
