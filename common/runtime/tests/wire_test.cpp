// BOD attempt telemetry (bus::BodAttempt) through its DDS form and into the
// run folder: every field survives to_wire/from_wire, the wire's bounds
// (strings, 256 curve samples) apply, and the recorder writes bod/<id>.csv
// and bod/<id>_curves.csv, refusing (counting) what came off the wire
// malformed: non-finite numbers, an unknown verdict code, an unknown observer.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "artms/config/scenario.hpp"
#include "artms/runtime/wire.hpp"
#include "artms/sim/services.hpp"

namespace artms::runtime {
namespace {

namespace fs = std::filesystem;

bus::BodAttempt attempt(std::uint32_t n) {
  bus::BodAttempt b;
  b.observer = "SV2";
  b.attempt = n;
  b.t_est_tt_ns = 768409209184000000LL + n;
  b.track = 3;
  b.target = "SV4";
  b.verdict = bus::BodVerdict::kUsable;
  b.why = "";
  b.action = "SOD initialised from BOD, no estimate before";
  b.measurements = 102;
  b.iterations = 3;
  b.residual_rms_rad = 3.9192 * 4.84813681109536e-6;
  b.correlation_inflation = 1.2105;
  b.model_correction_rms_rad = 1.5e-5;
  b.uncorrected_range_m = 49187.5;
  b.a_observer_m = 6937558.068;
  b.range_m = 51085.675;
  b.sigma_range_m = 573.141;
  b.a_roe_mean_m = {94.582, 51086.354, 364.187, 498.595, -44.852, -1822.264};
  for (std::size_t i = 0; i < 36; ++i) b.covariance_a_roe_m2[i] = 0.5 + static_cast<double>(i);
  for (std::size_t i = 0; i < 6; ++i) b.covariance_a_roe_m2[i * 7] = std::pow(10.0 + static_cast<double>(i), 2);
  b.mahalanobis2 = -1.0;
  for (int k = 0; k < 5; ++k) b.curve.push_back({2000.0 * (k + 1), 1e-5 * (5 - k), 100.0 * (5 - k), k != 0});
  return b;
}

bus::BodAttempt through_wire(const bus::BodAttempt& b) {
  std::vector<artms_msg_BodSample> buffer;
  const artms_msg_BodAttempt m = to_wire(b, buffer);
  return from_wire(m);
}

std::vector<std::string> lines(const fs::path& p) {
  std::ifstream in(p);
  std::vector<std::string> out;
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}

TEST(Wire, BodAttemptRoundTrip) {
  const bus::BodAttempt b = attempt(1);
  const bus::BodAttempt w = through_wire(b);
  EXPECT_EQ(w.observer, b.observer);
  EXPECT_EQ(w.attempt, b.attempt);
  EXPECT_EQ(w.t_est_tt_ns, b.t_est_tt_ns);
  EXPECT_EQ(w.track, b.track);
  EXPECT_EQ(w.target, b.target);
  EXPECT_EQ(w.verdict, b.verdict);
  EXPECT_EQ(w.why, b.why);
  EXPECT_EQ(w.action, b.action);
  EXPECT_EQ(w.measurements, b.measurements);
  EXPECT_EQ(w.iterations, b.iterations);
  EXPECT_EQ(w.residual_rms_rad, b.residual_rms_rad);
  EXPECT_EQ(w.correlation_inflation, b.correlation_inflation);
  EXPECT_EQ(w.model_correction_rms_rad, b.model_correction_rms_rad);
  EXPECT_EQ(w.uncorrected_range_m, b.uncorrected_range_m);
  EXPECT_EQ(w.a_observer_m, b.a_observer_m);
  EXPECT_EQ(w.range_m, b.range_m);
  EXPECT_EQ(w.sigma_range_m, b.sigma_range_m);
  EXPECT_EQ(w.a_roe_mean_m, b.a_roe_mean_m);
  EXPECT_EQ(w.covariance_a_roe_m2, b.covariance_a_roe_m2);
  EXPECT_EQ(w.mahalanobis2, b.mahalanobis2);
  ASSERT_EQ(w.curve.size(), b.curve.size());
  for (std::size_t k = 0; k < b.curve.size(); ++k) {
    EXPECT_EQ(w.curve[k].a_dlambda_m, b.curve[k].a_dlambda_m);
    EXPECT_EQ(w.curve[k].residual_rms_rad, b.curve[k].residual_rms_rad);
    EXPECT_EQ(w.curve[k].chi2, b.curve[k].chi2);
    EXPECT_EQ(w.curve[k].converged, b.curve[k].converged);
  }
}

TEST(Wire, BodAttemptBounds) {
  bus::BodAttempt b = attempt(1);
  b.why = std::string(300, 'w');
  b.action = std::string(300, 'a');
  b.target = std::string(40, 't');
  b.curve.assign(bus::kMaxBodSamples + 10, {1.0, 1e-6, 2.0, true});
  const bus::BodAttempt w = through_wire(b);
  EXPECT_EQ(w.why, std::string(bus::kEventTextChars, 'w'));
  EXPECT_EQ(w.action, std::string(bus::kEventTextChars, 'a'));
  EXPECT_EQ(w.target, std::string(bus::kIdChars, 't'));
  EXPECT_EQ(w.curve.size(), bus::kMaxBodSamples);
}

TEST(Wire, RecorderWritesBodFilesAndRejectsMalformedAttempts) {
  const config::Scenario sc = config::load_scenario(std::string(ARTMS_SCENARIO_DIR) + "/starling_pse_bod.yaml");
  const fs::path dir = fs::path(::testing::TempDir()) / "artms_wire_bod";
  fs::remove_all(dir);
  std::size_t rejected = 0;
  {
    sim::Recorder rec(sc, dir.string());
    // Header-only files exist before any attempt.
    rec.flush(sc.epoch.ns_since_j2000);
    EXPECT_EQ(lines(dir / "bod" / "SV2.csv").size(), 1u);
    EXPECT_EQ(lines(dir / "bod" / "SV2_curves.csv").size(), 1u);

    bus::BodAttempt ok = attempt(1);
    ok.curve[0].residual_rms_rad = std::numeric_limits<double>::quiet_NaN();  // unconverged: allowed, written empty
    ok.curve[0].chi2 = std::numeric_limits<double>::infinity();
    rec.add(through_wire(ok));

    bus::BodAttempt failed = attempt(2);
    failed.verdict = bus::BodVerdict::kMinimumAtEdge;
    failed.why = "the smallest residual is at the nearest sample (2.0 km): the range is outside [2.0, 200.0] km";
    failed.action = "not usable";
    failed.mahalanobis2 = 12.5;
    rec.add(through_wire(failed));

    bus::BodAttempt nan_range = attempt(3);
    nan_range.range_m = std::numeric_limits<double>::quiet_NaN();
    rec.add(through_wire(nan_range));
    bus::BodAttempt inf_cov = attempt(4);
    inf_cov.covariance_a_roe_m2[7] = std::numeric_limits<double>::infinity();
    rec.add(through_wire(inf_cov));
    bus::BodAttempt nan_converged = attempt(5);
    nan_converged.curve[2].chi2 = std::numeric_limits<double>::quiet_NaN();  // converged: refused
    rec.add(through_wire(nan_converged));
    bus::BodAttempt nan_correction = attempt(8);
    nan_correction.model_correction_rms_rad = std::numeric_limits<double>::quiet_NaN();
    rec.add(through_wire(nan_correction));
    bus::BodAttempt unknown_code = attempt(6);
    unknown_code.verdict = static_cast<bus::BodVerdict>(bus::kMaxBodVerdict + 1);
    rec.add(through_wire(unknown_code));
    bus::BodAttempt stranger = attempt(7);
    stranger.observer = "SV9";
    rec.add(through_wire(stranger));

    rec.flush(sim::Recorder::kAll);
    rejected = rec.rejected();
  }
  EXPECT_EQ(rejected, 6u);
  const auto rows = lines(dir / "bod" / "SV2.csv");
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[0].substr(0, 38), "t_utc,t_tt_ns,observer,attempt,track,t");
  EXPECT_EQ(rows[1],
            "2024-05-08T02:59:00.000Z,768409209184000001,SV2,1,3,SV4,0,usable,102,3,3.9192,1.2105,6937558.068,"
            "51085.675,573.141,94.582,51086.354,364.187,498.595,-44.852,-1822.264,10.000,11.000,12.000,13.000,"
            "14.000,15.000,,3.094,49187.500,SOD initialised from BOD; no estimate before,");
  EXPECT_NE(rows[2].find(",4,minimum_at_edge,"), std::string::npos) << rows[2];
  EXPECT_NE(rows[2].find(",12.500,3.094,49187.500,not usable,the smallest residual is at the nearest sample (2.0 km): the range is "
                         "outside [2.0; 200.0] km"),
            std::string::npos)
      << rows[2];
  const auto curves = lines(dir / "bod" / "SV2_curves.csv");
  ASSERT_EQ(curves.size(), 11u);
  EXPECT_EQ(curves[0], "attempt,sample,a_dlambda_m,residual_rms_arcsec,chi2,converged");
  EXPECT_EQ(curves[1], "1,0,2000.000,,,0");
  EXPECT_EQ(curves[2].substr(0, 15), "1,1,4000.000,8.");
  EXPECT_EQ(curves[6].substr(0, 4), "2,0,");
  for (const auto& l : curves) {
    std::size_t commas = 0;
    for (char c : l) commas += c == ',' ? 1 : 0;
    EXPECT_EQ(commas, 5u) << l;
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace artms::runtime
