// sim::Crosslink stepped without DDS on starling_it_pair.yaml (two observers
// with a 00:30-01:15 outage on every link): a broadcast is never relayed in
// the step it was sent in (whether it arrived then or not), latency holds it
// to the first step at or after t_sent + latency, an outage drops it with
// its reason, and every (broadcast, link) gets exactly one outcome.
#include <gtest/gtest.h>

#include <map>

#include "artms/config/scenario.hpp"
#include "artms/sim/services.hpp"

namespace artms::sim {
namespace {

config::Scenario pair_scenario(double latency_s) {
  config::Scenario sc = config::load_scenario(std::string(ARTMS_SCENARIO_DIR) + "/starling_it_pair.yaml");
  sc.duration_s = 7200.0;
  sc.crosslink.latency_s = latency_s;
  return sc;
}

std::vector<bus::TruthState> states_at(const config::Scenario& sc, const bus::Tick& tick) {
  std::vector<bus::TruthState> out;
  for (const auto& s : sc.spacecraft) {
    bus::TruthState m;
    m.spacecraft = s.id;
    m.t_tt_ns = tick.t_tt_ns;
    const auto x = sc.initial_state_eci(s.id);  // close enough for the range check
    for (int i = 0; i < 3; ++i) m.r_eci_m[static_cast<std::size_t>(i)] = x.r_m[i];
    out.push_back(m);
  }
  return out;
}

bus::IslBroadcast broadcast(const std::string& sender, std::int64_t t_ns, std::uint32_t seq) {
  bus::IslBroadcast b;
  b.sender = sender;
  b.t_tt_ns = t_ns;
  b.broadcast_seq = seq;
  b.source = 2;
  return b;
}

// Every observer broadcasts at every step; `early`: the broadcast of step k
// reaches the emulator during step k, else at step k + 1.
std::vector<bus::IslOutcome> run(const config::Scenario& sc, bool early) {
  Crosslink xl(sc, "crosslink-emulator");
  const std::int64_t steps = static_cast<std::int64_t>(sc.duration_s / sc.step_s);
  std::vector<bus::IslOutcome> outcomes;
  std::vector<bus::IslBroadcast> late;
  for (std::int64_t k = 0; k <= steps + 1; ++k) {
    const bus::Tick tick{k, sc.epoch.plus_seconds(static_cast<double>(std::min(k, steps)) * sc.step_s).ns_since_j2000,
                         k == steps + 1};
    std::vector<bus::IslBroadcast> in = std::move(late);
    late.clear();
    if (k < steps) {  // nobody broadcasts at the last navigation step
      for (const auto& o : sc.observers) {
        (early ? in : late).push_back(broadcast(o.spacecraft, tick.t_tt_ns, static_cast<std::uint32_t>(k)));
      }
    }
    xl.links(tick, states_at(sc, tick), std::move(in));
    const auto ro = xl.relay(tick, [](std::size_t) { return true; });
    for (const auto& r : ro.relays) EXPECT_GT(r.msg.t_relayed_tt_ns, r.msg.t_tt_ns);
    outcomes.insert(outcomes.end(), ro.outcomes.begin(), ro.outcomes.end());
  }
  return outcomes;
}

TEST(Crosslink, ABroadcastIsRelayedAtTheNextStepWhenItArrived) {
  const auto sc = pair_scenario(0.0);
  const auto a = run(sc, true), b = run(sc, false);
  ASSERT_EQ(a.size(), b.size());
  std::map<std::string, int> reasons;
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].sender, b[i].sender);
    EXPECT_EQ(a[i].broadcast_seq, b[i].broadcast_seq);
    EXPECT_EQ(a[i].t_tt_ns, b[i].t_tt_ns);
    EXPECT_EQ(a[i].reason, b[i].reason);
    ++reasons[a[i].reason];
    if (a[i].reason != "end_of_run") {
      EXPECT_EQ(a[i].t_tt_ns - a[i].t_sent_tt_ns, 60'000'000'000LL);
    }
  }
  // 120 broadcasts per link (steps 0..119), two links, one outcome each.
  EXPECT_EQ(a.size(), 2U * 120U);
  EXPECT_GT(reasons["outage"], 0);
  EXPECT_GT(reasons["delivered"], 0);
}

TEST(Crosslink, LatencyHoldsARelayToTheFirstStepAfterIt) {
  int decided = 0;
  for (const auto& o : run(pair_scenario(90.0), true)) {
    if (o.reason == "end_of_run") continue;
    EXPECT_EQ(o.t_tt_ns - o.t_sent_tt_ns, 120'000'000'000LL);
    ++decided;
  }
  EXPECT_EQ(decided, 2 * 119);  // the broadcasts of step 119 reach no step >= t + 90 s
}

}  // namespace
}  // namespace artms::sim
