#include "artms/io/duration.hpp"

#include <gtest/gtest.h>

#include <stdexcept>

namespace artms::io {
namespace {

TEST(Duration, ParsesUnits) {
  EXPECT_DOUBLE_EQ(parse_duration_s("90s"), 90.0);
  EXPECT_DOUBLE_EQ(parse_duration_s("30m"), 1800.0);
  EXPECT_DOUBLE_EQ(parse_duration_s("6h"), 21600.0);
  EXPECT_DOUBLE_EQ(parse_duration_s("1.5d"), 129600.0);
  EXPECT_DOUBLE_EQ(parse_duration_s("120"), 120.0);
}

TEST(Duration, RejectsGarbageNamingIt) {
  for (const char* bad : {"", "d", "-5s", "1x", "1 h", "abc", "1e400s", "nan"}) {
    try {
      (void)parse_duration_s(bad);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(std::string("'") + bad + "'"), std::string::npos);
    }
  }
}

}  // namespace
}  // namespace artms::io
