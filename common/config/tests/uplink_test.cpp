#include "artms/config/uplink.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <string>

namespace artms::config {
namespace {

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Replaces the first `from` in the file by `to`; false when `from` is not there.
bool replace_in_file(const std::string& path, const std::string& from, const std::string& to) {
  std::string text = read_text(path);
  const auto at = text.find(from);
  if (at == std::string::npos) return false;
  text.replace(at, from.size(), to);
  std::ofstream(path) << text;
  return true;
}

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
  EXPECT_EQ(b.tuning.sod.target_lines, SodTuning::TargetLines::kConsiderObserver);
  EXPECT_EQ(b.force_model.gravity_degree, 10);
  EXPECT_EQ(b.swarm_ids, (std::vector<std::string>{"SV4", "SV2", "SV3"}));
  // No truth: the file mentions no orbit elements.
  const std::string text = read_text(path);
  for (const char* forbidden : {"roe", "a_km", "qns", "kepler", "r_eci"}) {
    EXPECT_EQ(text.find(forbidden), std::string::npos) << forbidden;
  }
  EXPECT_THROW(make_uplink(s, "SV2"), std::out_of_range);
}

TEST(Uplink, RoundTripsTheVariableAtmosphereAndOnboardProperties) {
  Scenario s = load_scenario(std::string(ARTMS_SCENARIO_DIR) + "/starling_pse.yaml");
  s.onboard_force_model = dynamics::ForceModelOptions::flight_like_truth();
  s.onboard_force_model.space_weather.daily = {{180.0, 4.0}};
  s.onboard_force_model.space_weather.kp_daily_sigma = 0.5;
  s.onboard_force_model.space_weather.seed = 99;
  s.onboard_force_model.space_weather.start = s.epoch;
  s.spacecraft[1].onboard_properties.mass_kg = 9.0;
  const ObserverUplink u = make_uplink(s, "SV4");
  const std::string path = ::testing::TempDir() + "/uplink_sv4_j71.json";
  write_uplink(u, path);
  const ObserverUplink b = read_uplink(path);
  EXPECT_EQ(b.force_model.atmosphere_model, dynamics::AtmosphereModel::kJacchiaScaledHarrisPriester);
  EXPECT_EQ(b.force_model.space_weather, u.force_model.space_weather);
  EXPECT_EQ(b.force_model.describe(), u.force_model.describe());
  EXPECT_DOUBLE_EQ(b.onboard_properties(s.spacecraft[1].id).mass_kg, 9.0);
  EXPECT_DOUBLE_EQ(b.onboard_properties("SV4").mass_kg, dynamics::SpacecraftProperties{}.mass_kg);
  EXPECT_EQ(b.onboard_properties_by_id.size(), s.spacecraft.size());
}

TEST(Uplink, RoundTripsTheCameraEncodingAndMatchTolerance) {
  const Scenario s = load_scenario(std::string(ARTMS_SCENARIO_DIR) + "/starling_pse.yaml");
  ObserverUplink u = make_uplink(s, "SV4");
  u.camera_calibration.width_px = 1024;
  u.camera_calibration.height_px = 768;
  u.camera_calibration.fx_px = u.camera_calibration.fy_px = 5116.0;
  u.camera_calibration.dn_shift_bits = 4;
  u.camera_calibration.match_tolerance_rad = 2.9e-4;
  u.camera_calibration.centroid_gaussian_fit = true;
  const std::string path = ::testing::TempDir() + "/uplink_sv4_camera.json";
  write_uplink(u, path);
  const ObserverUplink b = read_uplink(path);
  EXPECT_EQ(b.camera_calibration.dn_shift_bits, 4);
  EXPECT_DOUBLE_EQ(b.camera_calibration.match_tolerance_rad, 2.9e-4);
  EXPECT_TRUE(b.camera_calibration.centroid_gaussian_fit);
}

TEST(Uplink, RoundTripsTheCoarseOrbitOfMode4) {
  const Scenario s = load_scenario(std::string(ARTMS_SCENARIO_DIR) + "/starling_pse.yaml");
  ObserverUplink u = make_uplink(s, "SV4");
  ObserverUplink::CoarseOrbit c;
  c.t = s.epoch;
  c.x_eci.r_m = astro::Vec3(7.0e6, 1.0, -2.0);
  c.x_eci.v_mps = astro::Vec3(0.5, 7.5e3, 1.0);
  c.P_rv = Eigen::Matrix<double, 6, 6>::Identity() * 4.0;
  c.P_rv(0, 1) = c.P_rv(1, 0) = 0.5;
  u.coarse_orbit = c;
  const std::string path = ::testing::TempDir() + "/uplink_sv4_mode4.json";
  write_uplink(u, path);
  const ObserverUplink b = read_uplink(path);
  ASSERT_TRUE(b.coarse_orbit.has_value());
  EXPECT_EQ(b.coarse_orbit->t, c.t);
  EXPECT_EQ(b.coarse_orbit->x_eci.r_m, c.x_eci.r_m);
  EXPECT_EQ(b.coarse_orbit->x_eci.v_mps, c.x_eci.v_mps);
  EXPECT_EQ(b.coarse_orbit->P_rv, c.P_rv);
  // Modes 1-3 carry none.
  write_uplink(make_uplink(s, "SV4"), path);
  EXPECT_FALSE(read_uplink(path).coarse_orbit.has_value());
}

TEST(Uplink, AdaptiveFormAndAverageRoundTrip) {
  const Scenario s = load_scenario(std::string(ARTMS_SCENARIO_DIR) + "/starling_pse.yaml");
  ObserverUplink u = make_uplink(s, "SV4");
  u.tuning.sod.adaptive_form = SodTuning::AdaptiveForm::kBlock;
  u.tuning.sod.adaptive_average = SodTuning::AdaptiveAverage::kUnclamped;
  const std::string path = ::testing::TempDir() + "/uplink_sv4_adaptive.json";
  write_uplink(u, path);
  const ObserverUplink b = read_uplink(path);
  EXPECT_EQ(b.tuning.sod.adaptive_form, SodTuning::AdaptiveForm::kBlock);
  EXPECT_EQ(b.tuning.sod.adaptive_average, SodTuning::AdaptiveAverage::kUnclamped);
  ASSERT_TRUE(replace_in_file(path, "\"block\"", "\"full\""));
  EXPECT_THROW((void)read_uplink(path), std::runtime_error);
}

// A number of tuning.sod: written and read back; an older uplink without
// its key reads as `older`; a negative value is refused. `text` is how
// write_uplink prints `value`.
void expect_sod_number_round_trips(double SodTuning::*field, const std::string& key, double value,
                                   const std::string& text, double older, const std::string& file) {
  const Scenario s = load_scenario(std::string(ARTMS_SCENARIO_DIR) + "/starling_pse.yaml");
  ObserverUplink u = make_uplink(s, "SV4");
  u.tuning.sod.*field = value;
  const std::string path = ::testing::TempDir() + "/" + file;
  write_uplink(u, path);
  EXPECT_DOUBLE_EQ(read_uplink(path).tuning.sod.*field, value);
  ASSERT_TRUE(replace_in_file(path, "\"" + key + "\"", "\"" + key + "_gone\""));
  EXPECT_EQ(read_uplink(path).tuning.sod.*field, older);
  write_uplink(u, path);
  ASSERT_TRUE(replace_in_file(path, "\"" + key + "\": " + text, "\"" + key + "\": -1.0"));
  EXPECT_THROW((void)read_uplink(path), std::runtime_error);
}

TEST(Uplink, DragDensityErrorRoundTripsAndOlderUplinksLeaveItOff) {
  expect_sod_number_round_trips(&SodTuning::drag_density_error, "drag_density_error", 0.3, "0.3", 0.0,
                                "uplink_sv4_drag_floor.json");
}

TEST(Uplink, AdaptiveTimeConstantRoundTripsAndOlderUplinksKeepTheDefault) {
  expect_sod_number_round_trips(&SodTuning::adaptive_time_constant_s, "adaptive_time_constant_s", 600.0, "600.0",
                                1170.0, "uplink_sv4_tau.json");
}

TEST(Uplink, SenderClocksRoundTripAndOlderUplinksLeaveThemOff) {
  const Scenario s = load_scenario(std::string(ARTMS_SCENARIO_DIR) + "/starling_pse.yaml");
  ObserverUplink u = make_uplink(s, "SV4");
  u.tuning.sod.time_tag_senders = true;
  const std::string path = ::testing::TempDir() + "/uplink_sv4_senders.json";
  write_uplink(u, path);
  EXPECT_TRUE(read_uplink(path).tuning.sod.time_tag_senders);
  ASSERT_TRUE(replace_in_file(path, "\"time_tag_senders\"", "\"time_tag_senders_unknown\""));
  EXPECT_FALSE(read_uplink(path).tuning.sod.time_tag_senders);
}

TEST(Uplink, TargetLinesRoundTripAndAnUnknownValueIsNamed) {
  const Scenario s = load_scenario(std::string(ARTMS_SCENARIO_DIR) + "/starling_pse.yaml");
  ObserverUplink u = make_uplink(s, "SV4");
  u.tuning.sod.target_lines = SodTuning::TargetLines::kUpdateObserver;
  const std::string path = ::testing::TempDir() + "/uplink_sv4_lines.json";
  write_uplink(u, path);
  EXPECT_EQ(read_uplink(path).tuning.sod.target_lines, SodTuning::TargetLines::kUpdateObserver);
  ASSERT_TRUE(replace_in_file(path, "\"update_observer\"", "\"sometimes\""));
  try {
    (void)read_uplink(path);
    ADD_FAILURE() << "an unknown tuning.sod.target_lines was accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("tuning.sod.target_lines"), std::string::npos) << e.what();
  }
}

TEST(Uplink, BodFitRatioRoundTripsAndAnOlderUplinkReadsTheDefault) {
  const Scenario s = load_scenario(std::string(ARTMS_SCENARIO_DIR) + "/starling_pse.yaml");
  ObserverUplink u = make_uplink(s, "SV4");
  u.tuning.bod.max_fit_ratio = 2.25;
  const std::string path = ::testing::TempDir() + "/uplink_sv4_fit.json";
  write_uplink(u, path);
  EXPECT_DOUBLE_EQ(read_uplink(path).tuning.bod.max_fit_ratio, 2.25);
  ASSERT_TRUE(replace_in_file(path, "\"max_fit_ratio\":", "\"unknown_key_of_a_later_version\":"));
  EXPECT_DOUBLE_EQ(read_uplink(path).tuning.bod.max_fit_ratio, BodTuning{}.max_fit_ratio);
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
