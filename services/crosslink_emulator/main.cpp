// artms-crosslink-emulator: the only place the state of the inter-satellite
// link lives (DESIGN.md section 2). It reads every observer's broadcasts
// (artms_isl_broadcast, partition "isl-tx") and relays each one to each
// other observer through one writer per directed link (artms_isl_relay).
// Per link and step it decides whether the link is up: crosslink disabled,
// a scenario outage window, or range beyond crosslink.max_range_km (from
// truth) take it down. A link going down moves its writer into the partition
// "isl-down", which no reader subscribes to, so the DDS match disappears and
// whatever is written there is lost in DDS itself; going up moves it back
// into "isl-<from>-<to>". Random loss (crosslink.loss_probability, a seeded
// generator per link) drops single messages; latency holds a message until
// t_sent + latency. Every (broadcast, link) gets exactly one outcome
// (artms_isl_outcome -> isl.csv): delivered or dropped with its reason.
// README.md in this folder has the details.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "artms/runtime/runtime.hpp"

namespace {

using namespace artms;

struct Pending {
  std::int64_t release_ns;   // t_sent + latency
  std::size_t order;         // arrival order (deterministic: per sender, by sequence)
  std::size_t link;
  std::shared_ptr<artms_msg_IslBroadcast> msg;  // deep copy (own buffers)
  std::vector<artms_msg_BearingMeasurement> meas;
};

struct Link {
  std::string from, to;
  std::unique_ptr<dds::Writer<artms_msg_IslBroadcast>> writer;
  std::mt19937_64 rng;
  std::string down_reason;  // "" = up
  bool announced = false;
};

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
  std::vector<Link> links;
  std::vector<dds::MatchExpectation> expect = {
      {"event writer", events.writer().handle(), true, topo.readers_of_topic.at("event")},
      {"link_state writer", link_writer.handle(), true, topo.readers_of_topic.at("link_state")},
      {"isl_outcome writer", outcome_writer.handle(), true, topo.readers_of_topic.at("isl_outcome")},
      {"truth_state reader", truth_reader.handle(), false, 1},
      {"isl_broadcast reader", tx_reader.handle(), false, static_cast<int>(sc.observers.size())}};
  std::map<std::string, std::size_t> index;
  for (std::size_t k = 0; k < sc.spacecraft.size(); ++k) index[sc.spacecraft[k].id] = k;
  for (const auto& [from, to] : runtime::isl_links(sc)) {
    Link l;
    l.from = from;
    l.to = to;
    const bool up = topo.isl_relay_readers.at(from + "->" + to) > 0;
    l.writer = std::make_unique<dds::Writer<artms_msg_IslBroadcast>>(
        participant, topics.isl_relay, runtime::isl_relay_writer_qos(from, to, up, lifespan_s));
    // Deterministic loss draws: scenario seed + link (indices of its ends).
    std::seed_seq seq{static_cast<std::uint64_t>(sc.seed), std::uint64_t{0x15c11}, std::uint64_t{index[from]},
                      std::uint64_t{index[to]}};
    l.rng.seed(seq);
    l.down_reason = up ? "" : "initial";  // replaced at the first step
    links.push_back(std::move(l));
  }
  for (const auto& l : links) {
    expect.push_back({"isl_relay writer " + l.from + "->" + l.to, l.writer->handle(), true,
                      topo.isl_relay_readers.at(l.from + "->" + l.to)});
  }
  clock.announce_ready(participant, expect, 60.0);

  std::vector<Pending> pending;
  std::size_t arrivals = 0;
  std::map<std::string, Eigen::Vector3d> pos;
  const std::int64_t latency_ns = std::llround(sc.crosslink.latency_s * 1e9);
  const astro::TimeTT t_end = sc.epoch.plus_seconds(sc.duration_s - 0.5 * sc.step_s);
  std::size_t delivered = 0, dropped = 0;

  const auto outcome = [&](const Pending& p, const Link& l, std::int64_t t, bool ok, const std::string& reason,
                           double range_m) {
    artms_msg_IslOutcome o{};
    dds::copy_string(o.sender, sizeof o.sender, l.from);
    dds::copy_string(o.receiver, sizeof o.receiver, l.to);
    o.broadcast_seq = p.msg->broadcast_seq;
    o.t_sent_tt_ns = p.msg->t_tt_ns;
    o.t_tt_ns = t;
    o.delivered = ok;
    dds::copy_string(o.reason, sizeof o.reason, reason);
    o.source = p.msg->source;
    o.measurements = static_cast<std::uint32_t>(p.meas.size());
    o.range_m = range_m;
    outcome_writer.write(o);
    (ok ? delivered : dropped) += 1;
  };

  while (auto tick = clock.wait_tick()) {
    const astro::TimeTT t{tick->t_tt_ns};
    truth_reader.take_each([&](const artms_msg_TruthState& m) {
      if (m.t_tt_ns != tick->t_tt_ns) return;
      pos[dds::to_string(m.spacecraft, sizeof m.spacecraft)] =
          Eigen::Vector3d(m.r_eci_m[0], m.r_eci_m[1], m.r_eci_m[2]);
    });
    // New broadcasts: one pending relay per other observer (DDS keeps each
    // writer's order; across senders the order is made deterministic below).
    tx_reader.take_each([&](const artms_msg_IslBroadcast& b) {
      const std::string s = dds::to_string(b.sender, sizeof b.sender);
      for (std::size_t k = 0; k < links.size(); ++k) {
        if (links[k].from != s) continue;
        Pending p;
        p.release_ns = b.t_tt_ns + latency_ns;
        p.link = k;
        p.msg = std::make_shared<artms_msg_IslBroadcast>(b);
        p.meas.assign(b.measurements._buffer, b.measurements._buffer + b.measurements._length);
        p.msg->measurements._buffer = nullptr;
        p.msg->measurements._length = p.msg->measurements._maximum = 0;
        p.msg->measurements._release = false;
        p.order = arrivals++;
        pending.push_back(std::move(p));
      }
    });
    if (tick->final_step) {
      // Nothing is written at the final tick (the recorder may already be
      // closing); every relay was decided at the last navigation step.
      std::fprintf(stderr, "[%s] %zu relays delivered, %zu dropped\n", opt.name.c_str(), delivered, dropped);
      clock.done(tick->step);
      return 0;
    }
    // Link states at t.
    std::vector<double> range(links.size(), 0.0);
    for (std::size_t k = 0; k < links.size(); ++k) {
      Link& l = links[k];
      const auto a = pos.find(l.from), b = pos.find(l.to);
      range[k] = (a != pos.end() && b != pos.end()) ? (a->second - b->second).norm() : 0.0;
      const std::string reason = runtime::isl_link_down_reason(sc, l.from, l.to, t, range[k]);
      const bool changed = reason != l.down_reason;
      if (changed) {
        const bool up = reason.empty();
        l.writer->set_partitions(participant, topics.isl_relay,
                                 runtime::isl_relay_writer_qos(l.from, l.to, up, lifespan_s));
        if (!wait_matched(*l.writer, up ? 1 : 0, 30.0)) {
          events.warning(t.ns_since_j2000, "relay writer " + l.from + "->" + l.to + " did not " +
                                               (up ? "match its receiver" : "lose its match") +
                                               " within 30 s of the partition switch");
        }
      }
      if (changed || !l.announced) {
        artms_msg_LinkState st{};
        dds::copy_string(st.from_id, sizeof st.from_id, l.from);
        dds::copy_string(st.to_id, sizeof st.to_id, l.to);
        st.t_tt_ns = t.ns_since_j2000;
        st.up = reason.empty();
        dds::copy_string(st.reason, sizeof st.reason, reason.empty() ? (l.announced ? "restored" : "start") : reason);
        link_writer.write(st);
        if (l.announced) {
          events.info(t.ns_since_j2000, "link " + l.from + "->" + l.to + (reason.empty() ? " up" : " down: " + reason));
        }
        l.announced = true;
      }
      l.down_reason = reason;
    }
    // Relays due now (release time reached), in (release, arrival) order;
    // at the last navigation step every remaining one is decided.
    const bool last_step = t >= t_end;
    std::stable_sort(pending.begin(), pending.end(), [&](const Pending& x, const Pending& y) {
      if (x.release_ns != y.release_ns) return x.release_ns < y.release_ns;
      if (x.msg->t_tt_ns != y.msg->t_tt_ns) return x.msg->t_tt_ns < y.msg->t_tt_ns;
      if (x.link != y.link) return x.link < y.link;
      return x.order < y.order;
    });
    std::size_t n_done = 0;
    for (; n_done < pending.size(); ++n_done) {
      Pending& p = pending[n_done];
      Link& l = links[p.link];
      if (p.release_ns > t.ns_since_j2000) {
        if (!last_step) break;
        outcome(p, l, t.ns_since_j2000, false, "end_of_run", range[p.link]);
        continue;
      }
      // One draw per (broadcast, link) whatever the link state, so that the
      // loss pattern does not depend on outages.
      const bool lost = std::uniform_real_distribution<double>(0.0, 1.0)(l.rng) < sc.crosslink.loss_probability;
      artms_msg_IslBroadcast relay = *p.msg;
      dds::copy_string(relay.receiver, sizeof relay.receiver, l.to);
      relay.t_relayed_tt_ns = t.ns_since_j2000;
      relay.measurements._buffer = p.meas.data();
      relay.measurements._length = relay.measurements._maximum = static_cast<std::uint32_t>(p.meas.size());
      relay.measurements._release = false;
      if (!l.down_reason.empty()) {
        // Written into "isl-down": no reader matches, DDS drops it.
        if (l.writer->matched_readers() != 0) {
          throw std::runtime_error("link " + l.from + "->" + l.to + " is down but its relay writer is still matched");
        }
        l.writer->write(relay);
        outcome(p, l, t.ns_since_j2000, false, l.down_reason, range[p.link]);
      } else if (lost) {
        outcome(p, l, t.ns_since_j2000, false, "loss", range[p.link]);
      } else if (l.writer->matched_readers() < 1) {
        // The receiver process is gone (killed): nobody to deliver to.
        events.warning(t.ns_since_j2000, "link " + l.from + "->" + l.to + " up but its receiver is not matched");
        outcome(p, l, t.ns_since_j2000, false, "no_receiver", range[p.link]);
      } else {
        l.writer->write(relay);
        outcome(p, l, t.ns_since_j2000, true, "delivered", range[p.link]);
      }
    }
    pending.erase(pending.begin(), pending.begin() + static_cast<std::ptrdiff_t>(n_done));
    for (auto& l : links) {
      if (l.down_reason.empty() && !l.writer->wait_for_acks(opt.step_timeout_s)) {
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
