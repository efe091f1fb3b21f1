// io::CsvTable: columns by name, malformed rows named by file and line, an
// unfinished last line left out and named, numbers checked.
#include <gtest/gtest.h>
#include <gmock/gmock.h>

#include <filesystem>
#include <fstream>

#include "artms/io/csv.hpp"

namespace artms::io {
namespace {

std::string write(const std::string& name, const std::string& text) {
  const auto path = std::filesystem::path(::testing::TempDir()) / name;
  std::ofstream(path, std::ios::binary) << text;
  return path.string();
}

std::string error_of(const std::string& path) {
  try {
    (void)CsvTable::read(path);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

TEST(CsvTable, ReadsColumnsByNameWithEmptyTrailingFields) {
  const auto t = CsvTable::read(write("ok.csv", "a,b,reason\n1,2.5,\n3,-4e-3,x\n"));
  ASSERT_EQ(t.size(), 2U);
  EXPECT_EQ(t.integer(0, "a"), 1);
  EXPECT_DOUBLE_EQ(t.number(1, "b"), -4e-3);
  EXPECT_EQ(t.text(0, "reason"), "");
  EXPECT_EQ(t.line(1), 3);
  EXPECT_EQ(t.truncated_line(), 0);
}

TEST(CsvTable, AMalformedRowIsAnErrorNamingFileAndLine) {
  const auto path = write("bad.csv", "a,b\n1,2\n3\n4,5\n");
  EXPECT_THAT(error_of(path), ::testing::HasSubstr("bad.csv:3: 1 fields, the header has 2"));
}

TEST(CsvTable, AnUnfinishedLastLineIsLeftOutAndNamed) {
  const auto t = CsvTable::read(write("cut.csv", "a,b\n1,2\n3"));
  EXPECT_EQ(t.size(), 1U);
  EXPECT_EQ(t.truncated_line(), 3);
}

TEST(CsvTable, UnknownColumnsAndNonNumbersAreNamed) {
  const auto t = CsvTable::read(write("num.csv", "a,b\n1,x\n"));
  EXPECT_THROW((void)t.column("c"), std::runtime_error);
  try {
    (void)t.number(0, "b");
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("num.csv:2: column 'b': 'x' is not a number"));
  }
  EXPECT_THAT(error_of(write("empty.csv", "")), ::testing::HasSubstr("empty (no header)"));
}

}  // namespace
}  // namespace artms::io
