#include <algorithm>
#include <cmath>

#include "artms/config/links.hpp"
#include "artms/sim/services.hpp"

namespace artms::sim {

Crosslink::Crosslink(const config::Scenario& sc, std::string source)
    : sc_(sc),
      events_(std::move(source)),
      latency_ns_(std::llround(sc.crosslink.latency_s * 1e9)),
      t_end_(sc.epoch.plus_seconds(sc.duration_s - 0.5 * sc.step_s)) {
  std::map<std::string, std::size_t> index;
  for (std::size_t k = 0; k < sc.spacecraft.size(); ++k) index[sc.spacecraft[k].id] = k;
  for (const auto& [from, to] : config::isl_links(sc)) {
    Link l;
    l.from = from;
    l.to = to;
    // Up at the epoch (from the initial states): its writer starts matched.
    l.up_at_epoch = config::isl_link_up_at_epoch(sc, from, to);
    links_.push_back(l);
    // Deterministic loss draws: scenario seed + link (indices of its ends).
    std::seed_seq seq{static_cast<std::uint64_t>(sc.seed), std::uint64_t{0x15c11}, std::uint64_t{index[from]},
                      std::uint64_t{index[to]}};
    rng_.emplace_back(seq);
    down_reason_.push_back(l.up_at_epoch ? "" : "initial");  // replaced at the first step
    announced_.push_back(false);
  }
  range_.assign(links_.size(), 0.0);
}

Crosslink::LinkOutput Crosslink::links(const bus::Tick& tick, const std::vector<bus::TruthState>& states,
                                       std::vector<bus::IslBroadcast> broadcasts) {
  LinkOutput out;
  const astro::TimeTT t{tick.t_tt_ns};
  for (const auto& m : states) {
    if (m.t_tt_ns == tick.t_tt_ns) pos_[m.spacecraft] = Eigen::Vector3d(m.r_eci_m[0], m.r_eci_m[1], m.r_eci_m[2]);
  }
  // New broadcasts: one pending relay per other observer (each sender's
  // order is kept; across senders the order is made deterministic in relay()).
  for (auto& b : broadcasts) {
    auto msg = std::make_shared<const bus::IslBroadcast>(std::move(b));
    for (std::size_t k = 0; k < links_.size(); ++k) {
      if (links_[k].from != msg->sender) continue;
      pending_.push_back({msg->t_tt_ns + latency_ns_, arrivals_++, k, msg});
    }
  }
  if (tick.final_step) return out;  // nothing is written at the final tick
  for (std::size_t k = 0; k < links_.size(); ++k) {
    const Link& l = links_[k];
    const auto a = pos_.find(l.from), b = pos_.find(l.to);
    range_[k] = (a != pos_.end() && b != pos_.end()) ? (a->second - b->second).norm() : 0.0;
    const std::string reason = config::isl_link_down_reason(sc_, l.from, l.to, t, range_[k]);
    const bool changed = reason != down_reason_[k];
    if (changed) out.changes.push_back({k, reason.empty()});
    if (changed || !announced_[k]) {
      out.states.push_back({l.from, l.to, t.ns_since_j2000, reason.empty(),
                            reason.empty() ? (announced_[k] ? "restored" : "start") : reason});
      if (announced_[k]) {
        events_.info(t.ns_since_j2000, "link " + l.from + "->" + l.to + (reason.empty() ? " up" : " down: " + reason));
      }
      announced_[k] = true;
    }
    down_reason_[k] = reason;
  }
  out.events = events_.take();
  return out;
}

Crosslink::RelayOutput Crosslink::relay(const bus::Tick& tick, const std::function<bool(std::size_t)>& receiver_present) {
  RelayOutput out;
  if (tick.final_step) return out;
  const astro::TimeTT t{tick.t_tt_ns};
  const bool last_step = t >= t_end_;
  std::stable_sort(pending_.begin(), pending_.end(), [](const Pending& x, const Pending& y) {
    if (x.release_ns != y.release_ns) return x.release_ns < y.release_ns;
    if (x.msg->t_tt_ns != y.msg->t_tt_ns) return x.msg->t_tt_ns < y.msg->t_tt_ns;
    if (x.link != y.link) return x.link < y.link;
    return x.order < y.order;
  });
  const auto outcome = [&](const Pending& p, bool ok, const std::string& reason) {
    bus::IslOutcome o;
    o.sender = links_[p.link].from;
    o.receiver = links_[p.link].to;
    o.broadcast_seq = p.msg->broadcast_seq;
    o.t_sent_tt_ns = p.msg->t_tt_ns;
    o.t_tt_ns = t.ns_since_j2000;
    o.delivered = ok;
    o.reason = reason;
    o.source = p.msg->source;
    o.measurements = static_cast<std::uint32_t>(p.msg->measurements.size());
    o.range_m = range_[p.link];
    out.outcomes.push_back(std::move(o));
    (ok ? delivered_ : dropped_) += 1;
  };
  std::size_t n_done = 0;
  for (; n_done < pending_.size(); ++n_done) {
    const Pending& p = pending_[n_done];
    // Due: its release time reached and sent at an earlier step (a broadcast
    // of this step may or may not have arrived yet: it always waits).
    if (p.release_ns > t.ns_since_j2000 || p.msg->t_tt_ns >= t.ns_since_j2000) {
      if (!last_step) break;
      outcome(p, false, "end_of_run");
      continue;
    }
    // One draw per (broadcast, link) whatever the link state, so that the
    // loss pattern does not depend on outages.
    const bool lost = std::uniform_real_distribution<double>(0.0, 1.0)(rng_[p.link]) < sc_.crosslink.loss_probability;
    Relay r;
    r.link = p.link;
    r.msg = *p.msg;
    r.msg.receiver = links_[p.link].to;
    r.msg.t_relayed_tt_ns = t.ns_since_j2000;
    if (!down_reason_[p.link].empty()) {
      r.down = true;  // into the down partition: no reader, lost in transport
      out.relays.push_back(std::move(r));
      outcome(p, false, down_reason_[p.link]);
    } else if (lost) {
      outcome(p, false, "loss");
    } else if (!receiver_present(p.link)) {
      // The receiver process is gone (killed): nobody to deliver to.
      events_.warning(t.ns_since_j2000,
                      "link " + links_[p.link].from + "->" + links_[p.link].to + " up but its receiver is not matched");
      outcome(p, false, "no_receiver");
    } else {
      out.relays.push_back(std::move(r));
      outcome(p, true, "delivered");
    }
  }
  pending_.erase(pending_.begin(), pending_.begin() + static_cast<std::ptrdiff_t>(n_done));
  out.events = events_.take();
  return out;
}

std::string Crosslink::summary() const {
  return std::to_string(delivered_) + " relays delivered, " + std::to_string(dropped_) + " dropped";
}

}  // namespace artms::sim
