// Resident memory of the swarm's processes, sampled by the launcher at every
// whole simulated hour (VmRSS from /proc/<pid>/status) and written to
// timing.json ("rss_kb": per process, [simulated hour, kB] pairs), which like
// all of timing.json is not part of the byte-identity guarantee. Soak tests
// read it to check that memory does not grow.
#pragma once

#include <sys/types.h>

#include <cmath>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

namespace artms::swarm {

class MemorySampler {
 public:
  // Samples each running process once per new whole simulated hour.
  template <class Children>
  void sample(const Children& children, double sim_s) {
    const long hour = static_cast<long>(std::floor(sim_s / 3600.0));
    if (hour <= last_hour_) return;
    last_hour_ = hour;
    for (const auto& c : children) {
      if (!c.running) continue;
      const long kb = rss_kb(c.pid);
      if (kb > 0) samples_[c.name].emplace_back(hour, kb);
    }
  }
  [[nodiscard]] nlohmann::json to_json() const {
    nlohmann::json j = nlohmann::json::object();
    for (const auto& [name, v] : samples_) {
      j[name] = nlohmann::json::array();
      for (const auto& [h, kb] : v) j[name].push_back({h, kb});
    }
    return j;
  }

  static long rss_kb(pid_t pid) {
    std::ifstream in("/proc/" + std::to_string(pid) + "/status");
    std::string key;
    while (in >> key) {
      if (key == "VmRSS:") {
        long kb = 0;
        in >> kb;
        return kb;
      }
      std::string rest;
      std::getline(in, rest);
    }
    return -1;
  }

 private:
  long last_hour_ = -1;
  std::map<std::string, std::vector<std::pair<long, long>>> samples_;
};

}  // namespace artms::swarm
