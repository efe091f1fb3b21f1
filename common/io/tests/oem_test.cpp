#include "artms/io/oem.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

namespace artms::io {
namespace {

OemFile sample_file() {
  OemFile f;
  f.creation = astro::tt_from_utc_string("2024-05-08T00:00:00Z");
  OemSegment s{"SV4", "SV4", {}};
  for (int k = 0; k < 3; ++k) {
    s.samples.push_back({f.creation.plus_seconds(60.0 * k),
                         {astro::Vec3(6.9e6 + k, -1.2345678e6, 3.0e5),
                          astro::Vec3(100.25, 7400.125, -1.0e-3)}});
  }
  f.segments.push_back(s);
  return f;
}

TEST(Oem, WriteThenReadRoundTripsToMicrometres) {
  std::stringstream ss;
  write_oem(ss, sample_file());
  const std::string text = ss.str();
  EXPECT_EQ(text.rfind("CCSDS_OEM_VERS = 2.0\n", 0), 0u);
  EXPECT_NE(text.find("REF_FRAME = EME2000"), std::string::npos);
  EXPECT_NE(text.find("2024-05-08T00:01:00.000000 6900.001000000"), std::string::npos);
  const OemFile back = read_oem(ss);
  ASSERT_EQ(back.segments.size(), 1u);
  const OemFile original = sample_file();
  const auto& a = original.segments[0].samples;
  const auto& b = back.segments[0].samples;
  ASSERT_EQ(b.size(), a.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(b[k].t, a[k].t);
    EXPECT_LT((b[k].x_eci.r_m - a[k].x_eci.r_m).norm(), 1e-5);
    EXPECT_LT((b[k].x_eci.v_mps - a[k].x_eci.v_mps).norm(), 1e-8);
  }
}

TEST(Oem, ReaderRejectsNonConformingFilesNamingTheLine) {
  std::stringstream good;
  write_oem(good, sample_file());
  const std::string text = good.str();
  const auto expect_error = [](const std::string& bad, const std::string& fragment) {
    std::istringstream in(bad);
    try {
      (void)read_oem(in, "t.oem");
      ADD_FAILURE() << "accepted a file lacking: " << fragment;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    }
  };
  std::string no_frame = text;
  no_frame.erase(no_frame.find("REF_FRAME = EME2000\n"), 20);
  expect_error(no_frame, "REF_FRAME");
  std::string bad_version = text;
  bad_version.replace(bad_version.find("2.0"), 3, "1.0");
  expect_error(bad_version, "t.oem:1");
  std::string bad_number = text;
  bad_number.replace(bad_number.find("6900.001000000"), 4, "69x0");
  expect_error(bad_number, "six numbers");
  expect_error("", "no ephemeris segment");
}

TEST(Oem, WriterRejectsNonIncreasingTimes) {
  OemFile f = sample_file();
  f.segments[0].samples[2].t = f.segments[0].samples[1].t;
  std::stringstream ss;
  EXPECT_THROW(write_oem(ss, f), std::invalid_argument);
}

TEST(Oem, StreamWriterWritesWhatWriteOemWrites) {
  // Two objects with interleaved samples (as a recorder receives them).
  OemFile f = sample_file();
  OemSegment second{"SV2", "SV2", {}};
  for (const auto& s : f.segments[0].samples) second.samples.push_back({s.t, {s.x_eci.r_m * 1.01, s.x_eci.v_mps}});
  f.segments.push_back(second);
  std::stringstream expected;
  write_oem(expected, f);
  const std::string path = ::testing::TempDir() + "/stream.oem";
  {
    OemStreamWriter w(path, f.creation);
    for (std::size_t k = 0; k < f.segments[0].samples.size(); ++k) {
      w.add("SV2", f.segments[1].samples[k]);
      w.add("SV4", f.segments[0].samples[k]);
    }
    EXPECT_THROW(w.add("SV4", f.segments[0].samples[0]), std::invalid_argument);
    w.finish({"SV4", "SV2", "SV9"});
  }
  std::ifstream in(path);
  std::stringstream got;
  got << in.rdbuf();
  EXPECT_EQ(got.str(), expected.str());
  EXPECT_FALSE(std::ifstream(path + ".SV4.part").good());  // temporary files removed
}

}  // namespace
}  // namespace artms::io
