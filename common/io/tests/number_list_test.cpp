#include "artms/io/number_list.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <stdexcept>

namespace artms::io {
namespace {

TEST(NumberList, ParsesExactlyTheCount) {
  EXPECT_EQ(parse_number_list("7e6,0,-1.5", 3, "--rv"), (std::vector<double>{7e6, 0.0, -1.5}));
}

TEST(NumberList, RejectsGarbageNamingTheOptionAndItem) {
  const auto message = [](const std::string& text, std::size_t count) {
    try {
      (void)parse_number_list(text, count, "--rv");
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(message("1,abc,3", 3), "--rv: 'abc' is not a number");
  EXPECT_EQ(message("1,2x,3", 3), "--rv: '2x' is not a number");
  EXPECT_EQ(message("1,nan,3", 3), "--rv: 'nan' is not a number");
  EXPECT_EQ(message("1,,3", 3), "--rv: '' is not a number");
  EXPECT_EQ(message("1,2", 3), "--rv needs 3 comma-separated numbers, got 2");
  EXPECT_EQ(message("1,2,3,4", 3), "--rv needs 3 comma-separated numbers, got 4");
}

}  // namespace
}  // namespace artms::io
