#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <tuple>

#include "artms/astro/constants.hpp"
#include "artms/sim/services.hpp"

namespace artms::sim {

namespace fs = std::filesystem;

namespace {

std::string fmt(const char* format, ...) __attribute__((format(printf, 1, 2)));
std::string fmt(const char* format, ...) {
  char buf[1024];
  va_list ap;
  va_start(ap, format);
  std::vsnprintf(buf, sizeof buf, format, ap);
  va_end(ap);
  return buf;
}

std::string utc(std::int64_t t) { return astro::utc_string(astro::TimeTT{t}, 3); }

// Free text in a CSV field: the run folder's CSV files are never quoted, so
// separators, quotes and line breaks are replaced.
std::string csv_text(const std::string& s) {
  std::string out = s;
  for (char& c : out) {
    if (c == ',') {
      c = ';';
    } else if (c == '"') {
      c = '\'';
    } else if (c == '\n' || c == '\r') {
      c = ' ';
    }
  }
  return out;
}

// A number that may be absent: empty when not finite (or when `absent`).
std::string opt_num(const char* format, double v, bool absent = false) {
  return absent || !std::isfinite(v) ? std::string() : fmt(format, v);
}

constexpr double kRadToArcsec = 1.0 / astro::kArcsecToRad;

// SAMUS decides a measurement at most an hour or so after its frame
// (initiation, confirmation): measurements are written two hours behind.
constexpr std::int64_t kMeasurementLagNs = 7200LL * 1000000000LL;

}  // namespace

// One output file whose lines are written in (time, source, arrival) order.
class Recorder::Sink {
 public:
  Sink(const fs::path& path, const std::string& header) : out_(path) {
    if (!out_) throw std::runtime_error("cannot write " + path.string());
    if (!header.empty()) out_ << header << "\n";
  }
  void add(std::int64_t t, const std::string& source, std::string text) {
    pending_.push_back({t, source, counter_[source]++, std::move(text)});
  }
  // Writes every line stamped strictly before `t_limit`.
  void flush(std::int64_t t_limit) {
    std::stable_sort(pending_.begin(), pending_.end(), [](const Line& a, const Line& b) {
      return std::tie(a.t, a.source, a.order) < std::tie(b.t, b.source, b.order);
    });
    std::size_t n = 0;
    while (n < pending_.size() && pending_[n].t < t_limit) {
      out_ << pending_[n].text << "\n";
      ++n;
    }
    pending_.erase(pending_.begin(), pending_.begin() + static_cast<std::ptrdiff_t>(n));
    out_.flush();
  }

 private:
  struct Line {
    std::int64_t t;
    std::string source;
    std::size_t order;  // arrival order within one source (DDS keeps it per writer)
    std::string text;
  };
  std::ofstream out_;
  std::vector<Line> pending_;
  std::map<std::string, std::size_t> counter_;
};

Recorder::Recorder(const config::Scenario& sc, const std::string& out_dir)
    : sc_(sc), truth_((fs::path(out_dir) / "truth.oem").string(), sc.epoch) {
  const fs::path dir(out_dir);
  fs::create_directories(dir / "nav");
  for (const auto& o : sc.observers) {
    nav_[o.spacecraft] = std::make_unique<Sink>(
        dir / "nav" / (o.spacecraft + ".csv"),
        "t_utc,t_tt_ns,mode,health,source,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps,"
        "sigma_x_m,sigma_y_m,sigma_z_m,sigma_vx_mps,sigma_vy_mps,sigma_vz_mps,targets,frames_received,isl_sent,"
        "isl_received,isl_rejected,covariance_upper");
  }
  // IMP telemetry per observer, the columns of artms-imp (DESIGN.md section 7).
  for (const auto& o : sc.observers) {
    fs::create_directories(dir / "imp" / o.spacecraft);
    imp_attitude_[o.spacecraft] = std::make_unique<Sink>(
        dir / "imp" / o.spacecraft / "attitude.csv",
        "frame,t_tt_ns,status,qw,qx,qy,qz,stars_matched,residual_arcsec,attitude_sigma_arcsec,candidates,"
        "hot_pixels_removed,uncatalogued_stars_removed");
    imp_meas_[o.spacecraft] =
        std::make_unique<Sink>(dir / "imp" / o.spacecraft / "measurements.csv",
                               "frame,t_tt_ns,track_id,x_px,y_px,ux_eci,uy_eci,uz_eci,az_rad,el_rad,sigma_rad");
  }
  targets_ = std::make_unique<Sink>(dir / "nav" / "targets.csv",
                                    "t_utc,t_tt_ns,observer,target,da,dlambda,dex,dey,dix,diy,"
                                    "sigma_da,sigma_dlambda,sigma_dex,sigma_dey,sigma_dix,sigma_diy,"
                                    "local_measurements,remote_measurements,covariance_upper,bearing_nis_sum,"
                                    "bearing_updates,health");
  gnss_ = std::make_unique<Sink>(dir / "gnss.csv", "t_utc,t_tt_ns,spacecraft,valid,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps");
  // One row per (broadcast, directed link): the crosslink emulator's outcome.
  isl_ = std::make_unique<Sink>(
      dir / "isl.csv", "t_utc,t_tt_ns,sender,receiver,sequence,t_sent_tt_ns,source,measurements,range_m,status,reason");
  links_ = std::make_unique<Sink>(dir / "links.csv", "t_utc,t_tt_ns,from,to,up,reason");
  events_ = std::make_unique<Sink>(dir / "events.log", "");
  // BOD telemetry (modes 1-4 run BOD): one row per attempt, one per sample
  // of its residual curve.
  bool any_bod = false;
  for (const auto& o : sc.observers) any_bod = any_bod || (o.mode >= 1 && o.mode <= 4);
  if (any_bod) fs::create_directories(dir / "bod");
  for (const auto& o : sc.observers) {
    if (o.mode < 1 || o.mode > 4) continue;
    bod_[o.spacecraft] = std::make_unique<Sink>(
        dir / "bod" / (o.spacecraft + ".csv"),
        "t_utc,t_tt_ns,observer,attempt,track,target,verdict,verdict_name,measurements,iterations,"
        "residual_rms_arcsec,correlation_inflation,a_observer_m,range_m,sigma_range_m,"
        "a_da_m,a_dlambda_m,a_dex_m,a_dey_m,a_dix_m,a_diy_m,"
        "sigma_a_da_m,sigma_a_dlambda_m,sigma_a_dex_m,sigma_a_dey_m,sigma_a_dix_m,sigma_a_diy_m,"
        "mahalanobis2,model_correction_arcsec,uncorrected_range_m,action,why");
    bod_curves_[o.spacecraft] = std::make_unique<Sink>(dir / "bod" / (o.spacecraft + "_curves.csv"),
                                                       "attempt,sample,a_dlambda_m,residual_rms_arcsec,chi2,converged");
  }
  frames_ = std::make_unique<Sink>(dir / "frames.csv",
                                   "t_utc,t_tt_ns,observer,frame,time_tag_tt_ns,dropped,exclusion,stars,target,x_px,"
                                   "y_px,vmag,range_m,visible,reason");
}

Recorder::~Recorder() {
  try {
    finish();
  } catch (...) {
  }
}

void Recorder::add(const bus::TruthState& m) {
  try {
    truth_.add(m.spacecraft, {astro::TimeTT{m.t_tt_ns},
                              {astro::Vec3(m.r_eci_m[0], m.r_eci_m[1], m.r_eci_m[2]),
                               astro::Vec3(m.v_eci_mps[0], m.v_eci_mps[1], m.v_eci_mps[2])}});
  } catch (const std::invalid_argument&) {
    ++rejected_;  // not after the previous sample of that object
  }
}

void Recorder::add(const bus::GnssFix& f) {
  gnss_->add(f.t_tt_ns, f.spacecraft,
             fmt("%s,%lld,%s,%d,%.3f,%.3f,%.3f,%.6f,%.6f,%.6f", utc(f.t_tt_ns).c_str(),
                 static_cast<long long>(f.t_tt_ns), f.spacecraft.c_str(), f.valid ? 1 : 0, f.r_eci_m[0], f.r_eci_m[1],
                 f.r_eci_m[2], f.v_eci_mps[0], f.v_eci_mps[1], f.v_eci_mps[2]));
}

void Recorder::add(const bus::NavTelemetry& m) {
  auto it = nav_.find(m.observer);
  if (it == nav_.end()) {
    ++rejected_;
    return;
  }
  const auto sd = [&](std::size_t i) { return std::sqrt(std::max(0.0, m.covariance_rv[i * 6 + i])); };
  it->second->add(m.t_tt_ns, m.observer,
                  fmt("%s,%lld,%d,%d,%d,%.3f,%.3f,%.3f,%.6f,%.6f,%.6f,%.3f,%.3f,%.3f,%.6f,%.6f,%.6f,%u,%u,%u,%u,%u",
                      utc(m.t_tt_ns).c_str(), static_cast<long long>(m.t_tt_ns), m.mode, static_cast<int>(m.health),
                      static_cast<int>(m.source), m.r_eci_m[0], m.r_eci_m[1], m.r_eci_m[2], m.v_eci_mps[0],
                      m.v_eci_mps[1], m.v_eci_mps[2], sd(0), sd(1), sd(2), sd(3), sd(4), sd(5),
                      static_cast<unsigned>(m.targets.size()), m.frames_received, m.isl_sent, m.isl_received,
                      m.isl_rejected) +
                      // Full covariance of [r; v] (m, m/s), upper triangle row by row, space-separated in one
                      // column (absolute NEES and RTN sigmas in the evaluation).
                      [&] {
                        std::string c = ",";
                        for (std::size_t r = 0; r < 6; ++r) {
                          for (std::size_t col = r; col < 6; ++col) {
                            c += fmt(r == 0 && col == 0 ? "%.9e" : " %.9e", m.covariance_rv[r * 6 + col]);
                          }
                        }
                        return c;
                      }());
  for (const auto& e : m.targets) {
    std::string line =
        fmt("%s,%lld,%s,%s", utc(m.t_tt_ns).c_str(), static_cast<long long>(m.t_tt_ns), m.observer.c_str(), e.target.c_str());
    for (std::size_t i = 0; i < 6; ++i) line += fmt(",%.9e", e.roe[i]);
    for (std::size_t i = 0; i < 6; ++i) line += fmt(",%.9e", std::sqrt(std::max(0.0, e.covariance_roe[i * 6 + i])));
    line += fmt(",%u,%u,", e.local_measurements, e.remote_measurements);
    // Full covariance (dimensionless ROE), upper triangle row by row,
    // space-separated in one column (for NEES in the evaluation).
    for (std::size_t r = 0; r < 6; ++r) {
      for (std::size_t c = r; c < 6; ++c) line += fmt(r == 0 && c == 0 ? "%.9e" : " %.9e", e.covariance_roe[r * 6 + c]);
    }
    line += fmt(",%.9e,%u,%u", e.bearing_nis_sum, e.bearing_updates, static_cast<unsigned>(e.health));
    targets_->add(m.t_tt_ns, m.observer, line);
  }
}

void Recorder::add(const bus::Event& e) {
  events_->add(e.t_tt_ns, e.source,
               fmt("%s [%s] %s: %s", utc(e.t_tt_ns).c_str(), e.source.c_str(), bus::to_string(e.severity),
                   e.text.c_str()));
}

void Recorder::add(const bus::LinkState& l) {
  links_->add(l.t_tt_ns, l.from_id,
              fmt("%s,%lld,%s,%s,%d,%s", utc(l.t_tt_ns).c_str(), static_cast<long long>(l.t_tt_ns), l.from_id.c_str(),
                  l.to_id.c_str(), l.up ? 1 : 0, l.reason.c_str()));
}

void Recorder::add(const bus::FrameTruth& f) {
  const std::string head = fmt("%s,%lld,%s,%u,%lld,%d,%s,%u", utc(f.t_tt_ns).c_str(), static_cast<long long>(f.t_tt_ns),
                               f.observer.c_str(), f.frame_seq, static_cast<long long>(f.time_tag_tt_ns),
                               f.dropped ? 1 : 0, f.exclusion.c_str(), f.stars_used);
  if (f.targets.empty()) frames_->add(f.t_tt_ns, f.observer, head + ",,,,,,,");
  for (const auto& tp : f.targets) {
    frames_->add(f.t_tt_ns, f.observer,
                 head + fmt(",%s,%.3f,%.3f,%.3f,%.1f,%d,%s", tp.target.c_str(), tp.x_px, tp.y_px, tp.vmag, tp.range_m,
                            tp.visible ? 1 : 0, tp.reason.c_str()));
  }
}

void Recorder::add(const bus::ImpReport& r) {
  auto it = imp_attitude_.find(r.observer);
  if (it == imp_attitude_.end()) {
    ++rejected_;
    return;
  }
  if (r.status == bus::FrameStatus::kOk) {
    it->second->add(r.t_tt_ns, r.observer,
                    fmt("%u,%lld,ok,%.12f,%.12f,%.12f,%.12f,%u,%.3f,%.3f,%u,%u,%u", r.frame_seq,
                        static_cast<long long>(r.t_tt_ns), r.q_cam_from_eci[0], r.q_cam_from_eci[1], r.q_cam_from_eci[2],
                        r.q_cam_from_eci[3], r.stars_matched, r.residual_arcsec, r.attitude_sigma_arcsec, r.candidates,
                        r.hot_pixels_removed, r.uncatalogued_stars_removed));
  } else if (r.status == bus::FrameStatus::kNoDetections || r.status == bus::FrameStatus::kNotIdentified ||
             r.status == bus::FrameStatus::kCorrupt) {
    it->second->add(r.t_tt_ns, r.observer,
                    fmt("%u,%lld,%s,,,,,%u,,,0,0,0", r.frame_seq, static_cast<long long>(r.t_tt_ns),
                        bus::to_string(r.status), r.stars_matched));
  } else if (r.status != bus::FrameStatus::kEnd) {
    ++rejected_;  // an unknown status code
  }
  for (const auto& m : r.measurements) {
    imp_meas_[r.observer]->add(m.t_tt_ns, r.observer,
                               fmt("%u,%lld,%d,%.4f,%.4f,%.12f,%.12f,%.12f,%.9f,%.9f,%.3e", m.frame_seq,
                                   static_cast<long long>(m.t_tt_ns), m.track_id, m.x_px, m.y_px, m.u_eci[0],
                                   m.u_eci[1], m.u_eci[2], m.az_rad, m.el_rad, m.sigma_rad));
  }
}

void Recorder::add(const bus::IslOutcome& o) {
  // One writer (the emulator): its order is kept for equal times.
  isl_->add(o.t_tt_ns, "crosslink",
            fmt("%s,%lld,%s,%s,%u,%lld,%d,%u,%.1f,%s,%s", utc(o.t_tt_ns).c_str(), static_cast<long long>(o.t_tt_ns),
                o.sender.c_str(), o.receiver.c_str(), o.broadcast_seq, static_cast<long long>(o.t_sent_tt_ns), o.source,
                o.measurements, o.range_m, o.delivered ? "delivered" : "dropped", o.reason.c_str()));
}

void Recorder::add(const bus::BodAttempt& b) {
  const auto it = bod_.find(b.observer);
  if (it == bod_.end() || static_cast<std::uint8_t>(b.verdict) > bus::kMaxBodVerdict) {
    ++rejected_;  // an observer without BOD, or an unknown verdict code
    return;
  }
  // The IDL's bounds, so that the files do not depend on whether it crossed DDS.
  const std::size_t samples = std::min(b.curve.size(), bus::kMaxBodSamples);
  bool finite = std::isfinite(b.residual_rms_rad) && std::isfinite(b.correlation_inflation) &&
                std::isfinite(b.a_observer_m) && std::isfinite(b.range_m) && std::isfinite(b.sigma_range_m) &&
                std::isfinite(b.mahalanobis2) && std::isfinite(b.model_correction_rms_rad) &&
                std::isfinite(b.uncorrected_range_m);
  for (double v : b.a_roe_mean_m) finite = finite && std::isfinite(v);
  for (double v : b.covariance_a_roe_m2) finite = finite && std::isfinite(v);
  for (std::size_t k = 0; k < samples; ++k) {
    const auto& c = b.curve[k];
    // An unconverged sample may carry non-finite residuals (written empty).
    finite = finite && std::isfinite(c.a_dlambda_m) &&
             (!c.converged || (std::isfinite(c.residual_rms_rad) && std::isfinite(c.chi2)));
  }
  if (!finite) {
    ++rejected_;
    return;
  }
  const auto sd = [&](std::size_t i) { return std::sqrt(std::max(0.0, b.covariance_a_roe_m2[i * 6 + i])); };
  std::string line = fmt("%s,%lld,%s,%u,%d,%s,%d,%s,%u,%u,%.4f,%.4f,%.3f,%.3f,%.3f", utc(b.t_est_tt_ns).c_str(),
                         static_cast<long long>(b.t_est_tt_ns), b.observer.c_str(), b.attempt, b.track,
                         csv_text(bus::bounded(b.target, bus::kIdChars)).c_str(), static_cast<int>(b.verdict),
                         bus::to_string(b.verdict), b.measurements, b.iterations, b.residual_rms_rad * kRadToArcsec,
                         b.correlation_inflation, b.a_observer_m, b.range_m, b.sigma_range_m);
  for (std::size_t i = 0; i < 6; ++i) line += fmt(",%.3f", b.a_roe_mean_m[i]);
  for (std::size_t i = 0; i < 6; ++i) line += fmt(",%.3f", sd(i));
  // mahalanobis2 < 0: health check 1 was not made (empty).
  for (const std::string& field : {opt_num("%.3f", b.mahalanobis2, b.mahalanobis2 < 0.0),
                                   fmt("%.3f", b.model_correction_rms_rad * kRadToArcsec),
                                   fmt("%.3f", b.uncorrected_range_m),
                                   csv_text(bus::bounded(b.action, bus::kEventTextChars)),
                                   csv_text(bus::bounded(b.why, bus::kEventTextChars))}) {
    line += ',';
    line += field;
  }
  it->second->add(b.t_est_tt_ns, b.observer, std::move(line));
  auto& curves = *bod_curves_.at(b.observer);
  for (std::size_t k = 0; k < samples; ++k) {
    const auto& c = b.curve[k];
    std::string row = fmt("%u,%zu,%.3f,", b.attempt, k, c.a_dlambda_m);
    row += opt_num("%.4f", c.residual_rms_rad * kRadToArcsec);
    row += ',';
    row += opt_num("%.3f", c.chi2);
    row += c.converged ? ",1" : ",0";
    curves.add(b.t_est_tt_ns, b.observer, std::move(row));
  }
}

void Recorder::flush(std::int64_t limit) {
  for (auto& [id, sink] : nav_) sink->flush(limit);
  for (auto& [id, sink] : imp_attitude_) sink->flush(limit);
  const std::int64_t lagged = limit == kAll ? limit : limit - kMeasurementLagNs;
  for (auto& [id, sink] : imp_meas_) sink->flush(lagged);
  targets_->flush(limit);
  gnss_->flush(limit);
  isl_->flush(limit);
  links_->flush(limit);
  events_->flush(limit);
  frames_->flush(limit);
  for (auto& [id, sink] : bod_) sink->flush(limit);
  for (auto& [id, sink] : bod_curves_) sink->flush(limit);
}

void Recorder::on_tick(const bus::Tick& tick) {
  // Everything stamped before this tick's time is complete.
  flush(tick.final_step ? kAll : tick.t_tt_ns);
  if (tick.final_step) finish();
}

void Recorder::finish() {
  if (finished_) return;
  finished_ = true;
  flush(kAll);
  std::vector<std::string> order;
  for (const auto& s : sc_.spacecraft) order.push_back(s.id);
  truth_.finish(order);
}

}  // namespace artms::sim
