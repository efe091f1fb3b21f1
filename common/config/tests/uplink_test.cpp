#include "artms/config/uplink.hpp"

#include <gtest/gtest.h>

#include <fstream>

namespace artms::config {
namespace {

TEST(Uplink, RoundTripsAndCarriesNoOrbits) {
  const Scenario s = load_scenario(std::string(ARTMS_SCENARIO_DIR) + "/starling_pse.yaml");
  const ObserverUplink u = make_uplink(s, "SV4");
  const std::string path = ::testing::TempDir() + "/uplink_sv4.json";
  write_uplink(u, path);
  const ObserverUplink b = read_uplink(path);
  EXPECT_EQ(b.scenario_name, "starling-pse");
  EXPECT_EQ(b.epoch, s.epoch);
  EXPECT_EQ(b.observer.spacecraft, "SV4");
  EXPECT_EQ(b.observer.mode, u.observer.mode);
  EXPECT_EQ(b.observer.camera.boresight, astro::Boresight::kMinusVelocity);
  EXPECT_DOUBLE_EQ(b.tuning.sod.bearing_sigma_arcsec, 0.0);
  EXPECT_DOUBLE_EQ(b.tuning.sod.underweighting, 0.5);
  EXPECT_FALSE(b.tuning.sod.adaptive_process_noise);
  EXPECT_DOUBLE_EQ(b.tuning.sod.process_noise_scale, 0.001);
  EXPECT_EQ(b.force_model.gravity_degree, 10);
  EXPECT_EQ(b.swarm_ids, (std::vector<std::string>{"SV4", "SV2", "SV3"}));
  // No truth: the file mentions no orbit elements.
  std::ifstream in(path);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (const char* forbidden : {"roe", "a_km", "qns", "kepler", "r_eci"}) {
    EXPECT_EQ(text.find(forbidden), std::string::npos) << forbidden;
  }
  EXPECT_THROW(make_uplink(s, "SV2"), std::out_of_range);
}

TEST(Uplink, MalformedFileNamesFileAndKey) {
  const std::string path = ::testing::TempDir() + "/bad_uplink.json";
  std::ofstream(path) << R"({"scenario": "x", "epoch_tt_ns": "soon"})";
  try {
    (void)read_uplink(path);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("bad_uplink.json"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace artms::config
