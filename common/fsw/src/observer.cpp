#include "artms/fsw/observer.hpp"

#include "artms/dynamics/ephemeris.hpp"

#include <algorithm>
#include <cmath>
#include <set>
#include <span>
#include <stdexcept>
#include <tuple>

#include "artms/astro/bearing.hpp"
#include "artms/astro/constants.hpp"
#include "artms/astro/elements.hpp"

namespace artms::fsw {

namespace {

std::array<double, 3> to_array(const Eigen::Vector3d& v) { return {v[0], v[1], v[2]}; }

// One IMP measurement as telemetry (artms-imp's columns).
bus::ImpMeasurement imp_measurement(std::uint32_t frame_seq, std::int64_t t_ns, int track, const imp::Candidate& c) {
  bus::ImpMeasurement m;
  m.frame_seq = frame_seq;
  m.t_tt_ns = t_ns;
  m.track_id = track;
  m.x_px = c.x_px;
  m.y_px = c.y_px;
  m.u_eci = to_array(c.u_eci);
  const astro::Bearing b = astro::bearing_from_los(c.u_cam);
  m.az_rad = b.az_rad;
  m.el_rad = b.el_rad;
  m.sigma_rad = c.sigma_rad;
  return m;
}

}  // namespace

imp::Intrinsics intrinsics_from(const config::CameraCalibration& c) {
  return {c.width_px, c.height_px, c.fx_px, c.fy_px, c.cx_px, c.cy_px, c.k1, c.k2, c.p1, c.p2};
}

imp::FrameProcessorOptions frame_processor_options(const config::CameraCalibration& c,
                                                   const config::ImpTuning& imp_tuning) {
  imp::FrameProcessorOptions fo;
  fo.detection.threshold_sigma = imp_tuning.detection_sigma;
  fo.detection.psf_sigma_px = c.psf_sigma_px;
  fo.detection.gain_e_per_dn = c.gain_e_per_dn;
  fo.detection.saturation_dn = c.saturation_dn;
  if (c.match_tolerance_rad > 0.0) fo.star_id.match_tolerance_rad = c.match_tolerance_rad;
  if (c.centroid_gaussian_fit) fo.detection.centroid_method = imp::CentroidMethod::kGaussianFit;
  return fo;
}

imp::SamusOptions samus_options(const config::CameraCalibration& c, const config::ImpTuning& imp_tuning) {
  imp::SamusOptions so;
  so.dbscan_min_points = imp_tuning.dbscan_min_points;
  so.dbscan_radius_rad = imp_tuning.dbscan_radius_px / c.fx_px;
  so.dbscan_frames = imp_tuning.dbscan_frames;
  return so;
}

imp::AidedDetectionOptions aided_detection_options(const config::CameraCalibration& c,
                                                   const config::ImpTuning& imp_tuning) {
  // Matched-filter options for aided detection and for the faint-star check
  // of single detections; the check keeps the default threshold when aided
  // detection is off (aided_detection_snr 0).
  imp::AidedDetectionOptions o;
  if (imp_tuning.aided_detection_snr > 0.0) o.threshold_snr = imp_tuning.aided_detection_snr;
  o.false_alarms_per_search = imp_tuning.aided_false_alarms;
  o.psf_sigma_px = c.psf_sigma_px;
  o.gain_e_per_dn = c.gain_e_per_dn;
  return o;
}

Observer::Observer(ObserverSetup setup, std::string source)
    : setup_(std::move(setup)),
      up_(setup_.uplink),
      me_(up_.observer.spacecraft),
      events_(std::move(source)),
      onboard_(*setup_.forces, setup_.uplink.onboard_properties(setup_.uplink.observer.spacecraft)),
      n_scan_(imp::SamusOptions{}.n_scan),
      // As old as a bearing can be when broadcast and still reach a
      // receiver's filter in time (its remote hold minus the transport: one
      // period, the latency, two steps).
      isl_repeat_window_s_(remote_bearing_max_age_s(up_) -
                           (up_.isl_period_s + up_.isl_latency_s + 2.0 * up_.step_s)) {
  if (!setup_.forces) throw std::invalid_argument("fsw::Observer: no onboard force model");
  if (up_.camera_calibration.present() && !up_.star_catalog_file.empty()) {
    const auto& c = up_.camera_calibration;
    K_ = intrinsics_from(c);
    // Identification with the stars down to kStarIdVmagLimit; the blend
    // check with every star of the file (FrameProcessor::set_blend_stars).
    std::vector<imp::CatalogStar> id_stars;
    std::vector<Eigen::Vector3d> blend_stars;
    for (const auto& s : setup_.star_catalog) {
      if (s.vmag <= kStarIdVmagLimit) id_stars.push_back(s);
      blend_stars.push_back(s.u_eci);
    }
    catalog_ = imp::StarIdCatalog::build(std::move(id_stars), 2.0 * K_.half_diagonal_fov_rad());
    processor_.emplace(K_, *catalog_, frame_processor_options(c, up_.tuning.imp));
    processor_->set_blend_stars(std::move(blend_stars));
    // The faint-star check of single detections looks at the frames before
    // too (45 % of frames dropped: the one before is often missing).
    processor_->keep_recent_frames(kFaintStarFramesBefore);
    samus_.emplace(samus_options(c, up_.tuning.imp));
  }
  aided_options_ = aided_detection_options(up_.camera_calibration, up_.tuning.imp);
  // Navigation modes 1 and 3: SOD from GNSS, the ground a-priori, IMP's
  // bearings (and in mode 3 the remote ones); mode 2: SOD from GNSS, its
  // targets initialised by BOD from IMP's tracks (no a-priori); mode 4: as 3
  // without GNSS, SOD from the uplinked coarse orbit.
  const int mode = up_.observer.mode;
  if (((mode == 1 || mode == 3) && samus_ && !up_.apriori.empty()) || (mode == 2 && samus_) ||
      (mode == 4 && samus_ && !up_.apriori.empty() && up_.coarse_orbit)) {
    navigator_.emplace(up_, *setup_.forces);
  }
}

void Observer::drain_navigator(std::int64_t t_ns) {
  if (!navigator_) return;
  for (const auto& m : navigator_->take_messages()) events_.info(t_ns, m);
}

void Observer::take_gnss(const std::vector<bus::GnssFix>& fixes, astro::TimeTT t) {
  for (const auto& f : fixes) {
    if (f.spacecraft != me_) continue;
    if (!f.valid) {
      // A GNSS outage (scenario gnss.outages): said once when it starts and
      // once when fixes return; SOD keeps navigating on the onboard model and
      // the bearings meanwhile.
      if (!gnss_outage_since_) {
        gnss_outage_since_ = astro::TimeTT{f.t_tt_ns};
        events_.warning(f.t_tt_ns, "GNSS: no valid fix (outage): SOD navigates on the onboard model and the "
                                   "bearings until fixes return");
      }
      continue;
    }
    if (gnss_outage_since_) {
      char buf[160];
      std::snprintf(buf, sizeof buf, "GNSS: valid fixes again after %.0f s without",
                    astro::seconds_between(*gnss_outage_since_, astro::TimeTT{f.t_tt_ns}));
      events_.info(f.t_tt_ns, buf);
      gnss_outage_since_.reset();
    }
    Fix fix{astro::TimeTT{f.t_tt_ns},
            {astro::Vec3(f.r_eci_m[0], f.r_eci_m[1], f.r_eci_m[2]),
             astro::Vec3(f.v_eci_mps[0], f.v_eci_mps[1], f.v_eci_mps[2])},
            f.sigma_position_m,
            f.sigma_velocity_mps};
    if (!fix.x.r_m.allFinite() || !fix.x.v_mps.allFinite() || !(fix.x.r_m.norm() > 6.4e6)) {
      ++n_.gnss_rejected;  // counted rejection of a corrupt message
      events_.warning(t.ns_since_j2000, "rejected a GNSS fix with invalid content (" +
                                            std::to_string(n_.gnss_rejected) + " so far)");
      continue;
    }
    if (!last_fix_ || last_fix_->t <= fix.t) last_fix_ = fix;
    if (navigator_) navigator_->add_gnss({fix.t, fix.x, fix.sigma_r, fix.sigma_v});
  }
}

std::string Observer::check_relay(const bus::IslBroadcast& b, RemoteBroadcast& rb) const {
  rb.sender = b.sender;
  if (rb.sender == me_ || std::find(up_.swarm_ids.begin(), up_.swarm_ids.end(), rb.sender) == up_.swarm_ids.end()) {
    return "unknown sender '" + rb.sender + "'";
  }
  if (b.receiver != me_) return "addressed to another receiver";
  if (b.source > bus::kMaxSolutionSource) return "unknown orbit source " + std::to_string(b.source);
  rb.t = astro::TimeTT{b.t_tt_ns};
  rb.seq = b.broadcast_seq;
  rb.source = b.source;
  rb.reinitialising = b.reinitialising;
  for (int i = 0; i < 3; ++i) {
    rb.x_eci.r_m[i] = b.r_eci_m[static_cast<std::size_t>(i)];
    rb.x_eci.v_mps[i] = b.v_eci_mps[static_cast<std::size_t>(i)];
  }
  for (int i = 0; i < 36; ++i) rb.P_rv.data()[i] = b.covariance_rv[static_cast<std::size_t>(i)];
  if (!rb.x_eci.r_m.allFinite() || !rb.x_eci.v_mps.allFinite() || !rb.P_rv.allFinite()) {
    return "non-finite orbit or covariance";
  }
  if (b.source != static_cast<std::uint8_t>(bus::SolutionSource::kNone)) {
    if (!(rb.x_eci.r_m.norm() > 6.4e6)) return "orbit below the Earth's surface";
    bool pos_diag = true;
    for (int i = 0; i < 6; ++i) pos_diag = pos_diag && rb.P_rv(i, i) > 0.0;
    if (!pos_diag) return "empty covariance";
  }
  for (std::size_t k = 0; k < b.measurements.size(); ++k) {
    const auto& m = b.measurements[k];
    RemoteBearing r;
    r.t = astro::TimeTT{m.t_tt_ns};
    r.track = m.track;
    r.u_eci = Eigen::Vector3d(m.u_eci[0], m.u_eci[1], m.u_eci[2]);
    r.sigma_rad = m.sigma_rad;
    if (!r.u_eci.allFinite() || std::abs(r.u_eci.norm() - 1.0) > 1e-6 || !std::isfinite(r.sigma_rad) ||
        !(r.sigma_rad > 0.0) || r.track.empty()) {
      return "invalid bearing " + std::to_string(k);
    }
    rb.bearings.push_back(std::move(r));
  }
  return "";
}

void Observer::take_relays(std::vector<bus::IslBroadcast> relays, astro::TimeTT t) {
  // Relayed ISL broadcasts of the other observers: only those relayed at
  // earlier steps are consumed, in (relay time, sender, sequence) order; the
  // rest wait (one relayed during this step may not have arrived yet).
  for (auto& b : relays) {
    IslIn in;
    in.t_relayed_ns = b.t_relayed_tt_ns;
    in.seq = b.broadcast_seq;
    in.why = check_relay(b, in.rb);
    in.sender = b.sender;
    isl_in_.push_back(std::move(in));
  }
  std::stable_sort(isl_in_.begin(), isl_in_.end(), [](const IslIn& x, const IslIn& y) {
    return std::tie(x.t_relayed_ns, x.sender, x.seq) < std::tie(y.t_relayed_ns, y.sender, y.seq);
  });
  std::size_t n_isl = 0;
  for (; n_isl < isl_in_.size() && isl_in_[n_isl].t_relayed_ns < t.ns_since_j2000; ++n_isl) {
    const IslIn& in = isl_in_[n_isl];
    if (!in.why.empty()) {
      ++n_.isl_rejected;
      events_.warning(t.ns_since_j2000, "rejected an ISL broadcast from '" + in.sender + "': " + in.why + " (" +
                                            std::to_string(n_.isl_rejected) + " so far)");
      continue;
    }
    ++n_.isl_received;
    ++isl_received_from_[in.rb.sender];
    // A sender heard again after a silence of more than three periods: the
    // links were down, so the broadcasts this observer made meanwhile were
    // most likely lost too; its next broadcast repeats the bearings of the
    // last isl_repeat_window_s (receivers drop what they already have).
    const auto heard = isl_last_heard_.find(in.rb.sender);
    if (heard != isl_last_heard_.end() && astro::seconds_between(heard->second, in.rb.t) > 3.0 * up_.isl_period_s &&
        !isl_repeat_pending_) {
      isl_repeat_pending_ = true;
      events_.info(t.ns_since_j2000, "ISL: " + in.rb.sender + " heard again after " +
                                         std::to_string(std::llround(astro::seconds_between(heard->second, in.rb.t))) +
                                         " s; the next broadcast repeats the bearings of the last " +
                                         std::to_string(std::llround(isl_repeat_window_s_)) + " s");
    }
    isl_last_heard_[in.rb.sender] = in.rb.t;
    if (navigator_) navigator_->add_remote(in.rb);
  }
  isl_in_.erase(isl_in_.begin(), isl_in_.begin() + static_cast<std::ptrdiff_t>(n_isl));
}

void Observer::keep_for_isl(std::int64_t t_ns, int track, const Eigen::Vector3d& u_eci, double sigma_rad) {
  if (track == bus::kUntracked) return;  // untracked candidate: not a measurement
  bus::BearingMeasurement b;
  // The image time as the ground calibrated it (the uplinked time-tag
  // correction): a receiver cannot know the sender's camera clock. SOD's own
  // estimate of the offset is not applied (docs/sod.md, "Time tags and the
  // ISL": it made the receivers' errors a bias common to every bearing).
  b.t_tt_ns = astro::TimeTT{t_ns}.plus_seconds(up_.observer.camera.time_tag_correction_s).ns_since_j2000;
  const std::string label = track >= 0 ? me_ + "-" + std::to_string(track)
                                       : me_ + "-target-" + std::to_string(bus::single_detection_target(track));
  b.track = bus::bounded(label, bus::kIdChars);
  b.u_eci = to_array(u_eci);
  b.sigma_rad = sigma_rad;
  isl_bearings_.push_back(std::move(b));
}

void Observer::report_measurement(std::vector<bus::ImpMeasurement>& out, std::uint32_t frame_seq, std::int64_t t_ns,
                                  int track, const imp::Candidate& c) {
  out.push_back(imp_measurement(frame_seq, t_ns, track, c));
  // A candidate SOD assigned as a single detection and that SAMUS later
  // releases in a track is broadcast once only.
  if (track >= 0 && navigator_ && navigator_->direct_assigned(astro::TimeTT{t_ns}, c.u_eci)) return;
  keep_for_isl(t_ns, track, c.u_eci, c.sigma_rad);
}

void Observer::handle_frame(const bus::CameraFrame& f, astro::TimeTT t, ObserverOutputs& out) {
  const bool ok = f.width > 0 && f.height > 0 && f.bit_depth > 0 && f.bit_depth <= 16 &&
                  f.pixels.size() == static_cast<std::size_t>(f.width) * f.height;
  bus::ImpReport rep;
  rep.observer = me_;
  rep.frame_seq = f.frame_seq;
  rep.t_tt_ns = f.time_tag_tt_ns;
  if (!ok || (processor_ && (f.width != K_.width || f.height != K_.height))) {
    ++n_.frames_rejected;
    events_.warning(t.ns_since_j2000, "rejected a corrupt camera frame (" + std::to_string(n_.frames_rejected) +
                                          " so far): size does not match its header or the camera");
    rep.status = bus::FrameStatus::kCorrupt;
    out.imp.push_back(std::move(rep));
    return;
  }
  ++n_.frames_received;
  if (!processor_) return;
  std::span<const std::uint16_t> pixels(f.pixels.data(), f.pixels.size());
  // Stored values are DN * 2^dn_shift_bits (MSB-aligned sensors): IMP works in DN.
  if (const int shift = up_.camera_calibration.dn_shift_bits; shift > 0) {
    decoded_.resize(f.pixels.size());
    for (std::size_t i = 0; i < f.pixels.size(); ++i) decoded_[i] = static_cast<std::uint16_t>(f.pixels[i] >> shift);
    pixels = decoded_;
  }
  const astro::TimeTT tf{f.time_tag_tt_ns};
  // The observer's own orbit (SAMUS, and IMP's aberration): its latest GNSS
  // fix propagated, or in mode 4 (no GNSS) SOD's estimate.
  std::optional<astro::StateVector> own;
  if (last_fix_) {
    own = astro::cartesian_from_qns(onboard_.propagate(astro::qns_from_cartesian(last_fix_->x), last_fix_->t, tf));
  } else if (navigator_ && up_.observer.mode == 4) {
    if (const NavReport r = navigator_->report(tf); r.valid) own = r.x_eci;
  }
  // The stars as this observer sees them: the Earth's velocity about the
  // Sun (the onboard ephemeris) plus its own; without an orbit yet, the
  // Earth's alone (the orbital part, <= 5", is then left in the attitude).
  std::optional<Eigen::Vector3d> v_bcrs;
  if (up_.tuning.imp.aberration_correction) {
    v_bcrs = dynamics::earth_velocity_bcrs_mps(tf) + (own ? own->v_mps : Eigen::Vector3d::Zero());
  }
  const imp::FrameSummary fr = processor_->process(pixels, tf, v_bcrs);
  rep.status = fr.attitude_usable ? bus::FrameStatus::kOk
                                  : (fr.status == "no_detections" ? bus::FrameStatus::kNoDetections
                                                                  : bus::FrameStatus::kNotIdentified);
  rep.stars_matched = static_cast<std::uint32_t>(fr.stars_matched);
  rep.candidates = static_cast<std::uint32_t>(fr.candidates.size());
  rep.hot_pixels_removed = static_cast<std::uint32_t>(fr.hot_pixels_removed);
  rep.uncatalogued_stars_removed = static_cast<std::uint32_t>(fr.uncatalogued_stars_removed);
  std::vector<bus::ImpMeasurement>& meas = rep.measurements;
  const auto release_direct = [&](PendingDirect p) {
    expected_signal_sigma(target_signal_[p.target], p.c, p.t_ns);
    navigator_->add_direct(astro::TimeTT{p.t_ns}, p.target, p.c.u_eci, p.q_cam_from_eci, p.c.sigma_rad);
    report_measurement(meas, p.frame_seq, p.t_ns, bus::single_detection_track(p.target), p.c);
  };
  if (fr.attitude_usable) {
    rep.q_cam_from_eci = astro::wxyz_from_quaternion(fr.q_cam_from_eci);
    rep.residual_arcsec = fr.residual_rms_rad / astro::kArcsecToRad;
    rep.attitude_sigma_arcsec = fr.attitude_sigma_rad / astro::kArcsecToRad;
    // Single detections SOD assigned in earlier frames: a source at the same
    // inertial direction in this frame is a faint star (refused); none there
    // releases the bearing. One that neither this frame nor the frames before
    // it could check (off their sensors) is released only from a narrow
    // validity region (NavigatorOptions::direct_unverified_max_sigma_rad).
    if (navigator_) {
      for (const auto& p : pending_direct_) {
        const auto star = processor_->source_at(pixels, p.c.u_eci, aided_options_);
        if (star && *star) {
          ++n_.direct_refused_star;
          continue;
        }
        if (!star && !p.checked_before && !unverified_direct_usable(p)) continue;
        // The same sky stacked over this frame and the kept ones, deeper
        // than one frame: a faint star at the direction, or one beside it
        // that pulls the centroid (docs/imp_samus.md "Faint stars beside a
        // faint target").
        const auto& fo = processor_->options();
        const auto sky = processor_->stacked_sky(pixels, p.c.u_eci, {p.c.x_px, p.c.y_px}, aided_options_,
                                                 fo.blend_radius_px, kStackedNeighbourFalseAlarms);
        if (sky && sky->snr_at >= kStackedStarSnr) {
          ++n_.direct_refused_stacked_star;
          continue;
        }
        if (sky && sky->neighbour_snr >= sky->neighbour_threshold && !p.c.blended) {
          PendingDirect q = p;
          q.c.blended = true;
          q.c.sigma_rad = std::hypot(p.c.sigma_rad, fo.blend_sigma_px / K_.fx);
          ++n_.direct_blended_stacked;
          release_direct(q);
          continue;
        }
        release_direct(p);
      }
      pending_direct_.clear();
    }
    if (own) {
      imp::TrackerInput in;
      in.frame = f.frame_seq;
      in.t = tf;
      in.observer_eci = *own;
      in.boresight_eci = fr.q_cam_from_eci.toRotationMatrix().transpose().col(2);
      in.candidates = fr.candidates;
      // SOD-aided tracking for tracks bound to converged targets.
      const auto aided = navigator_ ? navigator_->predictions(tf, *samus_) : std::vector<imp::TargetPrediction>{};
      frame_attitude_[f.frame_seq] = fr.q_cam_from_eci;
      while (frame_attitude_.size() > 64) frame_attitude_.erase(frame_attitude_.begin());
      frame_times_ns_.push_back(f.time_tag_tt_ns);
      while (frame_times_ns_.size() > 64) frame_times_ns_.pop_front();
      const imp::SamusFrameSummary ss = samus_->process(in, aided);
      // SOD-aided assignment of single detections of untracked targets,
      // among the candidates no SAMUS track took; reported with track id
      // -2 - k (k: the target's index in the uplinked a-priori).
      if (navigator_) {
        // SOD-aided detection (imp/aided_detection.hpp): an untracked target
        // with no candidate in its validity region is searched for below the
        // frame's detection threshold.
        std::vector<imp::Candidate> candidates = fr.candidates;
        std::set<int> searched;  // targets whose aided search ran in this frame
        if (up_.tuning.imp.aided_detection_snr > 0.0) {
          const Eigen::Matrix3d R_cam_from_eci = fr.q_cam_from_eci.toRotationMatrix();
          const auto pixel_of = [&](const Eigen::Vector3d& u) { return K_.project(R_cam_from_eci * u); };
          const double tf_s = static_cast<double>(f.time_tag_tt_ns) * 1e-9;
          for (const auto& reg : navigator_->untracked_regions(tf, pixel_of)) {
            // Forced photometry at the prediction, every frame: the target's
            // brightness unselected by the noise, for the 1-sigma of its
            // aided detections; corrected for the prediction's spread.
            imp::ForcedPhotometry& photometry = forced_[reg.target];
            const auto expected = photometry.expected_before(tf_s);
            if (const auto nu = processor_->forced_snr(pixels, reg.px, aided_options_)) {
              photometry.add(tf_s, *nu, imp::forced_photometry_gain(reg.cov_px2, aided_options_.psf_sigma_px));
            }
            const Eigen::Matrix2d S_inv =
                (reg.cov_px2 + std::pow(aided_options_.psf_sigma_px, 2) * Eigen::Matrix2d::Identity()).inverse();
            const bool have = std::any_of(fr.candidates.begin(), fr.candidates.end(), [&](const imp::Candidate& c) {
              const Eigen::Vector2d d = Eigen::Vector2d(c.x_px, c.y_px) - reg.px;
              return d.dot(S_inv * d) <= aided_options_.gate_chi2;
            });
            searched.insert(reg.target);
            if (have) {
              unseen_.erase(reg.target);
              continue;
            }
            std::string why;
            const auto c = processor_->aided_candidate(pixels, reg.px, reg.cov_px2, aided_options_, &why, expected);
            if (c) {
              candidates.push_back(*c);
              ++n_.aided_detections;
              unseen_.erase(reg.target);
              continue;
            }
            // Not in this frame alone: the frames since it was last seen,
            // stacked along its predicted motion.
            const auto stack = static_cast<std::size_t>(up_.tuning.imp.aided_stack_frames);
            if (stack < 2) continue;
            auto& unseen = unseen_[reg.target];
            const std::uint32_t updates = navigator_->target_bearing_updates(reg.target);
            if (why != "none" || unseen_updates_[reg.target] != updates) {
              unseen.clear();
              unseen_updates_[reg.target] = updates;
              if (why != "none") continue;
            }
            unseen.insert(unseen.begin(), {tf_s, reg.px});
            while (unseen.size() > stack || (unseen.size() > 1 && tf_s - unseen.back().t_s > kMaxStackSpanS)) {
              unseen.pop_back();
            }
            if (unseen.size() < stack) continue;
            const auto st =
                processor_->stacked_aided_candidate(pixels, unseen, reg.cov_px2, aided_options_, &why);
            if (st) {
              candidates.push_back(*st);
              ++n_.aided_detections;
              ++n_.aided_stacked;
              unseen.clear();  // each frame in one stacked detection at most
            } else if (why == "frames not kept") {
              unseen.resize(1);
            }
          }
        }
        // A target not searched in this frame starts its stack again.
        std::erase_if(unseen_, [&](const auto& kv) { return !searched.contains(kv.first); });
        // Refused when a frame before shows a source at its inertial
        // direction (a faint star); otherwise held for the next frame's look.
        for (const auto& a : navigator_->assign_untracked(tf, candidates, ss.taken, in.observer_eci, *samus_)) {
          const imp::Candidate& c = candidates[static_cast<std::size_t>(a.candidate)];
          // A source at the same inertial direction in a frame before is a faint star too.
          const auto before = processor_->source_before(c.u_eci, aided_options_);
          if (before && *before) {
            ++n_.direct_refused_star;
            continue;
          }
          pending_direct_.push_back(
              {f.frame_seq, f.time_tag_tt_ns, a.target, c, fr.q_cam_from_eci, a.region_sigma_rad, before.has_value()});
        }
      }
      for (auto m : ss.released) {
        const std::int64_t t_ns = m.t.ns_since_j2000;
        expected_signal_sigma(track_signal_[m.track_id], m.c, t_ns);
        report_measurement(meas, static_cast<std::uint32_t>(m.frame), t_ns, m.track_id, m.c);
        const auto qa = frame_attitude_.find(static_cast<std::uint32_t>(m.frame));
        if (navigator_ && qa != frame_attitude_.end()) {
          navigator_->add_bearing(astro::TimeTT{t_ns}, m.track_id, m.c.u_eci, qa->second, m.c.sigma_rad, m.segment);
        }
      }
    } else {
      // No orbit yet: SAMUS cannot run; the candidates are reported untracked.
      for (const auto& c : fr.candidates) report_measurement(meas, f.frame_seq, f.time_tag_tt_ns, bus::kUntracked, c);
    }
  }
  n_.measurements_released += meas.size();
  out.imp.push_back(std::move(rep));
  // Histories of tracks that ended long ago (SAMUS starts new ones all run long).
  const double t_frame_s = static_cast<double>(f.time_tag_tt_ns) * 1e-9;
  std::erase_if(track_signal_, [&](const auto& kv) { return t_frame_s - kv.second.last_t_s() > 7200.0; });
}

void Observer::expected_signal_sigma(imp::SignalHistory& h, imp::Candidate& c, std::int64_t t_ns) {
  if (!up_.tuning.imp.signal_history || !processor_ || c.aided || c.saturated || !(c.signal_dn > 0.0)) return;
  const double t_s = static_cast<double>(t_ns) * 1e-9;
  const imp::SignalHistory::Estimate e = h.estimate(t_s, c.signal_dn, c.signal_variance_dn2);
  c.sigma_rad = processor_->sigma_rad_for_signal(c, e.signal_dn, e.variance_dn2);
  if (!c.blended) h.add(t_s, c.signal_dn, c.signal_variance_dn2);
}

bool Observer::unverified_direct_usable(const PendingDirect& p) {
  if (navigator_ && p.region_sigma_rad <= navigator_->options().direct_unverified_max_sigma_rad) return true;
  ++n_.direct_refused_unverified;
  return false;
}

void Observer::flush_imp(astro::TimeTT t, ObserverOutputs& out) {
  // Last navigation step: SAMUS releases what it holds.
  samus_flushed_ = true;
  bus::ImpReport rep;
  rep.observer = me_;
  rep.t_tt_ns = t.ns_since_j2000;
  rep.status = bus::FrameStatus::kEnd;
  for (auto p : pending_direct_) {  // no later frame to check them against
    if (!p.checked_before && !unverified_direct_usable(p)) continue;
    expected_signal_sigma(target_signal_[p.target], p.c, p.t_ns);
    if (navigator_) navigator_->add_direct(astro::TimeTT{p.t_ns}, p.target, p.c.u_eci, p.q_cam_from_eci, p.c.sigma_rad);
    rep.measurements.push_back(imp_measurement(p.frame_seq, p.t_ns, bus::single_detection_track(p.target), p.c));
  }
  pending_direct_.clear();
  for (auto m : samus_->flush()) {
    const std::int64_t t_ns = m.t.ns_since_j2000;
    expected_signal_sigma(track_signal_[m.track_id], m.c, t_ns);
    const auto qa = frame_attitude_.find(static_cast<std::uint32_t>(m.frame));
    if (navigator_ && qa != frame_attitude_.end()) {
      navigator_->add_bearing(astro::TimeTT{t_ns}, m.track_id, m.c.u_eci, qa->second, m.c.sigma_rad, m.segment);
    }
    rep.measurements.push_back(imp_measurement(static_cast<std::uint32_t>(m.frame), t_ns, m.track_id, m.c));
  }
  n_.measurements_released += rep.measurements.size();
  out.imp.push_back(std::move(rep));
  events_.info(t.ns_since_j2000, "IMP: " + std::to_string(n_.frames_received) + " frames, " +
                                     std::to_string(samus_->tracks().size()) + " tracks, " +
                                     std::to_string(n_.measurements_released) + " measurements reported, " +
                                     std::to_string(n_.aided_detections) + " SOD-aided detections" +
                                     (up_.tuning.imp.aided_stack_frames >= 2
                                          ? " (" + std::to_string(n_.aided_stacked) + " on stacked frames)"
                                          : std::string()) +
                                     ", " +
                                     std::to_string(n_.direct_refused_star) +
                                     " single detections refused as faint stars (seen again at the same "
                                     "inertial direction), " +
                                     std::to_string(n_.direct_refused_unverified) +
                                     " refused unchecked (no frame could check them; region too wide)");
  // A second line: event texts are bounded (bus::kEventTextChars).
  events_.info(t.ns_since_j2000, "IMP, the sky stacked at single detections' directions: " +
                                     std::to_string(n_.direct_refused_stacked_star) + " refused as faint stars, " +
                                     std::to_string(n_.direct_blended_stacked) +
                                     " weighted as blends (a faint neighbour within the blend radius); " +
                                     std::to_string(navigator_ ? navigator_->eclipsed_searches_skipped() : 0) +
                                     " aided searches skipped (target predicted in the Earth's shadow)");
}

bus::NavTelemetry Observer::navigation(astro::TimeTT t) const {
  bus::NavTelemetry nav;
  nav.frames_received = n_.frames_received;
  nav.observer = me_;
  nav.t_tt_ns = t.ns_since_j2000;
  nav.mode = 0;
  const NavReport nr = navigator_ ? navigator_->report(t) : NavReport{};
  if (nr.valid) {
    nav.mode = static_cast<std::uint8_t>(up_.observer.mode);
    nav.health = static_cast<bus::Health>(nr.health);
    nav.source = up_.observer.mode == 4 ? bus::SolutionSource::kSodAnglesOnly : bus::SolutionSource::kSod;
    nav.r_eci_m = to_array(nr.x_eci.r_m);
    nav.v_eci_mps = to_array(nr.x_eci.v_mps);
    for (int i = 0; i < 36; ++i) nav.covariance_rv[static_cast<std::size_t>(i)] = nr.P_rv.data()[i];
    for (const auto& tr : nr.targets) {
      bus::TargetEstimate e;
      e.target = bus::bounded(tr.id, bus::kIdChars);
      for (int i = 0; i < 6; ++i) e.roe[static_cast<std::size_t>(i)] = tr.roe[i];
      for (int i = 0; i < 36; ++i) e.covariance_roe[static_cast<std::size_t>(i)] = tr.P_roe.data()[i];
      e.local_measurements = tr.local_measurements;
      e.remote_measurements = tr.remote_measurements;
      e.bearing_nis_sum = tr.bearing_nis_sum;
      e.bearing_updates = tr.bearing_updates;
      e.health = static_cast<bus::Health>(tr.health);
      nav.targets.push_back(std::move(e));
    }
  } else if (last_fix_) {
    astro::StateVector x = last_fix_->x;
    const double dt = astro::seconds_between(last_fix_->t, t);
    if (dt != 0.0) x = astro::cartesian_from_qns(onboard_.propagate(astro::qns_from_cartesian(x), last_fix_->t, t));
    // Uncertainty of a propagated fix: velocity error times age, plus an
    // unmodelled acceleration of 1e-6 m/s^2 (services/observer/README.md).
    const double sr = std::hypot(last_fix_->sigma_r, last_fix_->sigma_v * dt, 0.5e-6 * dt * dt);
    const double sv = std::hypot(last_fix_->sigma_v, 1e-6 * dt);
    nav.health = bus::Health::kHealthy;
    nav.source = bus::SolutionSource::kGnss;
    nav.r_eci_m = to_array(x.r_m);
    nav.v_eci_mps = to_array(x.v_mps);
    for (std::size_t i = 0; i < 3; ++i) {
      nav.covariance_rv[i * 6 + i] = sr * sr;
      nav.covariance_rv[(i + 3) * 6 + i + 3] = sv * sv;
    }
  } else {
    nav.health = bus::Health::kNoSolution;
    nav.source = bus::SolutionSource::kNone;
  }
  return nav;
}

void Observer::broadcast(astro::TimeTT t, const bus::NavTelemetry& nav, ObserverOutputs& out) {
  // The orbit just reported and the bearings decided since the previous
  // broadcast.
  last_broadcast_ = t;
  bus::IslBroadcast b;
  b.sender = me_;
  b.t_tt_ns = t.ns_since_j2000;
  b.broadcast_seq = n_.isl_sent;
  b.r_eci_m = nav.r_eci_m;
  b.v_eci_mps = nav.v_eci_mps;
  b.covariance_rv = nav.covariance_rv;
  b.source = static_cast<std::uint8_t>(nav.source);
  b.reinitialising = nav.health == bus::Health::kReinitialising;
  // Bearings broadcast within the repeat window are kept; after a silence
  // of the links they go out again with the new ones.
  while (!isl_recent_.empty() &&
         astro::seconds_between(astro::TimeTT{isl_recent_.front().t_tt_ns}, t) > isl_repeat_window_s_) {
    isl_recent_.pop_front();
  }
  if (isl_repeat_pending_) b.measurements.assign(isl_recent_.begin(), isl_recent_.end());
  b.measurements.insert(b.measurements.end(), isl_bearings_.begin(), isl_bearings_.end());
  isl_repeat_pending_ = false;
  out.isl = std::move(b);
  ++n_.isl_sent;
  isl_recent_.insert(isl_recent_.end(), isl_bearings_.begin(), isl_bearings_.end());
  isl_bearings_.clear();
}

ObserverOutputs Observer::step(const bus::Tick& tick, ObserverInputs in) {
  ObserverOutputs out;
  const astro::TimeTT t{tick.t_tt_ns};
  // The final tick only closes the run: whatever were written now might not
  // be recorded, so nothing is processed.
  if (tick.final_step) return out;
  if (!announced_) {
    announced_ = true;
    const int mode = up_.observer.mode;
    const std::string head = "navigation mode " + std::to_string(mode);
    if (navigator_) {
      if (mode == 2) {
        events_.info(t.ns_since_j2000, head + ": IMP, BOD and SOD (GNSS fixes, no a-priori: BOD initialises every "
                                              "target from its IMP track, every " +
                                              std::to_string(static_cast<int>(up_.tuning.bod.period_s / 60.0)) +
                                              " min); SOD starts at the first GNSS fix");
      } else if (mode == 4) {
        events_.info(t.ns_since_j2000, head + (up_.tuning.bod.enabled ? ": IMP, BOD and SOD" : ": IMP and SOD") +
                                           " from bearings only (local and remote; no GNSS): the absolute orbit "
                                           "starts from the uplinked coarse orbit, the targets from the ground "
                                           "a-priori");
      } else {
        events_.info(t.ns_since_j2000, head + (up_.tuning.bod.enabled ? ": IMP, BOD and SOD" : ": IMP and SOD") +
                                           " (GNSS fixes, the ground a-priori and " +
                                           (mode == 3 ? "local and remote bearings" : "its own bearings") +
                                           "); SOD starts at the first GNSS fix");
      }
    } else if (mode == 0) {
      events_.info(t.ns_since_j2000, head + ": the GNSS-only baseline" + (processor_ ? " with IMP" : ", IMP off"));
    } else {
      const std::string why = !processor_        ? "no camera calibration or star catalog uplinked"
                              : up_.apriori.empty() ? "no ground a-priori uplinked"
                              : mode == 4 && !up_.coarse_orbit ? "no coarse orbit uplinked"
                                                    : "this mode is not implemented";
      events_.warning(t.ns_since_j2000, head + " requested but " + why +
                                            ": running the GNSS-only baseline (mode 0)" +
                                            (processor_ ? " with IMP" : ", IMP off"));
    }
  }
  take_gnss(in.gnss, t);
  take_relays(std::move(in.relays), t);
  // Camera frames are held until the step after the one they were rendered
  // at (t_frame = epoch + frame_seq * cadence), so that whether a frame of
  // this step has already arrived never changes what is processed when.
  for (auto& f : in.frames) held_frames_.push_back(std::move(f));
  while (!held_frames_.empty() &&
         up_.epoch.plus_seconds(static_cast<double>(held_frames_.front().frame_seq) * up_.observer.camera.cadence_s) <
             t) {
    handle_frame(held_frames_.front(), t, out);
    held_frames_.pop_front();
  }
  // Last navigation step: SAMUS releases what it holds.
  const bool last_step = t >= up_.epoch.plus_seconds(up_.duration_s - 0.5 * up_.step_s);
  if (last_step && samus_ && !samus_flushed_) flush_imp(t, out);
  // SOD catches up with everything IMP has decided.
  if (navigator_) {
    if (last_step) {
      navigator_->finish(*samus_);
      events_.info(t.ns_since_j2000,
                   "SOD: " + std::to_string(navigator_->late_measurements()) +
                       " local bearings too late for the filter; " + std::to_string(navigator_->remote_broadcasts()) +
                       " broadcasts received, remote bearings " + std::to_string(navigator_->remote_assigned()) +
                       " fused, " + std::to_string(navigator_->remote_unassigned()) + " not assigned, " +
                       std::to_string(navigator_->remote_late()) + " too late, " +
                       std::to_string(navigator_->remote_repeated()) + " repeats dropped");
      // A second line: event texts are bounded (bus::kEventTextChars).
      events_.info(t.ns_since_j2000,
                   "SOD, local bearings not fused: " + std::to_string(navigator_->blended_measurements()) +
                       " left out (another target predicted within " +
                       std::to_string(static_cast<int>(NavigatorOptions{}.blend_separation_px)) + " px), " +
                       std::to_string(navigator_->refused_measurements()) + " refused by the gate, " +
                       std::to_string(navigator_->association_measurements()) +
                       " of tracks not bound to a target (association only)");
    } else {
      // Decided up to the frame n_scan frames back, and not past the oldest
      // measurement SAMUS may still release (a tentative track's first: a
      // target found again after an eclipse); at most max_lag_s behind.
      std::int64_t safe = frame_times_ns_.size() > static_cast<std::size_t>(n_scan_)
                              ? frame_times_ns_[frame_times_ns_.size() - 1 - static_cast<std::size_t>(n_scan_)]
                              : up_.epoch.ns_since_j2000;
      if (const auto held = samus_ ? samus_->oldest_undecided() : std::nullopt) {
        safe = std::min(safe, held->plus_seconds(navigator_->time_tag_correction_s()).ns_since_j2000 - 1);
      }
      navigator_->advance(astro::TimeTT{safe}, t, *samus_);
    }
    drain_navigator(t.ns_since_j2000);
  }
  bus::NavTelemetry nav = navigation(t);
  // ISL broadcast every crosslink period (not at the last navigation step:
  // the run ends before anybody could receive it).
  if (!last_step && (!last_broadcast_ || astro::seconds_between(*last_broadcast_, t) >= up_.isl_period_s - 1e-6)) {
    broadcast(t, nav, out);
  }
  nav.isl_sent = n_.isl_sent;
  nav.isl_received = n_.isl_received;
  nav.isl_rejected = n_.isl_rejected;
  out.nav = std::move(nav);
  if (navigator_) out.bod = navigator_->take_bod_records();
  out.events = events_.take();
  return out;
}

std::string Observer::isl_summary() const {
  std::string from;
  for (const auto& [s, n] : isl_received_from_) from += " " + s + ":" + std::to_string(n);
  return "ISL: " + std::to_string(n_.isl_sent) + " broadcasts sent, " + std::to_string(n_.isl_received) +
         " received (" + from + " ), " + std::to_string(n_.isl_rejected) + " rejected";
}

}  // namespace artms::fsw
