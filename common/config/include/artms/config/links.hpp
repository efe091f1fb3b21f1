// The inter-satellite links of a scenario and their state (docs/runtime.md,
// "Crosslink"): shared by the crosslink emulator and the start-up topology.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "artms/config/scenario.hpp"

namespace artms::config {

// The link from -> to at time t, given the distance between the two
// (truth): "" when up, else why it is down: "disabled" (crosslink.enabled
// false), "outage" (a scenario outage window holds t; "*" matches any end),
// "range" (range_m > crosslink.max_range_m). Random loss is per message, not
// a link state.
std::string isl_link_down_reason(const Scenario& s, const std::string& from, const std::string& to, astro::TimeTT t,
                                 double range_m);
// Is the link up at the scenario epoch (range from the initial states)?
bool isl_link_up_at_epoch(const Scenario& s, const std::string& from, const std::string& to);
// Every directed link between observers, in scenario order (from-major).
std::vector<std::pair<std::string, std::string>> isl_links(const Scenario& s);

}  // namespace artms::config
