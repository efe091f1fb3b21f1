// artms-swarm run --in-process: the swarm's objects (sim::Truth,
// sim::CameraRenderer, sim::Crosslink, one fsw::Observer per observer built
// from its uplink file, sim::Recorder) stepped in one process without DDS,
// with the lock-step semantics of the DDS run (DESIGN.md section 3): at tick
// k everybody has the truth states and GNSS fixes of t_k, and what a
// component writes at step k reaches the others at step k + 1. The run
// folder is byte-identical to the DDS run's (but timing.json and logs/).
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "artms/config/scenario.hpp"

namespace artms::swarm {

struct InProcessResult {
  bool ok = true;
  std::string failure;      // which component failed and why
  std::string failed;       // the failing component's service name
  double sim_s = 0.0;       // simulated time reached
};

// dir holds uplink/ (written by the launcher); outputs go to dir, events
// and the components' closing lines to dir/logs/in-process.log.
// progress(sim_s) is called after every step; stop() is polled.
InProcessResult run_in_process(const config::Scenario& sc, const std::filesystem::path& dir,
                               const std::function<void(double)>& progress, const std::function<bool()>& stop);

}  // namespace artms::swarm
