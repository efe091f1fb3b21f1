#include <cmath>

#include "artms/astro/frames.hpp"
#include "artms/sim/services.hpp"

namespace artms::sim {

CameraRenderer::CameraRenderer(const config::Scenario& sc, std::string source) : sc_(sc), events_(std::move(source)) {
  for (const auto& o : sc.observers) {
    Channel c;
    c.id = o.spacecraft;
    c.setup = std::make_unique<render::FrameSetup>(
        render::make_frame_setup(sc, o.spacecraft, "", o.camera.flight_like, false));
    channels_.push_back(std::move(c));
  }
}

std::vector<std::string> CameraRenderer::observers() const {
  std::vector<std::string> out;
  for (const auto& c : channels_) out.push_back(c.id);
  return out;
}

CameraRenderer::StepOutput CameraRenderer::step(const bus::Tick& tick, const std::vector<bus::TruthState>& states) {
  StepOutput out;
  if (tick.final_step) return out;
  const astro::TimeTT t{tick.t_tt_ns};
  std::map<std::string, astro::StateVector> now;
  for (const auto& m : states) {
    if (m.t_tt_ns != tick.t_tt_ns) continue;
    now[m.spacecraft] = {astro::Vec3(m.r_eci_m[0], m.r_eci_m[1], m.r_eci_m[2]),
                         astro::Vec3(m.v_eci_mps[0], m.v_eci_mps[1], m.v_eci_mps[2])};
  }
  const double since = astro::seconds_between(sc_.epoch, t);
  for (auto& c : channels_) {
    const double cadence = c.setup->camera_config.cadence_s;
    const double phase = std::fmod(since, cadence);
    if (phase > 1e-6 && cadence - phase > 1e-6) continue;
    if (!now.count(c.id)) {
      events_.error(t.ns_since_j2000, "no truth state for observer " + c.id + " at this step");
      continue;
    }
    imaging::RenderRequest req;
    req.observer = c.id;
    req.frame_index = static_cast<std::uint64_t>(std::llround(since / cadence));
    req.t = t;
    req.observer_eci = now.at(c.id);
    for (const auto& [id, x] : now) {
      if (id != c.id) req.targets.push_back({id, x.r_m});
    }
    req.q_cam_from_eci = c.setup->attitude(req.observer_eci, req.frame_index);
    imaging::RenderedFrame f = c.setup->renderer.render(req);
    ++c.rendered;
    bus::FrameTruth ft;
    ft.observer = c.id;
    ft.frame_seq = static_cast<std::uint32_t>(req.frame_index);
    ft.t_tt_ns = t.ns_since_j2000;
    ft.time_tag_tt_ns = f.time_tag.ns_since_j2000;
    ft.dropped = f.dropped;
    ft.exclusion = bus::bounded(f.exclusion.excluded ? f.exclusion.reason : "none", bus::kShortReasonChars);
    ft.q_cam_from_eci = astro::wxyz_from_quaternion(req.q_cam_from_eci);
    ft.stars_used = static_cast<std::uint32_t>(f.stars.size());
    for (const auto& tp : f.targets) {
      ft.targets.push_back({bus::bounded(tp.id, bus::kIdChars), tp.x_px, tp.y_px, tp.vmag, tp.range_m, tp.visible,
                            bus::bounded(tp.reason, bus::kReasonChars)});
    }
    out.truths.push_back(std::move(ft));
    if (f.exclusion.excluded) ++c.excluded;
    if (f.dropped) {
      ++c.dropped;
      continue;
    }
    bus::CameraFrame frame;
    frame.observer = c.id;
    frame.camera = bus::bounded(c.setup->camera_config.model, bus::kIdChars);
    frame.frame_seq = static_cast<std::uint32_t>(req.frame_index);
    frame.time_tag_tt_ns = f.time_tag.ns_since_j2000;
    frame.width = static_cast<std::uint16_t>(f.width);
    frame.height = static_cast<std::uint16_t>(f.height);
    frame.bit_depth = static_cast<std::uint8_t>(c.setup->renderer.camera().bit_depth);
    frame.pixels = std::move(f.pixels);
    out.frames.push_back(std::move(frame));
  }
  out.events = events_.take();
  return out;
}

std::vector<std::string> CameraRenderer::summary() const {
  std::vector<std::string> out;
  for (const auto& c : channels_) {
    out.push_back(c.id + ": " + std::to_string(c.rendered) + " frames rendered, " + std::to_string(c.dropped) +
                  " dropped, " + std::to_string(c.excluded) + " excluded");
  }
  return out;
}

}  // namespace artms::sim
