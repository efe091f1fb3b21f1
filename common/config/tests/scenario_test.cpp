// Scenario files: the Starling scenarios reproduce Table 2 of the paper, the
// derived quantities, and one test per validation case (file, line, field
// path and message checked). Bad files are written under ::testing::TempDir().
#include "artms/config/scenario.hpp"
#include "artms/config/uplink.hpp"
#include "artms/dynamics/j2_mean.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "artms/astro/constants.hpp"
#include "artms/astro/elements.hpp"
#include "artms/astro/roe.hpp"
#include "artms/astro/time.hpp"

namespace artms::config {
namespace {

using ::testing::HasSubstr;

std::string scenario_path(const std::string& file) {
  return std::string(ARTMS_SCENARIO_DIR) + "/" + file;
}

// Writes `text` to TempDir()/artms_config_tests/name and returns the path.
std::string write_file(const std::string& name, const std::string& text) {
  const auto dir = std::filesystem::path(::testing::TempDir()) / "artms_config_tests";
  std::filesystem::create_directories(dir);
  const auto path = dir / name;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
  return path.string();
}

std::string dump(const std::vector<Diagnostic>& diags) {
  std::ostringstream os;
  for (const auto& d : diags) os << "  " << d.format() << "\n";
  return os.str();
}

// Validates `text` (as file `name`) and checks that exactly one diagnostic
// carries `field`, at `line`, with `phrase` in its message, and that its
// formatted form starts with "<path>:<line>:<col>: <field>: ".
Diagnostic expect_one(const std::string& name, const std::string& text, int line,
                      const std::string& field, const std::string& phrase) {
  const std::string path = write_file(name, text);
  const auto diags = validate_scenario_file(path);
  std::vector<Diagnostic> hits;
  for (const auto& d : diags) {
    if (d.field == field) hits.push_back(d);
  }
  EXPECT_EQ(hits.size(), 1u) << "no single diagnostic for '" << field << "'; got:\n" << dump(diags);
  if (hits.size() != 1) return {};
  const Diagnostic& d = hits.front();
  EXPECT_EQ(d.file, path);
  EXPECT_EQ(d.line, line) << d.format();
  EXPECT_GT(d.column, 0) << d.format();
  EXPECT_THAT(d.message, HasSubstr(phrase)) << d.format();
  const std::string prefix =
      path + ":" + std::to_string(line) + ":" + std::to_string(d.column) + ": " + field + ": ";
  EXPECT_EQ(d.format().rfind(prefix, 0), 0u) << d.format();
  EXPECT_THAT(d.format(), HasSubstr(name));
  return d;
}

// A valid two-spacecraft scenario; the bad files below are edits of it.
// Line numbers: 1 name, 2 epoch, 3 duration, 4 spacecraft, 5-6 SV4,
// 7-8 SV2, 9 observers, 10-11 SV4 observer.
const std::string kValid = R"(name: test-swarm
epoch: 2024-05-08T00:00:00Z
duration: 6h
spacecraft:
  - id: SV4
    qns: {a_km: 6943, ex: 0.0001, ey: 0.0016, i_deg: 99.4, raan_deg: -38.0, u_deg: -153.0}
  - id: SV2
    relative: {chief: SV4, roe_m: [23, -52266, -471, -523, 35, 1811]}
observers:
  - spacecraft: SV4
    camera: {cadence: 60s}
)";

// --- The Starling scenarios (Table 2) ------------------------------------------

struct Table2Case {
  const char* file;
  const char* epoch_utc;
  std::array<double, 6> sv4;  // a_km, ex, ey, i_deg, raan_deg, u_deg
  std::array<double, 6> sv2;  // a*droe in m w.r.t. SV4
  std::array<double, 6> sv3;
};

// Table 2 of the StarFOX paper, copied from the .tex independently of the
// YAML files.
const Table2Case kTable2[] = {
    {"starling_it.yaml",
     "2024-02-05T00:00:00Z",
     {6945, 0.0007, 0.0014, 99.4, -152.3, -41.8},
     {21, -124350, 110, 202, 79, 1005},
     {-1, -79328, 42, 452, 36, 827}},
    {"starling_pse.yaml",
     "2024-05-08T00:00:00Z",
     {6943, 0.0001, 0.0016, 99.4, -38.0, -153.0},
     {23, -52266, -471, -523, 35, 1811},
     {-30, -155320, -297, -315, 16, 1144}},  // Table 2 prints +155320: sign read as a typo (starling_pse.yaml)
};

TEST(StarlingScenarios, BothFilesLoad) {
  for (const auto& c : kTable2) {
    SCOPED_TRACE(c.file);
    const Scenario s = load_scenario(scenario_path(c.file));
    EXPECT_EQ(s.epoch, astro::tt_from_utc_string(c.epoch_utc));
    EXPECT_DOUBLE_EQ(s.duration_s, 19.0 * 3600.0);
    EXPECT_DOUBLE_EQ(s.step_s, 60.0);
    EXPECT_EQ(s.seed, 7u);
    ASSERT_EQ(s.spacecraft.size(), 3u);
    EXPECT_EQ(s.spacecraft[0].id, "SV4");
    EXPECT_EQ(s.spacecraft[0].orbit.kind, InitialOrbit::Kind::kQns);
    for (const auto* id : {"SV2", "SV3"}) {
      const auto& sc = s.spacecraft_by_id(id);
      EXPECT_EQ(sc.orbit.kind, InitialOrbit::Kind::kRelative) << id;
      EXPECT_EQ(sc.orbit.chief, "SV4") << id;
    }
    ASSERT_EQ(s.observers.size(), 1u);
    const auto& o = s.observers[0];
    EXPECT_EQ(o.spacecraft, "SV4");
    EXPECT_EQ(o.mode, 1);
    EXPECT_EQ(o.camera.boresight, astro::Boresight::kMinusVelocity);
    EXPECT_DOUBLE_EQ(o.camera.cadence_s, 60.0);
    EXPECT_TRUE(o.gnss.enabled);
    EXPECT_FALSE(s.crosslink.use_remote_gnss);
    EXPECT_DOUBLE_EQ(s.tuning.sod.bearing_sigma_arcsec, 0.0);  // IMP's own sigma (docs/sod.md)
    EXPECT_FALSE(s.tuning.sod.adaptive_process_noise);
    // PSE's SV2 at 42 km is the tightest single-observer estimate: Q x 0.01
    // dominated its covariance (docs/sod.md "Results").
    EXPECT_DOUBLE_EQ(s.tuning.sod.process_noise_scale, s.name == "starling-pse" ? 0.001 : 0.01);
    EXPECT_DOUBLE_EQ(s.tuning.bod.period_s, 5400.0);
    EXPECT_EQ(s.source_path, scenario_path(c.file));
    EXPECT_TRUE(validate_scenario_file(scenario_path(c.file)).empty());
  }
  EXPECT_EQ(load_scenario(scenario_path("starling_it.yaml")).name, "starling-it");
  EXPECT_EQ(load_scenario(scenario_path("starling_pse.yaml")).name, "starling-pse");
}

TEST(StarlingScenarios, Sv4ElementsMatchTable2) {
  for (const auto& c : kTable2) {
    SCOPED_TRACE(c.file);
    const Scenario s = load_scenario(scenario_path(c.file));
    const astro::QnsElements q = astro::qns_from_cartesian(s.initial_state_eci("SV4"));
    EXPECT_NEAR(q.a_m, c.sv4[0] * 1e3, 1e-6);
    EXPECT_NEAR(q.ex, c.sv4[1], 1e-12);
    EXPECT_NEAR(q.ey, c.sv4[2], 1e-12);
    EXPECT_NEAR(q.i_rad, c.sv4[3] * astro::kDegToRad, 1e-12);
    EXPECT_NEAR(astro::wrap_pi(q.raan_rad - c.sv4[4] * astro::kDegToRad), 0.0, 1e-12);
    EXPECT_NEAR(astro::wrap_pi(q.u_rad - c.sv4[5] * astro::kDegToRad), 0.0, 1e-12);
  }
}

TEST(StarlingScenarios, Table2RoeRoundTripThroughCartesian) {
  for (const auto& c : kTable2) {
    const Scenario s = load_scenario(scenario_path(c.file));
    const astro::QnsElements sv4 = astro::qns_from_cartesian(s.initial_state_eci("SV4"));
    const std::pair<const char*, const std::array<double, 6>*> targets[] = {{"SV2", &c.sv2},
                                                                            {"SV3", &c.sv3}};
    for (const auto& [id, expected] : targets) {
      SCOPED_TRACE(std::string(c.file) + " " + id);
      const astro::QnsElements t = astro::qns_from_cartesian(s.initial_state_eci(id));
      const astro::Vec6 a_droe = sv4.a_m * astro::roe_from_qns(sv4, t).as_vector();
      for (int k = 0; k < 6; ++k) {
        EXPECT_NEAR(a_droe[k], (*expected)[static_cast<std::size_t>(k)], 1e-6) << "component " << k;
      }
    }
  }
}

TEST(StarlingScenarios, ReferencePeriodIsSv4Period) {
  const Scenario s = load_scenario(scenario_path("starling_it.yaml"));
  EXPECT_NEAR(s.reference_period_s(), astro::orbit_period_s(6945e3), 1e-9);
  // 19 h is about 12 orbits.
  EXPECT_NEAR(s.duration_s / s.reference_period_s(), 12.0, 0.2);
}

// --- Derived quantities ---------------------------------------------------------

TEST(Scenario, ServicesListInStartOrder) {
  const Scenario s = load_scenario(scenario_path("starling_pse.yaml"));
  EXPECT_EQ(services(s), (std::vector<std::string>{"truth", "camera-renderer", "crosslink-emulator",
                                                   "observer-SV4", "recorder"}));
  const std::string two = kValid + R"(  - spacecraft: SV2
    mode: 3
)";
  const Scenario s2 = load_scenario(write_file("two_observers.yaml", two));
  EXPECT_EQ(services(s2),
            (std::vector<std::string>{"truth", "camera-renderer", "crosslink-emulator",
                                      "observer-SV4", "observer-SV2", "recorder"}));
}

TEST(Scenario, SpacecraftByIdThrowsNamingTheId) {
  const Scenario s = load_scenario(scenario_path("starling_pse.yaml"));
  EXPECT_EQ(s.spacecraft_by_id("SV3").id, "SV3");
  try {
    (void)s.spacecraft_by_id("SV1");
    FAIL() << "expected std::out_of_range";
  } catch (const std::out_of_range& e) {
    EXPECT_THAT(e.what(), HasSubstr("'SV1'"));
  }
  EXPECT_THROW((void)s.initial_state_eci("SV9"), std::out_of_range);
}

TEST(Scenario, RelativeChainResolvesThroughEachChief) {
  const std::string text = kValid + R"(  - spacecraft: SV2
    mode: 1
)";
  std::string chained = text;
  chained.replace(chained.find("observers:"), 0,
                  "  - id: SV3\n    relative: {chief: SV2, roe_m: [5, 1000, 20, -30, 40, 50]}\n");
  const Scenario s = load_scenario(write_file("chain.yaml", chained));
  const auto q4 = astro::qns_from_cartesian(s.initial_state_eci("SV4"));
  const auto q2 = astro::qns_from_cartesian(s.initial_state_eci("SV2"));
  const auto q3 = astro::qns_from_cartesian(s.initial_state_eci("SV3"));
  // SV3's ROE are relative to SV2, scaled by SV2's semi-major axis.
  const astro::Vec6 a_droe_32 = q2.a_m * astro::roe_from_qns(q2, q3).as_vector();
  astro::Vec6 expected;
  expected << 5, 1000, 20, -30, 40, 50;
  EXPECT_LT((a_droe_32 - expected).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_NEAR(q2.a_m, q4.a_m * (1.0 + 23.0 / q4.a_m), 1e-6);
}

TEST(Scenario, KeplerOrbitAndDefaults) {
  const std::string text = R"(name: kepler
epoch: 2024-05-08
duration: 5400
spacecraft:
  - id: A
    kepler: {a_km: 7000, e: 0.001, i_deg: 98, raan_deg: 10, argp_deg: 20, M_deg: 30}
observers:
  - spacecraft: A
)";
  const Scenario s = load_scenario(write_file("kepler.yaml", text));
  const auto oe = astro::kepler_from_cartesian(s.initial_state_eci("A"));
  EXPECT_NEAR(oe.a_m, 7000e3, 1e-5);
  EXPECT_NEAR(oe.e, 0.001, 1e-12);
  EXPECT_NEAR(oe.M_rad, 30.0 * astro::kDegToRad, 1e-9);
  // Everything not given takes the struct defaults.
  const Scenario d;
  EXPECT_EQ(s.seed, d.seed);
  EXPECT_DOUBLE_EQ(s.step_s, d.step_s);
  EXPECT_EQ(s.force_model.gravity_degree, d.force_model.gravity_degree);
  EXPECT_DOUBLE_EQ(s.spacecraft[0].properties.mass_kg, dynamics::SpacecraftProperties{}.mass_kg);
  const ObserverConfig od;
  EXPECT_EQ(s.observers[0].mode, od.mode);
  EXPECT_EQ(s.observers[0].camera.model, od.camera.model);
  EXPECT_EQ(s.observers[0].camera.boresight, od.camera.boresight);
  EXPECT_DOUBLE_EQ(s.crosslink.max_range_m, CrosslinkConfig{}.max_range_m);
  EXPECT_DOUBLE_EQ(s.tuning.sod.eps_ambig, SodTuning{}.eps_ambig);
  EXPECT_TRUE(s.maneuvers.empty());
  EXPECT_TRUE(s.faults.empty());
}

TEST(Scenario, InstantsAsUtcOrOffsetFromEpoch) {
  const std::string text = kValid + R"(maneuvers:
  - {spacecraft: SV2, epoch: 2h, dv_rtn_mps: [0, 0.01, 0]}
  - {spacecraft: SV2, epoch: "2024-05-08T03:00:00Z", dv_rtn_mps: [0, -0.01, 0]}
crosslink:
  outages: [{from: SV4, start: 1h, end: 90m}]
)";
  const Scenario s = load_scenario(write_file("instants.yaml", text));
  ASSERT_EQ(s.maneuvers.size(), 2u);
  EXPECT_EQ(s.maneuvers[0].epoch, s.epoch.plus_seconds(7200.0));
  EXPECT_EQ(s.maneuvers[1].epoch, s.epoch.plus_seconds(10800.0));
  EXPECT_DOUBLE_EQ(s.maneuvers[0].dv_rtn_mps.y(), 0.01);
  ASSERT_EQ(s.crosslink.outages.size(), 1u);
  EXPECT_EQ(s.crosslink.outages[0].from, "SV4");
  EXPECT_EQ(s.crosslink.outages[0].to, "*");
  EXPECT_EQ(s.crosslink.outages[0].window.end, s.epoch.plus_seconds(5400.0));
}

TEST(Scenario, GravityDegreeAloneMeansSquareField) {
  const Scenario s =
      load_scenario(write_file("grav.yaml", kValid + "force_model: {gravity_degree: 20}\n"));
  EXPECT_EQ(s.force_model.gravity_degree, 20);
  EXPECT_EQ(s.force_model.gravity_order, 20);
}

TEST(ScenarioValidation, SpacecraftIdsAreAtMost20Characters) {
  std::string text = kValid;
  const auto at = text.find("id: SV2");
  ASSERT_NE(at, std::string::npos);
  text.replace(at, 7, "id: SV2_with_a_very_long_name");
  const auto diags = validate_scenario_file(write_file("long_id.yaml", text));
  bool found = false;
  for (const auto& d : diags) {
    found = found || d.message.find("at most 20 characters, got 25") != std::string::npos;
  }
  EXPECT_TRUE(found) << dump(diags);
}

TEST(ScenarioLoad, OneForceModelBlockMeansBothSides) {
  const Scenario s = load_scenario(write_file("fm_one.yaml", kValid + "force_model: {gravity_degree: 20, srp: true}\n"));
  EXPECT_EQ(s.onboard_force_model.gravity_degree, 20);
  EXPECT_TRUE(s.onboard_force_model.srp);
  EXPECT_TRUE(s.force_models_agree());
}

TEST(ScenarioLoad, TruthAndOnboardForceModelsApart) {
  const Scenario s = load_scenario(write_file(
      "fm_two.yaml", kValid + "force_model:\n  truth: {gravity_degree: 40, srp: true}\n  onboard: {gravity_degree: 10}\n"));
  EXPECT_EQ(s.force_model.gravity_degree, 40);
  EXPECT_TRUE(s.force_model.srp);
  EXPECT_EQ(s.onboard_force_model.gravity_degree, 10);
  EXPECT_FALSE(s.onboard_force_model.srp);
  EXPECT_FALSE(s.force_models_agree());
  // The uplink carries the onboard side only.
  EXPECT_EQ(make_uplink(s, "SV4").force_model.gravity_degree, 10);
}

TEST(ScenarioLoad, PlannedManeuverGoesUpToItsObserverAndIsExecutedWithItsError) {
  const Scenario s = load_scenario(write_file(
      "man_planned.yaml",
      kValid + "maneuvers:\n  - {spacecraft: SV4, epoch: 2h, dv_rtn_mps: [0, 0.05, 0], planned: true, "
               "execution_sigma_fraction: 0.05}\n  - {spacecraft: SV2, epoch: 3h, dv_rtn_mps: [0, 0.5, 0]}\n"));
  ASSERT_EQ(s.maneuvers.size(), 2u);
  EXPECT_TRUE(s.maneuvers[0].planned);
  EXPECT_FALSE(s.maneuvers[1].planned);
  // The uplink carries the observer's own planned burn (commanded), not the target's.
  const ObserverUplink u = make_uplink(s, "SV4");
  ASSERT_EQ(u.planned_maneuvers.size(), 1u);
  EXPECT_EQ(u.planned_maneuvers[0].t, s.epoch.plus_seconds(7200.0));
  EXPECT_DOUBLE_EQ(u.planned_maneuvers[0].dv_rtn_mps[1], 0.05);
  EXPECT_DOUBLE_EQ(u.planned_maneuvers[0].execution_sigma_fraction, 0.05);
  const std::string path = ::testing::TempDir() + "/uplink_planned.json";
  write_uplink(u, path);
  const ObserverUplink b = read_uplink(path);
  ASSERT_EQ(b.planned_maneuvers.size(), 1u);
  EXPECT_EQ(b.planned_maneuvers[0].dv_rtn_mps, u.planned_maneuvers[0].dv_rtn_mps);
  // The truth executes it with a deterministic error of the stated size.
  const astro::Vec3 dv = executed_maneuver_dv(s, 0);
  EXPECT_EQ(dv, executed_maneuver_dv(s, 0));
  EXPECT_NE(dv, s.maneuvers[0].dv_rtn_mps);
  EXPECT_NEAR(dv.norm(), 0.05, 4 * 0.05 * 0.05);
  EXPECT_EQ(executed_maneuver_dv(s, 1), s.maneuvers[1].dv_rtn_mps);
  const auto diags = validate_scenario_file(write_file(
      "man_bad.yaml", kValid + "maneuvers:\n  - {spacecraft: SV4, epoch: 2h, dv_rtn_mps: [0, 0.05, 0], "
                               "execution_sigma_fraction: 2}\n"));
  ASSERT_EQ(diags.size(), 1u) << dump(diags);
  EXPECT_EQ(diags[0].field, "maneuvers[0].execution_sigma_fraction");
}

TEST(ScenarioValidation, ABadFieldOfOneForceModelSideIsNamed) {
  const std::string path = write_file(
      "fm_bad.yaml", kValid + "force_model:\n  truth: {gravity_degree: 400}\n  onboard: {gravity_degree: 10}\n");
  const auto diags = validate_scenario_file(path);
  ASSERT_EQ(diags.size(), 1u) << dump(diags);
  EXPECT_EQ(diags[0].field, "force_model.truth.gravity_degree");
  EXPECT_EQ(diags[0].line, 13);
}

TEST(ScenarioLoad, SplitForceModelTruthDefaultsToTheFlightLikeWorld) {
  const Scenario s = load_scenario(write_file("fm_split.yaml", kValid + "seed: 42\nforce_model:\n  onboard: {gravity_degree: 10}\n"));
  dynamics::ForceModelOptions f = dynamics::ForceModelOptions::flight_like_truth();
  EXPECT_EQ(s.force_model.gravity_degree, f.gravity_degree);
  EXPECT_EQ(s.force_model.gravity_order, f.gravity_order);
  EXPECT_TRUE(s.force_model.srp && s.force_model.drag && s.force_model.sun && s.force_model.moon);
  EXPECT_EQ(s.force_model.atmosphere_model, dynamics::AtmosphereModel::kJacchiaScaledHarrisPriester);
  EXPECT_EQ(s.force_model.describe().substr(0, 13), "gravity 20x20");
  // Space weather counts days from the epoch and draws from the seed.
  EXPECT_EQ(s.force_model.space_weather.start, s.epoch);
  EXPECT_EQ(s.force_model.space_weather.seed, 42u);
  EXPECT_DOUBLE_EQ(s.force_model.space_weather.f107_sfu, dynamics::SpaceWeather{}.f107_sfu);
  // The onboard side keeps the paper's model.
  EXPECT_EQ(s.onboard_force_model.atmosphere_model, dynamics::AtmosphereModel::kHarrisPriester);
  EXPECT_FALSE(s.onboard_force_model.srp);
  EXPECT_FALSE(s.force_models_agree());
  // No block at all: the paper's model on both sides, as before.
  const Scenario plain = load_scenario(write_file("fm_none.yaml", kValid));
  EXPECT_TRUE(plain.force_models_agree());
  EXPECT_EQ(plain.force_model.atmosphere_model, dynamics::AtmosphereModel::kHarrisPriester);
  EXPECT_EQ(plain.force_model.gravity_degree, 10);
}

TEST(ScenarioLoad, ForceModelSidesByName) {
  const Scenario s = load_scenario(write_file("fm_named.yaml", kValid + "force_model: {truth: flight-like, onboard: paper}\n"));
  EXPECT_EQ(s.force_model.describe(), dynamics::ForceModelOptions::flight_like_truth().describe());
  EXPECT_EQ(s.onboard_force_model.describe(), dynamics::ForceModelOptions{}.describe());
  // The truth side made equal to the paper's model, key by key: they agree.
  const Scenario same = load_scenario(write_file(
      "fm_same.yaml", kValid + "force_model:\n  truth: {gravity_degree: 10, srp: false, atmosphere: harris-priester}\n"
                               "  onboard: paper\n"));
  EXPECT_TRUE(same.force_models_agree()) << same.force_model.describe();
  const Scenario both = load_scenario(write_file("fm_both.yaml", kValid + "force_model: {truth: paper, onboard: paper}\n"));
  EXPECT_TRUE(both.force_models_agree());
  expect_one("fm_name_bad.yaml", kValid + "force_model: {truth: flightlike}\n", 12, "force_model.truth",
             "flight-like or paper");
}

TEST(ScenarioLoad, SpaceWeatherAndAtmosphereKeys) {
  const std::string text = kValid + R"(force_model:
  truth:
    space_weather:
      f107_sfu: 210
      f107_81day_sfu: 180
      kp: 5.3
      f107_daily_sigma_sfu: 15
      kp_daily_sigma: 0.7
      density_error_sigma: 0.15
      density_error_time_s: 3600
      daily: [{f107_sfu: 230, kp: 8}, {f107_sfu: 200, kp: 6}]
  onboard: {gravity_degree: 10}
)";
  const Scenario s = load_scenario(write_file("sw.yaml", text));
  const dynamics::SpaceWeather& w = s.force_model.space_weather;
  EXPECT_DOUBLE_EQ(w.f107_sfu, 210.0);
  EXPECT_DOUBLE_EQ(w.f107_81day_sfu, 180.0);
  EXPECT_DOUBLE_EQ(w.kp, 5.3);
  EXPECT_DOUBLE_EQ(w.f107_daily_sigma_sfu, 15.0);
  EXPECT_DOUBLE_EQ(w.kp_daily_sigma, 0.7);
  EXPECT_DOUBLE_EQ(w.density_error_sigma, 0.15);
  EXPECT_DOUBLE_EQ(w.density_error_time_s, 3600.0);
  EXPECT_NE(s.force_model.describe().find("density model error sigma 0.15"), std::string::npos);
  ASSERT_EQ(w.daily.size(), 2u);
  EXPECT_DOUBLE_EQ(w.daily[1].kp, 6.0);
  EXPECT_DOUBLE_EQ(w.at(s.epoch.plus_seconds(90000.0)).f107_sfu, 200.0);
  EXPECT_NE(s.force_model.describe().find("2 daily values"), std::string::npos) << s.force_model.describe();
  // One block for both sides may name the variable atmosphere too.
  const Scenario one = load_scenario(write_file(
      "sw_one.yaml", kValid + "force_model: {atmosphere: jacchia-scaled-harris-priester, space_weather: {kp: 2}}\n"));
  EXPECT_TRUE(one.force_models_agree());
  EXPECT_EQ(one.onboard_force_model.atmosphere_model, dynamics::AtmosphereModel::kJacchiaScaledHarrisPriester);
  EXPECT_DOUBLE_EQ(one.onboard_force_model.space_weather.kp, 2.0);
}

TEST(ScenarioValidation, BadSpaceWeatherAndAtmosphereValuesAreNamed) {
  const std::string head = kValid + "force_model:\n  truth:\n    space_weather:\n";
  expect_one("sw_kp.yaml", head + "      kp: 12\n", 15, "force_model.truth.space_weather.kp", "0 <= kp <= 9");
  expect_one("sw_flux.yaml", head + "      f107_sfu: -5\n", 15, "force_model.truth.space_weather.f107_sfu",
             "f107_sfu > 0");
  expect_one("sw_nan.yaml", head + "      f107_81day_sfu: .nan\n", 15, "force_model.truth.space_weather.f107_81day_sfu",
             "finite");
  expect_one("sw_sigma.yaml", head + "      kp_daily_sigma: -1\n", 15, "force_model.truth.space_weather.kp_daily_sigma",
             ">= 0");
  expect_one("sw_daily.yaml", head + "      daily:\n        - {f107_sfu: 150, kp: 2}\n        - {f107_sfu: 0, kp: 2}\n", 17,
             "force_model.truth.space_weather.daily[1].f107_sfu", "f107_sfu > 0");
  expect_one("sw_daily_kp.yaml", head + "      daily: [{f107_sfu: 150}]\n", 15,
             "force_model.truth.space_weather.daily[0].kp", "missing required field");
  expect_one("sw_key.yaml", head + "      f107_sfx: 150\n", 15, "force_model.truth.space_weather.f107_sfx", "did you mean");
  expect_one("sw_rho.yaml", head + "      density_error_sigma: 1.5\n", 15,
             "force_model.truth.space_weather.density_error_sigma", "0 <= density_error_sigma <= 1");
  expect_one("sw_rho_t.yaml", head + "      density_error_time_s: 10\n", 15,
             "force_model.truth.space_weather.density_error_time_s", "60 <= density_error_time_s <= 864000 s");
  // The world's density error drawn from the run's seed is not for the onboard model.
  expect_one("sw_rho_onboard.yaml",
             kValid + "force_model:\n  onboard:\n    atmosphere: jacchia-scaled-harris-priester\n"
                      "    space_weather: {density_error_sigma: 0.1}\n",
             14, "force_model.onboard", "truth side only");
  expect_one("atm_bad.yaml", kValid + "force_model: {truth: {atmosphere: msis}}\n", 12, "force_model.truth.atmosphere",
             "harris-priester or jacchia-scaled-harris-priester");
  // Space weather for an atmosphere that does not use it.
  expect_one("sw_hp.yaml", kValid + "force_model: {space_weather: {kp: 2}}\n", 12, "force_model.space_weather",
             "atmosphere: jacchia-scaled-harris-priester");
}

TEST(ScenarioLoad, OnboardSpacecraftPropertiesAreUplinkedForEveryMember) {
  std::string text = kValid;
  const std::string sv2 = "    relative: {chief: SV4, roe_m: [23, -52266, -471, -523, 35, 1811]}\n";
  text.replace(text.find(sv2), sv2.size(),
               sv2 + "    mass_kg: 11.5\n    drag_area_m2: 0.08\n    onboard: {mass_kg: 10.5, cd: 2.4}\n");
  const Scenario s = load_scenario(write_file("sc_onboard.yaml", text));
  const auto& sv2c = s.spacecraft_by_id("SV2");
  EXPECT_DOUBLE_EQ(sv2c.properties.mass_kg, 11.5);  // truth
  EXPECT_DOUBLE_EQ(sv2c.properties.drag_area_m2, 0.08);
  EXPECT_DOUBLE_EQ(sv2c.onboard_properties.mass_kg, 10.5);  // what the ground uplinks
  EXPECT_DOUBLE_EQ(sv2c.onboard_properties.cd, 2.4);
  EXPECT_DOUBLE_EQ(sv2c.onboard_properties.drag_area_m2, dynamics::SpacecraftProperties{}.drag_area_m2);
  const ObserverUplink u = make_uplink(s, "SV4");
  EXPECT_DOUBLE_EQ(u.onboard_properties("SV2").mass_kg, 10.5);
  EXPECT_DOUBLE_EQ(u.onboard_properties("SV4").mass_kg, dynamics::SpacecraftProperties{}.mass_kg);
  EXPECT_EQ(u.onboard_properties_by_id.size(), 2u);
  // A truth-only attitude-like drag-area variation.
  std::string var = kValid;
  var.replace(var.find(sv2), sv2.size(), sv2 + "    drag_area_variation: 0.3\n");
  EXPECT_DOUBLE_EQ(load_scenario(write_file("sc_var.yaml", var)).spacecraft_by_id("SV2").properties.drag_area_variation, 0.3);
  var.replace(var.find("0.3\n"), 4, "1.2\n");
  expect_one("sc_var_bad.yaml", var, 9, "spacecraft[1].drag_area_variation", "0 <= drag_area_variation < 1");
  // Bad values are named.
  std::string bad = kValid;
  bad.replace(bad.find(sv2), sv2.size(), sv2 + "    onboard: {cd: -1, area: 2}\n");
  expect_one("sc_onboard_cd.yaml", bad, 9, "spacecraft[1].onboard.cd", "cd > 0");
  expect_one("sc_onboard_key.yaml", bad, 9, "spacecraft[1].onboard.area", "unknown key");
}

TEST(ScenarioLoad, MeanRoeAreRelativeToTheChiefsMeanElements) {
  std::string text = kValid;
  const std::string key = "roe_m: [23, -52266, -471, -523, 35, 1811]}";
  text.replace(text.find(key), key.size(), "roe_m: [23, -52266, -471, -523, 35, 1811], roe_type: mean}");
  const Scenario s = load_scenario(write_file("mean_roe.yaml", text));
  const auto chief = dynamics::mean_from_osculating(astro::qns_from_cartesian(s.initial_state_eci("SV4")));
  const auto dep = dynamics::mean_from_osculating(astro::qns_from_cartesian(s.initial_state_eci("SV2")));
  const astro::Vec6 a_roe = astro::roe_from_qns(chief, dep).as_vector() * chief.a_m;
  const astro::Vec6 want = (astro::Vec6() << 23, -52266, -471, -523, 35, 1811).finished();
  EXPECT_LT((a_roe - want).cwiseAbs().maxCoeff(), 0.01) << a_roe.transpose();
  // The default reads them as osculating: a different deputy.
  const Scenario o = load_scenario(write_file("osc_roe.yaml", kValid));
  EXPECT_GT((o.initial_state_eci("SV2").r_m - s.initial_state_eci("SV2").r_m).norm(), 10.0);
}

TEST(ScenarioValidation, AnUnknownRoeTypeIsNamed) {
  std::string text = kValid;
  const std::string key = "roe_m: [23, -52266, -471, -523, 35, 1811]}";
  text.replace(text.find(key), key.size(), "roe_m: [23, -52266, -471, -523, 35, 1811], roe_type: average}");
  const auto diags = validate_scenario_file(write_file("bad_roe_type.yaml", text));
  ASSERT_EQ(diags.size(), 1u) << dump(diags);
  EXPECT_EQ(diags[0].field, "spacecraft[1].relative.roe_type");
  EXPECT_THAT(diags[0].message, HasSubstr("expected osculating or mean"));
}

TEST(ScenarioValidation, Mode4LoadsWithoutGnssAndItsCoarseOrbit) {
  // Mode 4 turns GNSS off by default; coarse_orbit gives its starting orbit's
  // 1-sigma (a default when omitted).
  const std::string text = kValid + "    mode: 4\n    coarse_orbit: {sigma_roe_m: [10, 2500, 250, 250, 250, 250]}\n"
                                    "  - spacecraft: SV2\n    mode: 4\n";
  const std::string path = write_file("mode4.yaml", text);
  const auto diags = validate_scenario_file(path);
  ASSERT_TRUE(diags.empty()) << dump(diags);
  const Scenario s = load_scenario(path);
  ASSERT_EQ(s.observers.size(), 2u);
  EXPECT_EQ(s.observers[0].mode, 4);
  EXPECT_FALSE(s.observers[0].gnss.enabled);
  EXPECT_DOUBLE_EQ(s.observers[0].coarse_orbit_sigma_a_roe_m[1], 2500.0);
  EXPECT_DOUBLE_EQ(s.observers[1].coarse_orbit_sigma_a_roe_m[1], 5000.0);
}

TEST(ScenarioValidation, CoarseOrbitOnlyInMode4AndPositive) {
  expect_one("coarse_mode1.yaml", kValid + "    coarse_orbit: {sigma_roe_m: [10, 2500, 250, 250, 250, 250]}\n", 12,
             "observers[0].coarse_orbit", "starting orbit of navigation mode 4");
  const std::string bad = kValid + "    mode: 4\n    coarse_orbit: {sigma_roe_m: [10, 0, 250, 250, 250, 250]}\n"
                                   "  - spacecraft: SV2\n    mode: 4\n";
  expect_one("coarse_zero.yaml", bad, 13, "observers[0].coarse_orbit.sigma_roe_m", "out of range");
}
TEST(ScenarioLoad, AdaptiveFormAndAverageDefaultToThePapersAndAreNamedWhenWrong) {
  const Scenario d = load_scenario(write_file("adaptive_default.yaml", kValid));
  EXPECT_EQ(d.tuning.sod.adaptive_form, SodTuning::AdaptiveForm::kDiagonal);
  EXPECT_EQ(d.tuning.sod.adaptive_average, SodTuning::AdaptiveAverage::kClamped);
  const Scenario s = load_scenario(write_file(
      "adaptive_block.yaml", kValid + "tuning:\n  sod: {adaptive_form: block, adaptive_average: unclamped}\n"));
  EXPECT_EQ(s.tuning.sod.adaptive_form, SodTuning::AdaptiveForm::kBlock);
  EXPECT_EQ(s.tuning.sod.adaptive_average, SodTuning::AdaptiveAverage::kUnclamped);
  expect_one("adaptive_bad_form.yaml", kValid + "tuning:\n  sod: {adaptive_form: full}\n", 13,
             "tuning.sod.adaptive_form", "expected diagonal or block");
  expect_one("adaptive_bad_average.yaml", kValid + "tuning:\n  sod: {adaptive_average: 3}\n", 13,
             "tuning.sod.adaptive_average", "expected clamped or unclamped");
}
TEST(ScenarioLoad, DragDensityErrorIsOffByDefaultAndNamedWhenOutOfRange) {
  EXPECT_EQ(load_scenario(write_file("drag_floor_default.yaml", kValid)).tuning.sod.drag_density_error, 0.0);
  const Scenario s =
      load_scenario(write_file("drag_floor.yaml", kValid + "tuning:\n  sod: {drag_density_error: 0.3}\n"));
  EXPECT_DOUBLE_EQ(s.tuning.sod.drag_density_error, 0.3);
  expect_one("drag_floor_negative.yaml", kValid + "tuning:\n  sod: {drag_density_error: -0.1}\n", 13,
             "tuning.sod.drag_density_error", "out of range");
  expect_one("drag_floor_text.yaml", kValid + "tuning:\n  sod: {drag_density_error: high}\n", 13,
             "tuning.sod.drag_density_error", "expected a number");
}
TEST(ScenarioLoad, AdaptiveTimeConstantIsADurationNamedWhenOutOfRange) {
  EXPECT_EQ(load_scenario(write_file("tau_default.yaml", kValid)).tuning.sod.adaptive_time_constant_s, 1170.0);
  const Scenario s =
      load_scenario(write_file("tau.yaml", kValid + "tuning:\n  sod: {adaptive_time_constant: 3h}\n"));
  EXPECT_DOUBLE_EQ(s.tuning.sod.adaptive_time_constant_s, 3.0 * 3600.0);
  expect_one("tau_zero.yaml", kValid + "tuning:\n  sod: {adaptive_time_constant: 0s}\n", 13,
             "tuning.sod.adaptive_time_constant", "> 0 s");
  expect_one("tau_long.yaml", kValid + "tuning:\n  sod: {adaptive_time_constant: 40d}\n", 13,
             "tuning.sod.adaptive_time_constant", "at most 30 days");
}
TEST(ScenarioLoad, EpochWindowDrawsTheRunsEpochFromTheSeedAndMovesEveryInstantWithIt) {
  const std::string body = kValid + R"(    gnss: {outages: [{start: 1h, end: 2h}]}
crosslink:
  outages: [{from: SV4, start: 3h, end: 4h}]
maneuvers:
  - {spacecraft: SV2, epoch: 5h, dv_rtn_mps: [0, 0.05, 0]}
)";
  const Scenario fixed = load_scenario(write_file("ew_none.yaml", body));
  EXPECT_EQ(fixed.epoch, fixed.epoch_nominal);
  EXPECT_EQ(fixed.epoch_offset_s, 0.0);
  // Every instant keeps its offset from the run's epoch, and the space weather counts days from it.
  const auto expect_instants_follow = [](const Scenario& x) {
    EXPECT_EQ(x.epoch, x.epoch_nominal.plus_seconds(x.epoch_offset_s));
    EXPECT_EQ(astro::seconds_between(x.epoch, x.observers[0].gnss.outages[0].start), 3600.0);
    EXPECT_EQ(astro::seconds_between(x.epoch, x.observers[0].gnss.outages[0].end), 7200.0);
    EXPECT_EQ(astro::seconds_between(x.epoch, x.crosslink.outages[0].window.start), 10800.0);
    EXPECT_EQ(astro::seconds_between(x.epoch, x.crosslink.outages[0].window.end), 14400.0);
    EXPECT_EQ(astro::seconds_between(x.epoch, x.maneuvers[0].epoch), 18000.0);
    EXPECT_EQ(x.force_model.space_weather.start, x.epoch);
    EXPECT_EQ(x.onboard_force_model.space_weather.start, x.epoch);
    EXPECT_EQ(x.force_model.space_weather.seed, x.seed);
  };
  expect_instants_follow(fixed);
  Scenario s = load_scenario(write_file("ew_day.yaml", "epoch_window: 24h\n" + body));
  EXPECT_EQ(s.epoch_window_s, 86400.0);
  EXPECT_EQ(s.epoch_nominal, fixed.epoch_nominal);
  std::set<double> offsets;
  double first = -1.0;
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    set_seed(s, seed);
    expect_instants_follow(s);
    EXPECT_GE(s.epoch_offset_s, 0.0);
    EXPECT_LT(s.epoch_offset_s, 86400.0);
    EXPECT_EQ(s.epoch_offset_s, std::floor(s.epoch_offset_s));  // whole seconds
    if (seed == 1) first = s.epoch_offset_s;
    offsets.insert(s.epoch_offset_s);
  }
  EXPECT_GE(offsets.size(), 19u);  // the seeds fly at different times of day
  set_seed(s, 1);  // drawn again from the file's epoch, not from the last one
  EXPECT_EQ(s.epoch_offset_s, first);
  expect_instants_follow(s);
  set_epoch_window(s, 0.0);
  EXPECT_EQ(s.epoch, fixed.epoch);
  expect_instants_follow(s);
  EXPECT_THROW(set_epoch_window(s, -1.0), std::invalid_argument);
  EXPECT_THROW(set_epoch_window(s, 31.0 * 86400.0), std::invalid_argument);
  expect_one("ew_long.yaml", "epoch_window: 31d\n" + body, 1, "epoch_window", "at most 30 days");
  expect_one("ew_text.yaml", "epoch_window: a day\n" + body, 1, "epoch_window", "duration");
}
TEST(ScenarioLoad, PhaseWindowTurnsTheAbsoluteOrbitsByTheDrawnPhaseAndTheFormationFollows) {
  const Scenario fixed = load_scenario(write_file("pw_none.yaml", kValid));
  EXPECT_EQ(fixed.phase_offset_deg, 0.0);
  Scenario s = load_scenario(write_file("pw_full.yaml", "phase_window_deg: 360\n" + kValid));
  EXPECT_EQ(s.phase_window_deg, 360.0);
  const astro::QnsElements q0 = fixed.spacecraft_by_id("SV4").orbit.qns;
  const astro::Roe roe0 = astro::roe_from_qns(astro::qns_from_cartesian(fixed.initial_state_eci("SV4")),
                                              astro::qns_from_cartesian(fixed.initial_state_eci("SV2")));
  std::set<double> offsets;
  double first = -1.0;
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    set_seed(s, seed);
    EXPECT_GE(s.phase_offset_deg, 0.0);
    EXPECT_LT(s.phase_offset_deg, 360.0);
    if (seed == 1) first = s.phase_offset_deg;
    offsets.insert(s.phase_offset_deg);
    // The chief turned along its orbit by the offset, nothing else of it changed.
    const astro::QnsElements q = s.spacecraft_by_id("SV4").orbit.qns;
    EXPECT_NEAR(astro::wrap_pi(q.u_rad - q0.u_rad - s.phase_offset_deg * astro::kDegToRad), 0.0, 1e-12);
    EXPECT_EQ(q.a_m, q0.a_m);
    EXPECT_EQ(q.raan_rad, q0.raan_rad);
    // The deputy follows: the same osculating ROE (to the map's round-off), another place on the orbit.
    const astro::Roe roe = astro::roe_from_qns(astro::qns_from_cartesian(s.initial_state_eci("SV4")),
                                               astro::qns_from_cartesian(s.initial_state_eci("SV2")));
    EXPECT_LT(q0.a_m * (roe.as_vector() - roe0.as_vector()).cwiseAbs().maxCoeff(), 1e-3);  // m
    EXPECT_EQ(s.epoch, fixed.epoch);  // the epoch stays (its own window is 0)
  }
  EXPECT_EQ(offsets.size(), 20u);
  set_seed(s, 1);  // the same draw again
  EXPECT_EQ(s.phase_offset_deg, first);
  set_phase_window(s, 0.0);
  EXPECT_EQ(s.phase_offset_deg, 0.0);
  EXPECT_NEAR(s.spacecraft_by_id("SV4").orbit.qns.u_rad, q0.u_rad, 1e-12);
  EXPECT_THROW(set_phase_window(s, -1.0), std::invalid_argument);
  EXPECT_THROW(set_phase_window(s, 361.0), std::invalid_argument);
  expect_one("pw_big.yaml", "phase_window_deg: 400\n" + kValid, 1, "phase_window_deg", "400");
}
TEST(ScenarioLoad, ClockResidualIsDrawnPerSeedWithItsOneSigmaAndNamedWhenWrong) {
  const std::string faults =
      "faults:\n  - {observer: SV4, time_tag_offset_s: -0.4, time_tag_offset_sigma_s: 0.05, "
      "time_tag_drift_sigma_ppm: 2}\n";
  Scenario s = load_scenario(write_file("clock_draw.yaml", kValid + faults));
  ASSERT_EQ(s.faults.size(), 1u);
  const FaultConfig& f = s.faults.front();
  EXPECT_EQ(f.time_tag_offset_s, -0.4);  // the file's value kept apart from the draw
  // Over many seeds the residuals are centred with the given 1-sigmas, and independent.
  const int n = 4000;
  double so = 0.0, so2 = 0.0, sd = 0.0, sd2 = 0.0, sod = 0.0;
  for (int seed = 1; seed <= n; ++seed) {
    set_seed(s, static_cast<std::uint64_t>(seed));
    EXPECT_EQ(f.time_tag_offset_total_s(), -0.4 + f.time_tag_offset_drawn_s);
    EXPECT_EQ(f.time_tag_drift_total_ppm(), f.time_tag_drift_drawn_ppm);
    so += f.time_tag_offset_drawn_s;
    so2 += f.time_tag_offset_drawn_s * f.time_tag_offset_drawn_s;
    sd += f.time_tag_drift_drawn_ppm;
    sd2 += f.time_tag_drift_drawn_ppm * f.time_tag_drift_drawn_ppm;
    sod += f.time_tag_offset_drawn_s * f.time_tag_drift_drawn_ppm;
  }
  EXPECT_NEAR(so / n, 0.0, 4.0 * 0.05 / std::sqrt(n));
  EXPECT_NEAR(std::sqrt(so2 / n), 0.05, 0.05 * 0.05);  // 1-sigma within 5 % (its sampling 1-sigma ~1.1 %)
  EXPECT_NEAR(sd / n, 0.0, 4.0 * 2.0 / std::sqrt(n));
  EXPECT_NEAR(std::sqrt(sd2 / n), 2.0, 2.0 * 0.05);
  EXPECT_NEAR(sod / n / (0.05 * 2.0), 0.0, 0.07);  // uncorrelated (|rho| < 4.4 of its sampling sigma)
  set_seed(s, 7);
  const double offset7 = f.time_tag_offset_drawn_s;
  set_seed(s, 8);
  EXPECT_NE(f.time_tag_offset_drawn_s, offset7);
  set_seed(s, 7);
  EXPECT_EQ(f.time_tag_offset_drawn_s, offset7);  // the same seed, the same world
  // No 1-sigma: no draw.
  Scenario plain = load_scenario(write_file("clock_plain.yaml", kValid + "faults:\n  - {observer: SV4, time_tag_offset_s: -0.4}\n"));
  set_seed(plain, 7);
  EXPECT_EQ(plain.faults.front().time_tag_offset_total_s(), -0.4);
  EXPECT_EQ(plain.faults.front().time_tag_drift_total_ppm(), 0.0);
  expect_one("clock_bad.yaml", kValid + "faults:\n  - {observer: SV4, time_tag_offset_sigma_s: -1}\n", 13,
             "faults[0].time_tag_offset_sigma_s", "-1");
  expect_one("clock_bad2.yaml", kValid + "faults:\n  - {observer: SV4, time_tag_drift_sigma_ppm: 2e4}\n", 13,
             "faults[0].time_tag_drift_sigma_ppm", "20000");
}
TEST(ScenarioLoad, SenderClocksAreOffByDefaultAndNamedWhenWrong) {
  EXPECT_FALSE(load_scenario(write_file("senders_default.yaml", kValid)).tuning.sod.time_tag_senders);
  const Scenario s = load_scenario(
      write_file("senders_on.yaml", kValid + "tuning:\n  sod:\n    time_tag: {estimate: none, senders: true}\n"));
  EXPECT_TRUE(s.tuning.sod.time_tag_senders);
  expect_one("senders_bad.yaml", kValid + "tuning:\n  sod:\n    time_tag: {senders: 2}\n", 14,
             "tuning.sod.time_tag.senders", "true or false");
}
TEST(ScenarioLoad, TargetLinesDefaultToConsiderTheObserverAndAreNamedWhenWrong) {
  using L = SodTuning::TargetLines;
  EXPECT_EQ(load_scenario(write_file("lines_default.yaml", kValid)).tuning.sod.target_lines, L::kConsiderObserver);
  const Scenario s =
      load_scenario(write_file("lines_update.yaml", kValid + "tuning:\n  sod: {target_lines: update_observer}\n"));
  EXPECT_EQ(s.tuning.sod.target_lines, L::kUpdateObserver);
  expect_one("lines_bad.yaml", kValid + "tuning:\n  sod: {target_lines: both}\n", 13, "tuning.sod.target_lines",
             "expected consider_observer or update_observer");
}

TEST(ScenarioLoad, BodFitRatioDefaultsAndIsNamedWhenOutOfRange) {
  EXPECT_DOUBLE_EQ(load_scenario(write_file("fit_default.yaml", kValid)).tuning.bod.max_fit_ratio, 1.5);
  EXPECT_DOUBLE_EQ(
      load_scenario(write_file("fit_3.yaml", kValid + "tuning:\n  bod: {max_fit_ratio: 3}\n")).tuning.bod.max_fit_ratio,
      3.0);
  expect_one("fit_bad.yaml", kValid + "tuning:\n  bod: {max_fit_ratio: 0.5}\n", 13, "tuning.bod.max_fit_ratio",
             "out of range");
}

TEST(ScenarioValidation, Mode2WithATargetListLoads) {
  const std::string path =
      write_file("mode2.yaml", kValid + "    mode: 2\n    targets: [SV2]\n  - spacecraft: SV2\n    mode: 3\n");
  const auto diags = validate_scenario_file(path);
  EXPECT_TRUE(diags.empty()) << dump(diags);
  const Scenario s = load_scenario(path);
  EXPECT_EQ(s.observers[0].mode, 2);
  EXPECT_EQ(s.observers[0].targets, std::vector<std::string>{"SV2"});
}

// A target's gravity budget (docs/sod.md, "Unmodelled gravity in the thin
// directions"): read per target, carried by the uplink, absent for a target
// without one; a negative 1-sigma is named with its line.
TEST(ScenarioValidation, TargetGravityPeriodicBudgetReachesTheUplink) {
  const std::string path = write_file(
      "gravity_periodic.yaml",
      kValid + "    targets: [{id: SV2, gravity_periodic_roe_m: [0.17, 0, 0.127, 0.138, 0.051, 0.046]}]\n");
  const Scenario s = load_scenario(path);
  ASSERT_EQ(s.observers[0].target_gravity_periodic_a_roe_m.count("SV2"), 1u);
  const astro::Vec6 want = (astro::Vec6() << 0.17, 0.0, 0.127, 0.138, 0.051, 0.046).finished();
  EXPECT_EQ(s.observers[0].target_gravity_periodic_a_roe_m.at("SV2"), want);
  const std::string up = ::testing::TempDir() + "/uplink_gravity_periodic.json";
  write_uplink(make_uplink(s, "SV4"), up);
  const ObserverUplink b = read_uplink(up);
  ASSERT_EQ(b.observer.target_gravity_periodic_a_roe_m.size(), 1u);
  EXPECT_EQ(b.observer.target_gravity_periodic_a_roe_m.at("SV2"), want);
  EXPECT_TRUE(load_scenario(write_file("no_gravity_periodic.yaml", kValid))
                  .observers[0]
                  .target_gravity_periodic_a_roe_m.empty());
  expect_one("gravity_periodic_bad.yaml",
             kValid + "    targets: [{id: SV2, gravity_periodic_roe_m: [-0.1, 0, 0, 0, 0, 0]}]\n", 12,
             "observers[0].targets[0].gravity_periodic_roe_m", "out of range");
}

TEST(ScenarioLoad, AdaptiveTargetsDefaultsOnAndReachesTheUplink) {
  EXPECT_TRUE(load_scenario(write_file("adaptive_targets_default.yaml", kValid)).tuning.sod.adaptive_targets);
  const Scenario s =
      load_scenario(write_file("adaptive_targets.yaml", kValid + "tuning:\n  sod: {adaptive_targets: false}\n"));
  EXPECT_FALSE(s.tuning.sod.adaptive_targets);
  const std::string up = ::testing::TempDir() + "/uplink_adaptive_targets.json";
  write_uplink(make_uplink(s, "SV4"), up);
  EXPECT_FALSE(read_uplink(up).tuning.sod.adaptive_targets);
  expect_one("adaptive_targets_bad.yaml", kValid + "tuning:\n  sod: {adaptive_targets: 3}\n", 13,
             "tuning.sod.adaptive_targets", "");
}

// The ballistic state's random walk (docs/sod.md, "The ballistic walk from the
// density's budget"): sigma_fraction unless set, the walk with |dB| off unless
// set, both carried by the uplink, an out-of-range value named with its line.
TEST(ScenarioLoad, BallisticWalkDefaultsToItsPriorAndReachesTheUplink) {
  const Scenario d = load_scenario(
      write_file("ballistic_walk_default.yaml", kValid + "tuning:\n  sod: {ballistic: {sigma_fraction: 1.5}}\n"));
  EXPECT_FALSE(d.tuning.sod.ballistic_walk_fraction_per_day.has_value());
  EXPECT_DOUBLE_EQ(d.tuning.sod.ballistic_walk(), 1.5);
  EXPECT_EQ(d.tuning.sod.ballistic_density_change_per_day, 0.0);
  const Scenario s = load_scenario(
      write_file("ballistic_walk.yaml", kValid + "tuning:\n  sod: {ballistic: {estimate: true, walk_fraction_per_day: 0, "
                                                 "density_change_per_day: 0.19}}\n"));
  EXPECT_DOUBLE_EQ(s.tuning.sod.ballistic_sigma_fraction, 2.0);
  EXPECT_DOUBLE_EQ(s.tuning.sod.ballistic_walk(), 0.0);
  EXPECT_DOUBLE_EQ(s.tuning.sod.ballistic_density_change_per_day, 0.19);
  const std::string up = ::testing::TempDir() + "/uplink_ballistic_walk.json";
  write_uplink(make_uplink(s, "SV4"), up);
  const ObserverUplink b = read_uplink(up);
  EXPECT_DOUBLE_EQ(b.tuning.sod.ballistic_sigma_fraction, 2.0);
  EXPECT_DOUBLE_EQ(b.tuning.sod.ballistic_walk(), 0.0);
  EXPECT_DOUBLE_EQ(b.tuning.sod.ballistic_density_change_per_day, 0.19);
  expect_one("ballistic_walk_bad.yaml", kValid + "tuning:\n  sod: {ballistic: {walk_fraction_per_day: -1}}\n", 13,
             "tuning.sod.ballistic.walk_fraction_per_day", "out of range");
  expect_one("ballistic_change_bad.yaml", kValid + "tuning:\n  sod: {ballistic: {density_change_per_day: 11}}\n", 13,
             "tuning.sod.ballistic.density_change_per_day", "out of range");
}

// Stellar aberration: on in the world and corrected on board unless the
// scenario says otherwise; the onboard switch reaches the uplink.
TEST(ScenarioLoad, StellarAberrationIsOnInTheWorldAndCorrectedOnBoardByDefault) {
  const Scenario d = load_scenario(write_file("aberration_default.yaml", kValid));
  EXPECT_TRUE(d.observers.at(0).camera.stellar_aberration);
  EXPECT_TRUE(d.tuning.imp.aberration_correction);
  std::string text = kValid;
  text.replace(text.find("camera: {cadence: 60s}"), 22, "camera: {cadence: 60s, stellar_aberration: true}");
  const Scenario s = load_scenario(
      write_file("aberration_off.yaml", text + "tuning:\n  imp: {aberration_correction: false}\n"));
  EXPECT_TRUE(s.observers.at(0).camera.stellar_aberration);
  EXPECT_FALSE(s.tuning.imp.aberration_correction);
  const std::string up = ::testing::TempDir() + "/uplink_aberration.json";
  write_uplink(make_uplink(s, "SV4"), up);
  EXPECT_FALSE(read_uplink(up).tuning.imp.aberration_correction);
  write_uplink(make_uplink(d, "SV4"), up);
  EXPECT_TRUE(read_uplink(up).tuning.imp.aberration_correction);
  expect_one("aberration_bad.yaml", kValid + "tuning:\n  imp: {aberration_correction: 3}\n", 13,
             "tuning.imp.aberration_correction", "expected true or false");
}

// The aided detection's constant false-alarm rate: on by default (1e-4 per
// search), carried by the uplink, 0 in an uplink written before it (the fixed
// threshold), and a rate outside [0, 0.1] named.
TEST(ScenarioLoad, AidedDetectionFalseAlarmRateIsUplinkedAndChecked) {
  const Scenario d = load_scenario(write_file("false_alarms_default.yaml", kValid));
  EXPECT_DOUBLE_EQ(d.tuning.imp.aided_false_alarms, 1e-4);
  const Scenario s =
      load_scenario(write_file("false_alarms_fixed.yaml", kValid + "tuning:\n  imp: {aided_false_alarms: 0}\n"));
  EXPECT_DOUBLE_EQ(s.tuning.imp.aided_false_alarms, 0.0);
  const std::string up = ::testing::TempDir() + "/uplink_false_alarms.json";
  write_uplink(make_uplink(d, "SV4"), up);
  EXPECT_DOUBLE_EQ(read_uplink(up).tuning.imp.aided_false_alarms, 1e-4);
  write_uplink(make_uplink(s, "SV4"), up);
  EXPECT_DOUBLE_EQ(read_uplink(up).tuning.imp.aided_false_alarms, 0.0);
  expect_one("false_alarms_bad.yaml", kValid + "tuning:\n  imp: {aided_false_alarms: 0.5}\n", 13,
             "tuning.imp.aided_false_alarms", "expected 0 <= aided_false_alarms <= 0.1");
}

// The stacked aided search: carried by the uplink, 0 (off) in an uplink
// written before it, and a count outside [0, 5] named.
TEST(ScenarioLoad, AidedStackFramesAreUplinkedAndChecked) {
  const Scenario s =
      load_scenario(write_file("stack_frames.yaml", kValid + "tuning:\n  imp: {aided_stack_frames: 4}\n"));
  EXPECT_EQ(s.tuning.imp.aided_stack_frames, 4);
  const std::string up = ::testing::TempDir() + "/uplink_stack_frames.json";
  write_uplink(make_uplink(s, "SV4"), up);
  EXPECT_EQ(read_uplink(up).tuning.imp.aided_stack_frames, 4);
  // An uplink written before the key: off.
  std::string text;
  {
    std::ifstream in(up);
    text.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const auto at = text.find("\"aided_stack_frames\"");
  ASSERT_NE(at, std::string::npos);
  const auto end = text.find_first_of(",}", at);
  std::string older = text.substr(0, at) + text.substr(end + (text[end] == ',' ? 1 : 0));
  const std::string old_path = ::testing::TempDir() + "/uplink_stack_frames_old.json";
  std::ofstream(old_path) << older;
  EXPECT_EQ(read_uplink(old_path).tuning.imp.aided_stack_frames, 0);
  expect_one("stack_frames_bad.yaml", kValid + "tuning:\n  imp: {aided_stack_frames: 6}\n", 13,
             "tuning.imp.aided_stack_frames", "expected an integer 0 <= aided_stack_frames <= 5");
}

TEST(ScenarioValidation, UnknownOrSelfTargetsAreNamed) {
  const std::string path =
      write_file("targets.yaml", kValid + "    mode: 2\n    targets: [SV9, SV4]\n  - spacecraft: SV2\n    mode: 3\n");
  const auto diags = validate_scenario_file(path);
  ASSERT_EQ(diags.size(), 2u) << dump(diags);
  EXPECT_THAT(dump(diags), HasSubstr("SV9"));
  EXPECT_THAT(dump(diags), HasSubstr("not its own target"));
}

// --- Validation: one test per case ---------------------------------------------

TEST(ScenarioValidation, SyntaxErrorGivesYamlLineAndColumn) {
  const std::string text = R"(name: broken
epoch: 2024-05-08T00:00:00Z
spacecraft: [
  {id: SV4
observers: []
)";
  const std::string path = write_file("syntax.yaml", text);
  const auto diags = validate_scenario_file(path);
  ASSERT_EQ(diags.size(), 1u) << dump(diags);
  EXPECT_EQ(diags[0].file, path);
  EXPECT_GE(diags[0].line, 4);
  EXPECT_THAT(diags[0].message, HasSubstr("YAML syntax error"));
  EXPECT_THAT(diags[0].format(),
              HasSubstr("syntax.yaml:" + std::to_string(diags[0].line) + ":" +
                        std::to_string(diags[0].column) + ": YAML syntax error"));
}

TEST(ScenarioValidation, WrongTypeNamesFieldAndExpectation) {
  std::string text = kValid;
  text.replace(text.find("a_km: 6943"), 10, "a_km: big");
  expect_one("wrong_type.yaml", text, 6, "spacecraft[0].qns.a_km", "expected a number, got 'big'");
}

TEST(ScenarioValidation, QuotedNumberIsWrongType) {
  std::string text = kValid;
  text.replace(text.find("ex: 0.0001"), 10, "ex: \"0.0001\"");
  expect_one("quoted.yaml", text, 6, "spacecraft[0].qns.ex", "expected a number, got the string");
}

TEST(ScenarioValidation, MissingRequiredField) {
  std::string text = kValid;
  text.erase(text.find("epoch:"), std::string("epoch: 2024-05-08T00:00:00Z\n").size());
  expect_one("missing.yaml", text, 1, "epoch", "missing required field 'epoch'");
}

TEST(ScenarioValidation, MissingSpacecraftIdInList) {
  std::string text = kValid;
  text.replace(text.find("  - id: SV2\n    relative"), 11, "  - mass_kg: 10");
  // SV2 now has no id (line 7): reported at its mapping.
  expect_one("missing_id.yaml", text, 7, "spacecraft[1].id", "missing required field 'id'");
}

TEST(ScenarioValidation, EccentricityOutOfRange) {
  std::string text = kValid;
  text.replace(
      text.find("qns: {a_km: 6943"),
      std::string(
          "qns: {a_km: 6943, ex: 0.0001, ey: 0.0016, i_deg: 99.4, raan_deg: -38.0, u_deg: -153.0}")
          .size(),
      "kepler: {a_km: 7000, e: 1.2, i_deg: 98, raan_deg: 0, argp_deg: 0, M_deg: 0}");
  expect_one("ecc.yaml", text, 6, "spacecraft[0].kepler.e",
             "out of range: expected 0 <= e < 1, got 1.2");
}

TEST(ScenarioValidation, NegativeEccentricityOutOfRange) {
  std::string text = kValid;
  text.replace(
      text.find("qns: {a_km: 6943"),
      std::string(
          "qns: {a_km: 6943, ex: 0.0001, ey: 0.0016, i_deg: 99.4, raan_deg: -38.0, u_deg: -153.0}")
          .size(),
      "kepler: {a_km: 7000, e: -0.1, i_deg: 98, raan_deg: 0, argp_deg: 0, M_deg: 0}");
  expect_one("ecc_neg.yaml", text, 6, "spacecraft[0].kepler.e", "out of range");
}

TEST(ScenarioValidation, SemiMajorAxisBelowEarthPlus100Km) {
  std::string text = kValid;
  text.replace(text.find("a_km: 6943"), 10, "a_km: 6400");
  expect_one("low.yaml", text, 6, "spacecraft[0].qns.a_km", "Earth radius + 100 km");
}

TEST(ScenarioValidation, NegativeCadence) {
  std::string text = kValid;
  text.replace(text.find("cadence: 60s"), 12, "cadence: -60");
  expect_one("cadence.yaml", text, 11, "observers[0].camera.cadence",
             "out of range: expected cadence > 0 s, got -60 s");
}

TEST(ScenarioValidation, ZeroCadence) {
  std::string text = kValid;
  text.replace(text.find("cadence: 60s"), 12, "cadence: 0s");
  expect_one("cadence0.yaml", text, 11, "observers[0].camera.cadence", "expected cadence > 0 s");
}

TEST(ScenarioValidation, NanAndInfinityRejected) {
  std::string text = kValid;
  text.replace(text.find("ey: 0.0016"), 10, "ey: .nan");
  text.replace(text.find("roe_m: [23"), 10, "roe_m: [.inf");
  expect_one("nan.yaml", text, 6, "spacecraft[0].qns.ey", "expected a finite number");
  expect_one("nan.yaml", text, 8, "spacecraft[1].relative.roe_m[0]", "expected a finite number");
}

TEST(ScenarioValidation, ProbabilityOutsideUnitInterval) {
  const std::string text = kValid + R"(crosslink:
  loss_probability: 1.5
)";
  expect_one("prob.yaml", text, 13, "crosslink.loss_probability",
             "out of range: expected 0 <= loss_probability <= 1, got 1.5");
}

TEST(ScenarioValidation, ModeOutsideZeroToFour) {
  const std::string text = kValid + "    mode: 5\n";
  expect_one("mode.yaml", text, 12, "observers[0].mode", "expected an integer 0 <= mode <= 4");
}

TEST(ScenarioValidation, UnknownSpacecraftReference) {
  std::string text = kValid;
  text.replace(text.find("spacecraft: SV4\n    camera"), 15, "spacecraft: SV9");
  text.replace(text.find("chief: SV4"), 10, "chief: SV7");
  text += R"(maneuvers:
  - {spacecraft: SV5, epoch: 1h, dv_rtn_mps: [0, 0, 0]}
crosslink:
  outages:
    - {from: SV4, to: SV6, start: 1h, end: 2h}
)";
  expect_one("ref_obs.yaml", text, 10, "observers[0].spacecraft",
             "unknown spacecraft 'SV9' as observer (spacecraft defined: SV4, SV2)");
  expect_one("ref_chief.yaml", text, 8, "spacecraft[1].relative.chief", "unknown spacecraft 'SV7'");
  expect_one("ref_mnv.yaml", text, 13, "maneuvers[0].spacecraft", "unknown spacecraft 'SV5'");
  expect_one("ref_link.yaml", text, 16, "crosslink.outages[0].to", "unknown spacecraft 'SV6'");
}

TEST(ScenarioValidation, DuplicateSpacecraftId) {
  std::string text = kValid;
  text.replace(text.find("id: SV2"), 7, "id: SV4");
  expect_one("dup.yaml", text, 7, "spacecraft[1].id",
             "duplicate spacecraft id 'SV4' (first defined at line 5)");
}

TEST(ScenarioValidation, DuplicateObserver) {
  const std::string text = kValid + "  - spacecraft: SV4\n";
  expect_one("dup_obs.yaml", text, 12, "observers[1].spacecraft",
             "duplicate observer 'SV4' (already an observer at line 10)");
}

TEST(ScenarioValidation, UnknownKeyAtEveryLevel) {
  std::string text = kValid;
  text.replace(text.find("cadence: 60s"), 12, "cadense: 60s");
  text += "colour: blue\n";
  expect_one("unknown_key.yaml", text, 11, "observers[0].camera.cadense",
             "unknown key 'cadense' (did you mean 'cadence'?)");
  expect_one("unknown_key.yaml", text, 12, "colour", "unknown key 'colour'");
}

TEST(ScenarioValidation, RelativeChainWithCycle) {
  std::string text = kValid;
  text.replace(text.find("chief: SV4"), 10, "chief: SV3");
  text.replace(text.find("observers:"), 0,
               "  - id: SV3\n    relative: {chief: SV2, roe_m: [0, 1000, 0, 0, 0, 0]}\n");
  expect_one("cycle.yaml", text, 8, "spacecraft[1].relative.chief",
             "relative orbit chain has a cycle: SV2 -> SV3 -> SV2");
}

TEST(ScenarioValidation, OutageEndNotAfterStart) {
  const std::string text = kValid + R"(    gnss:
      outages:
        - {start: 2h, end: 1h}
)";
  expect_one("outage.yaml", text, 14, "observers[0].gnss.outages[0].end",
             "expected the window's end after its start");
}

TEST(ScenarioValidation, ManeuverOutsideScenarioSpan) {
  const std::string text = kValid + R"(maneuvers:
  - spacecraft: SV2
    epoch: 2024-05-08T07:00:00Z
    dv_rtn_mps: [0, 0.05, 0]
)";
  expect_one("maneuver.yaml", text, 14, "maneuvers[0].epoch", "outside the scenario span");
}

TEST(ScenarioValidation, NavigationModeConsistency) {
  // Line 12: mode 4 (multi-observer) alone; line 13: with GNSS on.
  const std::string text = kValid + R"(    mode: 4
    gnss: {enabled: true}
)";
  expect_one("mode4_gnss.yaml", text, 13, "observers[0].gnss.enabled",
             "mode 4 navigates without GNSS");
  // Line 12: mode 4 needs a second observer.
  const auto diags = validate_scenario_file(write_file("mode4_alone.yaml", text));
  bool alone = false;
  for (const auto& d : diags) {
    alone = alone || (d.field == "observers[0].mode" && d.line == 12 &&
                      d.message.find("expected at least two observers, got 1") != std::string::npos);
  }
  EXPECT_TRUE(alone) << dump(diags);
}

TEST(ScenarioValidation, ExactlyOneOrbitPerSpacecraft) {
  std::string text = kValid;
  text.replace(text.find("    relative:"), 0,
               "    kepler: {a_km: 7000, e: 0, i_deg: 98, raan_deg: 0, argp_deg: 0, M_deg: 0}\n");
  expect_one("two_orbits.yaml", text, 9, "spacecraft[1].relative",
             "expected exactly one of kepler, qns or relative");
}

TEST(ScenarioValidation, MissingFileIsReported) {
  const auto diags = validate_scenario_file("/nonexistent/dir/none.yaml");
  ASSERT_EQ(diags.size(), 1u);
  EXPECT_THAT(diags[0].format(), HasSubstr("none.yaml: cannot open scenario file"));
}

TEST(ScenarioValidation, ReportsAllErrorsAtOnce) {
  std::string text = kValid;
  text.replace(text.find("duration: 6h"), 12, "duration: long");         // line 3: type
  text.replace(text.find("ex: 0.0001"), 10, "ex: 0.0001, colour: red");  // line 6: key
  text.replace(text.find("cadence: 60s"), 12, "cadence: -5s");           // line 11: range
  const std::string path = write_file("three.yaml", text);
  const auto diags = validate_scenario_file(path);
  ASSERT_EQ(diags.size(), 3u) << dump(diags);
  EXPECT_EQ(diags[0].field, "duration");
  EXPECT_EQ(diags[0].line, 3);
  EXPECT_THAT(diags[0].message, HasSubstr("expected a duration"));
  EXPECT_EQ(diags[1].field, "spacecraft[0].qns.colour");
  EXPECT_EQ(diags[1].line, 6);
  EXPECT_THAT(diags[1].message, HasSubstr("unknown key"));
  EXPECT_EQ(diags[2].field, "observers[0].camera.cadence");
  EXPECT_EQ(diags[2].line, 11);
  EXPECT_THAT(diags[2].message, HasSubstr("out of range"));

  try {
    (void)load_scenario(path);
    FAIL() << "expected ScenarioError";
  } catch (const ScenarioError& e) {
    EXPECT_EQ(e.diagnostics().size(), 3u);
    const std::string what = e.what();
    EXPECT_EQ(std::count(what.begin(), what.end(), '\n'), 2);
    for (const auto& d : diags) EXPECT_THAT(what, HasSubstr(d.format()));
  }
}

}  // namespace
}  // namespace artms::config
