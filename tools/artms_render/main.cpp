// artms-render: renders frames for one observer of a scenario (DESIGN.md
// section 7): DIR/frame_<k>.png (16-bit holding the 12-bit values),
// DIR/preview_<k>.png (8-bit, stretched) and the truth sidecar
// DIR/frame_<k>.json. A dropped frame (scenario fault) has only its sidecar,
// with "dropped": true.
#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>

#include "artms/astro/constants.hpp"
#include "artms/config/scenario.hpp"
#include "artms/imaging/renderer.hpp"
#include "artms/io/duration.hpp"
#include "artms/io/paths.hpp"
#include "artms/render/frame_setup.hpp"
#include "artms/truth_propagator/cowell.hpp"

namespace {

using namespace artms;
namespace fs = std::filesystem;

nlohmann::json number_or_null(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

int run(int argc, char** argv) {
  CLI::App app{"Render NST-like star-tracker frames for one observer of a scenario, with truth sidecars.",
               "artms-render"};
  std::string scenario_path, observer, start, every = "60s", out, profile, camera_path;
  int count = 1;
  bool noise_free = false;
  app.add_option("scenario", scenario_path, "scenario YAML")->required();
  app.add_option("--observer", observer, "observer spacecraft id")->required();
  app.add_option("--start", start, "UTC of the first frame (default: scenario epoch)");
  app.add_option("--count", count, "number of frames")->capture_default_str()->check(CLI::Range(1, 100000));
  app.add_option("--every", every, "interval between frames")->capture_default_str();
  app.add_option("--out", out, "output folder")->required();
  app.add_option("--profile", profile, "target photometry: nominal | flight-like (default: the scenario's)");
  app.add_option("--camera", camera_path, "camera YAML (default config/cameras/<model>.yaml)");
  app.add_flag("--noise-free", noise_free, "no noise, no faint stars: the expected signal (for geometry checks)");
  std::uint64_t seed = 0;
  std::string epoch_window;
  double phase_window_deg = 0.0;
  auto* seed_opt = app.add_option("--seed", seed, "random seed (overrides the scenario's, as artms-swarm run --seed)");
  app.add_option("--epoch-window", epoch_window,
                 "overrides the scenario's epoch_window (the run's epoch drawn from the seed, as artms-swarm run)");
  auto* pw = app.add_option("--phase-window-deg", phase_window_deg,
                            "overrides the scenario's phase_window_deg (the orbit phase drawn from the seed, as "
                            "artms-swarm run)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  try {
    config::Scenario sc = config::load_scenario(scenario_path);
    if (!epoch_window.empty()) config::set_epoch_window(sc, io::parse_duration_s(epoch_window));
    if (pw->count() > 0) config::set_phase_window(sc, phase_window_deg);
    if (seed_opt->count() > 0) config::set_seed(sc, seed);
    const double every_s = io::parse_duration_s(every);
    if (!(every_s > 0.0)) throw std::invalid_argument("--every must be positive");
    const astro::TimeTT t0 = start.empty() ? sc.epoch : astro::tt_from_utc_string(start);
    if (t0 < sc.epoch) throw std::invalid_argument("--start is before the scenario epoch " + astro::utc_string(sc.epoch));
    if (!profile.empty() && profile != "nominal" && profile != "flight-like") {
      throw std::invalid_argument("--profile must be nominal or flight-like, got '" + profile + "'");
    }
    bool flight_like = false;
    for (const auto& o : sc.observers) {
      if (o.spacecraft == observer) flight_like = o.camera.flight_like;
    }
    if (!profile.empty()) flight_like = profile == "flight-like";
    render::FrameSetup setup = render::make_frame_setup(sc, observer, camera_path, flight_like, noise_free);
    fs::create_directories(out);
    // Truth for every spacecraft (the renderer is a truth-side tool).
    const auto forces = dynamics::ForceModel::load(sc.force_model, io::data_dir());
    std::vector<std::pair<std::string, truth::CowellPropagator>> props;
    for (const auto& s : sc.spacecraft) {
      std::vector<dynamics::ImpulsiveManeuver> man;
      for (std::size_t i = 0; i < sc.maneuvers.size(); ++i) {
        const auto& m = sc.maneuvers[i];
        if (m.spacecraft == s.id && sc.epoch < m.epoch) man.push_back({m.epoch, config::executed_maneuver_dv(sc, i)});
      }
      props.emplace_back(s.id, truth::CowellPropagator(forces, s.properties, sc.epoch, sc.initial_state_eci(s.id), man));
    }
    const auto& cam = setup.renderer.camera();
    int dropped = 0;
    // The observer's orbit at each frame (truth side): artms-imp --observer-orbit
    // takes it, or any coarse estimate in the same columns (e.g. nav/<id>.csv).
    std::ofstream orbit_csv(fs::path(out) / "observer_orbit.csv");
    orbit_csv << "t_tt_ns,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps\n";
    for (int k = 0; k < count; ++k) {
      const astro::TimeTT t = t0.plus_seconds(k * every_s);
      imaging::RenderRequest req;
      req.observer = observer;
      req.frame_index = static_cast<std::uint64_t>(std::llround(astro::seconds_between(sc.epoch, t) / every_s));
      req.t = t;
      for (auto& [id, p] : props) {
        const astro::StateVector x = p.state_at(t);
        if (id == observer) {
          req.observer_eci = x;
        } else {
          req.targets.push_back({id, x.r_m});
        }
      }
      req.q_cam_from_eci = setup.attitude(req.observer_eci, req.frame_index);
      {
        char row[256];
        const auto& x = req.observer_eci;
        std::snprintf(row, sizeof row, "%lld,%.4f,%.4f,%.4f,%.7f,%.7f,%.7f\n", static_cast<long long>(t.ns_since_j2000),
                      x.r_m.x(), x.r_m.y(), x.r_m.z(), x.v_mps.x(), x.v_mps.y(), x.v_mps.z());
        orbit_csv << row;
      }
      const imaging::RenderedFrame f = setup.renderer.render(req);
      char stem[32];
      std::snprintf(stem, sizeof stem, "frame_%06d", k);
      nlohmann::json j;
      j["t_utc"] = astro::utc_string(t, 3);
      j["t_tt_ns"] = t.ns_since_j2000;
      j["time_tag_tt_ns"] = f.time_tag.ns_since_j2000;
      j["observer"] = observer;
      j["width"] = f.width;
      j["height"] = f.height;
      j["fx_px"] = cam.fx_px;
      j["fy_px"] = cam.fy_px;
      j["cx_px"] = cam.cx_px;
      j["cy_px"] = cam.cy_px;
      j["k1"] = cam.k1;
      j["k2"] = cam.k2;
      const auto q = astro::wxyz_from_quaternion(req.q_cam_from_eci);
      j["q_cam_from_eci"] = {q[0], q[1], q[2], q[3]};
      j["dropped"] = f.dropped;
      j["exclusion"] = f.exclusion.excluded ? f.exclusion.reason : "none";
      j["faint_stars"] = f.faint_stars;
      j["stars"] = nlohmann::json::array();
      for (const auto& s : f.stars) {
        j["stars"].push_back({{"catalog_id", s.catalog_id}, {"ra_deg", s.ra_deg}, {"dec_deg", s.dec_deg},
                              {"vmag", s.vmag}, {"x_px", s.x_px}, {"y_px", s.y_px}});
      }
      j["targets"] = nlohmann::json::array();
      for (const auto& tt : f.targets) {
        j["targets"].push_back({{"id", tt.id}, {"x_px", number_or_null(tt.x_px)}, {"y_px", number_or_null(tt.y_px)},
                                {"vmag", number_or_null(tt.vmag)}, {"range_m", tt.range_m},
                                {"visible", tt.visible}, {"reason", tt.reason}});
      }
      std::ofstream(fs::path(out) / (std::string(stem) + ".json")) << j.dump(1) << "\n";
      if (f.dropped) {
        ++dropped;
        continue;
      }
      imaging::write_png16((fs::path(out) / (std::string(stem) + ".png")).string(), f.pixels, f.width, f.height);
      std::snprintf(stem, sizeof stem, "preview_%06d", k);
      imaging::write_preview_png8((fs::path(out) / (std::string(stem) + ".png")).string(), f.pixels, f.width,
                                  f.height);
      if (count >= 20 && (k + 1) % (count / 10) == 0) {
        std::fprintf(stderr, "artms-render: %d / %d frames\n", k + 1, count);
      }
    }
    std::fprintf(stderr, "artms-render: %d frames for %s into %s (%d dropped)\n", count, observer.c_str(),
                 out.c_str(), dropped);
  } catch (const config::ScenarioError& e) {
    std::cerr << e.what();
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "artms-render: error: " << e.what() << "\n";
    return 2;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return run(argc, argv); }
