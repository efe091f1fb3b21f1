// Comma-separated numbers on command lines ("7e6,0,0,0,7546,0").
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace artms::io {

// Exactly `count` finite numbers separated by commas. Throws
// std::invalid_argument naming `option` and the item that is not a number,
// or the count found.
std::vector<double> parse_number_list(const std::string& text, std::size_t count, const std::string& option);

}  // namespace artms::io
