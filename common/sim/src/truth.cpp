#include <cmath>
#include <stdexcept>

#include "artms/astro/frames.hpp"
#include "artms/sim/services.hpp"

namespace artms::sim {

namespace {

bool in_any(const std::vector<config::TimeWindow>& windows, astro::TimeTT t) {
  for (const auto& w : windows) {
    if (w.start <= t && t < w.end) return true;
  }
  return false;
}

template <typename V>
std::array<double, 3> arr(const V& v) {
  return {v[0], v[1], v[2]};
}

}  // namespace

Truth::Truth(const config::Scenario& sc, std::shared_ptr<const dynamics::ForceModel> forces, std::string source)
    : sc_(sc),
      forces_(std::move(forces)),
      source_(bus::bounded(std::move(source), bus::kIdChars)),
      steps_(static_cast<std::int64_t>(std::floor(sc.duration_s / sc.step_s + 1e-9))) {
  if (!forces_) throw std::invalid_argument("sim::Truth: no force model");
  // Truth propagators, one per spacecraft, with the scenario's maneuvers.
  for (const auto& s : sc.spacecraft) {
    std::vector<dynamics::ImpulsiveManeuver> man;
    for (std::size_t i = 0; i < sc.maneuvers.size(); ++i) {
      if (sc.maneuvers[i].spacecraft == s.id) man.push_back({sc.maneuvers[i].epoch, config::executed_maneuver_dv(sc, i)});
    }
    props_.emplace_back(s.id, truth::CowellPropagator(*forces_, s.properties, sc.epoch, sc.initial_state_eci(s.id), man));
  }
  // Camera boresight per observing spacecraft (attitude of the body = camera V).
  for (const auto& o : sc.observers) boresight_[o.spacecraft] = o.camera.boresight;
  for (std::size_t k = 0; k < sc.observers.size(); ++k) {
    const auto& o = sc.observers[k];
    if (!o.gnss.enabled) continue;
    std::seed_seq seq{static_cast<std::uint64_t>(sc.seed), std::uint64_t{0x67e55}, std::uint64_t{k}};
    gnss_.push_back({o.spacecraft, o.gnss, std::mt19937_64(seq)});
  }
}

bus::Tick Truth::tick(std::int64_t k) const {
  const astro::TimeTT t = sc_.epoch.plus_seconds(static_cast<double>(std::min(k, steps_)) * sc_.step_s);
  return {k, t.ns_since_j2000, k == steps_ + 1};
}

bus::Event Truth::started() const {
  return {source_, sc_.epoch.ns_since_j2000, bus::Severity::kInfo,
          bus::bounded("run started: " + std::to_string(sc_.spacecraft.size()) + " spacecraft, " +
                           forces_->options().describe(),
                       bus::kEventTextChars)};
}

Truth::StepOutput Truth::step(std::int64_t k) {
  if (k < 0 || k > steps_) throw std::out_of_range("sim::Truth::step: step " + std::to_string(k) + " out of range");
  StepOutput out;
  const astro::TimeTT t = astro::TimeTT{tick(k).t_tt_ns};
  std::map<std::string, astro::StateVector> now;
  for (auto& [id, prop] : props_) {
    const astro::StateVector x = prop.state_at(t);
    now[id] = x;
    bus::TruthState m;
    m.spacecraft = id;
    m.t_tt_ns = t.ns_since_j2000;
    m.r_eci_m = arr(x.r_m);
    m.v_eci_mps = arr(x.v_mps);
    const auto it = boresight_.find(id);
    const astro::Mat3 R = it != boresight_.end() ? astro::R_v_from_eci(x, it->second) : astro::R_rtn_from_eci(x);
    m.q_body_from_eci = astro::wxyz_from_quaternion(Eigen::Quaterniond(R));
    out.states.push_back(std::move(m));
  }
  const double since_epoch = static_cast<double>(k) * sc_.step_s;
  for (auto& g : gnss_) {
    const double phase = std::fmod(since_epoch, g.cfg.period_s);
    if (phase > 1e-6 && g.cfg.period_s - phase > 1e-6) continue;
    const astro::StateVector& x = now.at(g.spacecraft);
    bus::GnssFix f;
    f.spacecraft = g.spacecraft;
    f.t_tt_ns = t.ns_since_j2000;
    f.valid = !in_any(g.cfg.outages, t);
    for (std::size_t i = 0; i < 3; ++i) {
      // Noise is drawn even during outages so the sequence does not depend on them.
      const double nr = normal_(g.rng), nv = normal_(g.rng);
      f.r_eci_m[i] = f.valid ? x.r_m[static_cast<int>(i)] + g.cfg.sigma_position_m * nr : 0.0;
      f.v_eci_mps[i] = f.valid ? x.v_mps[static_cast<int>(i)] + g.cfg.sigma_velocity_mps * nv : 0.0;
    }
    f.sigma_position_m = g.cfg.sigma_position_m;
    f.sigma_velocity_mps = g.cfg.sigma_velocity_mps;
    out.gnss.push_back(std::move(f));
  }
  return out;
}

}  // namespace artms::sim
