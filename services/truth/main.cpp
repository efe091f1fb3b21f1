// artms-truth: the truth service and clock master (DESIGN.md sections 2, 3).
// Integrates every spacecraft with the CVODE truth propagator, publishes
// truth states and noisy GNSS fixes, and drives the lock-step clock.
#include <chrono>
#include <cstdio>
#include <map>
#include <random>
#include <set>
#include <thread>

#include "artms/astro/frames.hpp"
#include "artms/runtime/runtime.hpp"
#include "artms/truth_propagator/cowell.hpp"

namespace {

using namespace artms;

struct GnssChannel {
  std::string spacecraft;
  config::GnssConfig cfg;
  std::mt19937_64 rng;
};

bool in_any(const std::vector<config::TimeWindow>& windows, astro::TimeTT t) {
  for (const auto& w : windows) {
    if (w.start <= t && t < w.end) return true;
  }
  return false;
}

int run(const runtime::ServiceOptions& opt) {
  const config::Scenario sc = runtime::load_for_service(opt);
  const runtime::Topology topo = runtime::topology(sc);
  dds::Participant participant(dds::domain_from_environment());
  runtime::TopicSet topics(participant);
  dds::Writer<artms_msg_ClockTick> tick_writer(participant, topics.clock_tick, runtime::clock_qos());
  dds::Writer<artms_msg_TruthState> state_writer(participant, topics.truth_state, runtime::data_qos());
  dds::Writer<artms_msg_GnssFix> gnss_writer(participant, topics.gnss_fix, runtime::data_qos());
  dds::Reader<artms_msg_StepDone> done_reader(participant, topics.step_done, runtime::step_done_qos());
  dds::WaitSet waitset(participant);
  waitset.attach(done_reader.handle());
  runtime::EventLog events(participant, topics, opt.name);

  // Truth propagators, one per spacecraft, with the scenario's maneuvers.
  const auto forces = dynamics::ForceModel::load(sc.force_model, ARTMS_DATA_DIR);
  std::vector<std::pair<std::string, truth::CowellPropagator>> props;
  for (const auto& s : sc.spacecraft) {
    std::vector<dynamics::ImpulsiveManeuver> man;
    for (const auto& m : sc.maneuvers) {
      if (m.spacecraft == s.id) man.push_back({m.epoch, m.dv_rtn_mps});
    }
    props.emplace_back(s.id, truth::CowellPropagator(forces, s.properties, sc.epoch,
                                                     sc.initial_state_eci(s.id), man));
  }
  // Camera boresight per observing spacecraft (attitude of the body = camera V).
  std::map<std::string, astro::Boresight> boresight;
  for (const auto& o : sc.observers) boresight[o.spacecraft] = o.camera.boresight;
  std::vector<GnssChannel> gnss;
  for (std::size_t k = 0; k < sc.observers.size(); ++k) {
    const auto& o = sc.observers[k];
    if (!o.gnss.enabled) continue;
    std::seed_seq seq{static_cast<std::uint64_t>(sc.seed), std::uint64_t{0x67e55}, std::uint64_t{k}};
    gnss.push_back({o.spacecraft, o.gnss, std::mt19937_64(seq)});
  }

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
          throw std::runtime_error("service " + who + " reported failure at step " +
                                   std::to_string(d.step));
        }
        it->second = std::max(it->second, d.step);
      });
      std::string missing;
      for (const auto& [who, s] : last_done) {
        if (s < step) missing += (missing.empty() ? "" : ", ") + who;
      }
      if (missing.empty()) return;
      if (runtime::g_stop_requested) throw std::runtime_error("stop requested");
      const double left =
          std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count();
      if (left <= 0.0) {
        throw std::runtime_error("no answer within " + std::to_string(static_cast<int>(timeout_s)) +
                                 " s for step " + std::to_string(step) + " from: " + missing);
      }
      waitset.wait(std::min(left, 0.5));
    }
  };
  wait_all_done(-1, 60.0);
  events.info(sc.epoch.ns_since_j2000,
              "run started: " + std::to_string(sc.spacecraft.size()) + " spacecraft, " +
                  forces.options().describe());

  const auto steps = static_cast<std::int64_t>(std::floor(sc.duration_s / sc.step_s + 1e-9));
  const auto wall_start = std::chrono::steady_clock::now();
  std::normal_distribution<double> normal(0.0, 1.0);
  for (std::int64_t k = 0; k <= steps + 1; ++k) {
    const bool final_step = k == steps + 1;
    const astro::TimeTT t = sc.epoch.plus_seconds(static_cast<double>(std::min(k, steps)) * sc.step_s);
    if (!final_step) {
      for (auto& [id, prop] : props) {
        const astro::StateVector x = prop.state_at(t);
        artms_msg_TruthState m{};
        dds::copy_string(m.spacecraft, sizeof m.spacecraft, id);
        m.t_tt_ns = t.ns_since_j2000;
        for (int i = 0; i < 3; ++i) {
          m.r_eci_m[i] = x.r_m[i];
          m.v_eci_mps[i] = x.v_mps[i];
        }
        const auto it = boresight.find(id);
        const astro::Mat3 R = it != boresight.end() ? astro::R_v_from_eci(x, it->second)
                                                    : astro::R_rtn_from_eci(x);
        const auto q = astro::wxyz_from_quaternion(Eigen::Quaterniond(R));
        for (int i = 0; i < 4; ++i) m.q_body_from_eci[i] = q[static_cast<std::size_t>(i)];
        state_writer.write(m);
      }
      const double since_epoch = static_cast<double>(k) * sc.step_s;
      for (auto& g : gnss) {
        const double phase = std::fmod(since_epoch, g.cfg.period_s);
        if (phase > 1e-6 && g.cfg.period_s - phase > 1e-6) continue;
        const astro::StateVector x = [&] {
          for (auto& [id, prop] : props) {
            if (id == g.spacecraft) return prop.state_at(t);
          }
          throw std::logic_error("unknown GNSS spacecraft " + g.spacecraft);
        }();
        artms_msg_GnssFix f{};
        dds::copy_string(f.spacecraft, sizeof f.spacecraft, g.spacecraft);
        f.t_tt_ns = t.ns_since_j2000;
        f.valid = !in_any(g.cfg.outages, t);
        for (int i = 0; i < 3; ++i) {
          // Draw noise even during outages so the sequence does not depend on them.
          const double nr = normal(g.rng), nv = normal(g.rng);
          f.r_eci_m[i] = f.valid ? x.r_m[i] + g.cfg.sigma_position_m * nr : 0.0;
          f.v_eci_mps[i] = f.valid ? x.v_mps[i] + g.cfg.sigma_velocity_mps * nv : 0.0;
        }
        f.sigma_position_m = g.cfg.sigma_position_m;
        f.sigma_velocity_mps = g.cfg.sigma_velocity_mps;
        gnss_writer.write(f);
      }
      // Everything stamped <= t is in every reader's cache before the tick.
      for (auto* w : {static_cast<dds::Entity*>(&state_writer), static_cast<dds::Entity*>(&gnss_writer),
                      static_cast<dds::Entity*>(&events.writer())}) {
        if (!dds::detail::wait_for_acks(w->handle(), opt.step_timeout_s)) {
          throw std::runtime_error("a reader did not acknowledge data of step " + std::to_string(k));
        }
      }
    }
    if (opt.rate > 0.0 && !final_step) {
      // Real-time-scaled mode: tick k no earlier than its wall-clock time.
      const auto due = wall_start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                        std::chrono::duration<double>(static_cast<double>(k) * sc.step_s / opt.rate));
      std::this_thread::sleep_until(due);
    }
    artms_msg_ClockTick tick{};
    tick.step = k;
    tick.t_tt_ns = t.ns_since_j2000;
    tick.final_step = final_step;
    tick_writer.write(tick);
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
