#include "artms/config/links.hpp"

namespace artms::config {

std::string isl_link_down_reason(const Scenario& s, const std::string& from, const std::string& to,
                                 astro::TimeTT t, double range_m) {
  if (!s.crosslink.enabled) return "disabled";
  for (const auto& o : s.crosslink.outages) {
    const bool f = o.from == "*" || o.from == from;
    const bool r = o.to == "*" || o.to == to;
    if (f && r && !(t < o.window.start) && t < o.window.end) return "outage";
  }
  if (range_m > s.crosslink.max_range_m) return "range";
  return "";
}

std::vector<std::pair<std::string, std::string>> isl_links(const Scenario& s) {
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto& a : s.observers) {
    for (const auto& b : s.observers) {
      if (a.spacecraft != b.spacecraft) out.emplace_back(a.spacecraft, b.spacecraft);
    }
  }
  return out;
}

bool isl_link_up_at_epoch(const Scenario& s, const std::string& from, const std::string& to) {
  const double range_m = (s.initial_state_eci(from).r_m - s.initial_state_eci(to).r_m).norm();
  return isl_link_down_reason(s, from, to, s.epoch, range_m).empty();
}

}  // namespace artms::config
