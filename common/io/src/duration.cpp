#include "artms/io/duration.hpp"

#include <charconv>
#include <cmath>
#include <stdexcept>
#include <string>

namespace artms::io {

double parse_duration_s(std::string_view text) {
  const auto fail = [&]() {
    throw std::invalid_argument("invalid duration '" + std::string(text) +
                                "' (expected e.g. 90s, 30m, 6h, 1.5d or seconds)");
  };
  if (text.empty()) fail();
  double scale = 1.0;
  std::string_view number = text;
  switch (text.back()) {
    case 's': scale = 1.0; number.remove_suffix(1); break;
    case 'm': scale = 60.0; number.remove_suffix(1); break;
    case 'h': scale = 3600.0; number.remove_suffix(1); break;
    case 'd': scale = 86400.0; number.remove_suffix(1); break;
    default: break;
  }
  double value = 0.0;
  const auto res = std::from_chars(number.data(), number.data() + number.size(), value);
  if (number.empty() || res.ec != std::errc{} || res.ptr != number.data() + number.size() ||
      !std::isfinite(value) || value < 0.0) {
    fail();
  }
  return value * scale;
}

}  // namespace artms::io
