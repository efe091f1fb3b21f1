// artms-crosslink-emulator: the only place the state of the inter-satellite
// link lives (DESIGN.md section 2). The decisions (link states, loss,
// latency, one outcome per broadcast and link) are sim::Crosslink
// (common/sim); this file applies them with DDS: it reads every observer's
// broadcasts (artms_isl_broadcast, partition "isl-tx") and relays each one
// through one writer per directed link (artms_isl_relay). A link going down
// moves its writer into the partition "isl-down", which no reader
// subscribes to, so the DDS match disappears and whatever is written there
// is lost in DDS itself; going up moves it back into "isl-<from>-<to>".
// README.md in this folder has the details.
#include <chrono>
#include <cstdio>
#include <memory>

#include "artms/runtime/runtime.hpp"
#include "artms/runtime/wire.hpp"
#include "artms/sim/services.hpp"

namespace {

using namespace artms;

// Waits until the writer's match count is `want` (a partition switch is
// applied by discovery, asynchronously). Returns false on timeout.
bool wait_matched(const dds::Writer<artms_msg_IslBroadcast>& w, int want, double timeout_s) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (w.matched_readers() != want) {
    if (std::chrono::steady_clock::now() > deadline || runtime::g_stop_requested) return false;
    dds_sleepfor(DDS_MSECS(1));
  }
  return true;
}

int run(const runtime::ServiceOptions& opt) {
  const config::Scenario sc = runtime::load_for_service(opt);
  const runtime::Topology topo = runtime::topology(sc);
  sim::Crosslink xl(sc, opt.name);
  dds::Participant participant(dds::domain_from_environment());
  runtime::TopicSet topics(participant);
  runtime::LockStepClient clock(participant, topics, opt.name, opt.step_timeout_s);
  dds::Reader<artms_msg_TruthState> truth_reader(participant, topics.truth_state, runtime::data_qos());
  dds::Reader<artms_msg_IslBroadcast> tx_reader(participant, topics.isl_broadcast, runtime::isl_tx_qos());
  dds::Writer<artms_msg_LinkState> link_writer(participant, topics.link_state, runtime::data_qos());
  dds::Writer<artms_msg_IslOutcome> outcome_writer(participant, topics.isl_outcome, runtime::data_qos());
  runtime::EventLog events(participant, topics, opt.name);

  // Lifespan of relayed messages (wall clock, as DDS measures it): a relay
  // is consumed by its receiver one step later; anything older than a
  // broadcast period plus two steps (scaled by --rate in real-time mode) is
  // stale and expires in DDS. In lock-step at full speed it never triggers.
  const double lifespan_s = (sc.crosslink.period_s + 2.0 * sc.step_s) / (opt.rate > 0.0 ? opt.rate : 1.0);
  std::vector<dds::MatchExpectation> expect = {
      {"event writer", events.writer().handle(), true, topo.readers_of_topic.at("event")},
      {"link_state writer", link_writer.handle(), true, topo.readers_of_topic.at("link_state")},
      {"isl_outcome writer", outcome_writer.handle(), true, topo.readers_of_topic.at("isl_outcome")},
      {"truth_state reader", truth_reader.handle(), false, 1},
      {"isl_broadcast reader", tx_reader.handle(), false, static_cast<int>(sc.observers.size())}};
  std::vector<std::unique_ptr<dds::Writer<artms_msg_IslBroadcast>>> relay_writers;
  for (const auto& l : xl.links()) {
    relay_writers.push_back(std::make_unique<dds::Writer<artms_msg_IslBroadcast>>(
        participant, topics.isl_relay, runtime::isl_relay_writer_qos(l.from, l.to, l.up_at_epoch, lifespan_s)));
    expect.push_back({"isl_relay writer " + l.from + "->" + l.to, relay_writers.back()->handle(), true,
                      topo.isl_relay_readers.at(l.from + "->" + l.to)});
  }
  clock.announce_ready(participant, expect, 60.0);
  std::vector<bool> up;
  for (const auto& l : xl.links()) up.push_back(l.up_at_epoch);

  while (auto tick = clock.wait_tick()) {
    const bus::Tick tk = runtime::from_wire(*tick);
    const astro::TimeTT t{tk.t_tt_ns};
    auto lo = xl.links(tk, runtime::take_all<bus::TruthState>(truth_reader), runtime::take_all<bus::IslBroadcast>(tx_reader));
    if (tk.final_step) {
      // Nothing is written at the final tick (the recorder may already be
      // closing); every relay was decided at the last navigation step.
      std::fprintf(stderr, "[%s] %s\n", opt.name.c_str(), xl.summary().c_str());
      clock.done(tick->step);
      return 0;
    }
    for (const auto& c : lo.changes) {
      const auto& l = xl.links()[c.link];
      auto& w = *relay_writers[c.link];
      w.set_partitions(participant, topics.isl_relay, runtime::isl_relay_writer_qos(l.from, l.to, c.up, lifespan_s));
      up[c.link] = c.up;
      if (!wait_matched(w, c.up ? 1 : 0, 30.0)) {
        events.warning(t.ns_since_j2000, "relay writer " + l.from + "->" + l.to + " did not " +
                                             (c.up ? "match its receiver" : "lose its match") +
                                             " within 30 s of the partition switch");
      }
    }
    for (const auto& s : lo.states) runtime::write(link_writer, s);
    events.publish(lo.events);
    const auto ro = xl.relay(tk, [&](std::size_t k) { return relay_writers[k]->matched_readers() >= 1; });
    for (const auto& r : ro.relays) {
      auto& w = *relay_writers[r.link];
      if (r.down && w.matched_readers() != 0) {
        const auto& l = xl.links()[r.link];
        throw std::runtime_error("link " + l.from + "->" + l.to + " is down but its relay writer is still matched");
      }
      runtime::write(w, r.msg);  // a down link's relay is written into "isl-down": DDS drops it
    }
    for (const auto& o : ro.outcomes) runtime::write(outcome_writer, o);
    events.publish(ro.events);
    for (std::size_t k = 0; k < relay_writers.size(); ++k) {
      if (up[k] && !relay_writers[k]->wait_for_acks(opt.step_timeout_s)) {
        const auto& l = xl.links()[k];
        events.warning(t.ns_since_j2000, "relays on " + l.from + "->" + l.to + " not acknowledged by the receiver");
      }
    }
    for (dds_entity_t w : {link_writer.handle(), outcome_writer.handle(), events.writer().handle()}) {
      dds::detail::wait_for_acks(w, opt.step_timeout_s);
    }
    clock.done(tick->step);
  }
  return runtime::g_stop_requested ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  return runtime::run_service(
      argc, argv, "artms-crosslink-emulator",
      "Crosslink emulator: relays every observer's ISL broadcast to every other observer over one DDS\n"
      "writer per directed link; outage windows, range limit, random loss and latency from the scenario,\n"
      "outages applied by moving the link's writer out of the receiver's partition.",
      run);
}
