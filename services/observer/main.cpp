// artms-observer: one ARTMS process per observing spacecraft. It runs IMP on
// the frames it receives (frame processing and SAMUS tracking) and reports
// attitude and measurements as IMP telemetry; until SOD lands it navigates
// with the GNSS-only baseline (navigation mode 0): its own
// absolute orbit from GNSS fixes, propagated between fixes with the onboard
// GVE/RK4 model. It never reads truth: it subscribes to its GNSS fixes only.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>

#include "artms/astro/elements.hpp"
#include "artms/dynamics/gve.hpp"
#include "artms/config/uplink.hpp"
#include "artms/astro/bearing.hpp"
#include "artms/astro/constants.hpp"
#include "artms/imp/frame_processor.hpp"
#include "artms/imp/samus.hpp"
#include "artms/runtime/runtime.hpp"
#include "navigator.hpp"

#include <deque>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <tuple>

namespace {

using namespace artms;

// The uplinked onboard star catalog: catalog_id,ux_eci,uy_eci,uz_eci.
std::vector<imp::CatalogStar> read_star_catalog(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open the onboard star catalog " + path);
  std::string line;
  std::getline(in, line);
  std::vector<imp::CatalogStar> out;
  int lineno = 1;
  while (std::getline(in, line)) {
    ++lineno;
    std::stringstream ss(line);
    std::string f[4];
    for (auto& x : f) std::getline(ss, x, ',');
    try {
      imp::CatalogStar s{std::stoi(f[0]), Eigen::Vector3d(std::stod(f[1]), std::stod(f[2]), std::stod(f[3]))};
      if (!s.u_eci.allFinite() || std::abs(s.u_eci.norm() - 1.0) > 1e-6) throw std::invalid_argument("not a unit vector");
      out.push_back(s);
    } catch (const std::exception& e) {
      throw std::runtime_error(path + ":" + std::to_string(lineno) + ": bad star row (" + e.what() + ")");
    }
  }
  return out;
}

// One IMP measurement as telemetry (artms-imp's columns).
artms_msg_ImpMeasurement imp_measurement(std::uint32_t frame_seq, std::int64_t t_ns, int track,
                                         const imp::Candidate& c) {
  artms_msg_ImpMeasurement m{};
  m.frame_seq = frame_seq;
  m.t_tt_ns = t_ns;
  m.track_id = track;
  m.x_px = c.x_px;
  m.y_px = c.y_px;
  for (int i = 0; i < 3; ++i) m.u_eci[i] = c.u_eci[i];
  const astro::Bearing b = astro::bearing_from_los(c.u_cam);
  m.az_rad = b.az_rad;
  m.el_rad = b.el_rad;
  m.sigma_rad = c.sigma_rad;
  return m;
}

struct Fix {
  astro::TimeTT t;
  astro::StateVector x;
  double sigma_r, sigma_v;
};

int run(const runtime::ServiceOptions& opt) {
  // The observer knows only what the ground uplinked: never the scenario
  // (which holds the true orbits).
  if (opt.uplink_path.empty()) throw std::invalid_argument("artms-observer needs --uplink FILE");
  const config::ObserverUplink up = config::read_uplink(opt.uplink_path);
  const std::string me = up.observer.spacecraft;
  if (opt.name != "observer-" + me) {
    throw std::invalid_argument("service name " + opt.name + " does not match the uplink's observer " + me);
  }
  const config::ObserverConfig* cfg = &up.observer;
  dds::Participant participant(dds::domain_from_environment());
  runtime::TopicSet topics(participant);
  runtime::LockStepClient clock(participant, topics, opt.name, opt.step_timeout_s);
  dds::Reader<artms_msg_GnssFix> gnss_reader(participant, topics.gnss_fix, runtime::data_qos());
  // Only this observer's frames: the renderer writes them in partition frames-<id>.
  dds::Reader<artms_msg_CameraFrame> frame_reader(participant, topics.camera_frame, runtime::frame_qos(me));
  dds::Writer<artms_msg_NavTelemetry> nav_writer(participant, topics.nav_telemetry, runtime::data_qos());
  runtime::EventLog events(participant, topics, opt.name);
  dds::Writer<artms_msg_ImpReport> imp_writer(participant, topics.imp_report, runtime::data_qos());
  // Inter-satellite link: broadcasts go to the crosslink emulator (partition
  // isl-tx); what it relays to this observer arrives in isl-<sender>-<me>.
  dds::Writer<artms_msg_IslBroadcast> isl_writer(participant, topics.isl_broadcast, runtime::isl_tx_qos());
  dds::Reader<artms_msg_IslBroadcast> relay_reader(participant, topics.isl_relay, runtime::isl_relay_reader_qos(me));
  // IMP (paper, "Image Processing"): the uplinked sensor calibration and star
  // catalog, SAMUS tuned by the uplinked telecommands.
  std::optional<imp::StarIdCatalog> catalog;
  std::optional<imp::FrameProcessor> processor;
  std::optional<imp::Samus> samus;
  imp::Intrinsics K;
  if (up.camera_calibration.present() && !up.star_catalog_file.empty()) {
    const auto& c = up.camera_calibration;
    K = {c.width_px, c.height_px, c.fx_px, c.fy_px, c.cx_px, c.cy_px, c.k1, c.k2};
    const std::string cat_path =
        (std::filesystem::path(opt.uplink_path).parent_path() / up.star_catalog_file).string();
    catalog = imp::StarIdCatalog::build(read_star_catalog(cat_path), 2.0 * K.half_diagonal_fov_rad());
    imp::FrameProcessorOptions fo;
    fo.detection.threshold_sigma = up.tuning.imp.detection_sigma;
    fo.detection.psf_sigma_px = c.psf_sigma_px;
    fo.detection.gain_e_per_dn = c.gain_e_per_dn;
    fo.detection.saturation_dn = c.saturation_dn;
    processor.emplace(K, *catalog, fo);
    imp::SamusOptions so;
    so.dbscan_min_points = up.tuning.imp.dbscan_min_points;
    so.dbscan_radius_rad = up.tuning.imp.dbscan_radius_px / c.fx_px;
    so.dbscan_frames = up.tuning.imp.dbscan_frames;
    samus.emplace(so);
  }

  // The onboard model (the observer's own, not the truth propagator).
  const auto forces = dynamics::ForceModel::load(up.force_model, ARTMS_DATA_DIR);
  const dynamics::GveRk4Propagator onboard(forces, dynamics::SpacecraftProperties{});
  // Navigation mode 1: SOD from GNSS, the ground a-priori and IMP's bearings.
  std::optional<observer::Navigator> navigator;
  if ((cfg->mode == 1 || cfg->mode == 3) && samus && !up.apriori.empty()) navigator.emplace(up, forces);
  std::deque<std::int64_t> frame_times_ns;                 // time tags of frames given to SAMUS
  std::map<std::uint32_t, Eigen::Quaterniond> frame_attitude;  // recent frames' q_cam_from_eci
  const int n_scan = imp::SamusOptions{}.n_scan;
  auto drain_messages = [&](std::int64_t t_ns) {
    if (!navigator) return;
    for (const auto& m : navigator->take_messages()) events.info(t_ns, m);
  };
  // Readers of what the observer writes: the recorder only (runtime::topology).
  const std::map<std::string, int> rt = {{"nav_telemetry", 1}, {"event", 1}, {"imp_report", 1}};
  clock.announce_ready(participant,
                       {{"nav_telemetry writer", nav_writer.handle(), true, rt.at("nav_telemetry")},
                        {"event writer", events.writer().handle(), true, rt.at("event")},
                        {"imp_report writer", imp_writer.handle(), true, rt.at("imp_report")},
                        {"gnss_fix reader", gnss_reader.handle(), false, cfg->gnss.enabled ? 1 : 0},
                        {"camera_frame reader", frame_reader.handle(), false, 1},
                        // The emulator reads every broadcast; relay writers
                        // match only while their link is up (the emulator
                        // waits for those), so none is required here.
                        {"isl_broadcast writer", isl_writer.handle(), true, 1}},
                       60.0);

  std::optional<Fix> last_fix;
  std::uint32_t aided_detections = 0, direct_refused_star = 0;
  struct PendingDirect {
    std::uint32_t frame_seq;
    std::int64_t t_ns;
    int target;
    imp::Candidate c;
    Eigen::Quaterniond q_cam_from_eci;
  };
  std::vector<PendingDirect> pending_direct;
  // Matched-filter options for aided detection and for the faint-star check
  // of single detections; the check keeps the default threshold when aided
  // detection is off (aided_detection_snr 0).
  imp::AidedDetectionOptions aided_options;
  if (up.tuning.imp.aided_detection_snr > 0.0) aided_options.threshold_snr = up.tuning.imp.aided_detection_snr;
  aided_options.psf_sigma_px = up.camera_calibration.psf_sigma_px;
  std::map<int, imp::ForcedPhotometry> forced;  // per target index: forced photometry at its prediction
  aided_options.gain_e_per_dn = up.camera_calibration.gain_e_per_dn;
  // ISL: bearings decided since the last broadcast, counters.
  std::vector<artms_msg_BearingMeasurement> isl_bearings;
  std::optional<astro::TimeTT> last_broadcast;
  std::uint32_t isl_sent = 0, isl_received = 0, isl_rejected = 0;
  std::map<std::string, std::uint32_t> isl_received_from;
  std::map<std::string, astro::TimeTT> isl_last_heard;  // sender -> time of its latest broadcast received
  std::deque<artms_msg_BearingMeasurement> isl_recent;  // broadcast within the repeat window
  bool isl_repeat_pending = false;
  // As old as a bearing can be when broadcast and still reach a receiver's
  // filter in time (its remote hold minus the transport: one period, the
  // latency, two steps).
  const double isl_repeat_window_s =
      observer::remote_bearing_max_age_s(up) - (up.isl_period_s + up.isl_latency_s + 2.0 * up.step_s);
  struct IslIn {
    std::int64_t t_relayed_ns = 0;
    std::string sender;
    std::uint32_t seq = 0;
    observer::RemoteBroadcast rb;
    std::string why;  // non-empty: rejected
  };
  std::vector<IslIn> isl_in;  // taken, waiting for a later step
  const auto isl_keep = [&](std::int64_t t_ns, int track, const Eigen::Vector3d& u_eci, double sigma_rad) {
    if (track == -1) return;  // untracked candidate: not a measurement
    artms_msg_BearingMeasurement b{};
    b.t_tt_ns = t_ns;
    const std::string label = track >= 0 ? me + "-" + std::to_string(track) : me + "-target-" + std::to_string(-2 - track);
    dds::copy_string(b.track, sizeof b.track, label);
    for (int i = 0; i < 3; ++i) b.u_eci[i] = u_eci[i];
    b.sigma_rad = sigma_rad;
    isl_bearings.push_back(b);
  };
  // A relayed broadcast: checked, then handed to the navigator.
  const auto isl_check = [&](const artms_msg_IslBroadcast& b, observer::RemoteBroadcast& rb) -> std::string {
    rb.sender = dds::to_string(b.sender, sizeof b.sender);
    if (rb.sender == me || std::find(up.swarm_ids.begin(), up.swarm_ids.end(), rb.sender) == up.swarm_ids.end()) {
      return "unknown sender '" + rb.sender + "'";
    }
    if (dds::to_string(b.receiver, sizeof b.receiver) != me) return "addressed to another receiver";
    if (b.source > 3) return "unknown orbit source " + std::to_string(b.source);
    rb.t = astro::TimeTT{b.t_tt_ns};
    rb.seq = b.broadcast_seq;
    rb.source = b.source;
    rb.reinitialising = b.reinitialising;
    for (int i = 0; i < 3; ++i) {
      rb.x_eci.r_m[i] = b.r_eci_m[i];
      rb.x_eci.v_mps[i] = b.v_eci_mps[i];
    }
    for (int i = 0; i < 36; ++i) rb.P_rv.data()[i] = b.covariance_rv[i];
    if (!rb.x_eci.r_m.allFinite() || !rb.x_eci.v_mps.allFinite() || !rb.P_rv.allFinite()) return "non-finite orbit or covariance";
    if (b.source != 0) {
      if (!(rb.x_eci.r_m.norm() > 6.4e6)) return "orbit below the Earth's surface";
      bool pos_diag = true;
      for (int i = 0; i < 6; ++i) pos_diag = pos_diag && rb.P_rv(i, i) > 0.0;
      if (!pos_diag) return "empty covariance";
    }
    for (std::uint32_t k = 0; k < b.measurements._length; ++k) {
      const auto& m = b.measurements._buffer[k];
      observer::RemoteBearing r;
      r.t = astro::TimeTT{m.t_tt_ns};
      r.track = dds::to_string(m.track, sizeof m.track);
      r.u_eci = Eigen::Vector3d(m.u_eci[0], m.u_eci[1], m.u_eci[2]);
      r.sigma_rad = m.sigma_rad;
      if (!r.u_eci.allFinite() || std::abs(r.u_eci.norm() - 1.0) > 1e-6 || !std::isfinite(r.sigma_rad) ||
          !(r.sigma_rad > 0.0) || r.track.empty()) {
        return "invalid bearing " + std::to_string(k);
      }
      rb.bearings.push_back(std::move(r));
    }
    return "";
  };
  std::uint32_t frames_received = 0;
  std::size_t frames_rejected = 0;
  std::size_t rejected = 0;
  std::size_t measurements_released = 0;
  bool samus_flushed = false;
  struct HeldFrame {
    artms_msg_CameraFrame msg{};
    std::vector<std::uint16_t> pixels;
  };
  std::deque<HeldFrame> held_frames;
  bool announced = false;
  while (auto tick = clock.wait_tick()) {
    const astro::TimeTT t{tick->t_tt_ns};
    if (!announced) {
      announced = true;
      events.info(t.ns_since_j2000,
                  "navigation mode " + std::to_string(cfg->mode) +
                      " requested; SOD not available yet: running IMP and the GNSS-only baseline (mode 0)" +
                      (processor ? std::string() : std::string("; no camera calibration or star catalog uplinked: IMP off")));
    }
    gnss_reader.take_each([&](const artms_msg_GnssFix& f) {
      if (dds::to_string(f.spacecraft, sizeof f.spacecraft) != me || !f.valid) return;
      Fix fix{astro::TimeTT{f.t_tt_ns},
              {astro::Vec3(f.r_eci_m[0], f.r_eci_m[1], f.r_eci_m[2]),
               astro::Vec3(f.v_eci_mps[0], f.v_eci_mps[1], f.v_eci_mps[2])},
              f.sigma_position_m, f.sigma_velocity_mps};
      if (!fix.x.r_m.allFinite() || !fix.x.v_mps.allFinite() || !(fix.x.r_m.norm() > 6.4e6)) {
        ++rejected;  // counted rejection of a corrupt message
        events.warning(t.ns_since_j2000, "rejected a GNSS fix with invalid content (" +
                                             std::to_string(rejected) + " so far)");
        return;
      }
      if (!last_fix || last_fix->t <= fix.t) last_fix = fix;
      if (navigator) navigator->add_gnss({fix.t, fix.x, fix.sigma_r, fix.sigma_v});
    });
    // Relayed ISL broadcasts of the other observers. A relay written by the
    // emulator during this step may or may not be here yet (services are not
    // ordered within a step): only those relayed at earlier steps are
    // consumed, in (relay time, sender, sequence) order, the rest wait.
    relay_reader.take_each([&](const artms_msg_IslBroadcast& b) {
      IslIn in;
      in.t_relayed_ns = b.t_relayed_tt_ns;
      in.seq = b.broadcast_seq;
      in.why = isl_check(b, in.rb);
      in.sender = dds::to_string(b.sender, sizeof b.sender);
      isl_in.push_back(std::move(in));
    });
    std::stable_sort(isl_in.begin(), isl_in.end(), [](const IslIn& x, const IslIn& y) {
      return std::tie(x.t_relayed_ns, x.sender, x.seq) < std::tie(y.t_relayed_ns, y.sender, y.seq);
    });
    std::size_t n_isl = 0;
    for (; n_isl < isl_in.size() && isl_in[n_isl].t_relayed_ns < t.ns_since_j2000; ++n_isl) {
      const IslIn& in = isl_in[n_isl];
      if (!in.why.empty()) {
        ++isl_rejected;
        events.warning(t.ns_since_j2000, "rejected an ISL broadcast from '" + in.sender + "': " + in.why + " (" +
                                             std::to_string(isl_rejected) + " so far)");
        continue;
      }
      ++isl_received;
      ++isl_received_from[in.rb.sender];
      // A sender heard again after a silence of more than three periods: the
      // links were down, so the broadcasts this observer made meanwhile were
      // most likely lost too; its next broadcast repeats the bearings of the
      // last isl_repeat_window_s (receivers drop what they already have).
      const auto heard = isl_last_heard.find(in.rb.sender);
      if (heard != isl_last_heard.end() && astro::seconds_between(heard->second, in.rb.t) > 3.0 * up.isl_period_s &&
          !isl_repeat_pending) {
        isl_repeat_pending = true;
        events.info(t.ns_since_j2000, "ISL: " + in.rb.sender + " heard again after " +
                                          std::to_string(std::llround(astro::seconds_between(heard->second, in.rb.t))) +
                                          " s; the next broadcast repeats the bearings of the last " +
                                          std::to_string(std::llround(isl_repeat_window_s)) + " s");
      }
      isl_last_heard[in.rb.sender] = in.rb.t;
      if (navigator) navigator->add_remote(in.rb);
    }
    isl_in.erase(isl_in.begin(), isl_in.begin() + static_cast<std::ptrdiff_t>(n_isl));
    // Camera frames: checked, then IMP (frame processing, SAMUS tracking with
    // the coarse orbit from the latest GNSS fix); the decided measurements
    // go out as IMP telemetry.
    // Frames are held until the step after the one they were rendered at
    // (t_frame = epoch + frame_seq * cadence), so that whether a frame of this
    // step has already arrived never changes what is processed when.
    frame_reader.take_each([&](const artms_msg_CameraFrame& f) {
      HeldFrame h;
      h.msg = f;
      h.msg.pixels._buffer = nullptr;
      h.msg.pixels._release = false;
      if (f.pixels._buffer != nullptr) h.pixels.assign(f.pixels._buffer, f.pixels._buffer + f.pixels._length);
      held_frames.push_back(std::move(h));
    });
    const auto handle_frame = [&](const artms_msg_CameraFrame& f) {
      const bool ok = f.width > 0 && f.height > 0 && f.bit_depth > 0 && f.bit_depth <= 16 &&
                      f.pixels._length == static_cast<std::uint32_t>(f.width) * f.height;
      artms_msg_ImpReport rep{};
      dds::copy_string(rep.observer, sizeof rep.observer, me);
      rep.frame_seq = f.frame_seq;
      rep.t_tt_ns = f.time_tag_tt_ns;
      if (!ok || (processor && (f.width != K.width || f.height != K.height))) {
        ++frames_rejected;
        events.warning(t.ns_since_j2000, "rejected a corrupt camera frame (" + std::to_string(frames_rejected) +
                                             " so far): size does not match its header or the camera");
        rep.status = 3;
        imp_writer.write(rep);
        return;
      }
      ++frames_received;
      if (!processor) return;
      const double t_s = static_cast<double>(f.time_tag_tt_ns) * 1e-9;
      const imp::FrameSummary fr =
          processor->process(std::span<const std::uint16_t>(f.pixels._buffer, f.pixels._length), t_s);
      rep.status = fr.attitude_usable ? 0 : (fr.status == "no_detections" ? 1 : 2);
      rep.stars_matched = static_cast<std::uint32_t>(fr.stars_matched);
      rep.candidates = static_cast<std::uint32_t>(fr.candidates.size());
      rep.hot_pixels_removed = static_cast<std::uint32_t>(fr.hot_pixels_removed);
      rep.uncatalogued_stars_removed = static_cast<std::uint32_t>(fr.uncatalogued_stars_removed);
      std::vector<artms_msg_ImpMeasurement> out;
      auto add = [&](std::uint32_t frame_seq, std::int64_t t_ns, int track, const imp::Candidate& c) {
        out.push_back(imp_measurement(frame_seq, t_ns, track, c));
        // A candidate SOD assigned as a single detection and that SAMUS later
        // releases in a track is broadcast once only.
        if (track >= 0 && navigator && navigator->direct_assigned(astro::TimeTT{t_ns}, c.u_eci)) return;
        isl_keep(t_ns, track, c.u_eci, c.sigma_rad);
      };
      const auto release_direct = [&](const PendingDirect& p) {
        navigator->add_direct(astro::TimeTT{p.t_ns}, p.target, p.c.u_eci, p.q_cam_from_eci, p.c.sigma_rad);
        add(p.frame_seq, p.t_ns, -2 - p.target, p.c);
      };
      if (fr.attitude_usable) {
        const auto q = astro::wxyz_from_quaternion(fr.q_cam_from_eci);
        for (int i = 0; i < 4; ++i) rep.q_cam_from_eci[i] = q[static_cast<std::size_t>(i)];
        rep.residual_arcsec = fr.residual_rms_rad / astro::kArcsecToRad;
        rep.attitude_sigma_arcsec = fr.attitude_sigma_rad / astro::kArcsecToRad;
        // Single detections SOD assigned in earlier frames: a source at the
        // same inertial direction in this frame is a faint star (refused);
        // otherwise (or off this frame's sensor) the bearing is released.
        if (navigator) {
          const std::span<const std::uint16_t> px(f.pixels._buffer, f.pixels._length);
          for (const auto& p : pending_direct) {
            const auto star = processor->source_at(px, p.c.u_eci, aided_options);
            if (star && *star) {
              ++direct_refused_star;
              continue;
            }
            release_direct(p);
          }
          pending_direct.clear();
        }
        if (last_fix) {
          imp::TrackerInput in;
          in.frame = f.frame_seq;
          in.t_s = t_s;
          const astro::TimeTT tf{f.time_tag_tt_ns};
          in.observer_eci = astro::cartesian_from_qns(onboard.propagate(astro::qns_from_cartesian(last_fix->x), last_fix->t, tf));
          in.boresight_eci = fr.q_cam_from_eci.toRotationMatrix().transpose().col(2);
          in.candidates = fr.candidates;
          // SOD-aided tracking for tracks bound to converged targets.
          const auto aided = navigator ? navigator->predictions(tf, *samus) : std::vector<imp::TargetPrediction>{};
          frame_attitude[f.frame_seq] = fr.q_cam_from_eci;
          while (frame_attitude.size() > 64) frame_attitude.erase(frame_attitude.begin());
          frame_times_ns.push_back(f.time_tag_tt_ns);
          while (frame_times_ns.size() > 64) frame_times_ns.pop_front();
          const imp::SamusFrameSummary ss = samus->process(in, aided);
          // SOD-aided assignment of single detections of untracked targets,
          // among the candidates no SAMUS track took; reported with track id
          // -2 - k (k: the target's index in the uplinked a-priori).
          if (navigator) {
            // SOD-aided detection (imp/aided_detection.hpp): an untracked
            // target with no candidate in its validity region is searched
            // for below the frame's detection threshold.
            std::vector<imp::Candidate> candidates = fr.candidates;
            if (up.tuning.imp.aided_detection_snr > 0.0) {
              const Eigen::Matrix3d R_cam_from_eci = fr.q_cam_from_eci.toRotationMatrix();
              const auto pixel_of = [&](const Eigen::Vector3d& u) { return K.project(R_cam_from_eci * u); };
              const std::span<const std::uint16_t> pixels(f.pixels._buffer, f.pixels._length);
              const double tf_s = static_cast<double>(f.time_tag_tt_ns) * 1e-9;
              for (const auto& reg : navigator->untracked_regions(tf, pixel_of)) {
                // Forced photometry at the prediction, every frame: the
                // target's brightness unselected by the noise, for the
                // 1-sigma of its aided detections.
                imp::ForcedPhotometry& photometry = forced[reg.target];
                const auto expected = photometry.expected_before(tf_s);
                if (const auto nu = processor->forced_snr(pixels, reg.px, aided_options)) photometry.add(tf_s, *nu);
                const Eigen::Matrix2d S_inv =
                    (reg.cov_px2 + std::pow(aided_options.psf_sigma_px, 2) * Eigen::Matrix2d::Identity()).inverse();
                const bool have = std::any_of(fr.candidates.begin(), fr.candidates.end(), [&](const imp::Candidate& c) {
                  const Eigen::Vector2d d = Eigen::Vector2d(c.x_px, c.y_px) - reg.px;
                  return d.dot(S_inv * d) <= aided_options.gate_chi2;
                });
                if (have) continue;
                const auto c = processor->aided_candidate(pixels, reg.px, reg.cov_px2, aided_options, nullptr, expected);
                if (c) {
                  candidates.push_back(*c);
                  ++aided_detections;
                }
              }
            }
            // Held until the next frame has shown that it is not a faint star.
            for (const auto& [ci, k] : navigator->assign_untracked(tf, candidates, ss.taken, in.observer_eci, *samus)) {
              pending_direct.push_back({f.frame_seq, f.time_tag_tt_ns, k, candidates[static_cast<std::size_t>(ci)],
                                        fr.q_cam_from_eci});
            }
          }
          for (const auto& m : ss.released) {
            const std::int64_t t_ns = static_cast<std::int64_t>(std::llround(m.t_s * 1e9));
            add(static_cast<std::uint32_t>(m.frame), t_ns, m.track_id, m.c);
            const auto qa = frame_attitude.find(static_cast<std::uint32_t>(m.frame));
            if (navigator && qa != frame_attitude.end()) {
              navigator->add_bearing(astro::TimeTT{t_ns}, m.track_id, m.c.u_eci, qa->second, m.c.sigma_rad, m.segment);
            }
          }
        } else {
          // No orbit yet: SAMUS cannot run; the candidates are reported untracked.
          for (const auto& c : fr.candidates) add(f.frame_seq, f.time_tag_tt_ns, -1, c);
        }
      }
      rep.measurements._buffer = out.data();
      rep.measurements._length = rep.measurements._maximum = static_cast<std::uint32_t>(out.size());
      rep.measurements._release = false;
      imp_writer.write(rep);
      measurements_released += out.size();
    };
    while (!held_frames.empty() &&
           up.epoch.plus_seconds(static_cast<double>(held_frames.front().msg.frame_seq) * cfg->camera.cadence_s) < t) {
      HeldFrame& h = held_frames.front();
      h.msg.pixels._buffer = h.pixels.data();
      h.msg.pixels._length = h.msg.pixels._maximum = static_cast<std::uint32_t>(h.pixels.size());
      handle_frame(h.msg);
      held_frames.pop_front();
    }
    // Last navigation step (the final tick only closes the run, and what is
    // written then may not reach the recorder): SAMUS releases what it holds.
    const bool last_step = !tick->final_step && t >= up.epoch.plus_seconds(up.duration_s - 0.5 * up.step_s);
    if (last_step && samus && !samus_flushed) {
      samus_flushed = true;
      std::vector<artms_msg_ImpMeasurement> out;
      for (const auto& p : pending_direct) {  // no later frame to check them against
        if (navigator) navigator->add_direct(astro::TimeTT{p.t_ns}, p.target, p.c.u_eci, p.q_cam_from_eci, p.c.sigma_rad);
        out.push_back(imp_measurement(p.frame_seq, p.t_ns, -2 - p.target, p.c));
      }
      pending_direct.clear();
      for (const auto& m : samus->flush()) {
        const auto qa = frame_attitude.find(static_cast<std::uint32_t>(m.frame));
        if (navigator && qa != frame_attitude.end()) {
          navigator->add_bearing(astro::TimeTT{static_cast<std::int64_t>(std::llround(m.t_s * 1e9))}, m.track_id,
                                 m.c.u_eci, qa->second, m.c.sigma_rad, m.segment);
        }
        out.push_back(imp_measurement(static_cast<std::uint32_t>(m.frame),
                                      static_cast<std::int64_t>(std::llround(m.t_s * 1e9)), m.track_id, m.c));
      }
      artms_msg_ImpReport rep{};
      dds::copy_string(rep.observer, sizeof rep.observer, me);
      rep.t_tt_ns = t.ns_since_j2000;
      rep.status = 4;
      rep.measurements._buffer = out.data();
      rep.measurements._length = rep.measurements._maximum = static_cast<std::uint32_t>(out.size());
      rep.measurements._release = false;
      imp_writer.write(rep);
      measurements_released += out.size();
      events.info(t.ns_since_j2000, "IMP: " + std::to_string(frames_received) + " frames, " +
                                        std::to_string(samus->tracks().size()) + " tracks, " +
                                        std::to_string(measurements_released) + " measurements reported, " +
                                        std::to_string(aided_detections) + " SOD-aided detections, " +
                                        std::to_string(direct_refused_star) +
                                        " single detections refused as faint stars (seen again at the same "
                                        "inertial direction)");
    }
    // SOD catches up with everything IMP has decided.
    if (navigator && !tick->final_step) {
      if (last_step) {
        navigator->finish(*samus);
        events.info(t.ns_since_j2000,
                    "SOD: " + std::to_string(navigator->late_measurements()) + " local bearings too late for the filter; " +
                        std::to_string(navigator->remote_broadcasts()) + " broadcasts received, remote bearings " +
                        std::to_string(navigator->remote_assigned()) + " fused, " +
                        std::to_string(navigator->remote_unassigned()) + " not assigned, " +
                        std::to_string(navigator->remote_late()) + " too late, " +
                        std::to_string(navigator->remote_repeated()) + " repeats dropped; " +
                        std::to_string(navigator->blended_measurements()) +
                        " local bearings left out, another target predicted within " +
                        std::to_string(static_cast<int>(observer::NavigatorOptions{}.blend_separation_px)) + " px");
      } else {
        const std::int64_t safe = frame_times_ns.size() > static_cast<std::size_t>(n_scan)
                                      ? frame_times_ns[frame_times_ns.size() - 1 - static_cast<std::size_t>(n_scan)]
                                      : up.epoch.ns_since_j2000;
        navigator->advance(astro::TimeTT{safe}, t, *samus);
      }
      drain_messages(t.ns_since_j2000);
    }
    std::vector<artms_msg_TargetEstimate> estimates;
    if (!tick->final_step) {
      artms_msg_NavTelemetry nav{};
      nav.frames_received = frames_received;
      dds::copy_string(nav.observer, sizeof nav.observer, me);
      nav.t_tt_ns = t.ns_since_j2000;
      nav.mode = 0;
      const observer::NavReport nr = navigator ? navigator->report(t) : observer::NavReport{};
      if (nr.valid) {
        nav.mode = static_cast<std::uint8_t>(cfg->mode);
        nav.health = static_cast<std::uint8_t>(nr.health);
        nav.source = 1;  // SOD
        for (int i = 0; i < 3; ++i) {
          nav.r_eci_m[i] = nr.x_eci.r_m[i];
          nav.v_eci_mps[i] = nr.x_eci.v_mps[i];
        }
        for (int i = 0; i < 36; ++i) nav.covariance_rv[i] = nr.P_rv.data()[i];
        for (const auto& tr : nr.targets) {
          artms_msg_TargetEstimate e{};
          dds::copy_string(e.target, sizeof e.target, tr.id);
          for (int i = 0; i < 6; ++i) e.roe[i] = tr.roe[i];
          for (int i = 0; i < 36; ++i) e.covariance_roe[i] = tr.P_roe.data()[i];
          e.local_measurements = tr.local_measurements;
          e.remote_measurements = tr.remote_measurements;
          estimates.push_back(e);
        }
        nav.targets._buffer = estimates.data();
        nav.targets._length = nav.targets._maximum = static_cast<std::uint32_t>(estimates.size());
        nav.targets._release = false;
      } else if (last_fix) {
        astro::StateVector x = last_fix->x;
        const double dt = astro::seconds_between(last_fix->t, t);
        if (dt != 0.0) {
          const auto oe = onboard.propagate(astro::qns_from_cartesian(x), last_fix->t, t);
          x = astro::cartesian_from_qns(oe);
        }
        // Uncertainty of a propagated fix: velocity error times age, plus an
        // unmodelled acceleration of 1e-6 m/s^2 (documented in the README).
        const double sr = std::hypot(last_fix->sigma_r, last_fix->sigma_v * dt, 0.5e-6 * dt * dt);
        const double sv = std::hypot(last_fix->sigma_v, 1e-6 * dt);
        nav.health = 0;
        nav.source = 2;  // GNSS
        for (int i = 0; i < 3; ++i) {
          nav.r_eci_m[i] = x.r_m[i];
          nav.v_eci_mps[i] = x.v_mps[i];
          nav.covariance_rv[i * 6 + i] = sr * sr;
          nav.covariance_rv[(i + 3) * 6 + i + 3] = sv * sv;
        }
      } else {
        nav.health = 2;  // no solution yet
        nav.source = 0;
      }
      // ISL broadcast every crosslink period (not at the last navigation
      // step: the run ends before anybody could receive it): the orbit just
      // reported and the bearings decided since the previous broadcast.
      if (!last_step && (!last_broadcast || astro::seconds_between(*last_broadcast, t) >= up.isl_period_s - 1e-6)) {
        last_broadcast = t;
        artms_msg_IslBroadcast b{};
        dds::copy_string(b.sender, sizeof b.sender, me);
        b.t_tt_ns = t.ns_since_j2000;
        b.broadcast_seq = isl_sent;
        for (int i = 0; i < 3; ++i) {
          b.r_eci_m[i] = nav.r_eci_m[i];
          b.v_eci_mps[i] = nav.v_eci_mps[i];
        }
        for (int i = 0; i < 36; ++i) b.covariance_rv[i] = nav.covariance_rv[i];
        b.source = nav.source;  // 1 SOD, 2 GNSS fallback, 0 none
        b.reinitialising = nav.health == 1;
        // Bearings broadcast within the repeat window are kept; after a
        // silence of the links they go out again with the new ones.
        while (!isl_recent.empty() &&
               astro::seconds_between(astro::TimeTT{isl_recent.front().t_tt_ns}, t) > isl_repeat_window_s) {
          isl_recent.pop_front();
        }
        std::vector<artms_msg_BearingMeasurement> payload;
        if (isl_repeat_pending) payload.assign(isl_recent.begin(), isl_recent.end());
        payload.insert(payload.end(), isl_bearings.begin(), isl_bearings.end());
        isl_repeat_pending = false;
        b.measurements._buffer = payload.data();
        b.measurements._length = b.measurements._maximum = static_cast<std::uint32_t>(payload.size());
        b.measurements._release = false;
        isl_writer.write(b);
        ++isl_sent;
        isl_recent.insert(isl_recent.end(), isl_bearings.begin(), isl_bearings.end());
        isl_bearings.clear();
      }
      nav.isl_sent = isl_sent;
      nav.isl_received = isl_received;
      nav.isl_rejected = isl_rejected;
      nav_writer.write(nav);
    }
    for (dds::Entity* w : {static_cast<dds::Entity*>(&nav_writer), static_cast<dds::Entity*>(&events.writer()),
                           static_cast<dds::Entity*>(&imp_writer), static_cast<dds::Entity*>(&isl_writer)}) {
      dds::detail::wait_for_acks(w->handle(), opt.step_timeout_s);
    }
    clock.done(tick->step);
    if (tick->final_step) {
      std::string from;
      for (const auto& [s, n] : isl_received_from) from += " " + s + ":" + std::to_string(n);
      std::fprintf(stderr, "[%s] ISL: %u broadcasts sent, %u received (%s ), %u rejected\n", opt.name.c_str(), isl_sent,
                   isl_received, from.c_str(), isl_rejected);
      return 0;
    }
  }
  if (clock.timed_out()) {
    std::fprintf(stderr, "[%s] error: no clock tick within %.0f s (is truth running?)\n",
                 opt.name.c_str(), opt.step_timeout_s);
    return 1;
  }
  return runtime::g_stop_requested ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  return runtime::run_service(argc, argv, "artms-observer",
                              "One ARTMS observer process (IMP -> BOD -> SOD on its own frames, GNSS and ISL).\n"
      "Mode 1 (SOD with GNSS, ground a-priori and its own bearings) or the GNSS-only baseline.",
                              run);
}
