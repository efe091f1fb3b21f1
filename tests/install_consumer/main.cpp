// The installed ARTMS onboard software in a project of its own: one
// fsw::Observer built from a hand-made setup (navigation mode 0, no camera,
// j2 onboard force model read from the installed data) and stepped a few
// ticks with one GNSS fix. Prints the data folder and the navigation source;
// exits 1 unless the observer navigates on GNSS.
#include <cstdio>
#include <exception>
#include <memory>
#include <string>

#include "artms/astro/constants.hpp"
#include "artms/astro/elements.hpp"
#include "artms/dynamics/forces.hpp"
#include "artms/fsw/observer.hpp"
#include "artms/io/paths.hpp"

namespace {

using namespace artms;

int run() {
  const astro::TimeTT t0 = astro::tt_from_utc_string("2024-05-08T00:00:00Z");
  const std::string data = io::data_dir();
  std::printf("data: %s\n", data.c_str());

  fsw::ObserverSetup setup;
  auto& up = setup.uplink;
  up.scenario_name = "install-consumer";
  up.epoch = t0;
  up.duration_s = 300.0;
  up.step_s = 60.0;
  up.isl_period_s = 120.0;
  up.swarm_max_cadence_s = 60.0;
  up.observer.spacecraft = "SV4";
  up.observer.mode = 0;
  up.observer.gnss.enabled = true;
  up.swarm_ids = {"SV4"};
  up.force_model = dynamics::ForceModelOptions::parse("j2");
  setup.forces = std::make_shared<const dynamics::ForceModel>(dynamics::ForceModel::load(up.force_model, data));

  fsw::Observer observer(std::move(setup), "observer-SV4");
  const astro::StateVector x = astro::cartesian_from_kepler(
      {6943000.0, 0.0016, 99.4 * astro::kDegToRad, -38.0 * astro::kDegToRad, 86.4 * astro::kDegToRad, 0.0});

  bus::SolutionSource source = bus::SolutionSource::kNone;
  for (std::int64_t k = 0; k < 4; ++k) {
    const bus::Tick tick{k, t0.plus_seconds(60.0 * static_cast<double>(k)).ns_since_j2000, false};
    fsw::ObserverInputs in;
    if (k == 1) {  // one GNSS fix, stamped at the epoch
      bus::GnssFix f;
      f.spacecraft = "SV4";
      f.t_tt_ns = t0.ns_since_j2000;
      f.valid = true;
      for (std::size_t i = 0; i < 3; ++i) {
        f.r_eci_m[i] = x.r_m[static_cast<Eigen::Index>(i)];
        f.v_eci_mps[i] = x.v_mps[static_cast<Eigen::Index>(i)];
      }
      f.sigma_position_m = 2.0;
      f.sigma_velocity_mps = 0.01;
      in.gnss.push_back(f);
    }
    const fsw::ObserverOutputs out = observer.step(tick, std::move(in));
    if (!out.nav) {
      std::fprintf(stderr, "step %lld: no navigation telemetry\n", static_cast<long long>(k));
      return 1;
    }
    source = out.nav->source;
    std::printf("step %lld: source %s, health %s\n", static_cast<long long>(k), bus::to_string(source),
                bus::to_string(out.nav->health));
  }
  std::printf("navigation source: %s\n", bus::to_string(source));
  return source == bus::SolutionSource::kGnss ? 0 : 1;
}

}  // namespace

int main() {
  try {
    return run();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "artms-install-consumer: error: %s\n", e.what());
    return 2;
  }
}
