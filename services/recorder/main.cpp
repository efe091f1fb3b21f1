// artms-recorder: records every topic of a run into the run folder
// (DESIGN.md section 8): truth.oem, nav/<observer>.csv, gnss.csv, isl.csv,
// events.log, imp/<observer>/{attitude,measurements}.csv. Output is deterministic: samples are buffered and written in
// (time, source) order once a step is complete (everything stamped before
// tick k has been acknowledged by the time tick k arrives).
#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <limits>
#include <tuple>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <vector>

#include "artms/io/oem.hpp"
#include "artms/runtime/runtime.hpp"

namespace {

using namespace artms;
namespace fs = std::filesystem;

struct Line {
  std::int64_t t;
  std::string source;
  std::size_t order;  // arrival order within one source (DDS keeps it per writer)
  std::string text;
};

class SortedSink {
 public:
  explicit SortedSink(const fs::path& path, const std::string& header) : out_(path) {
    if (!out_) throw std::runtime_error("cannot write " + path.string());
    if (!header.empty()) out_ << header << "\n";
  }
  void add(std::int64_t t, const std::string& source, std::string text) {
    pending_.push_back({t, source, counter_[source]++, std::move(text)});
  }
  // Writes every line stamped strictly before `t_limit` (all when t_limit is max).
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
  std::ofstream out_;
  std::vector<Line> pending_;
  std::map<std::string, std::size_t> counter_;
};

std::string fmt(const char* format, ...) __attribute__((format(printf, 1, 2)));
std::string fmt(const char* format, ...) {
  char buf[1024];
  va_list ap;
  va_start(ap, format);
  std::vsnprintf(buf, sizeof buf, format, ap);
  va_end(ap);
  return buf;
}

int run(const runtime::ServiceOptions& opt) {
  const config::Scenario sc = runtime::load_for_service(opt);
  const fs::path dir(opt.out_dir);
  fs::create_directories(dir / "nav");
  dds::Participant participant(dds::domain_from_environment());
  runtime::TopicSet topics(participant);
  runtime::LockStepClient clock(participant, topics, opt.name, opt.step_timeout_s);
  const auto q = runtime::data_qos();
  dds::Reader<artms_msg_TruthState> truth_reader(participant, topics.truth_state, q);
  dds::Reader<artms_msg_GnssFix> gnss_reader(participant, topics.gnss_fix, q);
  dds::Reader<artms_msg_NavTelemetry> nav_reader(participant, topics.nav_telemetry, q);
  dds::Reader<artms_msg_Event> event_reader(participant, topics.event, q);
  dds::Reader<artms_msg_LinkState> link_reader(participant, topics.link_state, q);
  dds::Reader<artms_msg_IslOutcome> isl_reader(participant, topics.isl_outcome, q);
  dds::Reader<artms_msg_FrameTruth> frame_truth_reader(participant, topics.frame_truth, q);
  dds::Reader<artms_msg_ImpReport> imp_reader(participant, topics.imp_report, q);

  std::map<std::string, std::unique_ptr<SortedSink>> nav;
  for (const auto& o : sc.observers) {
    nav[o.spacecraft] = std::make_unique<SortedSink>(
        dir / "nav" / (o.spacecraft + ".csv"),
        "t_utc,t_tt_ns,mode,health,source,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps,"
        "sigma_x_m,sigma_y_m,sigma_z_m,sigma_vx_mps,sigma_vy_mps,sigma_vz_mps,targets,frames_received,isl_sent,isl_received,isl_rejected");
  }
  // IMP telemetry per observer, the columns of artms-imp (DESIGN.md section 7).
  // Measurements are decided by SAMUS a few frames late: that file is
  // written sorted by frame time, two simulated hours behind the clock.
  std::map<std::string, std::unique_ptr<SortedSink>> imp_attitude, imp_meas;
  for (const auto& o : sc.observers) {
    fs::create_directories(dir / "imp" / o.spacecraft);
    imp_attitude[o.spacecraft] = std::make_unique<SortedSink>(
        dir / "imp" / o.spacecraft / "attitude.csv",
        "frame,t_tt_ns,status,qw,qx,qy,qz,stars_matched,residual_arcsec,attitude_sigma_arcsec,candidates,"
        "hot_pixels_removed,"
        "uncatalogued_stars_removed");
    imp_meas[o.spacecraft] = std::make_unique<SortedSink>(
        dir / "imp" / o.spacecraft / "measurements.csv",
        "frame,t_tt_ns,track_id,x_px,y_px,ux_eci,uy_eci,uz_eci,az_rad,el_rad,sigma_rad");
  }
  SortedSink targets(dir / "nav" / "targets.csv",
                     "t_utc,t_tt_ns,observer,target,da,dlambda,dex,dey,dix,diy,"
                     "sigma_da,sigma_dlambda,sigma_dex,sigma_dey,sigma_dix,sigma_diy,"
                     "local_measurements,remote_measurements,covariance_upper");
  SortedSink gnss(dir / "gnss.csv", "t_utc,t_tt_ns,spacecraft,valid,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps");
  // One row per (broadcast, directed link): the crosslink emulator's outcome.
  SortedSink isl(dir / "isl.csv",
                 "t_utc,t_tt_ns,sender,receiver,sequence,t_sent_tt_ns,source,measurements,range_m,status,reason");
  SortedSink links(dir / "links.csv", "t_utc,t_tt_ns,from,to,up,reason");
  SortedSink events(dir / "events.log", "");
  SortedSink frames(dir / "frames.csv",
                    "t_utc,t_tt_ns,observer,frame,time_tag_tt_ns,dropped,exclusion,stars,target,x_px,y_px,"
                    "vmag,range_m,visible,reason");
  // Truth samples stream to per-object temporary files (flat memory on long runs).
  io::OemStreamWriter truth((dir / "truth.oem").string(), sc.epoch);

  std::size_t rejected = 0;
  const auto utc = [](std::int64_t t) { return astro::utc_string(astro::TimeTT{t}, 3); };
  const auto drain = [&]() {
    truth_reader.take_each([&](const artms_msg_TruthState& m) {
      const std::string id = dds::to_string(m.spacecraft, sizeof m.spacecraft);
      try {
        truth.add(id, {astro::TimeTT{m.t_tt_ns},
                       {astro::Vec3(m.r_eci_m[0], m.r_eci_m[1], m.r_eci_m[2]),
                        astro::Vec3(m.v_eci_mps[0], m.v_eci_mps[1], m.v_eci_mps[2])}});
      } catch (const std::invalid_argument&) {
        ++rejected;  // not after the previous sample of that object
      }
    });
    gnss_reader.take_each([&](const artms_msg_GnssFix& f) {
      const std::string id = dds::to_string(f.spacecraft, sizeof f.spacecraft);
      gnss.add(f.t_tt_ns, id,
               fmt("%s,%lld,%s,%d,%.3f,%.3f,%.3f,%.6f,%.6f,%.6f", utc(f.t_tt_ns).c_str(),
                   static_cast<long long>(f.t_tt_ns), id.c_str(), f.valid ? 1 : 0, f.r_eci_m[0],
                   f.r_eci_m[1], f.r_eci_m[2], f.v_eci_mps[0], f.v_eci_mps[1], f.v_eci_mps[2]));
    });
    nav_reader.take_each([&](const artms_msg_NavTelemetry& m) {
      const std::string id = dds::to_string(m.observer, sizeof m.observer);
      auto it = nav.find(id);
      if (it == nav.end()) {
        ++rejected;
        return;
      }
      const auto sd = [&](int i) { return std::sqrt(std::max(0.0, m.covariance_rv[i * 6 + i])); };
      it->second->add(
          m.t_tt_ns, id,
          fmt("%s,%lld,%d,%d,%d,%.3f,%.3f,%.3f,%.6f,%.6f,%.6f,%.3f,%.3f,%.3f,%.6f,%.6f,%.6f,%u,%u,%u,%u,%u",
              utc(m.t_tt_ns).c_str(), static_cast<long long>(m.t_tt_ns), m.mode, m.health, m.source,
              m.r_eci_m[0], m.r_eci_m[1], m.r_eci_m[2], m.v_eci_mps[0], m.v_eci_mps[1],
              m.v_eci_mps[2], sd(0), sd(1), sd(2), sd(3), sd(4), sd(5), m.targets._length,
              m.frames_received, m.isl_sent, m.isl_received, m.isl_rejected));
      for (std::uint32_t k = 0; k < m.targets._length; ++k) {
        const auto& e = m.targets._buffer[k];
        std::string line = fmt("%s,%lld,%s,%s", utc(m.t_tt_ns).c_str(),
                               static_cast<long long>(m.t_tt_ns), id.c_str(),
                               dds::to_string(e.target, sizeof e.target).c_str());
        for (int i = 0; i < 6; ++i) line += fmt(",%.9e", e.roe[i]);
        for (int i = 0; i < 6; ++i) line += fmt(",%.9e", std::sqrt(std::max(0.0, e.covariance_roe[i * 6 + i])));
        line += fmt(",%u,%u,", e.local_measurements, e.remote_measurements);
        // Full covariance (dimensionless ROE), upper triangle row by row,
        // space-separated in one column (for NEES in the evaluation).
        for (int r = 0; r < 6; ++r) {
          for (int c = r; c < 6; ++c) line += fmt(r == 0 && c == 0 ? "%.9e" : " %.9e", e.covariance_roe[r * 6 + c]);
        }
        targets.add(m.t_tt_ns, id, line);
      }
    });
    event_reader.take_each([&](const artms_msg_Event& e) {
      static const char* kLevel[] = {"info", "warning", "error"};
      const std::string src = dds::to_string(e.source, sizeof e.source);
      events.add(e.t_tt_ns, src,
                 fmt("%s [%s] %s: %s", utc(e.t_tt_ns).c_str(), src.c_str(),
                     kLevel[std::min<int>(e.severity, 2)],
                     dds::to_string(e.text, sizeof e.text).c_str()));
    });
    link_reader.take_each([&](const artms_msg_LinkState& l) {
      const std::string from = dds::to_string(l.from_id, sizeof l.from_id);
      links.add(l.t_tt_ns, from,
                fmt("%s,%lld,%s,%s,%d,%s", utc(l.t_tt_ns).c_str(), static_cast<long long>(l.t_tt_ns),
                    from.c_str(), dds::to_string(l.to_id, sizeof l.to_id).c_str(), l.up ? 1 : 0,
                    dds::to_string(l.reason, sizeof l.reason).c_str()));
    });
    frame_truth_reader.take_each([&](const artms_msg_FrameTruth& f) {
      const std::string obs = dds::to_string(f.observer, sizeof f.observer);
      const std::string head =
          fmt("%s,%lld,%s,%u,%lld,%d,%s,%u", utc(f.t_tt_ns).c_str(), static_cast<long long>(f.t_tt_ns),
              obs.c_str(), f.frame_seq, static_cast<long long>(f.time_tag_tt_ns), f.dropped ? 1 : 0,
              dds::to_string(f.exclusion, sizeof f.exclusion).c_str(), f.stars_used);
      if (f.targets._length == 0) frames.add(f.t_tt_ns, obs, head + ",,,,,,,");
      for (std::uint32_t k = 0; k < f.targets._length; ++k) {
        const auto& tp = f.targets._buffer[k];
        frames.add(f.t_tt_ns, obs,
                   head + fmt(",%s,%.3f,%.3f,%.3f,%.1f,%d,%s", dds::to_string(tp.target, sizeof tp.target).c_str(),
                              tp.x_px, tp.y_px, tp.vmag, tp.range_m, tp.visible ? 1 : 0,
                              dds::to_string(tp.reason, sizeof tp.reason).c_str()));
      }
    });
    imp_reader.take_each([&](const artms_msg_ImpReport& r) {
      const std::string id = dds::to_string(r.observer, sizeof r.observer);
      auto it = imp_attitude.find(id);
      if (it == imp_attitude.end()) {
        ++rejected;
        return;
      }
      static const char* kStatus[] = {"ok", "no_detections", "not_identified", "corrupt", "end"};
      if (r.status == 0) {
        it->second->add(r.t_tt_ns, id,
                        fmt("%u,%lld,ok,%.12f,%.12f,%.12f,%.12f,%u,%.3f,%.3f,%u,%u,%u", r.frame_seq,
                            static_cast<long long>(r.t_tt_ns), r.q_cam_from_eci[0], r.q_cam_from_eci[1],
                            r.q_cam_from_eci[2], r.q_cam_from_eci[3], r.stars_matched, r.residual_arcsec,
                            r.attitude_sigma_arcsec, r.candidates, r.hot_pixels_removed, r.uncatalogued_stars_removed));
      } else if (r.status < 4) {
        it->second->add(r.t_tt_ns, id,
                        fmt("%u,%lld,%s,,,,,%u,,,0,0,0", r.frame_seq, static_cast<long long>(r.t_tt_ns),
                            kStatus[r.status], r.stars_matched));
      }
      for (std::uint32_t k = 0; k < r.measurements._length; ++k) {
        const auto& m = r.measurements._buffer[k];
        imp_meas[id]->add(m.t_tt_ns, id,
                          fmt("%u,%lld,%d,%.4f,%.4f,%.12f,%.12f,%.12f,%.9f,%.9f,%.3e", m.frame_seq,
                              static_cast<long long>(m.t_tt_ns), m.track_id, m.x_px, m.y_px, m.u_eci[0],
                              m.u_eci[1], m.u_eci[2], m.az_rad, m.el_rad, m.sigma_rad));
      }
    });
    isl_reader.take_each([&](const artms_msg_IslOutcome& o) {
      // One writer (the emulator): its order is kept for equal times.
      isl.add(o.t_tt_ns, "crosslink",
              fmt("%s,%lld,%s,%s,%u,%lld,%d,%u,%.1f,%s,%s", utc(o.t_tt_ns).c_str(), static_cast<long long>(o.t_tt_ns),
                  dds::to_string(o.sender, sizeof o.sender).c_str(), dds::to_string(o.receiver, sizeof o.receiver).c_str(),
                  o.broadcast_seq, static_cast<long long>(o.t_sent_tt_ns), o.source, o.measurements, o.range_m,
                  o.delivered ? "delivered" : "dropped", dds::to_string(o.reason, sizeof o.reason).c_str()));
    });
  };
  const auto flush_all = [&](std::int64_t limit) {
    for (auto& [id, sink] : nav) sink->flush(limit);
    for (auto& [id, sink] : imp_attitude) sink->flush(limit);
    // SAMUS decides a measurement at most an hour or so after its frame
    // (initiation, confirmation): measurements are written two hours behind.
    const std::int64_t lagged = limit == std::numeric_limits<std::int64_t>::max() ? limit : limit - 7200LL * 1000000000LL;
    for (auto& [id, sink] : imp_meas) sink->flush(lagged);
    targets.flush(limit);
    gnss.flush(limit);
    isl.flush(limit);
    links.flush(limit);
    events.flush(limit);
    frames.flush(limit);
  };
  const auto write_truth = [&]() {
    std::vector<std::string> order;
    for (const auto& s : sc.spacecraft) order.push_back(s.id);
    truth.finish(order);
  };

  clock.announce_ready(participant, {}, 60.0);
  while (auto tick = clock.wait_tick()) {
    drain();
    // Everything stamped before this tick's time is complete.
    flush_all(tick->final_step ? std::numeric_limits<std::int64_t>::max() : tick->t_tt_ns);
    if (tick->final_step) {
      write_truth();
      if (rejected > 0) std::fprintf(stderr, "[%s] rejected %zu malformed samples\n", opt.name.c_str(), rejected);
      clock.done(tick->step);
      return 0;
    }
    clock.done(tick->step);
  }
  // Stopped (signal) or timed out: keep what was recorded.
  drain();
  flush_all(std::numeric_limits<std::int64_t>::max());
  write_truth();
  std::fprintf(stderr, "[%s] stopped early; run folder holds what was recorded\n", opt.name.c_str());
  return clock.timed_out() ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  return runtime::run_service(argc, argv, "artms-recorder",
                              "Records every topic of a run into the run folder (truth.oem, nav/, gnss.csv, isl.csv,\n"
      "links.csv, events.log), deterministically ordered.",
                              run);
}
