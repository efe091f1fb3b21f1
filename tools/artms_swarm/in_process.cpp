#include "in_process.hpp"

#include <cstdio>
#include <fstream>
#include <map>

#include "artms/fsw/observer.hpp"
#include "artms/io/paths.hpp"
#include "artms/sim/services.hpp"

namespace artms::swarm {

namespace fs = std::filesystem;

InProcessResult run_in_process(const config::Scenario& sc, const fs::path& dir,
                               const std::function<void(double)>& progress, const std::function<bool()>& stop) {
  InProcessResult result;
  std::ofstream log(dir / "logs" / "in-process.log");
  const auto echo = [&](const std::vector<bus::Event>& events) {
    for (const auto& e : events) log << "[" << e.source << "] " << bus::to_string(e.severity) << ": " << e.text << "\n";
  };
  std::string current = "truth";
  try {
    auto forces = std::make_shared<const dynamics::ForceModel>(dynamics::ForceModel::load(sc.force_model, io::data_dir()));
    sim::Truth truth(sc, forces, "truth");
    current = "camera-renderer";
    sim::CameraRenderer renderer(sc, "camera-renderer");
    current = "crosslink-emulator";
    sim::Crosslink crosslink(sc, "crosslink-emulator");
    std::vector<std::unique_ptr<fsw::Observer>> observers;
    std::map<std::string, std::size_t> index;
    for (const auto& o : sc.observers) {
      current = "observer-" + o.spacecraft;
      index[o.spacecraft] = observers.size();
      observers.push_back(std::make_unique<fsw::Observer>(
          fsw::load_observer_setup((dir / "uplink" / (o.spacecraft + ".json")).string(), io::data_dir()), current));
    }
    current = "recorder";
    sim::Recorder recorder(sc, dir.string());
    const auto record = [&](const auto& messages) {
      for (const auto& m : messages) recorder.add(m);
    };
    const bus::Event started = truth.started();
    recorder.add(started);
    echo({started});

    // What each component wrote at the previous step, delivered at this one.
    std::vector<fsw::ObserverInputs> next(observers.size());
    std::vector<bus::IslBroadcast> broadcasts;
    for (std::int64_t k = 0; k <= truth.steps() + 1; ++k) {
      if (stop()) {
        current = "launcher";  // nobody failed: the run was interrupted
        throw std::runtime_error("stop requested");
      }
      const bus::Tick tick = truth.tick(k);
      std::vector<fsw::ObserverInputs> in = std::move(next);
      next.assign(observers.size(), {});
      current = "truth";
      sim::Truth::StepOutput world;
      if (!tick.final_step) world = truth.step(k);
      record(world.states);
      record(world.gnss);
      for (auto& i : in) i.gnss = world.gnss;
      current = "recorder";
      recorder.on_tick(tick);
      if (tick.final_step) {
        for (const auto& line : renderer.summary()) log << "[camera-renderer] " << line << "\n";
        log << "[crosslink-emulator] " << crosslink.summary() << "\n";
        for (const auto& o : observers) log << "[observer-" << o->id() << "] " << o->isl_summary() << "\n";
        if (recorder.rejected() > 0) log << "[recorder] rejected " << recorder.rejected() << " malformed samples\n";
        break;
      }
      current = "camera-renderer";
      auto frames = renderer.step(tick, world.states);
      record(frames.truths);
      record(frames.events);
      echo(frames.events);
      for (auto& f : frames.frames) next.at(index.at(f.observer)).frames.push_back(std::move(f));
      current = "crosslink-emulator";
      const auto links = crosslink.links(tick, world.states, std::move(broadcasts));
      broadcasts.clear();
      record(links.states);
      record(links.events);
      echo(links.events);
      auto relays = crosslink.relay(tick, [](std::size_t) { return true; });
      record(relays.outcomes);
      record(relays.events);
      echo(relays.events);
      for (auto& r : relays.relays) {
        if (!r.down) next.at(index.at(r.msg.receiver)).relays.push_back(std::move(r.msg));
      }
      for (std::size_t i = 0; i < observers.size(); ++i) {
        current = "observer-" + observers[i]->id();
        auto out = observers[i]->step(tick, std::move(in[i]));
        record(out.imp);
        if (out.nav) recorder.add(*out.nav);
        record(out.bod);
        record(out.events);
        echo(out.events);
        if (out.isl) broadcasts.push_back(std::move(*out.isl));
      }
      result.sim_s = astro::seconds_between(sc.epoch, astro::TimeTT{tick.t_tt_ns});
      progress(result.sim_s);
    }
  } catch (const std::exception& e) {
    result.ok = false;
    result.failed = current;
    result.failure = current + " failed: " + e.what();
    log << "[" << current << "] error: " << e.what() << "\n";
  }
  return result;
}

}  // namespace artms::swarm
