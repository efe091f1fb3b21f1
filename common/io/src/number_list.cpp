#include "artms/io/number_list.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace artms::io {

std::vector<double> parse_number_list(const std::string& text, std::size_t count, const std::string& option) {
  std::vector<double> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    std::size_t used = 0;
    double v = 0.0;
    try {
      v = std::stod(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != item.size() || !std::isfinite(v)) {
      throw std::invalid_argument(option + ": '" + item + "' is not a number");
    }
    out.push_back(v);
  }
  if (out.size() != count) {
    throw std::invalid_argument(option + " needs " + std::to_string(count) + " comma-separated numbers, got " +
                                std::to_string(out.size()));
  }
  return out;
}

}  // namespace artms::io
