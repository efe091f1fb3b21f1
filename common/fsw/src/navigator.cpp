#include "artms/fsw/navigator.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "artms/astro/constants.hpp"
#include "artms/astro/elements.hpp"
#include "artms/astro/roe.hpp"
#include "artms/dynamics/ephemeris.hpp"
#include "artms/dynamics/j2_mean.hpp"
#include "artms/dynamics/shadow.hpp"
#include "artms/sod/apriori.hpp"

namespace artms::fsw {

namespace {

using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;

Vec6 rv(const astro::StateVector& x) { return (Vec6() << x.r_m, x.v_mps).finished(); }

// d (r, v) / d qns by central differences.
Mat6 jacobian_rv_from_qns(const astro::QnsElements& oe) {
  Mat6 J;
  const Vec6 x0 = oe.as_vector();
  const double h[6] = {1.0, 1e-7, 1e-7, 1e-7, 1e-7, 1e-7};
  for (int j = 0; j < 6; ++j) {
    Vec6 a = x0, b = x0;
    a[j] += h[j];
    b[j] -= h[j];
    J.col(j) = (rv(astro::cartesian_from_qns(astro::QnsElements::from_vector(a))) -
                rv(astro::cartesian_from_qns(astro::QnsElements::from_vector(b)))) /
               (2.0 * h[j]);
  }
  return J;
}

// The observer's elements and target k's ROE, [alpha_o; droe_k] (12), from
// the filter state.
Eigen::VectorXd observer_target_mean(const sod::SodFilter& f, int k) {
  const int off = f.layout().target_offset(k);
  Eigen::VectorXd mean(12);
  mean << f.state().segment<6>(0), f.state().segment<6>(off);
  return mean;
}

// The same with their joint covariance.
void observer_target_block(const sod::SodFilter& f, int k, Eigen::VectorXd& mean, Eigen::MatrixXd& P) {
  const int off = f.layout().target_offset(k);
  mean = observer_target_mean(f, k);
  const auto& C = f.covariance();
  P.resize(12, 12);
  P << C.block(0, 0, 6, 6), C.block(0, off, 6, 6), C.block(off, 0, 6, 6), C.block(off, off, 6, 6);
}

// Line of sight (ECI, observer to target, not normalised) of [alpha_o; droe].
Eigen::Vector3d los_eci_of(const Eigen::VectorXd& s) {
  const auto o = astro::QnsElements::from_vector(s.head<6>());
  const auto t = astro::qns_from_roe(o, astro::Roe::from_vector(s.tail<6>()));
  return astro::cartesian_from_qns(t).r_m - astro::cartesian_from_qns(o).r_m;
}

}  // namespace

// BOD's expected post-fit misfit beyond IMP's noise, per bearing angle: the
// mean J2 model and the attitude's field-dependent errors. In the flight-like
// world (nst camera, starling_pse_flight.yaml seed 7) the post-fit RMS is
// 3.9-4.5" against IMP's RMS 1-sigma of 3.6": ~2" in quadrature (docs/bod.md).
constexpr double kBodExpectedMisfit_rad = 2.0 * astro::kArcsecToRad;

// 1-sigma per axis of the unknown manoeuvre that inflates a target whose
// bearings stopped fitting (docs/sod.md, health check 5): 2 cm/s per unit of
// the RMS normalised innovation, between 2 cm/s and 1 m/s.
double maneuver_sigma_mps(double mean_nis_or_d2) {
  return std::clamp(0.02 * std::sqrt(std::max(mean_nis_or_d2, 0.0)), 0.02, 1.0);
}

// Execution error of a planned maneuver: its 1-sigma fraction of the
// magnitude along the delta-v and the same fraction (rad) of pointing error
// across it, isotropic (floored at 10 um/s).
astro::Mat3 execution_covariance(const config::ObserverUplink::PlannedManeuver& m) {
  const double s = m.execution_sigma_fraction * m.dv_rtn_mps.norm();
  return astro::Mat3::Identity() * std::max(s * s, 1e-10);
}

double nominal_ballistic_m2pkg(const dynamics::SpacecraftProperties& sc = {}) {
  return sc.cd * sc.drag_area_m2 / sc.mass_kg;
}

sod::SodOptions sod_options(const config::SodTuning& t) {
  sod::SodOptions o;
  o.health.max_steps_without_update = t.max_steps_without_update;
  o.health.max_large_residuals = t.max_large_residuals;
  o.bearing_underweighting = t.underweighting;
  o.bearing_underweighting_nonlinearity = t.underweighting_nonlinearity;
  o.adaptive.enabled = t.adaptive_process_noise;
  o.adaptive.targets = t.adaptive_targets;
  o.adaptive.form = t.adaptive_form == config::SodTuning::AdaptiveForm::kBlock ? sod::AdaptiveNoiseForm::kBlock
                                                                                : sod::AdaptiveNoiseForm::kDiagonal;
  o.adaptive.average = t.adaptive_average == config::SodTuning::AdaptiveAverage::kUnclamped
                           ? sod::AdaptiveNoiseAverage::kUnclamped
                           : sod::AdaptiveNoiseAverage::kClamped;
  o.q_target_a_roe_m2ps *= t.process_noise_scale;
  o.adaptive.drag_density_error = t.drag_density_error;
  o.adaptive.density_change_per_day = t.ballistic_density_change_per_day;
  o.adaptive.time_constant_s = t.adaptive_time_constant_s;
  o.health.nis_window = t.nis_window;
  if (t.nis_window > 0) o.health.nis_max_mean = sod::chi2_quantile(2 * t.nis_window, 1.0 - t.nis_false_alarm) / t.nis_window;
  o.health.gnss_nis_window = t.nis_window > 0 ? 10 : 0;
  // Five times the quantile: the onboard model's own absolute error (10x10
  // gravity against the world's) already doubles the GNSS NIS; a burn's does not stop there.
  o.health.gnss_nis_max_mean = 5.0 * sod::chi2_quantile(6 * 10, 1.0 - t.nis_false_alarm) / 10.0;
  // The mean-shift test of the same fixes, tested at every fix: its false-alarm
  // probability is the scenario's per day of one-minute fixes (Bonferroni).
  o.health.gnss_bias_window = t.nis_window > 0 ? 10 : 0;
  o.health.gnss_bias_max = sod::chi2_quantile(6, 1.0 - t.nis_false_alarm / 1440.0);
  // Auxiliary random walks: the offset wanders by 1 ms and the drift by 1 ppm
  // per day; a target's effective ballistic coefficient (the density's
  // day-to-day error times Cd A/m) by ballistic.walk_fraction_per_day of the
  // nominal per day, plus density_change_per_day of its |dB| (in SodFilter).
  o.q_time_tag_offset_s2ps = 1e-6 / 86400.0;
  o.q_time_tag_drift_ps = 1e-12 / 86400.0;
  o.q_ballistic_m4pkg2ps = std::pow(t.ballistic_walk() * nominal_ballistic_m2pkg(), 2) / 86400.0;
  o.target_to_target_consider_observer = t.target_lines == config::SodTuning::TargetLines::kConsiderObserver;
  o.validate();
  return o;
}

sod::SodOptions sod_options(const config::SodTuning& t, const astro::QnsElements& observer) {
  sod::SodOptions o = sod_options(t);
  if (t.observer_acceleration_sigma_mps2 > 0.0) {
    o.q_observer = o.q_observer.cwiseMax(sod::observer_process_noise_from_acceleration(
        observer.a_m, observer.i_rad, t.observer_acceleration_sigma_mps2, astro::orbit_period_s(observer.a_m)));
  }
  return o;
}

sod::StateLayout sod_layout(const config::SodTuning& t, int n_targets, int n_senders) {
  using TT = config::SodTuning::TimeTagEstimation;
  sod::StateLayout layout{n_targets, 0};
  layout.n_time_tag = t.time_tag == TT::kNone ? 0 : t.time_tag == TT::kOffset ? 1 : 2;
  layout.ballistic = t.estimate_ballistic;
  layout.n_remote_clock = t.time_tag_senders ? n_senders : 0;
  return layout;
}

std::vector<dynamics::SpacecraftProperties> target_nominal_properties(const config::ObserverUplink& up,
                                                                      const std::vector<std::string>& target_ids) {
  std::vector<dynamics::SpacecraftProperties> out;
  out.reserve(target_ids.size());
  for (const auto& id : target_ids) out.push_back(up.onboard_properties(id));
  return out;
}

Eigen::VectorXd auxiliary_prior_variance(const config::SodTuning& t, const sod::StateLayout& layout) {
  Eigen::VectorXd var = Eigen::VectorXd::Zero(layout.size() - layout.aux_offset());
  if (layout.n_time_tag > 0) var[0] = t.time_tag_sigma_s * t.time_tag_sigma_s;
  if (layout.n_time_tag > 1) var[1] = std::pow(t.time_tag_drift_sigma_ppm * 1e-6, 2);
  for (int k = 0; layout.ballistic && k < layout.n_targets; ++k)
    var[layout.ballistic_index(k) - layout.aux_offset()] = std::pow(t.ballistic_sigma_fraction * nominal_ballistic_m2pkg(), 2);
  for (int j = 0; j < layout.n_remote_clock; ++j)
    var[layout.remote_clock_index(j) - layout.aux_offset()] = t.time_tag_senders_sigma_s * t.time_tag_senders_sigma_s;
  return var;
}

bod::Options bod_options(const config::BodTuning& t) {
  bod::Options o;
  o.samples = t.samples;
  o.max_iterations = t.max_iterations;
  o.range_min_m = t.range_min_m;
  o.range_max_m = t.range_max_m;
  o.min_measurements = t.min_measurements;
  o.max_measurements = t.max_measurements;
  o.max_sigma_range_fraction = t.max_sigma_range_fraction;
  o.max_residual_rms_rad = t.max_residual_arcsec * astro::kArcsecToRad;
  o.validate();
  return o;
}

double association_limit_d2(const NavigatorOptions& options, int n) {
  if (n < 1) return 0.0;
  return std::min(options.association_max_d2, sod::chi2_quantile(2 * n, options.association_confidence) / n);
}

double remote_bearing_max_age_s(const config::ObserverUplink& up) {
  return (imp::SamusOptions{}.n_scan + up.tuning.imp.dbscan_frames) * up.swarm_max_cadence_s + up.isl_period_s +
         up.isl_latency_s + 2.0 * up.step_s;
}

Navigator::Navigator(const config::ObserverUplink& up, const dynamics::ForceModel& forces, NavigatorOptions options)
    : up_(up), forces_(forces), opt_(options), onboard_(forces, up.onboard_properties(up.observer.spacecraft)) {
  fuse_remote_ = up.observer.mode >= 3;
  angles_only_ = up.observer.mode == 4;
  if (angles_only_ && !up.coarse_orbit) {
    throw std::invalid_argument("fsw::Navigator: navigation mode 4 needs the uplinked coarse_orbit (no GNSS)");
  }
  if (angles_only_) {
    // Mode 4: every prediction carries the observer's own absolute
    // uncertainty (kilometres at first), so a track's first bearings tell the
    // targets apart less well; binding asks for twice the bearings and a
    // clearer margin (a 3-bearing binding took SV2's track for SV3 in one of
    // ten 03/24/24-like runs, docs/sod.md).
    opt_.association_min_measurements = std::max(opt_.association_min_measurements, 6);
    opt_.association_ambiguity = std::max(opt_.association_ambiguity, 10.0);
  }
  if (opt_.remote_hold_s < 0.0) opt_.remote_hold_s = remote_bearing_max_age_s(up);
  if (fuse_remote_) opt_.max_lag_s = std::max(opt_.max_lag_s, opt_.remote_hold_s);
  // The targets: those of the ground a-priori, else (mode 2) the uplinked
  // target list, else every other spacecraft of the swarm.
  if (!up.apriori.empty()) {
    for (const auto& a : up.apriori) target_ids_.push_back(a.target);
  } else if (!up.observer.targets.empty()) {
    target_ids_ = up.observer.targets;
  } else {
    for (const auto& id : up.swarm_ids) {
      if (id != up.observer.spacecraft) target_ids_.push_back(id);
    }
  }
  for (const auto& id : up.swarm_ids) {
    if (id != up.observer.spacecraft) sender_clock_ids_.push_back(id);
  }
  time_tag_correction_s_ = up.observer.camera.time_tag_correction_s;
  has_estimate_.assign(target_ids_.size(), false);
  suspect_.assign(target_ids_.size(), false);
  last_fit_t_.assign(target_ids_.size(), up.epoch);
  last_bod_.resize(target_ids_.size());
  manoeuvre_flagged_.assign(target_ids_.size(), std::nullopt);
  pre_flag_.assign(target_ids_.size(), std::nullopt);
  bod_opt_ = bod_options(up.tuning.bod);
  if (up.tuning.bod.model_correction) {
    bod_opt_.onboard_forces = &forces_;  // BOD corrects the mean J2 theory for SOD's numerical model
    bod_opt_.onboard_properties = up.onboard_properties(up.observer.spacecraft);
  }
  if (up.tuning.bod.enabled) next_bod_ = up.epoch.plus_seconds(up.tuning.bod.period_s);
  local_.assign(target_ids_.size(), 0);
  nis_sum_.assign(target_ids_.size(), 0.0);
  nis_n_.assign(target_ids_.size(), 0);
  remote_.assign(target_ids_.size(), 0);
  sod_opt_ = sod_options(up.tuning.sod);
  planned_ = up.planned_maneuvers;
  std::stable_sort(planned_.begin(), planned_.end(), [](const auto& a, const auto& b) { return a.t < b.t; });
  // Mode 4: SOD starts from the coarse orbit at once (no GNSS fix to wait for).
  if (angles_only_) initialise_angles_only();
}

void Navigator::apply_planned_maneuvers(astro::TimeTT t) {
  while (next_planned_ < planned_.size() && !(t < planned_[next_planned_].t)) {
    const auto& m = planned_[next_planned_++];
    if (!filter_ || reinit_pending_ || m.t < filter_->epoch()) {
      messages_.push_back("planned maneuver at " + astro::utc_string(m.t, 0) +
                          " not applied to SOD (no estimate at that epoch; the next GNSS fixes carry it)");
      continue;
    }
    const double s = m.execution_sigma_fraction * m.dv_rtn_mps.norm();
    const sod::TimeUpdateSummary r = filter_->apply_observer_maneuver(m.t, m.dv_rtn_mps, execution_covariance(m));
    char buf[240];
    std::snprintf(buf, sizeof buf, "planned maneuver at %s applied in SOD: dv_RTN [%.4f, %.4f, %.4f] m/s, execution 1-sigma %.4f m/s%s%s",
                  astro::utc_string(m.t, 0).c_str(), m.dv_rtn_mps[0], m.dv_rtn_mps[1], m.dv_rtn_mps[2], s,
                  r.usable ? "" : "; NOT applied: ", r.usable ? "" : r.why.c_str());
    messages_.push_back(buf);
  }
}

void Navigator::add_remote(const RemoteBroadcast& b) {
  ++remote_broadcasts_;
  // Link watch: a sender silent for more than three ISL periods had its link
  // down (outage, range); count its broadcasts after that gap.
  LinkWatch& w = links_[b.sender];
  if (w.last && astro::seconds_between(*w.last, b.t) > 3.0 * up_.isl_period_s) {
    ++w.gap;
    w.since_gap = 1;
    char buf[160];
    std::snprintf(buf, sizeof buf, "ISL: broadcasts from %s again after %.0f s without", b.sender.c_str(),
                  astro::seconds_between(*w.last, b.t));
    messages_.push_back(buf);
  } else if (w.since_gap > 0) {
    ++w.since_gap;
  }
  w.last = b.t;
  if (!fuse_remote_ || b.bearings.empty()) return;
  auto it = std::find(senders_.begin(), senders_.end(), b.sender);
  if (it == senders_.end()) it = senders_.insert(senders_.end(), b.sender);
  const int sender = static_cast<int>(it - senders_.begin());
  const bool orbit_ok = b.source != 0 && !b.reinitialising && b.x_eci.r_m.allFinite() && b.x_eci.v_mps.allFinite() &&
                        b.P_rv.allFinite();
  std::map<std::int64_t, astro::StateVector> at;  // sender position per bearing epoch
  // Forget what is older than any bearing still worth queueing.
  const std::int64_t horizon = b.t.ns_since_j2000 - static_cast<std::int64_t>(4.0 * opt_.remote_hold_s * 1e9);
  for (auto seen = remote_seen_.begin(); seen != remote_seen_.end();) {
    seen = std::get<1>(*seen) < horizon ? remote_seen_.erase(seen) : std::next(seen);
  }
  for (const auto& rb : b.bearings) {
    if (!rb.u_eci.allFinite() || !(rb.sigma_rad > 0.0)) continue;
    if (!remote_seen_.emplace(b.sender, rb.t.ns_since_j2000, rb.track).second) {
      ++remote_repeated_;  // already queued from an earlier broadcast
      continue;
    }
    Event e;
    e.t = rb.t;
    e.kind = EventKind::kRemoteBearing;
    e.track = sender;
    e.u_eci = rb.u_eci;
    e.imp_sigma_rad = rb.sigma_rad;
    e.gap = w.gap;
    e.since_gap = w.since_gap;
    e.seq = b.seq;
    if (orbit_ok) {
      auto p = at.find(rb.t.ns_since_j2000);
      if (p == at.end()) {
        astro::StateVector x = b.x_eci;
        if (rb.t != b.t) {
          x = astro::cartesian_from_qns(onboard_.propagate(astro::qns_from_cartesian(b.x_eci), b.t, rb.t));
        }
        p = at.emplace(rb.t.ns_since_j2000, x).first;
      }
      e.sender_r_eci_m = p->second.r_m;
      e.sender_P_r_m2 = b.P_rv.topLeftCorner<3, 3>();
      e.sender_v_eci_mps = p->second.v_mps;
      e.sender_position_valid = true;
    }
    queue_.push_back(e);
  }
}

void Navigator::add_gnss(const sod::GnssMeasurement& m) {
  Event e;
  e.t = m.t;
  e.kind = EventKind::kGnss;
  e.gnss = m;
  queue_.push_back(e);
}

double Navigator::bearing_sigma(double imp_sigma_rad) const {
  const double s = up_.tuning.sod.bearing_sigma_arcsec;
  return s > 0.0 ? s * astro::kArcsecToRad : std::max(imp_sigma_rad, 1.0 * astro::kArcsecToRad);
}

Navigator::Event Navigator::bearing_event(astro::TimeTT t, EventKind kind, int track, const Eigen::Vector3d& u_eci,
                                          const Eigen::Quaterniond& q_cam_from_eci, double imp_sigma_rad) {
  Event e;
  e.t = t;
  e.kind = kind;
  e.track = track;
  e.u_eci = u_eci;
  e.q_cam_from_eci = q_cam_from_eci;
  e.imp_sigma_rad = imp_sigma_rad;
  return e;
}

void Navigator::add_bearing(astro::TimeTT t, int track, const Eigen::Vector3d& u_eci,
                            const Eigen::Quaterniond& q_cam_from_eci, double imp_sigma_rad, int segment) {
  Event e = bearing_event(t.plus_seconds(time_tag_correction_s_), EventKind::kTrackBearing, track,
                          u_eci, q_cam_from_eci, imp_sigma_rad);
  e.segment = segment;
  e.correction_s = time_tag_correction_s_;
  e.direct = direct_assigned(t, u_eci);
  queue_.push_back(e);
}

void Navigator::add_direct(astro::TimeTT t, int target, const Eigen::Vector3d& u_eci,
                           const Eigen::Quaterniond& q_cam_from_eci, double imp_sigma_rad) {
  Event e = bearing_event(t.plus_seconds(time_tag_correction_s_), EventKind::kDirectBearing, target, u_eci,
                          q_cam_from_eci, imp_sigma_rad);
  e.correction_s = time_tag_correction_s_;
  queue_.push_back(e);
  direct_.emplace_back(t, u_eci);
}

void Navigator::set_suspect(int k, bool on, const std::string& why) {
  if (k < 0 || suspect_[static_cast<std::size_t>(k)] == on) return;
  suspect_[static_cast<std::size_t>(k)] = on;
  messages_.push_back("SOD target " + target_ids_[static_cast<std::size_t>(k)] +
                      (on ? " suspect (health 1): " : " healthy again: ") + why);
}

void Navigator::record_nis(int k, const sod::UpdateSummary& s) {
  if (k >= 0 && s.usable && suspect_[static_cast<std::size_t>(k)] && filter_ && !next_bod_) {
    // Without BOD (whose health check 1 clears a suspect target when it agrees
    // or re-initialises it): healthy again once a whole NIS window fits (or,
    // without the window, one bearing).
    const double nis = filter_->recent_mean_nis(k);
    if (sod_opt_.health.nis_window == 0) {
      set_suspect(k, false, "a bearing fits its estimate again");
    } else if (std::isfinite(nis) && nis <= sod_opt_.health.nis_max_mean) {
      char buf[160];
      std::snprintf(buf, sizeof buf, "the mean NIS of its last %d bearings is %.2f (<= %.2f)", sod_opt_.health.nis_window,
                    nis, sod_opt_.health.nis_max_mean);
      set_suspect(k, false, buf);
    }
  }
  if (k >= 0 && s.usable) last_fit_t_[static_cast<std::size_t>(k)] = filter_ ? filter_->epoch() : astro::TimeTT{};
  if (k < 0 || !std::isfinite(s.nis) || (!s.usable && !s.gated)) return;
  nis_sum_[static_cast<std::size_t>(k)] += s.nis;
  ++nis_n_[static_cast<std::size_t>(k)];
}

bool Navigator::direct_assigned(astro::TimeTT t, const Eigen::Vector3d& u_eci) const {
  return std::any_of(direct_.begin(), direct_.end(), [&](const auto& d) {
    // SAMUS carries the frame's time tag unchanged (TimeTT): the same frame.
    return d.first == t && d.second == u_eci;
  });
}

astro::Roe Navigator::apriori_at(int k, astro::TimeTT t, const astro::QnsElements& observer_osc) const {
  // The uplinked ROE hold at the uplink epoch; carried with the J2 drift of
  // mean ROE (sod/apriori.hpp).
  return astro::Roe::from_vector(sod::apriori_roe_at(up_.apriori[static_cast<std::size_t>(k)].roe, observer_osc,
                                                     astro::seconds_between(up_.epoch, t)));
}

astro::Mat6 Navigator::apriori_covariance_at(int k, astro::TimeTT t, const astro::QnsElements& observer_osc) const {
  return sod::apriori_covariance_at(up_.apriori[static_cast<std::size_t>(k)].P_roe, observer_osc,
                                    astro::seconds_between(up_.epoch, t));
}

void Navigator::initialise(const sod::GnssMeasurement& g) {
  Vec6 var_rv;
  var_rv << Eigen::Vector3d::Constant(g.sigma_r_m * g.sigma_r_m), Eigen::Vector3d::Constant(g.sigma_v_mps * g.sigma_v_mps);
  const Mat6 J = astro::jacobian_qns_from_cartesian(g.x_eci);
  initialise_at(g.t, astro::qns_from_cartesian(g.x_eci), J * var_rv.asDiagonal() * J.transpose(),
                "the GNSS fix of " + astro::utc_string(g.t, 0));
}

void Navigator::initialise_angles_only() {
  // Navigation mode 4: the first time from the uplinked coarse orbit; after a
  // filter-wide health failure from the observer's own estimate, its
  // covariance widened by the coarse orbit's (no GNSS fix will come).
  const auto& c = *up_.coarse_orbit;
  const Mat6 J = astro::jacobian_qns_from_cartesian(c.x_eci);
  const Mat6 P_coarse = J * c.P_rv * J.transpose();
  if (!filter_) {
    initialise_at(c.t, astro::qns_from_cartesian(c.x_eci), P_coarse,
                  "the uplinked coarse orbit of " + astro::utc_string(c.t, 0) + " (mode 4: no GNSS)");
    return;
  }
  const Mat6 P_own = filter_->covariance().topLeftCorner<6, 6>();
  initialise_at(filter_->epoch(), filter_->observer(), P_own + P_coarse,
                "its own orbit estimate with the coarse orbit's covariance added (mode 4: no GNSS)");
}

void Navigator::initialise_at(astro::TimeTT t0, const astro::QnsElements& obs, Mat6 P_obs, const std::string& from) {
  a_observer_m_ = obs.a_m;
  P_obs += Mat6::Identity() * 1e-20;
  const int n = static_cast<int>(target_ids_.size());
  // Auxiliary states carry over a re-initialisation (the camera clock and
  // the targets' drag did not change); from their uplinked 1-sigma at first.
  Eigen::VectorXd aux;
  Eigen::MatrixXd P_aux;
  if (!filter_) {
    const sod::StateLayout layout = sod_layout(up_.tuning.sod, n, static_cast<int>(sender_clock_ids_.size()));
    // The onboard model's expected error on the observer's own orbit (mode 4
    // has no GNSS to correct it).
    sod_opt_ = sod_options(up_.tuning.sod, obs);
    // Each target flies its own uplinked nominal properties; its
    // differential ballistic state (if estimated) adds to that nominal.
    filter_.emplace(forces_, up_.onboard_properties(up_.observer.spacecraft), layout,
                    target_nominal_properties(up_, target_ids_), sod_opt_);
    aux = Eigen::VectorXd::Zero(layout.size() - layout.aux_offset());
    P_aux = auxiliary_prior_variance(up_.tuning.sod, layout).asDiagonal();
  } else {
    const int a0 = filter_->layout().aux_offset(), na = filter_->layout().size() - a0;
    aux = filter_->state().tail(na);
    P_aux = filter_->covariance().bottomRightCorner(na, na);
  }
  std::vector<astro::Roe> roes;
  const int n_all = filter_->layout().size();
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(n_all, n_all);
  P.topLeftCorner<6, 6>() = P_obs;
  if (aux.size() > 0) P.bottomRightCorner(aux.size(), aux.size()) = P_aux;
  int from_apriori = 0, from_bod = 0;
  const bool first = apriori_mean_.empty();
  if (first) apriori_mean_.assign(static_cast<std::size_t>(n), std::nullopt);
  for (int k = 0; k < n; ++k) {
    astro::Vec6 roe;
    astro::Mat6 Pk;
    has_estimate_[static_cast<std::size_t>(k)] = restart_estimate(k, t0, obs, roe, Pk);
    if (!has_estimate_[static_cast<std::size_t>(k)]) {
      // No estimate yet (mode 2): a placeholder 35 km ahead with a tight
      // covariance that nothing updates; left out of association, updates,
      // health and telemetry until BOD initialises it.
      roe << 0.0, 35e3 / obs.a_m, 0.0, 0.0, 0.0, 0.0;
      Pk = astro::Mat6::Identity() * std::pow(1.0 / obs.a_m, 2);
    } else if (last_bod_[static_cast<std::size_t>(k)]) {
      ++from_bod;
    } else {
      ++from_apriori;
    }
    if (first && has_estimate_[static_cast<std::size_t>(k)] && !last_bod_[static_cast<std::size_t>(k)]) {
      try {
        const astro::QnsElements obs_mean = dynamics::mean_from_osculating(obs);
        const astro::QnsElements target = astro::qns_from_roe(obs, astro::Roe::from_vector(roe));
        const astro::Vec6 roe_mean = astro::roe_from_qns(obs_mean, dynamics::mean_from_osculating(target)).as_vector();
        apriori_mean_[static_cast<std::size_t>(k)] = BodEstimate{t0, obs_mean, roe_mean, Pk};
      } catch (const std::exception&) {
        // the mean model refuses these elements: later restarts drift the osculating a-priori
      }
    }
    roes.push_back(astro::Roe::from_vector(roe));
    P.block<6, 6>(6 * (k + 1), 6 * (k + 1)) = Pk;
  }
  filter_->initialize(t0, filter_->make_state(obs, roes, aux), P);
  suspect_.assign(target_ids_.size(), false);
  manoeuvre_flagged_.assign(target_ids_.size(), std::nullopt);
  pre_flag_.assign(target_ids_.size(), std::nullopt);
  tracks_.clear();
  reinit_pending_ = false;
  std::string what;
  if (from_apriori > 0) {
    what = " with the ground a-priori of " + std::to_string(from_apriori) + " targets (" +
           std::to_string(up_.apriori_age_days) + " days old)";
  }
  if (from_bod > 0) what += (what.empty() ? " with " : " and ") + std::string("the latest BOD estimate of ") +
                            std::to_string(from_bod) + " targets";
  if (from_apriori + from_bod < n) {
    what += (what.empty() ? "; " : "; ") + std::to_string(n - from_apriori - from_bod) +
            " targets wait for BOD (no a-priori)";
  }
  messages_.push_back("SOD initialised at " + from + what);
}

bool Navigator::predict_plane(const sod::SodFilter& f, int k, const imp::Samus& samus, imp::TargetPrediction& out,
                              std::optional<astro::TimeTT> plane_t) const {
  Eigen::VectorXd mean;
  Eigen::MatrixXd P;
  observer_target_block(f, k, mean, P);
  astro::StateVector observer = astro::cartesian_from_qns(f.observer());
  if (plane_t) {
    // The observer a fraction of a second away (a time-tag offset): one
    // Taylor step of two-body motion moves its RTN frame by n dt.
    const double dt = astro::seconds_between(f.epoch(), *plane_t);
    const double r = observer.r_m.norm();
    const Eigen::Vector3d a = -astro::kGmEarth_m3ps2 * observer.r_m / (r * r * r);
    observer.r_m += observer.v_mps * dt + 0.5 * a * dt * dt;
    observer.v_mps += a * dt;
  }
  return samus.unscented_prediction(-1, mean, P, los_eci_of, observer, out);
}

bool Navigator::association_d2(sod::SodFilter& f, const imp::Samus& samus, const Event& e, std::vector<double>& d2,
                               std::vector<int>* unpredicted) const {
  // The bearing against every target's prediction, at the time the image
  // was taken as SOD knows it (its time-tag offset): squared Mahalanobis
  // distance in the plane, 1e6 where a target has no usable prediction.
  // The filter itself moves to the bearing's time only: an image time later
  // than that (an offset estimated below zero) would put the next event of
  // the same time (the other target's bearing in this frame, the GNSS fix
  // of the step) behind the filter's epoch. A copy predicts to the image time.
  astro::TimeTT t_image = e.t.plus_seconds(-time_tag_offset_at(e.t));
  if (t_image < f.epoch()) t_image = e.t;
  if (!f.time_update(e.t).usable) return false;
  std::optional<sod::SodFilter> at_image;
  if (t_image != e.t) {
    at_image.emplace(f);
    if (!at_image->time_update(t_image).usable) return false;
  }
  const sod::SodFilter& g = at_image ? *at_image : f;
  Eigen::Vector2d p;
  if (!samus.plane_coordinates(e.u_eci, astro::cartesian_from_qns(g.observer()), p)) return false;
  const double s2 = std::pow(bearing_sigma(e.imp_sigma_rad), 2);
  d2.assign(target_ids_.size(), 1e6);
  for (std::size_t k = 0; k < target_ids_.size(); ++k) {
    imp::TargetPrediction pr;
    if (has_estimate_[k] && predict_plane(g, static_cast<int>(k), samus, pr)) {
      const Eigen::Matrix2d S = pr.cov + s2 * Eigen::Matrix2d::Identity();
      d2[k] = std::min((p - pr.p).dot(S.ldlt().solve(p - pr.p)), 1e6);
    } else if (unpredicted) {
      ++(*unpredicted)[k];
    }
  }
  return true;
}

void Navigator::process(const Event& queued, const imp::Samus& samus) {
  // A local bearing queued before the own-clock check changed the time-tag
  // correction takes the new one.
  Event rebased;
  const bool stale = (queued.kind == EventKind::kTrackBearing || queued.kind == EventKind::kDirectBearing) &&
                     queued.correction_s != time_tag_correction_s_;
  if (stale) {
    rebased = queued;
    rebased.t = queued.t.plus_seconds(time_tag_correction_s_ - queued.correction_s);
    rebased.correction_s = time_tag_correction_s_;
  }
  const Event& e = stale ? rebased : queued;
  if (e.kind == EventKind::kTrackBearing && next_bod_) {
    // Bounded: the latest batch_orbits orbits (at the longest LEO period) of every track.
    const double keep_s = up_.tuning.bod.batch_orbits * 6400.0;
    auto& h = history_[e.track];
    h.push_back({e.t, e.u_eci, e.q_cam_from_eci, e.segment, e.imp_sigma_rad});
    while (!h.empty() && astro::seconds_between(h.front().t, e.t) > keep_s) h.pop_front();
    if (history_.size() > 64) {
      std::erase_if(history_, [&](const auto& kv) {
        return kv.second.empty() || astro::seconds_between(kv.second.back().t, e.t) > keep_s;
      });
    }
  }
  apply_planned_maneuvers(e.t);
  if (!filter_ || (reinit_pending_ && e.kind == EventKind::kGnss)) {
    if (e.kind == EventKind::kGnss) initialise(e.gnss);
    else ++late_;
    return;
  }
  auto& f = *filter_;
  if (e.t < f.epoch()) {
    if (e.kind == EventKind::kTrackBearing || e.kind == EventKind::kDirectBearing) ++late_;
    return;
  }
  if (e.kind == EventKind::kGnss) {
    const auto s = f.update_gnss(e.gnss);
    if (!s.usable && !s.gated) messages_.push_back("SOD: GNSS update not usable: " + s.why);
  } else if (e.kind == EventKind::kDirectBearing) {
    if (blended(f, e.track, e.t)) return;
    const auto m = sod::bearing_measurement_from_unit_eci(e.t, e.track, e.u_eci, bearing_sigma(e.imp_sigma_rad),
                                                          e.q_cam_from_eci.toRotationMatrix());
    const auto s = f.update_bearing(m);
    record_nis(e.track, s);
    if (s.usable) ++local_[static_cast<std::size_t>(e.track)];
    else ++refused_;
  } else {
    auto& as = tracks_[e.track];
    // A track that SAMUS joined across a gap since it was bound may have
    // come back on another target (IT: SAMUS's first track follows SV3, loses
    // it in a gap and comes back on SV2, 5 px away; the first bearings after
    // the join reached SV3 before the gate refused three, and in 2 of 20
    // runs SV3's estimate was then too far off for its own track to be
    // bound for hours). It stays held on its target while each of its next
    // association_min_measurements bearings passes the association's test on
    // its own, and those are fused; the first that fails unbinds it, and it
    // is associated again. (Unbinding every join lost the first bearings
    // after each eclipse: IT SV3, ~12 joins in 19 h.)
    if (as.target >= 0 && e.segment != as.segment) {
      as.segment = e.segment;
      as.held = opt_.association_min_measurements;
      messages_.push_back("IMP track " + std::to_string(e.track) + " joined across a gap: held on target " +
                          target_ids_[static_cast<std::size_t>(as.target)] + " while its next " +
                          std::to_string(as.held) + " bearings fit it alone");
    }
    if (as.target >= 0 && as.held > 0) {
      std::vector<double> d2;
      std::vector<int> unpredicted(target_ids_.size(), 0);
      if (!association_d2(f, samus, e, d2, &unpredicted)) return;
      const auto k = static_cast<std::size_t>(as.target);
      double second = 1e30;
      bool others_predicted = true;  // a target without a prediction could own the bearing
      for (std::size_t j = 0; j < d2.size(); ++j) {
        if (j == k) continue;
        second = std::min(second, d2[j]);
        if (unpredicted[j] > 0) others_predicted = false;
      }
      if (unpredicted[k] == 0 && others_predicted && d2[k] < opt_.association_max_d2 &&
          second > opt_.association_ambiguity * d2[k]) {
        --as.held;
      } else {
        char buf[240];
        std::snprintf(buf, sizeof buf,
                      "IMP track %d unbound from target %s after a join across a gap (d2 %.3g, next target "
                      "%.3g): associated again",
                      e.track, target_ids_[k].c_str(), d2[k], second);
        messages_.push_back(buf);
        as = Association{};
      }
    }
    as.last = e.t;
    if (as.target < 0) {
      ++association_;
      std::vector<double> d2;
      if (as.n == 0) as.first = e.t;
      as.d2_sum.resize(target_ids_.size(), 0.0);
      as.unpredicted.resize(target_ids_.size(), 0);
      if (!association_d2(f, samus, e, d2, &as.unpredicted)) return;
      // A bearing taken while its nearest target is predicted within
      // blend_separation_px of another may be either's: SAMUS can swap
      // where two targets cross (IT with the phase drawn, seed 26: track 2
      // followed SV2 to 5.8 px from SV3, went on with SV3's light, and was
      // bound to SV2 by bearings of both). The association starts again.
      const auto nearest = static_cast<int>(std::min_element(d2.begin(), d2.end()) - d2.begin());
      if (blended(f, nearest, e.t, false)) {
        as.d2_sum.assign(target_ids_.size(), 0.0);
        as.unpredicted.assign(target_ids_.size(), 0);
        as.n = 0;
        return;
      }
      for (std::size_t k = 0; k < target_ids_.size(); ++k) as.d2_sum[k] += d2[k];
      ++as.n;
      if (as.n >= opt_.association_min_measurements) {
        std::vector<std::size_t> order(target_ids_.size());
        for (std::size_t k = 0; k < order.size(); ++k) order[k] = k;
        std::sort(order.begin(), order.end(), [&](auto a, auto b) { return as.d2_sum[a] < as.d2_sum[b]; });
        const double best = as.d2_sum[order[0]] / as.n;
        const double second = order.size() > 1 ? as.d2_sum[order[1]] / as.n : 1e30;
        // The target is taken when another track bound to it has had a
        // bearing since this one's association began (both see an object at
        // once). A track that ended before this one began handed the target
        // over: SAMUS follows a target on successive tracks (PSE anti-velocity
        // camera: a new track every ~1/3 orbit, the old one joined again
        // across its gap), and waiting for the old one to age out lost
        // half of SV2's bearings.
        bool taken = false;
        for (const auto& [tid, other] : tracks_) {
          if (tid != e.track && other.target == static_cast<int>(order[0]) && !(other.last < as.first) &&
              astro::seconds_between(other.last, e.t) < 1800.0) {
            taken = true;
          }
        }
        const int k_best = static_cast<int>(order[0]);
        // The track is this target's only if no other target could own it:
        // one without a usable prediction could (bod_assist: the 20 km
        // target's 3.5-day a-priori has none; its track, nearest the 150 km
        // target's prediction, inflated that one's covariance, was bound to
        // it, and the 150 km target never recovered).
        bool others_predicted = true;
        for (std::size_t k = 0; k < target_ids_.size(); ++k) {
          if (static_cast<int>(k) != k_best && as.unpredicted[k] > 0) others_predicted = false;
        }
        if (best >= opt_.lost_min_d2 && best < opt_.lost_max_d2 && second > opt_.association_ambiguity * best &&
            !taken && others_predicted && f.counters(k_best).accepted > 0 &&
            f.counters(k_best).steps_without_update >= opt_.lost_after_steps) {
          // The target's own bearings stopped and a new track sits nearest
          // its prediction, too far for its covariance: it moved (a
          // manoeuvre) or the filter is over-confident. Inflate so that the
          // mean d2 falls to a quarter of the association limit, and
          // associate again from the next bearings.
          const double sigma_dv = maneuver_sigma_mps(best);
          const double since_s = astro::seconds_between(last_fit_t_[static_cast<std::size_t>(k_best)], e.t);
          f.inflate_target_maneuver(k_best, sigma_dv, std::max(0.0, since_s));
          char buf[360];
          std::snprintf(buf, sizeof buf,
                        "no bearing for %.0f s while the unbound IMP track %d is nearest its prediction (mean d2 "
                        "%.3g over %d bearings, next target %.3g): a manoeuvre or an over-confident estimate; "
                        "covariance inflated by an unknown manoeuvre of %.3g m/s (1-sigma per axis)",
                        since_s, e.track, best, as.n, second, sigma_dv);
          set_suspect(k_best, true, buf);
          as.d2_sum.assign(target_ids_.size(), 0.0);
          as.unpredicted.assign(target_ids_.size(), 0);
          as.n = 0;
          return;
        }
        if (best < association_limit_d2(opt_, as.n) && second > opt_.association_ambiguity * best && !taken) {
          as.target = static_cast<int>(order[0]);
          as.segment = e.segment;
          char buf[200];
          std::snprintf(buf, sizeof buf, "IMP track %d bound to target %s (mean d2 %.2f over %d bearings, next %.1f)",
                        e.track, target_ids_[order[0]].c_str(), best, as.n, second);
          messages_.push_back(buf);
        }
      }
      return;
    }
    if (e.direct) return;  // already fused as a single detection of this target (kDirectBearing)
    if (blended(f, as.target, e.t)) return;
    const double sigma = bearing_sigma(e.imp_sigma_rad);
    const Eigen::Matrix3d R_v_from_eci = e.q_cam_from_eci.toRotationMatrix();
    const auto m = sod::bearing_measurement_from_unit_eci(e.t, as.target, e.u_eci, sigma, R_v_from_eci);
    const auto s = f.update_bearing(m);
    record_nis(as.target, s);
    if (s.usable) ++local_[static_cast<std::size_t>(as.target)];
    else ++refused_;
    // A bound track whose bearings the gate keeps refusing has most likely
    // swapped to another object (two targets crossing a few pixels apart):
    // it is unbound and goes through the association again, before the
    // target fails health check (3) and loses its estimate.
    as.gated_in_row = s.gated ? as.gated_in_row + 1 : 0;
    if (as.gated_in_row >= opt_.unbind_after_gated) {
      messages_.push_back("IMP track " + std::to_string(e.track) + " unbound from target " +
                          target_ids_[static_cast<std::size_t>(as.target)] + ": " +
                          std::to_string(as.gated_in_row) + " successive bearings refused by the gate");
      set_suspect(as.target, true,
                  "the bearings of its IMP track " + std::to_string(e.track) +
                      " no longer fit its estimate (a manoeuvre, a swap or an over-confident filter); until one fits "
                      "again or BOD re-initialises it");
      as = Association{};
      as.last = e.t;
    }
  }
  check_health();
  report_aux();
}

astro::TimeTT Navigator::image_time(astro::TimeTT tag) const {
  const astro::TimeTT t = tag.plus_seconds(time_tag_correction_s_);
  return t.plus_seconds(-time_tag_offset_at(t));
}

double Navigator::time_tag_offset_at(astro::TimeTT t) const {
  if (!filter_ || filter_->layout().n_time_tag == 0) return 0.0;
  const auto& L = filter_->layout();
  const auto& x = filter_->state();
  double dt = x[L.time_tag_offset()];
  if (L.n_time_tag > 1) dt += x[L.time_tag_drift()] * astro::seconds_between(filter_->epoch(), t);
  return dt;
}

void Navigator::report_aux() {
  if (!filter_) return;
  const auto& f = *filter_;
  const auto& L = f.layout();
  if (L.size() == L.aux_offset() || (next_aux_report_ && f.epoch() < *next_aux_report_)) return;
  next_aux_report_ = f.epoch().plus_seconds(3600.0);
  const auto& x = f.state();
  const auto sd = [&](int i) { return std::sqrt(f.covariance()(i, i)); };
  std::string m = "SOD auxiliary states:";
  char buf[160];
  if (L.n_time_tag > 0) {
    std::snprintf(buf, sizeof buf, " time-tag offset %+.4f s (1-sigma %.4f)", x[L.time_tag_offset()], sd(L.time_tag_offset()));
    m += buf;
  }
  if (L.n_time_tag > 1) {
    std::snprintf(buf, sizeof buf, ", drift %+.2f ppm (1-sigma %.2f)", 1e6 * x[L.time_tag_drift()], 1e6 * sd(L.time_tag_drift()));
    m += buf;
  }
  for (int k = 0; L.ballistic && k < L.n_targets; ++k) {
    std::snprintf(buf, sizeof buf, "%s differential Cd A/m of %s %+.5f m^2/kg (1-sigma %.5f)",
                  L.n_time_tag > 0 || k > 0 ? ";" : "", target_ids_[static_cast<std::size_t>(k)].c_str(),
                  x[L.ballistic_index(k)], sd(L.ballistic_index(k)));
    m += buf;
  }
  for (int j = 0; j < L.n_remote_clock; ++j) {
    std::snprintf(buf, sizeof buf, "%s time-tag offset of %s's camera %+.4f s (1-sigma %.4f)",
                  L.n_time_tag > 0 || L.ballistic || j > 0 ? ";" : "", sender_clock_ids_[static_cast<std::size_t>(j)].c_str(),
                  x[L.remote_clock_index(j)], sd(L.remote_clock_index(j)));
    m += buf;
  }
  messages_.push_back(m);
}

void Navigator::process_remote(const std::vector<Event>& group) {
  if (!group.empty()) apply_planned_maneuvers(group.front().t);
  if (!filter_ || reinit_pending_ || group.empty()) return;
  auto& f = *filter_;
  if (group.front().t < f.epoch()) {
    remote_late_ += group.size();
    return;
  }
  using L = sod::LineOfSightMeasurement;
  const std::string& sender = senders_[static_cast<std::size_t>(group.front().track)];
  const auto own = std::find(target_ids_.begin(), target_ids_.end(), sender);
  int from = own != target_ids_.end() ? static_cast<int>(own - target_ids_.begin()) : L::kExternal;
  if (from >= 0 && !has_estimate_[static_cast<std::size_t>(from)]) from = L::kExternal;  // no estimate of the sender yet
  if (from == L::kExternal && !group.front().sender_position_valid) {
    remote_unassigned_ += group.size();
    return;
  }
  // Candidate bodies: this observer and every target other than the sender.
  std::vector<int> bodies = {L::kObserver};
  for (int k = 0; k < static_cast<int>(target_ids_.size()); ++k) {
    if (k != from && has_estimate_[static_cast<std::size_t>(k)]) bodies.push_back(k);
  }
  int sender_clock = -1;
  if (f.layout().n_remote_clock > 0) {
    const auto c = std::find(sender_clock_ids_.begin(), sender_clock_ids_.end(), sender);
    if (c != sender_clock_ids_.end()) sender_clock = static_cast<int>(c - sender_clock_ids_.begin());
  }
  auto measurement = [&](const Event& e, int to) {
    L m;
    m.t = e.t;
    m.from = from;
    m.to = to;
    m.from_r_eci_m = e.sender_r_eci_m;
    m.from_P_r_m2 = e.sender_P_r_m2;
    m.from_v_eci_mps = e.sender_v_eci_mps;
    m.sender_clock = sender_clock;
    m.los_eci = e.u_eci;
    m.sigma_rad = bearing_sigma(e.imp_sigma_rad);
    return m;
  };
  const std::size_t J = group.size(), K = bodies.size();
  Eigen::MatrixXd D(J, K);
  for (std::size_t j = 0; j < J; ++j) {
    for (std::size_t k = 0; k < K; ++k) {
      const auto s = f.update_line_of_sight(measurement(group[j], bodies[k]), true);
      D(static_cast<Eigen::Index>(j), static_cast<Eigen::Index>(k)) = std::isfinite(s.mahalanobis) ? s.mahalanobis : 1e9;
    }
  }
  const double eps_assign = up_.tuning.sod.eps_assign, eps_ambig = up_.tuning.sod.eps_ambig;
  for (std::size_t j = 0; j < J; ++j) {
    int assigned = -1;
    for (std::size_t k = 0; k < K && assigned < 0; ++k) {
      const auto jj = static_cast<Eigen::Index>(j), kk = static_cast<Eigen::Index>(k);
      if (!(D(jj, kk) <= eps_assign)) continue;                      // (1)
      bool ok = true;
      for (std::size_t l = 0; l < J; ++l) {                          // (2)
        if (l != j && D(static_cast<Eigen::Index>(l), kk) < eps_ambig) ok = false;
      }
      for (std::size_t p = 0; p < K; ++p) {                          // (3)
        if (p != k && D(jj, static_cast<Eigen::Index>(p)) < eps_ambig) ok = false;
      }
      if (ok) assigned = static_cast<int>(k);
    }
    if (assigned < 0) {
      ++remote_unassigned_;
      continue;
    }
    const int to = bodies[static_cast<std::size_t>(assigned)];
    const int body = to >= 0 ? to : from;  // the target whose relative orbit it measures
    const auto su = f.update_line_of_sight(measurement(group[j], to));
    if (body >= 0) record_nis(body, su);
    if (su.usable) {
      ++remote_assigned_;
      if (body >= 0) ++remote_[static_cast<std::size_t>(body)];
      LinkWatch& w = links_[sender];
      const Event& e = group[j];
      // Reported again if a broadcast received earlier after the same silence
      // is fused later: a repeat after a silence carries older bearings than the
      // broadcast before it, and the filter fuses in time order.
      if (e.since_gap > 0 && (w.reported_gap < e.gap || (w.reported_gap == e.gap && e.since_gap < w.reported_since))) {
        w.reported_gap = e.gap;
        w.reported_since = e.since_gap;
        messages_.push_back("ISL: remote bearings from " + sender + " fused again, from its broadcast " +
                            std::to_string(e.seq) + " (received " + std::to_string(e.since_gap) +
                            (e.since_gap == 1 ? "st" : e.since_gap == 2 ? "nd" : e.since_gap == 3 ? "rd" : "th") +
                            " after the silence)");
      }
    }
  }
  check_health();
}

bool Navigator::blended(sod::SodFilter& f, int k, astro::TimeTT t, bool count) {
  const double fx = up_.camera_calibration.fx_px;
  if (!(opt_.blend_separation_px > 0.0) || !(fx > 0.0) || target_ids_.size() < 2) return false;
  if (!f.time_update(t).usable) return false;
  const Eigen::Vector3d u = los_eci_of(observer_target_mean(f, k)).normalized();
  for (int j = 0; j < static_cast<int>(target_ids_.size()); ++j) {
    if (j == k || !has_estimate_[static_cast<std::size_t>(j)]) continue;
    const Eigen::Vector3d v = los_eci_of(observer_target_mean(f, j)).normalized();
    const double angle = std::acos(std::clamp(u.dot(v), -1.0, 1.0));
    if (angle * fx < opt_.blend_separation_px) {
      if (count) ++blended_;
      return true;
    }
  }
  return false;
}

bool Navigator::check_own_clock() {
  auto& f = *filter_;
  const auto& L = f.layout();
  if (L.n_remote_clock < 2 || reinit_pending_) return false;
  std::vector<int> known;
  double sum_w = 0.0, sum_wd = 0.0, lo = 1e300, hi = -1e300;
  for (int j = 0; j < L.n_remote_clock; ++j) {
    const int i = L.remote_clock_index(j);
    const double d = f.state()[i], sd = std::sqrt(f.covariance()(i, i));
    if (!(sd <= opt_.clock_known_s)) continue;  // this sender's bearings have not told yet
    if (!(std::abs(d) >= opt_.clock_min_offset_s && std::abs(d) >= 5.0 * sd)) return false;  // one agrees with us
    known.push_back(j);
    sum_w += 1.0 / (sd * sd);
    sum_wd += d / (sd * sd);
    lo = std::min(lo, d);
    hi = std::max(hi, d);
  }
  if (known.size() < 2) return false;
  const double mean = sum_wd / sum_w;
  if (!(lo * hi > 0.0) || !(hi - lo <= 0.5 * std::abs(mean))) return false;
  // Every clock it hears from is off by the same amount: its own is.
  time_tag_correction_s_ += mean;
  std::string who;
  char buf[800];
  for (const int j : known) {
    const int i = L.remote_clock_index(j);
    std::snprintf(buf, sizeof buf, "%s%s %+.4f s (1-sigma %.4f)", who.empty() ? "" : ", ",
                  sender_clock_ids_[static_cast<std::size_t>(j)].c_str(), f.state()[i],
                  std::sqrt(f.covariance()(i, i)));
    who += buf;
  }
  // The senders' clocks keep what was learnt of them relative to each other,
  // now relative to the corrected clock. Those estimates were fitted against
  // orbits seen with the wrong clock: the correction takes three times the
  // weighted mean's 1-sigma (the own offset state, if any, is opened by it),
  // and each sender's clock also its distance from the consensus.
  const double sigma_correction = 3.0 / std::sqrt(sum_w);
  for (int j = 0; j < L.n_remote_clock; ++j) {
    const int i = L.remote_clock_index(j);
    const bool was_known = std::find(known.begin(), known.end(), j) != known.end();
    const double away = was_known ? f.state()[i] - mean : 0.0;
    f.shift_auxiliary(i, -mean);
    f.inflate_auxiliary(i, sigma_correction * sigma_correction + away * away);
  }
  if (L.n_time_tag > 0) f.inflate_auxiliary(L.time_tag_offset(), sigma_correction * sigma_correction);
  // The relative orbits and BOD's batches were fitted with the wrong clock.
  history_.clear();
  tracks_.clear();
  int restarted = 0, dropped = 0;
  for (std::size_t k = 0; k < target_ids_.size(); ++k) {
    if (!has_estimate_[k]) continue;
    last_bod_[k].reset();
    manoeuvre_flagged_[k].reset();
    pre_flag_[k].reset();
    suspect_[k] = false;
    astro::Vec6 roe;
    astro::Mat6 P;
    if (restart_estimate(static_cast<int>(k), f.epoch(), f.observer(), roe, P)) {
      f.reinitialize_target(static_cast<int>(k), roe, P);
      ++restarted;
    } else {
      has_estimate_[k] = false;
      ++dropped;
    }
  }
  std::snprintf(buf, sizeof buf,
                "SOD: own camera clock: the clocks of every sender known (%s) appear off by the same amount, so "
                "this observer's camera time tags are the likelier culprit; time-tag correction now %+.4f s (%+.4f "
                "from the check, 1-sigma %.4f%s); %d targets re-initialised from the ground a-priori, %d dropped "
                "until BOD initialises them again",
                who.c_str(), time_tag_correction_s_, mean, sigma_correction,
                L.n_time_tag > 0 ? ", added to its offset state" : ", not estimated further", restarted, dropped);
  messages_.push_back(buf);
  return true;
}

void Navigator::check_health() {
  auto& f = *filter_;
  if (check_own_clock()) return;
  sod::HealthReport h = f.health();
  if (h.filter.condition == sod::HealthCondition::kInconsistent && !reinit_pending_) {
    // The observer's GNSS fixes no longer fit its orbit: it manoeuvred
    // without a plan (or its model failed). Its own block and every target's
    // ROE (relative to it) get the covariance of an unknown burn through the
    // same map as a planned one, so that the fixes correct both; every target
    // is suspect until BOD agrees.
    const double nis = f.recent_mean_gnss_nis();
    const double sigma_dv = maneuver_sigma_mps(nis / 3.0);
    const auto r = f.apply_observer_maneuver(f.epoch(), astro::Vec3::Zero(), astro::Mat3::Identity() * sigma_dv * sigma_dv);
    f.clear_gnss_nis();
    char buf[320];
    std::snprintf(buf, sizeof buf,
                  "SOD: the observer's orbit does not fit its GNSS fixes (%s): an unplanned maneuver or a model "
                  "error; observer and targets inflated by an unknown maneuver of %.3g m/s (1-sigma per axis)%s",
                  h.filter.reason.c_str(), sigma_dv, r.usable ? "" : " (NOT applied)");
    messages_.push_back(buf);
    for (std::size_t k = 0; k < target_ids_.size(); ++k) {
      if (!has_estimate_[k]) continue;
      suspect_[k] = false;
      set_suspect(static_cast<int>(k), true, "its observer manoeuvred without a plan (GNSS consistency)");
    }
    h = f.health();
  }
  if (!h.filter.healthy() && !reinit_pending_ && angles_only_ &&
      (h.filter.condition == sod::HealthCondition::kNoMeasurementUpdate ||
       h.filter.condition == sod::HealthCondition::kOutOfRange)) {
    messages_.push_back("SOD unhealthy (" + std::string(sod::to_string(h.filter.condition)) + ": " + h.filter.reason +
                        "): re-initialising from its own orbit (coarse covariance added) and the ground a-priori");
    initialise_angles_only();
    return;
  }
  if (!h.filter.healthy() && !reinit_pending_ &&
      (h.filter.condition == sod::HealthCondition::kNoMeasurementUpdate ||
       h.filter.condition == sod::HealthCondition::kOutOfRange)) {
    reinit_pending_ = true;
    messages_.push_back("SOD unhealthy (" + std::string(sod::to_string(h.filter.condition)) + ": " + h.filter.reason +
                        "): re-initialising from the next GNSS fix and the ground a-priori");
  }
  for (std::size_t k = 0; k < h.targets.size(); ++k) {
    const auto c = h.targets[k].condition;
    if (!has_estimate_[k]) continue;
    const int ki = static_cast<int>(k);
    if (c == sod::HealthCondition::kInconsistent) {
      // Health check 5: the bearings no longer fit the covariance. The target
      // is suspect until one fits the inflated estimate, and BOD's next
      // attempt (check 1) re-initialises it if it is wrong, not just unsure.
      if (up_.tuning.bod.reinit_after_check5 && !manoeuvre_flagged_[k]) {
        manoeuvre_flagged_[k] = f.epoch();
        pre_flag_[k] = sod_mean_estimate(ki);  // before the inflation below
      }
      const double nis = f.recent_mean_nis(ki);
      const double sigma_dv = maneuver_sigma_mps(nis);
      f.inflate_target_maneuver(ki, sigma_dv, f.recent_nis_span_s(ki));
      // A drag the ballistic state had not learnt looks the same: open it again.
      if (f.layout().ballistic) {
        f.inflate_auxiliary(f.layout().ballistic_index(ki),
                            std::pow(up_.tuning.sod.ballistic_sigma_fraction * nominal_ballistic_m2pkg(), 2));
      }
      char buf[300];
      std::snprintf(buf, sizeof buf,
                    "its bearings do not fit its covariance (health check 5: %s); covariance inflated by an "
                    "unknown manoeuvre of %.3g m/s (1-sigma per axis)",
                    h.targets[k].reason.c_str(), sigma_dv);
      suspect_[k] = false;
      set_suspect(ki, true, buf);
      continue;
    }
    if (c != sod::HealthCondition::kLargeResiduals && c != sod::HealthCondition::kOutOfRange) continue;
    astro::Vec6 roe;
    astro::Mat6 P;
    const bool have = restart_estimate(ki, f.epoch(), f.observer(), roe, P);
    for (auto& [tid, as] : tracks_) {
      if (as.target == ki) as = Association{};
    }
    suspect_[k] = false;
    manoeuvre_flagged_[k].reset();
    pre_flag_[k].reset();
    if (have) {
      f.reinitialize_target(ki, roe, P);
    } else {
      has_estimate_[k] = false;
    }
    messages_.push_back("SOD target " + target_ids_[k] + " unhealthy (" + std::string(sod::to_string(c)) + ": " +
                        h.targets[k].reason + "): " +
                        (!have ? "dropped until BOD initialises it again"
                         : last_bod_[k] ? "re-initialised from its latest BOD estimate"
                                        : "re-initialised from the ground a-priori"));
  }
}

std::optional<std::array<double, 2>> Navigator::range_window(int k) const {
  const auto& ids = up_.observer.targets;
  const auto it = std::find(ids.begin(), ids.end(), target_ids_[static_cast<std::size_t>(k)]);
  if (it == ids.end() || up_.observer.target_ranges_m.size() != ids.size()) return std::nullopt;
  const auto w = up_.observer.target_ranges_m[static_cast<std::size_t>(it - ids.begin())];
  if (!(w[1] > w[0]) || !(w[0] > 0.0)) return std::nullopt;
  return w;
}

bool Navigator::restart_estimate(int k, astro::TimeTT t, const astro::QnsElements& observer_osc, astro::Vec6& roe,
                                 astro::Mat6& P) const {
  // A mean estimate made osculating at t; false where the mean model refuses
  // the observer's elements.
  const auto from_mean = [&](const BodEstimate& m) {
    try {
      const OsculatingRoe o = osculating_at(m, t, observer_osc);
      roe = o.roe;
      P = o.P;
      return true;
    } catch (const std::exception&) {
      return false;
    }
  };
  const auto ku = static_cast<std::size_t>(k);
  if (last_bod_[ku] && from_mean(*last_bod_[ku])) return true;
  if (ku >= up_.apriori.size()) return false;
  // Later than the first initialisation: the a-priori as mean ROE then,
  // carried with the J2 STM and made osculating again (the osculating ROE of
  // a 155 km along-track pair swing by ~400 m over an orbit with J2's
  // short-period terms, far beyond the a-priori's 1-sigma in dex, dey).
  if (ku < apriori_mean_.size() && apriori_mean_[ku] && t != apriori_mean_[ku]->t && from_mean(*apriori_mean_[ku]))
    return true;
  roe = apriori_at(k, t, observer_osc).as_vector();
  P = apriori_covariance_at(k, t, observer_osc);
  return true;
}

namespace {
// Jacobian of a map between ROE vectors by central differences (dlambda
// wrapped), for carrying a covariance through it.
template <typename Map>
Mat6 roe_map_jacobian(const Map& map, const Vec6& x) {
  Mat6 J;
  for (int k = 0; k < 6; ++k) {
    Vec6 a = x, c = x;
    a[k] += 1e-7;
    c[k] -= 1e-7;
    Vec6 d = map(a) - map(c);
    d[1] = astro::wrap_pi(d[1]);
    J.col(k) = d / 2e-7;
  }
  return J;
}
}  // namespace

Navigator::OsculatingRoe Navigator::osculating_at(const BodEstimate& b, astro::TimeTT t,
                                                 const astro::QnsElements& observer_osc) {
  // Mean ROE at t by the J2 STM, then roe_osc = roe(osc(observer mean), osc(target mean)),
  // the target's mean elements from eq. (4) inverted.
  const Mat6 Phi = dynamics::roe_stm_j2(b.observer_mean, astro::seconds_between(b.t, t));
  const Vec6 m = Phi * b.roe_mean;
  const Mat6 Pm = Phi * b.P_mean * Phi.transpose();
  const astro::QnsElements observer_mean = dynamics::mean_from_osculating(observer_osc);
  const astro::QnsElements observer_back = dynamics::osculating_from_mean(observer_mean);
  const auto map = [&](const Vec6& roe_mean) {
    const astro::QnsElements target = astro::qns_from_roe(observer_mean, astro::Roe::from_vector(roe_mean));
    return astro::roe_from_qns(observer_back, dynamics::osculating_from_mean(target)).as_vector();
  };
  OsculatingRoe o;
  o.roe = map(m);
  const Mat6 J = roe_map_jacobian(map, m);
  o.P = J * Pm * J.transpose();
  o.P = 0.5 * (o.P + o.P.transpose()).eval();
  return o;
}

namespace {
// Squared Mahalanobis distance between two ROE estimates (dlambda wrapped),
// with the sum of their covariances; NaN when it cannot be formed.
double roe_distance2(const Vec6& roe_a, const Mat6& P_a, const Vec6& roe_b, const Mat6& P_b) {
  Vec6 d = roe_a - roe_b;
  d[1] = astro::wrap_pi(d[1]);
  const Eigen::LDLT<Mat6> ldlt(P_a + P_b);
  return d.dot(ldlt.solve(d));
}
}  // namespace

double Navigator::bod_distance2(int k, const OsculatingRoe& b) const {
  const auto& f = *filter_;
  const int off = f.layout().target_offset(k);
  Mat6 P_sod = f.covariance().block<6, 6>(off, off);
  const auto& L = f.layout();
  if (b.clock_J.size() > 0 && L.n_time_tag > 0) {
    // Both errors hold the clock's: BOD's -J e_clock, SOD's through its
    // cross-covariance. Var(BOD - SOD) = P_BOD + J P_cc J^T + P_kk + J P_ck + P_kc J^T.
    const Mat6 cross = b.clock_J * f.covariance().block(L.time_tag_offset(), off, L.n_time_tag, 6);
    P_sod += cross + cross.transpose();
  }
  const double d2 = roe_distance2(b.roe, b.P, f.state().segment<6>(off), P_sod);
  return std::isfinite(d2) ? d2 : 1e30;
}

std::optional<Navigator::BodEstimate> Navigator::sod_mean_estimate(int k) const {
  // roe_mean = roe(mean(observer), mean(target)), the target's osculating
  // elements from SOD's osculating ROE; the covariance through the map's
  // Jacobian (central differences, as osculating_at).
  const auto& f = *filter_;
  const int off = f.layout().target_offset(k);
  const astro::QnsElements observer_osc = f.observer();
  try {
    const astro::QnsElements observer_mean = dynamics::mean_from_osculating(observer_osc);
    const auto map = [&](const Vec6& roe_osc) {
      const astro::QnsElements target = astro::qns_from_roe(observer_osc, astro::Roe::from_vector(roe_osc));
      return astro::roe_from_qns(observer_mean, dynamics::mean_from_osculating(target)).as_vector();
    };
    const Vec6 x = f.state().segment<6>(off);
    BodEstimate e{f.epoch(), observer_mean, map(x), Mat6::Zero()};
    const Mat6 J = roe_map_jacobian(map, x);
    e.P_mean = J * f.covariance().block<6, 6>(off, off) * J.transpose();
    e.P_mean = 0.5 * (e.P_mean + e.P_mean.transpose()).eval();
    if (!e.roe_mean.allFinite() || !e.P_mean.allFinite()) return std::nullopt;
    return e;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

double Navigator::pre_flag_distance2(int k, const OsculatingRoe& b, astro::TimeTT t) const {
  const auto& pre = pre_flag_[static_cast<std::size_t>(k)];
  if (!pre) return std::numeric_limits<double>::infinity();
  try {
    const OsculatingRoe o = osculating_at(*pre, t, filter_->observer());
    const double d2 = roe_distance2(b.roe, b.P, o.roe, o.P);
    return std::isfinite(d2) ? d2 : std::numeric_limits<double>::infinity();
  } catch (const std::exception&) {
    return std::numeric_limits<double>::infinity();
  }
}

void Navigator::bind_track(int track, int k, astro::TimeTT t) {
  Association& as = tracks_[track];
  as = Association{};
  as.target = k;
  as.last = t;
  const auto h = history_.find(track);
  as.segment = h != history_.end() && !h->second.empty() ? h->second.back().segment : 1;
}

bod::Options Navigator::bod_options_for_target(int k) const {
  bod::Options o = bod_opt_;
  if (!o.onboard_forces || k < 0) return o;
  // SOD propagates each target with its own nominal properties plus its
  // differential ballistic state.
  dynamics::SpacecraftProperties p = up_.onboard_properties(target_ids_[static_cast<std::size_t>(k)]);
  if (filter_ && filter_->layout().ballistic && has_estimate_[static_cast<std::size_t>(k)]) {
    const double b_nominal = p.cd * p.drag_area_m2 / p.mass_kg;
    const double db = filter_->state()[filter_->layout().ballistic_index(k)];
    // A drag that the estimate would make negative is left at 1 % of the nominal.
    p.drag_area_m2 *= std::max(b_nominal + db, 0.01 * b_nominal) / b_nominal;
  }
  o.target_properties = p;
  return o;
}

void Navigator::add_clock_doubt(OsculatingRoe& b, const std::vector<bod::Measurement>& batch,
                                const bod::ObserverPrior& prior, const bod::Options& options) const {
  const auto& f = *filter_;
  const auto& L = f.layout();
  if (L.n_time_tag == 0) return;
  // The batch's times are the tags less SOD's clock estimate: BOD's error
  // holds J (SOD's clock error), J = d roe / d(time shift) by solving the
  // batch again with its times shifted (finite differences of the size of a
  // clock's doubt: 0.05 s, and 10 ppm of t - SOD's epoch for the drift).
  constexpr double kShiftS = 0.05;
  constexpr double kDriftShift = 1e-5;
  b.clock_J = Eigen::MatrixXd::Zero(6, L.n_time_tag);
  for (int c = 0; c < L.n_time_tag; ++c) {
    std::vector<bod::Measurement> shifted = batch;
    for (auto& m : shifted) {
      m.t = m.t.plus_seconds(c == 0 ? kShiftS : kDriftShift * astro::seconds_between(f.epoch(), m.t));
    }
    const bod::Result rs = bod::solve(shifted, prior, options);
    if (!rs.usable()) throw std::runtime_error("its clock sensitivity: the shifted batch is not usable");
    const OsculatingRoe bs =
        osculating_at({prior.t_est, prior.mean, rs.roe_mean.as_vector(), rs.P_roe_mean}, prior.t_est, f.observer());
    Vec6 d = bs.roe - b.roe;
    d[1] = astro::wrap_pi(d[1]);
    b.clock_J.col(c) = d / (c == 0 ? kShiftS : kDriftShift);
  }
  const int o = L.time_tag_offset();
  const Eigen::MatrixXd P_clock = f.covariance().block(o, o, L.n_time_tag, L.n_time_tag);
  b.P_without_clock = b.P;
  b.P += b.clock_J * P_clock * b.clock_J.transpose();
  b.P = 0.5 * (b.P + b.P.transpose()).eval();
}

void Navigator::set_target_from_bod(int k, int track, const OsculatingRoe& b, astro::TimeTT t, const std::string& why) {
  if (b.clock_J.size() > 0) {
    filter_->reinitialize_target(k, b.roe, b.P_without_clock, b.clock_J);
  } else {
    filter_->reinitialize_target(k, b.roe, b.P);
  }
  suspect_[static_cast<std::size_t>(k)] = false;
  manoeuvre_flagged_[static_cast<std::size_t>(k)].reset();
  pre_flag_[static_cast<std::size_t>(k)].reset();
  has_estimate_[static_cast<std::size_t>(k)] = true;
  for (auto& [tid, as] : tracks_) {
    if (as.target == k) as = Association{};
  }
  bind_track(track, k, t);
  messages_.push_back("SOD target " + target_ids_[static_cast<std::size_t>(k)] + " " + why + "; IMP track " +
                      std::to_string(track) + " bound to it");
}

void Navigator::run_bod(astro::TimeTT t_est) {
  auto& f = *filter_;
  bod::ObserverPrior prior;
  prior.t_est = t_est;
  try {
    prior.mean = dynamics::mean_from_osculating(f.observer());
  } catch (const std::exception& ex) {
    messages_.push_back(std::string("BOD skipped: the observer's mean elements: ") + ex.what());
    return;
  }
  prior.P_prior = f.covariance().block<5, 5>(1, 1);
  const double span_s = up_.tuning.bod.batch_orbits * astro::orbit_period_s(prior.mean.a_m);
  int attempted = 0;
  // Usable results of unbound tracks while targets wait for a first estimate.
  struct Pending {
    int track;
    BodEstimate est;
    OsculatingRoe b;
    std::size_t record;
    std::string text;
    double range_m;
    int measurements;
  };
  std::vector<Pending> pending;
  for (auto it = history_.begin(); it != history_.end();) {
    auto& h = it->second;
    std::erase_if(h, [&](const TrackBearing& b) { return astro::seconds_between(b.t, t_est) > span_s; });
    if (h.empty()) {
      it = history_.erase(it);
      continue;
    }
    const int track = it->first;
    ++it;
    // The target of a bound track that health check 5 flagged: only the
    // bearings after the flag (after its manoeuvre) make its batch.
    const auto bound = tracks_.find(track);
    const int bound_target = bound != tracks_.end() ? bound->second.target : -1;
    const bool after = bound_target >= 0 && manoeuvre_flagged_[static_cast<std::size_t>(bound_target)].has_value();
    const astro::TimeTT after_t = after ? *manoeuvre_flagged_[static_cast<std::size_t>(bound_target)] : t_est;
    std::vector<bod::Measurement> batch;
    astro::TimeTT last = h.front().t;
    astro::TimeTT first = t_est;
    double sum_sigma2 = 0.0;
    for (const auto& b : h) {
      if (b.t > t_est || (after && b.t < after_t)) continue;
      first = std::min(first, b.t);
      sum_sigma2 += b.sigma_rad * b.sigma_rad;
      // The time tags as SOD knows them: less its estimated offset (and drift).
      batch.push_back({b.t.plus_seconds(-time_tag_offset_at(b.t)), b.u_eci, b.q_cam_from_eci.toRotationMatrix()});
      last = std::max(last, b.t);
    }
    // A track that is gone (nothing in the latest half hour), or too short.
    if (static_cast<int>(batch.size()) < bod_opt_.min_measurements || astro::seconds_between(last, t_est) > 1800.0) {
      if (after) {
        messages_.push_back("BOD on IMP track " + std::to_string(track) + " waits: " + std::to_string(batch.size()) +
                            " of " + std::to_string(bod_opt_.min_measurements) + " bearings of target " +
                            target_ids_[static_cast<std::size_t>(bound_target)] + " since health check 5 flagged it at " +
                            astro::utc_string(after_t, 0));
      }
      continue;
    }
    ++attempted;
    ++bod_attempts_;
    const bod::Options options = bod_options_for_target(bound_target);
    bod::Result r = bod::solve(batch, prior, options);
    const std::vector<bod::Measurement>* solved = &batch;
    // A batch that no single orbit fits (the target manoeuvred, or the track
    // swapped objects, within it) is tried again on its latest orbit alone.
    const double orbit_s = astro::orbit_period_s(prior.mean.a_m);
    std::vector<bod::Measurement> latest;
    if (!r.usable() && r.verdict != bod::Verdict::kTooFewMeasurements && up_.tuning.bod.batch_orbits > 1.0) {
      for (const auto& m : batch) {
        if (astro::seconds_between(m.t, t_est) <= orbit_s) latest.push_back(m);
      }
      if (static_cast<int>(latest.size()) >= bod_opt_.min_measurements && latest.size() < batch.size()) {
        bod::Result again = bod::solve(latest, prior, options);
        if (again.usable()) {
          messages_.push_back("BOD on IMP track " + std::to_string(track) + ": the " +
                              std::to_string(batch.size()) + "-bearing batch is not usable (" + r.brief() +
                              "); its latest orbit alone is");
          r = std::move(again);
          solved = &latest;
        }
      }
    }
    bus::BodAttempt& rec = bod_records_.emplace_back();
    rec.observer = up_.observer.spacecraft;
    rec.attempt = static_cast<std::uint32_t>(bod_attempts_);
    rec.t_est_tt_ns = t_est.ns_since_j2000;
    rec.track = track;
    rec.verdict = static_cast<bus::BodVerdict>(r.verdict);
    rec.why = bus::bounded(r.why, bus::kEventTextChars);
    rec.measurements = static_cast<std::uint32_t>(r.measurements);
    rec.iterations = static_cast<std::uint32_t>(r.iterations);
    rec.residual_rms_rad = r.residual_rms_rad;
    rec.correlation_inflation = r.correlation_inflation;
    rec.model_correction_rms_rad = r.model_correction_rms_rad;
    rec.uncorrected_range_m = r.uncorrected_range_m;
    rec.a_observer_m = r.a_observer_m;
    rec.range_m = r.range_m;
    rec.sigma_range_m = r.sigma_range_m;
    const double a_scale = r.a_observer_m > 0.0 ? r.a_observer_m : prior.mean.a_m;
    for (int i = 0; i < 6; ++i) {
      rec.a_roe_mean_m[static_cast<std::size_t>(i)] = r.roe_mean.as_vector()[i] * a_scale;
      for (int j = 0; j < 6; ++j) {
        rec.covariance_a_roe_m2[static_cast<std::size_t>(6 * i + j)] = r.P_roe_mean(i, j) * a_scale * a_scale;
      }
    }
    for (std::size_t i = 0; i < r.curve.size() && i < bus::kMaxBodSamples; ++i) {
      rec.curve.push_back({r.curve[i].a_dlambda_m, r.curve[i].residual_rms_rad, r.curve[i].chi2, r.curve[i].converged});
    }
    const auto decided = [&](int target, const std::string& action, double d2 = -1.0) {
      rec.target = target >= 0 ? target_ids_[static_cast<std::size_t>(target)] : "";
      rec.action = bus::bounded(action, bus::kEventTextChars);
      rec.mahalanobis2 = d2;
    };
    char head[96];
    std::snprintf(head, sizeof head, "BOD attempt %zu on IMP track %d at %s: ", bod_attempts_, track,
                  astro::utc_string(t_est, 0).c_str());
    // The BOD figures and the navigator's decision on them, as two events (event texts are bounded,
    // bus::kEventTextChars, and the decision must not be the part cut off).
    const auto say_decision = [&](const std::string& decision) {
      messages_.push_back(head + r.brief());
      messages_.push_back(std::string(head) + (decision.rfind("; ", 0) == 0 ? decision.substr(2) : decision));
    };
    if (!r.usable()) {
      decided(-1, "not usable");
      messages_.push_back(head + r.brief());
      continue;
    }
    ++bod_usable_;
    const BodEstimate est{t_est, prior.mean, r.roe_mean.as_vector(), r.P_roe_mean};
    OsculatingRoe b;
    try {
      b = osculating_at(est, t_est, f.observer());
      add_clock_doubt(b, *solved, prior, options);
    } catch (const std::exception& ex) {
      decided(-1, std::string("not used: ") + ex.what());
      messages_.push_back(head + r.brief() + "; not used: " + ex.what());
      continue;
    }
    const double chi2 = up_.tuning.bod.check_chi2;
    char buf[320];
    if (bound != tracks_.end() && bound->second.target >= 0) {
      // Health check (1) of the track's target.
      const int k = bound->second.target;
      const double d2 = bod_distance2(k, b);
      // BOD's fit against what it should be: IMP's RMS 1-sigma of the batch's
      // bearings with BOD's own expected misfit (kBodExpectedMisfit_rad). A
      // post-fit RMS above max_fit_ratio x that means the mean J2 model misses
      // this target's motion (unmodelled drag, a manoeuvre inside the batch)
      // and its estimate is biased beyond its covariance (docs/bod.md). It is
      // then neither a reason to re-initialise SOD nor evidence that SOD is right.
      const double sigma_rms = std::sqrt(sum_sigma2 / static_cast<double>(batch.size()));
      const double expected_rms = std::hypot(sigma_rms, kBodExpectedMisfit_rad);
      if (sigma_rms > 0.0 && r.residual_rms_rad > up_.tuning.bod.max_fit_ratio * expected_rms) {
        decided(k, "not used for health check 1: the mean model does not fit the bearings", d2);
        std::snprintf(buf, sizeof buf,
                      "not used for health check 1 of target %s: post-fit RMS %.1f arcsec = %.2f x the expected "
                      "%.1f (max %.2f), the mean model misses its motion (d2 %.1f); ",
                      target_ids_[static_cast<std::size_t>(k)].c_str(), r.residual_rms_rad / astro::kArcsecToRad,
                      r.residual_rms_rad / expected_rms, expected_rms / astro::kArcsecToRad,
                      up_.tuning.bod.max_fit_ratio, d2);
        messages_.push_back(std::string(head) + buf + r.brief());
        continue;
      }
      last_bod_[static_cast<std::size_t>(k)] = est;  // the latest usable BOD: the source of re-initialisations
      if (d2 > chi2) {
        std::snprintf(buf, sizeof buf,
                      "unhealthy (health check 1: squared Mahalanobis distance %.1f between BOD and SOD > %.2f): "
                      "re-initialised from BOD",
                      d2, chi2);
        messages_.push_back(head + r.brief());
        decided(k, "health check 1 failed: SOD re-initialised from BOD", d2);
        set_target_from_bod(k, track, b, t_est, buf);
      } else if (const auto flagged = manoeuvre_flagged_[static_cast<std::size_t>(k)]; flagged && first >= *flagged) {
        // After an unknown manoeuvre SOD's inflated covariance is a guess;
        // a batch made only of later bearings is not (paper: re-initialise
        // from the most recent BOD estimate). Unless BOD still fits SOD's
        // estimate from before the flag: then check 5 was a false alarm, and
        // SOD, which knows the target better than one batch, is kept.
        const double d2_pre = pre_flag_distance2(k, b, t_est);
        if (d2_pre > chi2) {
          std::snprintf(buf, sizeof buf,
                        "re-initialised from BOD: its first batch after health check 5 flagged a manoeuvre at %s "
                        "confirms it (squared Mahalanobis distance %.1f to SOD's estimate before the flag > %.2f; "
                        "%.1f to SOD now)",
                        astro::utc_string(*flagged, 0).c_str(), d2_pre, chi2, d2);
          messages_.push_back(head + r.brief());
          decided(k, "SOD re-initialised from BOD after a manoeuvre (health check 5, confirmed by BOD)", d2);
          set_target_from_bod(k, track, b, t_est, buf);
        } else {
          messages_.push_back(head + r.brief());
          std::snprintf(buf, sizeof buf,
                        "SOD target %s: no manoeuvre: BOD's first batch after health check 5 flagged one at %s fits "
                        "SOD's estimate from before the flag (squared Mahalanobis distance %.1f <= %.2f; %.1f to SOD "
                        "now); SOD kept",
                        target_ids_[static_cast<std::size_t>(k)].c_str(), astro::utc_string(*flagged, 0).c_str(),
                        d2_pre, chi2, d2);
          messages_.push_back(buf);
          decided(k, "health check 1 passed; BOD finds no manoeuvre (health check 5 not confirmed)", d2);
          manoeuvre_flagged_[static_cast<std::size_t>(k)].reset();
          pre_flag_[static_cast<std::size_t>(k)].reset();
          set_suspect(k, false, "BOD finds no manoeuvre");
        }
      } else {
        decided(k, "health check 1 passed", d2);
        std::snprintf(buf, sizeof buf, "; health check 1 passed for target %s (squared Mahalanobis distance %.1f <= %.2f)",
                      target_ids_[static_cast<std::size_t>(k)].c_str(), d2, chi2);
        say_decision(buf);
        std::snprintf(buf, sizeof buf, "BOD agrees (health check 1 passed, squared Mahalanobis distance %.1f)", d2);
        set_suspect(k, false, buf);
      }
      continue;
    }
    // An unbound track while targets wait for their first estimate (mode
    // 2): decided after every track is solved (below).
    bool any_waiting = false, fits_known = false;
    for (int k = 0; k < static_cast<int>(target_ids_.size()); ++k) {
      if (!has_estimate_[static_cast<std::size_t>(k)]) any_waiting = true;
      else if (!tracked(k, t_est) && bod_distance2(k, b) <= up_.tuning.bod.check_chi2) fits_known = true;
    }
    if (any_waiting && !fits_known) {
      pending.push_back({track, est, b, bod_records_.size() - 1, head + r.brief(), r.range_m, r.measurements});
      continue;
    }
    // Which target: the nearest in dlambda (a manoeuvre changes a target's
    // drift and eccentricity at once, its along-track place only slowly);
    // health check 1 then compares all six ROE.
    int best = -1;
    double dl_best = 1e300, dl_second = 1e300;
    for (int k = 0; k < static_cast<int>(target_ids_.size()); ++k) {
      if (!has_estimate_[static_cast<std::size_t>(k)] || tracked(k, t_est)) continue;
      const int o = f.layout().target_offset(k);
      const double dl = astro::wrap_pi(b.roe[1] - f.state()[o + 1]);
      const double d2 = dl * dl / (b.P(1, 1) + f.covariance()(o + 1, o + 1));
      if (d2 < dl_best) {
        dl_second = dl_best;
        dl_best = d2;
        best = k;
      } else if (d2 < dl_second) {
        dl_second = d2;
      }
    }
    if (best < 0) {
      decided(-1, "not used: every target has a bound IMP track");
      say_decision("; not used: every target has a bound IMP track");
      continue;
    }
    if (dl_second < 9.0 * dl_best && dl_best > 1.0) {
      std::snprintf(buf, sizeof buf,
                    "; not used: two targets without a bound track are as near in dlambda (squared distances %.1f, %.1f)",
                    dl_best, dl_second);
      decided(-1, std::string("not used") + buf);
      say_decision(buf);
      continue;
    }
    const double d2_best = bod_distance2(best, b);
    double d2_pre = 0.0;  // to SOD's estimate before a check-5 flag, when one is tested below
    const int off = f.layout().target_offset(best);
    const double sigma_sod = std::sqrt(f.covariance()(off + 1, off + 1));
    const double sigma_bod = std::sqrt(b.P(1, 1));
    const double range_est_m = std::abs(f.state()[off + 1]) * a_observer_m_;
    const double jump_m = std::abs(astro::wrap_pi(b.roe[1] - f.state()[off + 1])) * a_observer_m_;
    if (d2_best > chi2 && f.counters(best).accepted > 0 && (!suspect_[static_cast<std::size_t>(best)] || jump_m > 0.5 * range_est_m)) {
      // A target whose own bearings fit its estimate is not re-initialised
      // from a track it has not been seen on: the track is most likely
      // another object, or the same target seen on another track (after a
      // manoeuvre the target is suspect first: health check 5 or a lost track).
      // Nor by one half its range away: no manoeuvre of a few dm/s moves it so far within a BOD period.
      std::snprintf(buf, sizeof buf,
                    "; not used: target %s is nearest in dlambda but %s (squared distance %.1f > %.2f, a*dlambda "
                    "%.1f km from its estimate at %.1f km)",
                    target_ids_[static_cast<std::size_t>(best)].c_str(),
                    suspect_[static_cast<std::size_t>(best)] ? "the jump is implausible" : "its own bearings fit its estimate",
                    d2_best, chi2, jump_m / 1e3, range_est_m / 1e3);
      decided(-1, std::string("not used") + buf);
      say_decision(buf);
      continue;
    }
    last_bod_[static_cast<std::size_t>(best)] = est;
    messages_.push_back(head + r.brief());
    if (d2_best > chi2) {
      std::snprintf(buf, sizeof buf,
                    "unhealthy (health check 1: squared Mahalanobis distance %.1f between BOD and SOD > %.2f): "
                    "re-initialised from BOD",
                    d2_best, chi2);
      decided(best, "health check 1 failed: SOD re-initialised from BOD (unbound track)", d2_best);
      set_target_from_bod(best, track, b, t_est, buf);
    } else if (const auto flagged = manoeuvre_flagged_[static_cast<std::size_t>(best)];
               flagged && first >= *flagged && (d2_pre = pre_flag_distance2(best, b, t_est)) > chi2) {
      std::snprintf(buf, sizeof buf,
                    "re-initialised from BOD: its first batch after health check 5 flagged a manoeuvre at %s "
                    "confirms it (unbound track; squared Mahalanobis distance %.1f to SOD's estimate before the "
                    "flag > %.2f; %.1f to SOD now)",
                    astro::utc_string(*flagged, 0).c_str(), d2_pre, chi2, d2_best);
      decided(best, "SOD re-initialised from BOD after a manoeuvre (health check 5 confirmed by BOD, unbound track)", d2_best);
      set_target_from_bod(best, track, b, t_est, buf);
    } else if (sigma_bod < sigma_sod) {
      std::snprintf(buf, sizeof buf,
                    "refined from BOD (its track was not bound; BOD's a*dlambda 1-sigma %.0f m < SOD's %.0f m, "
                    "squared distance %.1f)",
                    sigma_bod * a_observer_m_, sigma_sod * a_observer_m_, d2_best);
      decided(best, "SOD refined from BOD (unbound track, BOD knows the range better)", d2_best);
      set_target_from_bod(best, track, b, t_est, buf);
    } else {
      decided(best, "track bound to the target (BOD consistent with SOD)", d2_best);
      bind_track(track, best, t_est);
      std::snprintf(buf, sizeof buf, "IMP track %d bound to target %s by BOD (squared distance %.1f)", track,
                    target_ids_[static_cast<std::size_t>(best)].c_str(), d2_best);
      messages_.push_back(buf);
    }
  }
  // Targets that wait for a first estimate (mode 2): one waiting target
  // takes the solution with the most bearings; several are told apart by
  // range only: by the uplinked range windows (observer targets[].range_km)
  // or, as many solutions as targets at hand, in the uplink's order
  // (nearest first).
  std::vector<int> waiting;
  for (int k = 0; k < static_cast<int>(target_ids_.size()); ++k) {
    if (!has_estimate_[static_cast<std::size_t>(k)]) waiting.push_back(k);
  }
  if (!pending.empty()) {
    std::vector<std::pair<int, std::size_t>> assign;  // (target, pending index)
    if (waiting.size() == 1) {
      std::size_t pick = 0;
      for (std::size_t i = 1; i < pending.size(); ++i) {
        if (pending[i].measurements > pending[pick].measurements) pick = i;
      }
      assign.emplace_back(waiting.front(), pick);
    } else if (pending.size() != waiting.size()) {
      // Fewer (or more) solutions than waiting targets: a solution whose
      // range lies in exactly one waiting target's uplinked window is that target's.
      for (std::size_t i = 0; i < pending.size(); ++i) {
        int only = -1, n = 0;
        for (const int k : waiting) {
          const auto w = range_window(k);
          if (w && pending[i].range_m >= (*w)[0] && pending[i].range_m <= (*w)[1]) {
            only = k;
            ++n;
          }
        }
        const bool taken = std::any_of(assign.begin(), assign.end(), [&](const auto& a) { return a.first == only; });
        if (n == 1 && !taken) assign.emplace_back(only, i);
      }
    } else {
      std::vector<std::size_t> order(pending.size());
      for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
      std::sort(order.begin(), order.end(), [&](auto a, auto b) { return pending[a].range_m < pending[b].range_m; });
      for (std::size_t i = 0; i < order.size(); ++i) assign.emplace_back(waiting[i], order[i]);
    }
    for (std::size_t i = 0; i < pending.size(); ++i) {
      Pending& p = pending[i];
      const auto it = std::find_if(assign.begin(), assign.end(), [&](const auto& a) { return a.second == i; });
      bus::BodAttempt& rec = bod_records_[p.record];
      messages_.push_back(p.text);
      if (it == assign.end()) {
        rec.action = waiting.size() > 1
                         ? bus::bounded(std::to_string(waiting.size()) + " targets wait for BOD and " +
                                            std::to_string(pending.size()) +
                                            " usable solutions: no range window holds it alone, and the targets "
                                            "are told apart by range order only when as many as them",
                                        bus::kEventTextChars)
                         : "not used: another track of the batch has more bearings";
        messages_.push_back("BOD: not used: " + rec.action);
        continue;
      }
      const int k = it->first;
      last_bod_[static_cast<std::size_t>(k)] = p.est;
      rec.target = target_ids_[static_cast<std::size_t>(k)];
      rec.action = "SOD initialised from BOD (no estimate before)";
      set_target_from_bod(k, p.track, p.b, t_est, "initialised by BOD (no a-priori)");
    }
  }
  // Targets still without an estimate after this attempt: say so (every BOD
  // period), so that a target the camera never shows is not silent.
  for (int k = 0; k < static_cast<int>(target_ids_.size()); ++k) {
    if (has_estimate_[static_cast<std::size_t>(k)]) continue;
    std::string text = "target " + target_ids_[static_cast<std::size_t>(k)] +
                       " still waits for BOD: no usable solution of an unbound IMP track";
    if (const auto w = range_window(k)) {
      char win[96];
      std::snprintf(win, sizeof win, " with its range in [%.0f, %.0f] km", (*w)[0] * 1e-3, (*w)[1] * 1e-3);
      text += win;
    }
    messages_.push_back(text);
  }
  if (attempted == 0) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "BOD at %s: no IMP track with %d bearings in the latest %.1f orbits",
                  astro::utc_string(t_est, 0).c_str(), bod_opt_.min_measurements, up_.tuning.bod.batch_orbits);
    messages_.push_back(buf);
  }
}

void Navigator::advance(astro::TimeTT t_safe, astro::TimeTT t_now, const imp::Samus& samus) {
  astro::TimeTT limit = std::max(t_safe, t_now.plus_seconds(-opt_.max_lag_s));
  if (fuse_remote_) limit = std::min(limit, t_now.plus_seconds(-opt_.remote_hold_s));
  process_until(limit, samus);
}

void Navigator::process_until(astro::TimeTT limit, const imp::Samus& samus) {
  std::stable_sort(queue_.begin(), queue_.end(), [](const Event& a, const Event& b) {
    return std::tie(a.t, a.kind, a.track) < std::tie(b.t, b.kind, b.track);
  });
  std::size_t n = 0;
  while (n < queue_.size() && queue_[n].t <= limit) {
    // BOD every tuning.bod.period, on what the filter has seen up to its epoch.
    if (next_bod_ && queue_[n].t >= *next_bod_) {
      if (filter_ && !reinit_pending_) run_bod(filter_->epoch());
      while (*next_bod_ <= queue_[n].t) *next_bod_ = next_bod_->plus_seconds(up_.tuning.bod.period_s);
    }
    if (queue_[n].kind != EventKind::kRemoteBearing) {
      process(queue_[n++], samus);
      continue;
    }
    std::vector<Event> group;
    const Event& first = queue_[n];
    const astro::TimeTT t0 = first.t;
    const int sender = first.track;
    while (n < queue_.size() && queue_[n].kind == EventKind::kRemoteBearing && queue_[n].t == t0 && queue_[n].track == sender) {
      group.push_back(queue_[n++]);
    }
    process_remote(group);
  }
  if (n > 0) ++version_;
  queue_.erase(queue_.begin(), queue_.begin() + static_cast<std::ptrdiff_t>(n));
}

const sod::SodFilter* Navigator::predicted_to(astro::TimeTT t, bool even_if_unusable) const {
  if (!filter_) return nullptr;
  if (!predicted_ || predicted_version_ != version_ || predicted_t_ != t) {
    predicted_.emplace(*filter_);
    predicted_usable_ = true;
    // The planned maneuvers between the filter's epoch and t are part of the prediction.
    for (std::size_t i = next_planned_; i < planned_.size() && !(t < planned_[i].t); ++i) {
      const auto& m = planned_[i];
      if (m.t < predicted_->epoch()) continue;
      predicted_usable_ =
          predicted_usable_ && predicted_->apply_observer_maneuver(m.t, m.dv_rtn_mps, execution_covariance(m)).usable;
    }
    // Telemetry and IMP's predictions: the linearised prediction (its mean
    // through the onboard model; in modes 3 and 4 the filter runs ~20 min
    // behind the clock, and the unscented one cost 90 % of a run).
    predicted_usable_ = predicted_usable_ && (!(predicted_->epoch() < t) || predicted_->predict_linearised(t).usable);
    predicted_version_ = version_;
    predicted_t_ = t;
  }
  return predicted_usable_ || even_if_unusable ? &*predicted_ : nullptr;
}

void Navigator::finish(const imp::Samus& samus) {
  process_until(astro::TimeTT{std::numeric_limits<std::int64_t>::max()}, samus);
}

NavReport Navigator::report(astro::TimeTT t) const {
  NavReport r;
  if (!filter_) return r;
  const sod::SodFilter* fp = predicted_to(t, true);
  const sod::SodFilter& f = *fp;
  const astro::QnsElements oe = f.observer();
  r.valid = true;
  r.health = reinit_pending_ ? 1 : (f.health().filter.healthy() ? 0 : 1);
  r.x_eci = astro::cartesian_from_qns(oe);
  const Mat6 J = jacobian_rv_from_qns(oe);
  r.P_rv = J * f.covariance().topLeftCorner<6, 6>() * J.transpose();
  for (std::size_t k = 0; k < target_ids_.size(); ++k) {
    if (!has_estimate_[k]) continue;  // no estimate yet (mode 2, before BOD)
    const int off = f.layout().target_offset(static_cast<int>(k));
    TargetReport tr;
    tr.id = target_ids_[k];
    tr.roe = f.state().segment<6>(off);
    tr.P_roe = f.covariance().block<6, 6>(off, off);
    // The onboard gravity's short-periodic error, which the bearings cannot
    // see: in the reported uncertainty, not in the filter (docs/sod.md,
    // "Unmodelled gravity in the thin directions").
    if (const auto it = up_.observer.target_gravity_periodic_a_roe_m.find(tr.id);
        it != up_.observer.target_gravity_periodic_a_roe_m.end()) {
      tr.P_roe.diagonal() += (it->second / oe.a_m).cwiseAbs2();
    }
    tr.local_measurements = local_[k];
    tr.remote_measurements = remote_[k];
    tr.bearing_nis_sum = nis_sum_[k];
    tr.bearing_updates = nis_n_[k];
    tr.health = suspect_[k] ? 1 : 0;
    r.targets.push_back(tr);
  }
  return r;
}

std::vector<Navigator::DirectAssignment> Navigator::assign_untracked(astro::TimeTT t,
                                                                     const std::vector<imp::Candidate>& candidates,
                                                                     const std::vector<int>& taken,
                                                                     const astro::StateVector& observer_eci,
                                                                     const imp::Samus& samus) {
  std::vector<DirectAssignment> used;
  // SAMUS releases a track's measurements at most dbscan_frames + n_scan frames late.
  while (!direct_.empty() && astro::seconds_between(direct_.front().first, t) > 4.0 * 3600.0) direct_.pop_front();
  if (!filter_ || reinit_pending_ || candidates.empty()) return used;
  // The target where the image saw it, on the plane of the candidates (the observer at the tag), as predictions().
  const sod::SodFilter* fp = predicted_to(image_time(t));
  if (!fp) return used;
  const sod::SodFilter& f = *fp;
  // Every target's prediction and every free candidate's squared Mahalanobis distance to it.
  const std::size_t K = target_ids_.size(), C = candidates.size();
  std::vector<bool> have(K, false);
  Eigen::MatrixXd d2 = Eigen::MatrixXd::Constant(static_cast<Eigen::Index>(C), static_cast<Eigen::Index>(K), 1e12);
  std::vector<double> width(K, 1e9);
  for (std::size_t k = 0; k < K; ++k) {
    imp::TargetPrediction pr;
    if (!has_estimate_[k] || !predict_plane(f, static_cast<int>(k), samus, pr, t)) continue;
    have[k] = true;
    width[k] = std::sqrt(pr.cov.trace());
    for (std::size_t c = 0; c < C; ++c) {
      Eigen::Vector2d p;
      if (!samus.plane_coordinates(candidates[c].u_eci, observer_eci, p)) continue;
      const Eigen::Matrix2d S = pr.cov + std::pow(candidates[c].sigma_rad, 2) * Eigen::Matrix2d::Identity();
      d2(static_cast<Eigen::Index>(c), static_cast<Eigen::Index>(k)) = (p - pr.p).dot(S.ldlt().solve(p - pr.p));
    }
  }
  const double ambig2 = up_.tuning.sod.eps_ambig * up_.tuning.sod.eps_ambig;
  for (std::size_t k = 0; k < K; ++k) {
    if (!have[k] || !(width[k] < opt_.direct_max_sigma_rad)) continue;
    if (tracked(static_cast<int>(k), t)) continue;
    if (predicted_eclipsed(f, static_cast<int>(k), image_time(t))) continue;
    int hit = -1, hits = 0;
    for (std::size_t c = 0; c < C; ++c) {
      if (std::find(taken.begin(), taken.end(), static_cast<int>(c)) != taken.end()) continue;
      if (!(d2(static_cast<Eigen::Index>(c), static_cast<Eigen::Index>(k)) <= opt_.direct_gate_chi2)) continue;
      bool ambiguous = false;
      for (std::size_t p = 0; p < K; ++p) {
        if (p != k && d2(static_cast<Eigen::Index>(c), static_cast<Eigen::Index>(p)) < ambig2) ambiguous = true;
      }
      if (ambiguous) continue;
      hit = static_cast<int>(c);
      ++hits;
    }
    if (hits != 1) continue;
    used.push_back({hit, static_cast<int>(k), width[k]});
  }
  return used;
}

bool Navigator::predicted_eclipsed(const sod::SodFilter& f, int k, astro::TimeTT t) const {
  if (!opt_.skip_eclipsed_targets) return false;
  Eigen::VectorXd mean;
  Eigen::MatrixXd P;
  observer_target_block(f, k, mean, P);
  return in_umbra(mean, P, t);
}

bool Navigator::in_umbra(const Eigen::VectorXd& mean, const Eigen::MatrixXd& P, astro::TimeTT t) const {
  if (!opt_.skip_eclipsed_targets) return false;
  const astro::Vec3 r_sun = dynamics::sun_position_eci_m(t);
  const auto lit = [&](const Eigen::VectorXd& s) {
    const auto o = astro::QnsElements::from_vector(s.head<6>());
    const auto r = astro::cartesian_from_qns(astro::qns_from_roe(o, astro::Roe::from_vector(s.tail<6>()))).r_m;
    return dynamics::sunlit_fraction(r, r_sun, dynamics::ShadowModel::kConical) > 0.0;
  };
  if (lit(mean)) return false;
  // The same sigma points as untracked_regions' (spread sqrt(12) sigma).
  const Eigen::LLT<Eigen::MatrixXd> llt(P * 12.0);
  if (llt.info() != Eigen::Success) return false;
  const Eigen::MatrixXd L = llt.matrixL();
  for (Eigen::Index i = 0; i < 12; ++i) {
    if (lit(mean + L.col(i)) || lit(mean - L.col(i))) return false;
  }
  return true;
}

bool Navigator::tracked(int k, astro::TimeTT t) const {
  return std::any_of(tracks_.begin(), tracks_.end(), [&](const auto& kv) {
    return kv.second.target == k && astro::seconds_between(kv.second.last, t) < 1800.0;
  });
}

std::vector<Navigator::PixelRegion> Navigator::untracked_regions(astro::TimeTT t, const PixelOf& pixel_of) const {
  std::vector<PixelRegion> out;
  if (!filter_ || reinit_pending_) return out;
  const sod::SodFilter* fp = predicted_to(image_time(t));
  if (!fp) return out;
  const sod::SodFilter& f = *fp;
  for (int k = 0; k < static_cast<int>(target_ids_.size()); ++k) {
    if (!has_estimate_[static_cast<std::size_t>(k)] || tracked(k, t)) continue;
    // Unscented transform of [observer QNS; target ROE] through the pixel of the line of sight.
    Eigen::VectorXd mean;
    Eigen::MatrixXd P;
    observer_target_block(f, k, mean, P);
    if (in_umbra(mean, P, image_time(t))) {
      ++eclipsed_skipped_;
      continue;
    }
    const Eigen::LLT<Eigen::MatrixXd> llt(P * 12.0);
    if (llt.info() != Eigen::Success) continue;
    const Eigen::MatrixXd L = llt.matrixL();
    std::vector<Eigen::Vector2d> pts;
    for (Eigen::Index i = 0; i < 12 && pts.size() == static_cast<std::size_t>(2 * i); ++i) {
      for (const double sgn : {1.0, -1.0}) {
        const auto px = pixel_of(los_eci_of(mean + sgn * L.col(i)).normalized());
        if (px) pts.push_back(*px);
      }
    }
    if (pts.size() != 24) continue;  // partly off the sensor
    PixelRegion r;
    r.target = k;
    r.px.setZero();
    for (const auto& p : pts) r.px += p;
    r.px /= 24.0;
    r.cov_px2.setZero();
    for (const auto& p : pts) r.cov_px2 += (p - r.px) * (p - r.px).transpose();
    r.cov_px2 /= 24.0;
    out.push_back(r);
  }
  return out;
}

std::vector<imp::TargetPrediction> Navigator::predictions(astro::TimeTT t, const imp::Samus& samus) const {
  std::vector<imp::TargetPrediction> out;
  if (!filter_ || reinit_pending_) return out;
  const sod::SodFilter* f = nullptr;
  for (const auto& [tid, as] : tracks_) {
    if (as.target < 0 || astro::seconds_between(as.last, t) > 1800.0) continue;
    const astro::Vec6 a_roe = filter_->a_roe_m(as.target);
    const astro::Vec6 sig = filter_->a_roe_sigma_m(as.target);
    if (!(sig[1] < opt_.aided_max_dlambda_fraction * a_roe.head<2>().norm())) continue;
    // SAMUS projects the frame's candidates with the observer at the frame's
    // time tag t; the image saw the target at image_time(t) (PSE flight,
    // -0.4 s tags: predicted at t, SOD's prediction was 3.9e-4 rad
    // (n * 0.4 s) off every candidate, beyond the aided gate, and SV2's
    // tracks broke every third of an orbit).
    if (!f && !(f = predicted_to(image_time(t)))) return out;
    imp::TargetPrediction p;
    if (predict_plane(*f, as.target, samus, p, t)) {
      p.track_id = tid;
      out.push_back(p);
    }
  }
  return out;
}

}  // namespace artms::fsw
