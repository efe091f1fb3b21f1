#include "artms/runtime/wire.hpp"

#include <algorithm>

namespace artms::runtime {

namespace {

template <std::size_t N>
std::string str(const char (&field)[N]) {
  return dds::to_string(field, N);
}
template <std::size_t N>
void set(char (&field)[N], const std::string& s) {
  dds::copy_string(field, N, s);
}
template <typename T, std::size_t N>
void copy(const T (&from)[N], std::array<T, N>& to) {
  std::copy(from, from + N, to.begin());
}
template <typename T, std::size_t N>
void copy(const std::array<T, N>& from, T (&to)[N]) {
  std::copy(from.begin(), from.end(), to);
}
// A DDS sequence viewing a vector's buffer (not owned: _release false).
template <typename Seq, typename T>
void view(Seq& seq, std::vector<T>& v) {
  seq._buffer = v.data();
  seq._length = seq._maximum = static_cast<std::uint32_t>(v.size());
  seq._release = false;
}

bus::BearingMeasurement plain(const artms_msg_BearingMeasurement& m) {
  bus::BearingMeasurement b;
  b.t_tt_ns = m.t_tt_ns;
  b.track = str(m.track);
  copy(m.u_eci, b.u_eci);
  b.sigma_rad = m.sigma_rad;
  return b;
}
artms_msg_BearingMeasurement wire(const bus::BearingMeasurement& b) {
  artms_msg_BearingMeasurement m{};
  m.t_tt_ns = b.t_tt_ns;
  set(m.track, b.track);
  copy(b.u_eci, m.u_eci);
  m.sigma_rad = b.sigma_rad;
  return m;
}

}  // namespace

bus::Tick from_wire(const artms_msg_ClockTick& m) { return {m.step, m.t_tt_ns, m.final_step}; }

bus::TruthState from_wire(const artms_msg_TruthState& m) {
  bus::TruthState s;
  s.spacecraft = str(m.spacecraft);
  s.t_tt_ns = m.t_tt_ns;
  copy(m.r_eci_m, s.r_eci_m);
  copy(m.v_eci_mps, s.v_eci_mps);
  copy(m.q_body_from_eci, s.q_body_from_eci);
  return s;
}
void write(dds::Writer<artms_msg_TruthState>& w, const bus::TruthState& s) {
  artms_msg_TruthState m{};
  set(m.spacecraft, s.spacecraft);
  m.t_tt_ns = s.t_tt_ns;
  copy(s.r_eci_m, m.r_eci_m);
  copy(s.v_eci_mps, m.v_eci_mps);
  copy(s.q_body_from_eci, m.q_body_from_eci);
  w.write(m);
}

bus::GnssFix from_wire(const artms_msg_GnssFix& m) {
  bus::GnssFix f;
  f.spacecraft = str(m.spacecraft);
  f.t_tt_ns = m.t_tt_ns;
  f.valid = m.valid;
  copy(m.r_eci_m, f.r_eci_m);
  copy(m.v_eci_mps, f.v_eci_mps);
  f.sigma_position_m = m.sigma_position_m;
  f.sigma_velocity_mps = m.sigma_velocity_mps;
  return f;
}
void write(dds::Writer<artms_msg_GnssFix>& w, const bus::GnssFix& f) {
  artms_msg_GnssFix m{};
  set(m.spacecraft, f.spacecraft);
  m.t_tt_ns = f.t_tt_ns;
  m.valid = f.valid;
  copy(f.r_eci_m, m.r_eci_m);
  copy(f.v_eci_mps, m.v_eci_mps);
  m.sigma_position_m = f.sigma_position_m;
  m.sigma_velocity_mps = f.sigma_velocity_mps;
  w.write(m);
}

bus::CameraFrame from_wire(const artms_msg_CameraFrame& m) {
  bus::CameraFrame f;
  f.observer = str(m.observer);
  f.camera = str(m.camera);
  f.frame_seq = m.frame_seq;
  f.time_tag_tt_ns = m.time_tag_tt_ns;
  f.width = m.width;
  f.height = m.height;
  f.bit_depth = m.bit_depth;
  if (m.pixels._buffer != nullptr) f.pixels.assign(m.pixels._buffer, m.pixels._buffer + m.pixels._length);
  return f;
}
void write(dds::Writer<artms_msg_CameraFrame>& w, const bus::CameraFrame& f) {
  artms_msg_CameraFrame m{};
  set(m.observer, f.observer);
  set(m.camera, f.camera);
  m.frame_seq = f.frame_seq;
  m.time_tag_tt_ns = f.time_tag_tt_ns;
  m.width = f.width;
  m.height = f.height;
  m.bit_depth = f.bit_depth;
  m.pixels._buffer = const_cast<std::uint16_t*>(f.pixels.data());  // read only by the writer
  m.pixels._length = m.pixels._maximum = static_cast<std::uint32_t>(f.pixels.size());
  m.pixels._release = false;
  w.write(m);
}

bus::FrameTruth from_wire(const artms_msg_FrameTruth& m) {
  bus::FrameTruth f;
  f.observer = str(m.observer);
  f.frame_seq = m.frame_seq;
  f.t_tt_ns = m.t_tt_ns;
  f.time_tag_tt_ns = m.time_tag_tt_ns;
  f.dropped = m.dropped;
  f.exclusion = str(m.exclusion);
  copy(m.q_cam_from_eci, f.q_cam_from_eci);
  f.stars_used = m.stars_used;
  for (std::uint32_t k = 0; k < m.targets._length; ++k) {
    const auto& t = m.targets._buffer[k];
    f.targets.push_back({str(t.target), t.x_px, t.y_px, t.vmag, t.range_m, t.visible, str(t.reason)});
  }
  return f;
}
void write(dds::Writer<artms_msg_FrameTruth>& w, const bus::FrameTruth& f) {
  artms_msg_FrameTruth m{};
  set(m.observer, f.observer);
  m.frame_seq = f.frame_seq;
  m.t_tt_ns = f.t_tt_ns;
  m.time_tag_tt_ns = f.time_tag_tt_ns;
  m.dropped = f.dropped;
  set(m.exclusion, f.exclusion);
  copy(f.q_cam_from_eci, m.q_cam_from_eci);
  m.stars_used = f.stars_used;
  std::vector<artms_msg_TargetPixel> tp(f.targets.size());
  for (std::size_t k = 0; k < f.targets.size(); ++k) {
    const auto& t = f.targets[k];
    set(tp[k].target, t.target);
    tp[k].x_px = t.x_px;
    tp[k].y_px = t.y_px;
    tp[k].vmag = t.vmag;
    tp[k].range_m = t.range_m;
    tp[k].visible = t.visible;
    set(tp[k].reason, t.reason);
  }
  view(m.targets, tp);
  w.write(m);
}

bus::ImpReport from_wire(const artms_msg_ImpReport& m) {
  bus::ImpReport r;
  r.observer = str(m.observer);
  r.frame_seq = m.frame_seq;
  r.t_tt_ns = m.t_tt_ns;
  r.status = static_cast<bus::FrameStatus>(m.status);
  copy(m.q_cam_from_eci, r.q_cam_from_eci);
  r.stars_matched = m.stars_matched;
  r.residual_arcsec = m.residual_arcsec;
  r.attitude_sigma_arcsec = m.attitude_sigma_arcsec;
  r.candidates = m.candidates;
  r.hot_pixels_removed = m.hot_pixels_removed;
  r.uncatalogued_stars_removed = m.uncatalogued_stars_removed;
  for (std::uint32_t k = 0; k < m.measurements._length; ++k) {
    const auto& x = m.measurements._buffer[k];
    bus::ImpMeasurement i;
    i.frame_seq = x.frame_seq;
    i.t_tt_ns = x.t_tt_ns;
    i.track_id = x.track_id;
    i.x_px = x.x_px;
    i.y_px = x.y_px;
    copy(x.u_eci, i.u_eci);
    i.az_rad = x.az_rad;
    i.el_rad = x.el_rad;
    i.sigma_rad = x.sigma_rad;
    r.measurements.push_back(i);
  }
  return r;
}
void write(dds::Writer<artms_msg_ImpReport>& w, const bus::ImpReport& r) {
  artms_msg_ImpReport m{};
  set(m.observer, r.observer);
  m.frame_seq = r.frame_seq;
  m.t_tt_ns = r.t_tt_ns;
  m.status = static_cast<std::uint8_t>(r.status);
  copy(r.q_cam_from_eci, m.q_cam_from_eci);
  m.stars_matched = r.stars_matched;
  m.residual_arcsec = r.residual_arcsec;
  m.attitude_sigma_arcsec = r.attitude_sigma_arcsec;
  m.candidates = r.candidates;
  m.hot_pixels_removed = r.hot_pixels_removed;
  m.uncatalogued_stars_removed = r.uncatalogued_stars_removed;
  std::vector<artms_msg_ImpMeasurement> meas(r.measurements.size());
  for (std::size_t k = 0; k < meas.size(); ++k) {
    const auto& i = r.measurements[k];
    auto& x = meas[k];
    x.frame_seq = i.frame_seq;
    x.t_tt_ns = i.t_tt_ns;
    x.track_id = i.track_id;
    x.x_px = i.x_px;
    x.y_px = i.y_px;
    copy(i.u_eci, x.u_eci);
    x.az_rad = i.az_rad;
    x.el_rad = i.el_rad;
    x.sigma_rad = i.sigma_rad;
  }
  view(m.measurements, meas);
  w.write(m);
}

bus::IslBroadcast from_wire(const artms_msg_IslBroadcast& m) {
  bus::IslBroadcast b;
  b.sender = str(m.sender);
  b.t_tt_ns = m.t_tt_ns;
  b.broadcast_seq = m.broadcast_seq;
  copy(m.r_eci_m, b.r_eci_m);
  copy(m.v_eci_mps, b.v_eci_mps);
  copy(m.covariance_rv, b.covariance_rv);
  b.source = m.source;
  b.reinitialising = m.reinitialising;
  for (std::uint32_t k = 0; k < m.measurements._length; ++k) b.measurements.push_back(plain(m.measurements._buffer[k]));
  b.receiver = str(m.receiver);
  b.t_relayed_tt_ns = m.t_relayed_tt_ns;
  return b;
}
void write(dds::Writer<artms_msg_IslBroadcast>& w, const bus::IslBroadcast& b) {
  artms_msg_IslBroadcast m{};
  set(m.sender, b.sender);
  m.t_tt_ns = b.t_tt_ns;
  m.broadcast_seq = b.broadcast_seq;
  copy(b.r_eci_m, m.r_eci_m);
  copy(b.v_eci_mps, m.v_eci_mps);
  copy(b.covariance_rv, m.covariance_rv);
  m.source = b.source;
  m.reinitialising = b.reinitialising;
  std::vector<artms_msg_BearingMeasurement> meas;
  meas.reserve(b.measurements.size());
  for (const auto& x : b.measurements) meas.push_back(wire(x));
  view(m.measurements, meas);
  set(m.receiver, b.receiver);
  m.t_relayed_tt_ns = b.t_relayed_tt_ns;
  w.write(m);
}

bus::IslOutcome from_wire(const artms_msg_IslOutcome& m) {
  bus::IslOutcome o;
  o.sender = str(m.sender);
  o.receiver = str(m.receiver);
  o.broadcast_seq = m.broadcast_seq;
  o.t_sent_tt_ns = m.t_sent_tt_ns;
  o.t_tt_ns = m.t_tt_ns;
  o.delivered = m.delivered;
  o.reason = str(m.reason);
  o.source = m.source;
  o.measurements = m.measurements;
  o.range_m = m.range_m;
  return o;
}
void write(dds::Writer<artms_msg_IslOutcome>& w, const bus::IslOutcome& o) {
  artms_msg_IslOutcome m{};
  set(m.sender, o.sender);
  set(m.receiver, o.receiver);
  m.broadcast_seq = o.broadcast_seq;
  m.t_sent_tt_ns = o.t_sent_tt_ns;
  m.t_tt_ns = o.t_tt_ns;
  m.delivered = o.delivered;
  set(m.reason, o.reason);
  m.source = o.source;
  m.measurements = o.measurements;
  m.range_m = o.range_m;
  w.write(m);
}

bus::NavTelemetry from_wire(const artms_msg_NavTelemetry& m) {
  bus::NavTelemetry n;
  n.observer = str(m.observer);
  n.t_tt_ns = m.t_tt_ns;
  n.mode = m.mode;
  n.health = static_cast<bus::Health>(m.health);
  n.source = static_cast<bus::SolutionSource>(m.source);
  copy(m.r_eci_m, n.r_eci_m);
  copy(m.v_eci_mps, n.v_eci_mps);
  copy(m.covariance_rv, n.covariance_rv);
  n.frames_received = m.frames_received;
  for (std::uint32_t k = 0; k < m.targets._length; ++k) {
    const auto& e = m.targets._buffer[k];
    bus::TargetEstimate t;
    t.target = str(e.target);
    copy(e.roe, t.roe);
    copy(e.covariance_roe, t.covariance_roe);
    t.local_measurements = e.local_measurements;
    t.remote_measurements = e.remote_measurements;
    t.bearing_nis_sum = e.bearing_nis_sum;
    t.bearing_updates = e.bearing_updates;
    t.health = static_cast<bus::Health>(e.health);
    n.targets.push_back(t);
  }
  n.isl_sent = m.isl_sent;
  n.isl_received = m.isl_received;
  n.isl_rejected = m.isl_rejected;
  return n;
}
void write(dds::Writer<artms_msg_NavTelemetry>& w, const bus::NavTelemetry& n) {
  artms_msg_NavTelemetry m{};
  set(m.observer, n.observer);
  m.t_tt_ns = n.t_tt_ns;
  m.mode = n.mode;
  m.health = static_cast<std::uint8_t>(n.health);
  m.source = static_cast<std::uint8_t>(n.source);
  copy(n.r_eci_m, m.r_eci_m);
  copy(n.v_eci_mps, m.v_eci_mps);
  copy(n.covariance_rv, m.covariance_rv);
  m.frames_received = n.frames_received;
  std::vector<artms_msg_TargetEstimate> est(n.targets.size());
  for (std::size_t k = 0; k < est.size(); ++k) {
    const auto& t = n.targets[k];
    set(est[k].target, t.target);
    copy(t.roe, est[k].roe);
    copy(t.covariance_roe, est[k].covariance_roe);
    est[k].local_measurements = t.local_measurements;
    est[k].remote_measurements = t.remote_measurements;
    est[k].bearing_nis_sum = t.bearing_nis_sum;
    est[k].bearing_updates = t.bearing_updates;
    est[k].health = static_cast<std::uint8_t>(t.health);
  }
  view(m.targets, est);
  m.isl_sent = n.isl_sent;
  m.isl_received = n.isl_received;
  m.isl_rejected = n.isl_rejected;
  w.write(m);
}

bus::LinkState from_wire(const artms_msg_LinkState& m) {
  return {str(m.from_id), str(m.to_id), m.t_tt_ns, m.up, str(m.reason)};
}
void write(dds::Writer<artms_msg_LinkState>& w, const bus::LinkState& l) {
  artms_msg_LinkState m{};
  set(m.from_id, l.from_id);
  set(m.to_id, l.to_id);
  m.t_tt_ns = l.t_tt_ns;
  m.up = l.up;
  set(m.reason, l.reason);
  w.write(m);
}

bus::Event from_wire(const artms_msg_Event& m) {
  return {str(m.source), m.t_tt_ns, static_cast<bus::Severity>(std::min<int>(m.severity, 2)), str(m.text)};
}
void write(dds::Writer<artms_msg_Event>& w, const bus::Event& e) {
  artms_msg_Event m{};
  set(m.source, e.source);
  m.t_tt_ns = e.t_tt_ns;
  m.severity = static_cast<std::uint8_t>(e.severity);
  set(m.text, e.text);
  w.write(m);
}

bus::BodAttempt from_wire(const artms_msg_BodAttempt& m) {
  bus::BodAttempt b;
  b.observer = str(m.observer);
  b.attempt = m.attempt;
  b.t_est_tt_ns = m.t_est_tt_ns;
  b.track = m.track;
  b.target = str(m.target);
  b.verdict = static_cast<bus::BodVerdict>(m.verdict);  // raw: the recorder refuses unknown codes
  b.why = str(m.why);
  b.action = str(m.action);
  b.measurements = m.measurements;
  b.iterations = m.iterations;
  b.residual_rms_rad = m.residual_rms_rad;
  b.correlation_inflation = m.correlation_inflation;
  b.model_correction_rms_rad = m.model_correction_rms_rad;
  b.uncorrected_range_m = m.uncorrected_range_m;
  b.a_observer_m = m.a_observer_m;
  b.range_m = m.range_m;
  b.sigma_range_m = m.sigma_range_m;
  copy(m.a_roe_mean_m, b.a_roe_mean_m);
  copy(m.covariance_a_roe_m2, b.covariance_a_roe_m2);
  b.mahalanobis2 = m.mahalanobis2;
  for (std::uint32_t k = 0; k < m.curve._length; ++k) {
    const auto& x = m.curve._buffer[k];
    b.curve.push_back({x.a_dlambda_m, x.residual_rms_rad, x.chi2, x.converged});
  }
  return b;
}
artms_msg_BodAttempt to_wire(const bus::BodAttempt& b, std::vector<artms_msg_BodSample>& curve) {
  artms_msg_BodAttempt m{};
  set(m.observer, b.observer);
  m.attempt = b.attempt;
  m.t_est_tt_ns = b.t_est_tt_ns;
  m.track = b.track;
  set(m.target, b.target);
  m.verdict = static_cast<std::uint8_t>(b.verdict);
  set(m.why, b.why);
  set(m.action, b.action);
  m.measurements = b.measurements;
  m.iterations = b.iterations;
  m.residual_rms_rad = b.residual_rms_rad;
  m.correlation_inflation = b.correlation_inflation;
  m.model_correction_rms_rad = b.model_correction_rms_rad;
  m.uncorrected_range_m = b.uncorrected_range_m;
  m.a_observer_m = b.a_observer_m;
  m.range_m = b.range_m;
  m.sigma_range_m = b.sigma_range_m;
  copy(b.a_roe_mean_m, m.a_roe_mean_m);
  copy(b.covariance_a_roe_m2, m.covariance_a_roe_m2);
  m.mahalanobis2 = b.mahalanobis2;
  curve.clear();
  for (std::size_t k = 0; k < b.curve.size() && k < bus::kMaxBodSamples; ++k) {
    const auto& x = b.curve[k];
    curve.push_back({x.a_dlambda_m, x.residual_rms_rad, x.chi2, x.converged});
  }
  view(m.curve, curve);
  return m;
}
void write(dds::Writer<artms_msg_BodAttempt>& w, const bus::BodAttempt& b) {
  std::vector<artms_msg_BodSample> curve;
  const artms_msg_BodAttempt m = to_wire(b, curve);
  w.write(m);
}

}  // namespace artms::runtime
