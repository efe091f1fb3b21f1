// fsw::Observer stepped without DDS: the lock-step contract (frames held to
// the step after their render time, relays consumed the step after they were
// relayed, nothing done at the final tick), the GNSS fallback, the counted
// rejection of corrupt or forged inputs, the ISL broadcast cadence, and the
// start-up event saying what actually runs.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "artms/astro/elements.hpp"
#include "artms/fsw/observer.hpp"
#include "artms/imaging/renderer.hpp"
#include "artms/render/camera_calibration.hpp"
#include "sod_scenario.hpp"

namespace artms::fsw {
namespace {

const astro::TimeTT kT0 = astro::tt_from_utc_string("2024-05-08T00:00:00Z");

ObserverSetup setup(int mode = 0) {
  ObserverSetup s;
  auto& up = s.uplink;
  up.scenario_name = "unit";
  up.epoch = kT0;
  up.duration_s = 600.0;
  up.step_s = 60.0;
  up.isl_period_s = 120.0;
  up.swarm_max_cadence_s = 60.0;
  up.observer.spacecraft = "SV4";
  up.observer.mode = mode;
  up.observer.camera.cadence_s = 60.0;
  up.observer.gnss.enabled = true;
  up.swarm_ids = {"SV2", "SV3", "SV4"};
  up.force_model = dynamics::ForceModelOptions::parse("j2");
  s.forces = std::make_shared<const dynamics::ForceModel>(dynamics::ForceModel::load(up.force_model, ARTMS_DATA_DIR));
  return s;
}

astro::StateVector orbit() { return astro::cartesian_from_qns(sod::testing::observer_at_start()); }

bus::GnssFix fix(astro::TimeTT t, const astro::StateVector& x, const std::string& who = "SV4") {
  bus::GnssFix f;
  f.spacecraft = who;
  f.t_tt_ns = t.ns_since_j2000;
  f.valid = true;
  for (int i = 0; i < 3; ++i) {
    f.r_eci_m[static_cast<std::size_t>(i)] = x.r_m[i];
    f.v_eci_mps[static_cast<std::size_t>(i)] = x.v_mps[i];
  }
  f.sigma_position_m = 2.0;
  f.sigma_velocity_mps = 0.01;
  return f;
}

bus::Tick tick(std::int64_t k, bool final_step = false) {
  return {k, kT0.plus_seconds(60.0 * static_cast<double>(k)).ns_since_j2000, final_step};
}

bus::CameraFrame frame(std::uint32_t seq, int width = 16, int height = 8) {
  bus::CameraFrame f;
  f.observer = "SV4";
  f.frame_seq = seq;
  f.time_tag_tt_ns = kT0.plus_seconds(60.0 * seq).ns_since_j2000;
  f.width = static_cast<std::uint16_t>(width);
  f.height = static_cast<std::uint16_t>(height);
  f.bit_depth = 12;
  f.pixels.assign(16 * 8, 100);
  return f;
}

bus::IslBroadcast relay(const std::string& sender, std::int64_t relayed_at_step, std::uint32_t seq = 0) {
  bus::IslBroadcast b;
  b.sender = sender;
  b.receiver = "SV4";
  b.t_tt_ns = tick(relayed_at_step).t_tt_ns;
  b.t_relayed_tt_ns = b.t_tt_ns;
  b.broadcast_seq = seq;
  b.source = static_cast<std::uint8_t>(bus::SolutionSource::kGnss);
  const astro::StateVector x = orbit();
  for (int i = 0; i < 3; ++i) {
    b.r_eci_m[static_cast<std::size_t>(i)] = x.r_m[i] + 1000.0;
    b.v_eci_mps[static_cast<std::size_t>(i)] = x.v_mps[i];
  }
  for (std::size_t i = 0; i < 6; ++i) b.covariance_rv[i * 6 + i] = 4.0;
  bus::BearingMeasurement m;
  m.t_tt_ns = b.t_tt_ns;
  m.track = sender + "-0";
  m.u_eci = {0.0, 0.0, 1.0};
  m.sigma_rad = 1e-5;
  b.measurements.push_back(m);
  return b;
}

bool has_event(const std::vector<bus::Event>& ev, const std::string& part, bus::Severity s) {
  for (const auto& e : ev) {
    if (e.severity == s && e.text.find(part) != std::string::npos) return true;
  }
  return false;
}

TEST(Observer, StartUpEventSaysWhatRunsAndNothingStale) {
  Observer o(setup(0), "observer-SV4");
  const auto out = o.step(tick(0), {});
  ASSERT_FALSE(out.events.empty());
  EXPECT_EQ(out.events[0].source, "observer-SV4");
  EXPECT_NE(out.events[0].text.find("navigation mode 0: the GNSS-only baseline, IMP off"), std::string::npos)
      << out.events[0].text;
  for (const auto& e : out.events) EXPECT_EQ(e.text.find("not available yet"), std::string::npos) << e.text;
  // Mode 1 without a camera or an a-priori says why it falls back, as a warning.
  Observer m1(setup(1), "observer-SV4");
  const auto out1 = m1.step(tick(0), {});
  EXPECT_TRUE(has_event(out1.events, "navigation mode 1 requested but no camera calibration", bus::Severity::kWarning));
  EXPECT_EQ(m1.navigator(), nullptr);
}

TEST(Observer, GnssFallbackPropagatesTheLatestFixWithAGrowingSigma) {
  Observer o(setup(), "observer-SV4");
  auto out = o.step(tick(0), {});
  ASSERT_TRUE(out.nav);
  EXPECT_EQ(out.nav->health, bus::Health::kNoSolution);
  EXPECT_EQ(out.nav->source, bus::SolutionSource::kNone);
  ObserverInputs in;
  const astro::StateVector x = orbit();
  in.gnss = {fix(kT0, x), fix(kT0, x, "SV2")};  // another spacecraft's fix is not ours
  in.gnss[1].r_eci_m[0] += 5e5;
  out = o.step(tick(1), std::move(in));
  ASSERT_TRUE(out.nav);
  EXPECT_EQ(out.nav->source, bus::SolutionSource::kGnss);
  EXPECT_EQ(out.nav->health, bus::Health::kHealthy);
  const Eigen::Vector3d r(out.nav->r_eci_m[0], out.nav->r_eci_m[1], out.nav->r_eci_m[2]);
  EXPECT_NEAR((r - x.r_m).norm(), x.v_mps.norm() * 60.0, 0.01 * x.v_mps.norm() * 60.0);  // one minute on
  const double s1 = std::sqrt(out.nav->covariance_rv[0]);
  EXPECT_GT(s1, 2.0);
  out = o.step(tick(2), {});
  EXPECT_GT(std::sqrt(out.nav->covariance_rv[0]), s1);
}

TEST(Observer, CorruptGnssFixesAreCountedAndNamed) {
  Observer o(setup(), "observer-SV4");
  ObserverInputs in;
  auto bad = fix(kT0, orbit());
  bad.r_eci_m[1] = std::numeric_limits<double>::quiet_NaN();
  auto low = fix(kT0, orbit());
  low.r_eci_m = {1000.0, 0.0, 0.0};
  in.gnss = {bad, low};
  const auto out = o.step(tick(0), std::move(in));
  EXPECT_EQ(o.counters().gnss_rejected, 2U);
  EXPECT_TRUE(has_event(out.events, "rejected a GNSS fix with invalid content (2 so far)", bus::Severity::kWarning));
  EXPECT_EQ(out.nav->source, bus::SolutionSource::kNone);
}

TEST(Observer, FramesAreHeldToTheStepAfterTheirRenderTimeAndCorruptOnesReported) {
  Observer o(setup(), "observer-SV4");
  ObserverInputs in;
  in.frames = {frame(1), frame(2, 15, 8)};  // frame 2: header says 15 columns, buffer holds 16 x 8
  // Both arrive at step 1: frame 1 (rendered at step 1) waits until step 2.
  auto out = o.step(tick(1), std::move(in));
  EXPECT_TRUE(out.imp.empty());
  EXPECT_EQ(o.counters().frames_received, 0U);
  out = o.step(tick(2), {});
  EXPECT_EQ(o.counters().frames_received, 1U);
  EXPECT_TRUE(out.imp.empty());  // IMP off: nothing to report for a good frame
  out = o.step(tick(3), {});
  ASSERT_EQ(out.imp.size(), 1U);
  EXPECT_EQ(out.imp[0].status, bus::FrameStatus::kCorrupt);
  EXPECT_EQ(out.imp[0].frame_seq, 2U);
  EXPECT_TRUE(has_event(out.events, "rejected a corrupt camera frame (1 so far)", bus::Severity::kWarning));
  EXPECT_EQ(out.nav->frames_received, 1U);
}

TEST(Observer, ForgedRelaysAreRejectedWithTheirReasonAndCounted) {
  Observer o(setup(), "observer-SV4");
  ObserverInputs in;
  auto stranger = relay("SV9", 0);
  auto elsewhere = relay("SV2", 0);
  elsewhere.receiver = "SV3";
  auto source = relay("SV2", 0);
  source.source = 7;
  auto nan_cov = relay("SV3", 0);
  nan_cov.covariance_rv[7] = std::numeric_limits<double>::quiet_NaN();
  auto bad_bearing = relay("SV3", 0, 1);
  bad_bearing.measurements[0].u_eci = {0.0, 0.0, 2.0};
  auto self = relay("SV4", 0);
  in.relays = {stranger, elsewhere, source, nan_cov, bad_bearing, self, relay("SV2", 0, 3)};
  const auto out = o.step(tick(1), std::move(in));
  EXPECT_EQ(o.counters().isl_rejected, 6U);
  EXPECT_EQ(o.counters().isl_received, 1U);
  for (const char* why : {"unknown sender 'SV9'", "addressed to another receiver", "unknown orbit source 7",
                          "non-finite orbit or covariance", "invalid bearing 0", "unknown sender 'SV4'"}) {
    EXPECT_TRUE(has_event(out.events, why, bus::Severity::kWarning)) << why;
  }
  EXPECT_EQ(out.nav->isl_rejected, 6U);
  EXPECT_EQ(out.nav->isl_received, 1U);
}

TEST(Observer, ARelayIsConsumedOnlyAtTheStepAfterItWasRelayed) {
  Observer o(setup(), "observer-SV4");
  ObserverInputs in;
  in.relays = {relay("SV2", 1)};  // relayed during step 1, arrived before step 1 was over
  o.step(tick(1), std::move(in));
  EXPECT_EQ(o.counters().isl_received, 0U);
  o.step(tick(2), {});
  EXPECT_EQ(o.counters().isl_received, 1U);
}

TEST(Observer, BroadcastsEveryIslPeriodButNotAtTheLastStepNorTheFinalTick) {
  Observer o(setup(), "observer-SV4");  // 600 s, steps of 60 s, ISL period 120 s
  std::vector<std::int64_t> sent;
  for (std::int64_t k = 0; k <= 11; ++k) {
    const auto out = o.step(tick(k, k == 11), {});
    if (out.isl) {
      EXPECT_EQ(out.isl->broadcast_seq, sent.size());
      EXPECT_EQ(out.isl->source, static_cast<std::uint8_t>(bus::SolutionSource::kNone));
      sent.push_back(k);
    }
    if (k == 11) {
      EXPECT_FALSE(out.nav);
      EXPECT_TRUE(out.imp.empty());
      EXPECT_TRUE(out.events.empty());
    }
  }
  EXPECT_EQ(sent, (std::vector<std::int64_t>{0, 2, 4, 6, 8}));  // step 10 is the last navigation step
}

// The lock-step contract: whether an input arrives during the step it was
// written in or at the next one never changes the outputs.
TEST(Observer, OutputsDoNotDependOnWhenWithinAStepAnInputArrived) {
  const auto run = [](bool early) {
    Observer o(setup(), "observer-SV4");
    std::vector<std::string> log;
    const astro::StateVector x = orbit();
    for (std::int64_t k = 0; k <= 6; ++k) {
      ObserverInputs in;
      in.gnss = {fix(astro::TimeTT{tick(k).t_tt_ns}, x)};
      // Written at step k - 1 (late arrival) or at step k (early arrival).
      const std::int64_t from = early ? k : k - 1;
      if (from >= 0) {
        in.frames = {frame(static_cast<std::uint32_t>(from), from == 3 ? 15 : 16)};
        in.relays = {relay("SV2", from, static_cast<std::uint32_t>(from))};
      }
      const auto out = o.step(tick(k), std::move(in));
      for (const auto& e : out.events) log.push_back(e.text);
      for (const auto& r : out.imp) log.push_back("imp " + std::to_string(r.frame_seq));
      log.push_back("nav " + std::to_string(out.nav->frames_received) + " " + std::to_string(out.nav->isl_received) +
                    " " + std::to_string(out.nav->r_eci_m[0]));
    }
    return log;
  };
  const auto late = run(false), early = run(true);
  // Line for line the same (the early run's frame and relay of step 6 wait
  // for step 7).
  ASSERT_EQ(late.size(), early.size());
  for (std::size_t i = 0; i < late.size(); ++i) EXPECT_EQ(late[i], early[i]) << "line " << i;
}

}  // namespace
}  // namespace artms::fsw

namespace artms::fsw {
namespace {

// IMP in the observer works in DN: a frame stored MSB-aligned (DN x 16, the
// camera calibration's dn_shift_bits = 4) gives the same attitude and
// candidates as the same frame in DN with shift 0; the shifted frame read
// as DN (a calibration that forgot the shift) does not.
TEST(Observer, ImpUndoesTheUplinkedPixelEncoding) {
  imaging::CameraModel cam = imaging::CameraModel::load(std::string(ARTMS_CONFIG_DIR) + "/cameras/nst_ideal.yaml");
  const std::string catalog = std::string(ARTMS_DATA_DIR) + "/stars/bsc5.dat";
  imaging::RenderOptions ro;
  const imaging::StarCatalog bsc = imaging::StarCatalog::load_bsc5(catalog, 6.5);
  const imaging::FrameRenderer renderer(cam, bsc, ro);
  imaging::RenderRequest req;
  req.observer = "SV4";
  req.frame_index = 1;
  req.t = kT0.plus_seconds(60.0);
  req.observer_eci = orbit();
  // Boresight along -velocity, camera y towards the Earth.
  const Eigen::Vector3d z = -req.observer_eci.v_mps.normalized();
  const Eigen::Vector3d y = (-req.observer_eci.r_m - (-req.observer_eci.r_m).dot(z) * z).normalized();
  Eigen::Matrix3d R;
  R.row(0) = y.cross(z).transpose();
  R.row(1) = y.transpose();
  R.row(2) = z.transpose();
  req.q_cam_from_eci = Eigen::Quaterniond(R);
  const imaging::RenderedFrame rf = renderer.render(req);
  ASSERT_FALSE(rf.pixels.empty());

  const auto run = [&](int shift_in_frame, int shift_uplinked) {
    ObserverSetup s = setup();
    s.uplink.camera_calibration = render::calibration_from(cam);
    s.uplink.camera_calibration.dn_shift_bits = shift_uplinked;
    s.uplink.star_catalog_file = "stars.csv";  // the uplinked file's name; its stars as read:
    for (const auto& st : bsc.stars()) s.star_catalog.push_back({st.catalog_id, st.unit_eci_at(kT0)});
    Observer o(s, "observer-SV4");
    bus::CameraFrame f = frame(1);
    f.width = static_cast<std::uint16_t>(cam.width_px);
    f.height = static_cast<std::uint16_t>(cam.height_px);
    f.pixels.clear();
    for (const auto v : rf.pixels) f.pixels.push_back(static_cast<std::uint16_t>(v << shift_in_frame));
    ObserverInputs in;
    in.frames = {f};
    std::vector<bus::ImpReport> reports;
    for (std::int64_t k = 1; k <= 3; ++k) {
      auto out = o.step(tick(k), k == 1 ? std::move(in) : ObserverInputs{});
      for (auto& r : out.imp) reports.push_back(std::move(r));
    }
    EXPECT_EQ(reports.size(), 1U);
    return reports.empty() ? bus::ImpReport{} : reports[0];
  };
  const bus::ImpReport dn = run(0, 0), encoded = run(4, 4), misread = run(4, 0);
  ASSERT_EQ(dn.status, bus::FrameStatus::kOk);
  EXPECT_EQ(encoded.status, bus::FrameStatus::kOk);
  EXPECT_EQ(encoded.stars_matched, dn.stars_matched);
  EXPECT_EQ(encoded.candidates, dn.candidates);
  for (std::size_t i = 0; i < 4; ++i) EXPECT_DOUBLE_EQ(encoded.q_cam_from_eci[i], dn.q_cam_from_eci[i]);
  EXPECT_DOUBLE_EQ(encoded.attitude_sigma_arcsec, dn.attitude_sigma_arcsec);
  EXPECT_TRUE(misread.status != bus::FrameStatus::kOk || misread.stars_matched != dn.stars_matched ||
              misread.attitude_sigma_arcsec != dn.attitude_sigma_arcsec)
      << "a frame read without its shift should not pass for the same frame";
}

}  // namespace
}  // namespace artms::fsw
