// artms-observer: one ARTMS process per observing spacecraft. Until IMP and
// SOD land it runs the GNSS-only baseline (navigation mode 0): its own
// absolute orbit from GNSS fixes, propagated between fixes with the onboard
// GVE/RK4 model. It never reads truth: it subscribes to its GNSS fixes only.
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>

#include "artms/astro/elements.hpp"
#include "artms/dynamics/gve.hpp"
#include "artms/config/uplink.hpp"
#include "artms/runtime/runtime.hpp"

namespace {

using namespace artms;

struct Fix {
  astro::TimeTT t;
  astro::StateVector x;
  double sigma_r, sigma_v;
};

int run(const runtime::ServiceOptions& opt) {
  // The observer knows only what the ground uplinked: never the scenario
  // (which holds the true orbits).
  if (opt.uplink_path.empty()) throw std::invalid_argument("artms-observer needs --uplink FILE");
  const config::ObserverUplink up = config::read_uplink(opt.uplink_path);
  const std::string me = up.observer.spacecraft;
  if (opt.name != "observer-" + me) {
    throw std::invalid_argument("service name " + opt.name + " does not match the uplink's observer " + me);
  }
  const config::ObserverConfig* cfg = &up.observer;
  dds::Participant participant(dds::domain_from_environment());
  runtime::TopicSet topics(participant);
  runtime::LockStepClient clock(participant, topics, opt.name, opt.step_timeout_s);
  dds::Reader<artms_msg_GnssFix> gnss_reader(participant, topics.gnss_fix, runtime::data_qos());
  // Only this observer's frames: the renderer writes them in partition frames-<id>.
  dds::Reader<artms_msg_CameraFrame> frame_reader(participant, topics.camera_frame, runtime::frame_qos(me));
  dds::Writer<artms_msg_NavTelemetry> nav_writer(participant, topics.nav_telemetry, runtime::data_qos());
  runtime::EventLog events(participant, topics, opt.name);
  // The onboard model (the observer's own, not the truth propagator).
  const auto forces = dynamics::ForceModel::load(up.force_model, ARTMS_DATA_DIR);
  const dynamics::GveRk4Propagator onboard(forces, dynamics::SpacecraftProperties{});

  // Readers of what the observer writes: the recorder only (runtime::topology).
  const std::map<std::string, int> rt = {{"nav_telemetry", 1}, {"event", 1}};
  clock.announce_ready(participant,
                       {{"nav_telemetry writer", nav_writer.handle(), true, rt.at("nav_telemetry")},
                        {"event writer", events.writer().handle(), true, rt.at("event")},
                        {"gnss_fix reader", gnss_reader.handle(), false, cfg->gnss.enabled ? 1 : 0},
                        {"camera_frame reader", frame_reader.handle(), false, 1}},
                       60.0);

  std::optional<Fix> last_fix;
  std::uint32_t frames_received = 0;
  std::size_t frames_rejected = 0;
  std::size_t rejected = 0;
  bool announced = false;
  while (auto tick = clock.wait_tick()) {
    const astro::TimeTT t{tick->t_tt_ns};
    if (!announced) {
      announced = true;
      events.info(t.ns_since_j2000,
                  "navigation mode " + std::to_string(cfg->mode) +
                      " requested; IMP/SOD not available yet: running the GNSS-only baseline (mode 0)");
    }
    gnss_reader.take_each([&](const artms_msg_GnssFix& f) {
      if (dds::to_string(f.spacecraft, sizeof f.spacecraft) != me || !f.valid) return;
      Fix fix{astro::TimeTT{f.t_tt_ns},
              {astro::Vec3(f.r_eci_m[0], f.r_eci_m[1], f.r_eci_m[2]),
               astro::Vec3(f.v_eci_mps[0], f.v_eci_mps[1], f.v_eci_mps[2])},
              f.sigma_position_m, f.sigma_velocity_mps};
      if (!fix.x.r_m.allFinite() || !fix.x.v_mps.allFinite() || !(fix.x.r_m.norm() > 6.4e6)) {
        ++rejected;  // counted rejection of a corrupt message
        events.warning(t.ns_since_j2000, "rejected a GNSS fix with invalid content (" +
                                             std::to_string(rejected) + " so far)");
        return;
      }
      if (!last_fix || last_fix->t <= fix.t) last_fix = fix;
    });
    // Camera frames (IMP arrives with the IMP issue): checked and counted.
    frame_reader.take_each([&](const artms_msg_CameraFrame& f) {
      const bool ok = f.width > 0 && f.height > 0 && f.bit_depth > 0 && f.bit_depth <= 16 &&
                      f.pixels._length == static_cast<std::uint32_t>(f.width) * f.height;
      if (!ok) {
        ++frames_rejected;
        events.warning(t.ns_since_j2000, "rejected a corrupt camera frame (" + std::to_string(frames_rejected) +
                                             " so far): size does not match its header");
        return;
      }
      ++frames_received;
    });
    if (!tick->final_step) {
      artms_msg_NavTelemetry nav{};
      nav.frames_received = frames_received;
      dds::copy_string(nav.observer, sizeof nav.observer, me);
      nav.t_tt_ns = t.ns_since_j2000;
      nav.mode = 0;
      if (last_fix) {
        astro::StateVector x = last_fix->x;
        const double dt = astro::seconds_between(last_fix->t, t);
        if (dt != 0.0) {
          const auto oe = onboard.propagate(astro::qns_from_cartesian(x), last_fix->t, t);
          x = astro::cartesian_from_qns(oe);
        }
        // Uncertainty of a propagated fix: velocity error times age, plus an
        // unmodelled acceleration of 1e-6 m/s^2 (documented in the README).
        const double sr = std::hypot(last_fix->sigma_r, last_fix->sigma_v * dt, 0.5e-6 * dt * dt);
        const double sv = std::hypot(last_fix->sigma_v, 1e-6 * dt);
        nav.health = 0;
        nav.source = 2;  // GNSS
        for (int i = 0; i < 3; ++i) {
          nav.r_eci_m[i] = x.r_m[i];
          nav.v_eci_mps[i] = x.v_mps[i];
          nav.covariance_rv[i * 6 + i] = sr * sr;
          nav.covariance_rv[(i + 3) * 6 + i + 3] = sv * sv;
        }
      } else {
        nav.health = 2;  // no solution yet
        nav.source = 0;
      }
      nav_writer.write(nav);
    }
    for (dds::Entity* w : {static_cast<dds::Entity*>(&nav_writer), static_cast<dds::Entity*>(&events.writer())}) {
      dds::detail::wait_for_acks(w->handle(), opt.step_timeout_s);
    }
    clock.done(tick->step);
    if (tick->final_step) return 0;
  }
  if (clock.timed_out()) {
    std::fprintf(stderr, "[%s] error: no clock tick within %.0f s (is truth running?)\n",
                 opt.name.c_str(), opt.step_timeout_s);
    return 1;
  }
  return runtime::g_stop_requested ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  return runtime::run_service(argc, argv, "artms-observer",
                              "One ARTMS observer process (IMP -> BOD -> SOD on its own frames, GNSS and ISL).\n"
      "Until IMP and SOD land it runs the GNSS-only baseline navigation mode.",
                              run);
}
