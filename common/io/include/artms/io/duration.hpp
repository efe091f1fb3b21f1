// Durations on command lines and in scenario files: "90s", "30m", "6h",
// "1.5d", or a plain number of seconds.
#pragma once

#include <string_view>

namespace artms::io {

// Returns seconds. Throws std::invalid_argument naming the text on anything
// else (negative values included).
double parse_duration_s(std::string_view text);

}  // namespace artms::io
