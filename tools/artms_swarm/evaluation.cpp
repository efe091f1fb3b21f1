#include "evaluation.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "artms/astro/elements.hpp"
#include "artms/astro/roe.hpp"
#include "artms/io/csv.hpp"
#include "artms/io/oem.hpp"

namespace artms::swarm {

namespace fs = std::filesystem;

std::vector<std::string> split_csv(const std::string& line, char sep) { return io::split_fields(line, sep); }

namespace {

// A run-folder file the evaluation could not read: on stderr and in
// summary.json ("evaluation_errors"), never silently skipped.
void report_error(nlohmann::json& summary, const std::string& what) {
  std::fprintf(stderr, "artms-swarm: evaluation: %s\n", what.c_str());
  summary["evaluation_errors"].push_back(what);
}

struct Row {
  std::int64_t t;
  std::string observer, target;
  astro::Vec6 roe, sigma;
  astro::Mat6 P;
  bool full_P = false;
  long local = 0, remote = 0;
  double nis_sum = 0.0;  // cumulative bearing NIS (nav/targets.csv bearing_nis_sum)
  long nis_n = 0;
  long health = 0;  // the target's own health (nav/targets.csv health; 0 healthy, 1 suspect)
};

std::string fixed(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

constexpr const char* kRoeNames[6] = {"da", "dlambda", "dex", "dey", "dix", "diy"};

}  // namespace

void evaluate_run(const config::Scenario& sc, const fs::path& dir, nlohmann::json& summary) {
  const double period_s = sc.reference_period_s();
  std::map<std::string, std::map<std::int64_t, astro::StateVector>> truth;
  try {
    if (fs::exists(dir / "truth.oem")) {
      for (const auto& seg : io::read_oem_file((dir / "truth.oem").string()).segments) {
        for (const auto& s : seg.samples) truth[seg.object_name][s.t.ns_since_j2000] = s.x_eci;
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "artms-swarm: evaluation: truth.oem unreadable (%s)\n", e.what());
    return;
  }
  fs::create_directories(dir / "eval");
  // Observers: absolute position/velocity errors, in ECI norms and in the
  // true orbit's RTN axes, and the quasi-nonsingular elements' errors times
  // a (the paper's mode-4 figure), each with its 1-sigma; NEES of the
  // position (3 dof) where the full covariance is recorded.
  {
    std::ofstream out(dir / "eval" / "observers.csv");
    out << "t_utc,t_tt_ns,observer,mode,source,pos_err_m,vel_err_mps,sigma_pos_m,sigma_vel_mps,"
           "err_r_m,err_t_m,err_n_m,sigma_r_m,sigma_t_m,sigma_n_m,err_vr_mps,err_vt_mps,err_vn_mps,"
           "sigma_vr_mps,sigma_vt_mps,sigma_vn_mps,err_a_da_m,err_a_du_m,err_a_dex_m,err_a_dey_m,err_a_di_m,"
           "err_a_draan_m,sigma_a_da_m,sigma_a_du_m,sigma_a_dex_m,sigma_a_dey_m,sigma_a_di_m,sigma_a_draan_m,"
           "nees_pos\n";
    for (const auto& o : sc.observers) {
      summary["observers"][o.spacecraft]["period_s"] = period_s;
      const fs::path path = dir / "nav" / (o.spacecraft + ".csv");
      if (!fs::exists(path)) continue;
      struct Abs {
        std::vector<double> t_s, pos, sig_pos, nees;
        std::vector<astro::Vec3> e_rtn, s_rtn, e_vrtn, s_vrtn;
        std::vector<astro::Vec6> e_oe, s_oe;
        std::vector<int> source;
      } a;
      try {
        const auto nav = io::CsvTable::read(path.string());
        const bool full = nav.has("covariance_upper");
        for (std::size_t k = 0; k < nav.size(); ++k) {
          if (nav.text(k, "health") == "2") continue;
          const std::int64_t t = nav.integer(k, "t_tt_ns");
          const auto it = truth[o.spacecraft].find(t);
          if (it == truth[o.spacecraft].end()) continue;
          const astro::StateVector& xt = it->second;
          astro::StateVector x;
          x.r_m = astro::Vec3(nav.number(k, "x_m"), nav.number(k, "y_m"), nav.number(k, "z_m"));
          x.v_mps = astro::Vec3(nav.number(k, "vx_mps"), nav.number(k, "vy_mps"), nav.number(k, "vz_mps"));
          astro::Mat6 P = astro::Mat6::Zero();
          if (full) {
            const auto v = io::split_fields(nav.text(k, "covariance_upper"), ' ');
            if (v.size() != 21) {
              throw std::runtime_error(nav.path() + ":" + std::to_string(nav.line(k)) + ": covariance_upper has " +
                                       std::to_string(v.size()) + " entries, expected 21");
            }
            std::size_t n = 0;
            for (int r = 0; r < 6; ++r) {
              for (int c = r; c < 6; ++c) P(r, c) = P(c, r) = std::stod(v[n++]);
            }
          } else {
            const char* names[6] = {"sigma_x_m", "sigma_y_m", "sigma_z_m", "sigma_vx_mps", "sigma_vy_mps", "sigma_vz_mps"};
            for (int i = 0; i < 6; ++i) P(i, i) = std::pow(nav.number(k, names[i]), 2);
          }
          const astro::Vec3 dr = x.r_m - xt.r_m, dv = x.v_mps - xt.v_mps;
          // RTN axes of the true orbit.
          astro::Mat3 R;
          R.row(0) = xt.r_m.normalized();
          R.row(2) = xt.r_m.cross(xt.v_mps).normalized();
          R.row(1) = R.row(2).cross(R.row(0));
          const astro::Mat3 Pr = R * P.topLeftCorner<3, 3>() * R.transpose();
          const astro::Mat3 Pv = R * P.bottomRightCorner<3, 3>() * R.transpose();
          const astro::Vec3 e_rtn = R * dr, e_vrtn = R * dv;
          const astro::Vec3 s_rtn = Pr.diagonal().cwiseMax(0.0).cwiseSqrt();
          const astro::Vec3 s_vrtn = Pv.diagonal().cwiseMax(0.0).cwiseSqrt();
          // Elements (a, u, ex, ey, i, RAAN) of estimate and truth; errors times a.
          const astro::QnsElements qe = astro::qns_from_cartesian(x), qt = astro::qns_from_cartesian(xt);
          astro::Vec6 e_oe;
          e_oe << qe.a_m - qt.a_m, std::remainder(qe.u_rad - qt.u_rad, 2.0 * M_PI) * qt.a_m, (qe.ex - qt.ex) * qt.a_m,
              (qe.ey - qt.ey) * qt.a_m, (qe.i_rad - qt.i_rad) * qt.a_m,
              std::remainder(qe.raan_rad - qt.raan_rad, 2.0 * M_PI) * qt.a_m;
          const astro::Mat6 J = astro::jacobian_qns_from_cartesian(x);  // rows: a, ex, ey, i, RAAN, u
          const astro::Vec6 var_q = (J * P * J.transpose()).diagonal().cwiseMax(0.0);
          astro::Vec6 s_oe;
          s_oe << std::sqrt(var_q[0]), std::sqrt(var_q[5]) * qt.a_m, std::sqrt(var_q[1]) * qt.a_m,
              std::sqrt(var_q[2]) * qt.a_m, std::sqrt(var_q[3]) * qt.a_m, std::sqrt(var_q[4]) * qt.a_m;
          double nees = std::nan("");
          if (full) {
            const Eigen::LDLT<astro::Mat3> ldlt(P.topLeftCorner<3, 3>());
            if (ldlt.info() == Eigen::Success && ldlt.isPositive()) nees = dr.dot(ldlt.solve(dr));
          }
          const double sr = std::sqrt(std::max(0.0, P.topLeftCorner<3, 3>().trace()));
          const double sv = std::sqrt(std::max(0.0, P.bottomRightCorner<3, 3>().trace()));
          char buf[320];
          std::snprintf(buf, sizeof buf, "%s,%lld,%s,%s,%s,%.3f,%.6f,%.3f,%.6f", nav.text(k, "t_utc").c_str(),
                        static_cast<long long>(t), o.spacecraft.c_str(), nav.text(k, "mode").c_str(),
                        nav.text(k, "source").c_str(), dr.norm(), dv.norm(), sr, sv);
          out << buf;
          for (const astro::Vec3* v : {&e_rtn, &s_rtn}) {
            for (int i = 0; i < 3; ++i) out << "," << fixed((*v)[i], 3);
          }
          for (const astro::Vec3* v : {&e_vrtn, &s_vrtn}) {
            for (int i = 0; i < 3; ++i) out << "," << fixed((*v)[i], 6);
          }
          for (const astro::Vec6* v : {&e_oe, &s_oe}) {
            for (int i = 0; i < 6; ++i) out << "," << fixed((*v)[i], 3);
          }
          std::snprintf(buf, sizeof buf, ",%.4f\n", nees);
          out << buf;
          a.t_s.push_back(static_cast<double>(t - sc.epoch.ns_since_j2000) * 1e-9);
          a.pos.push_back(dr.norm());
          a.sig_pos.push_back(sr);
          a.nees.push_back(nees);
          a.e_rtn.push_back(e_rtn);
          a.s_rtn.push_back(s_rtn);
          a.e_vrtn.push_back(e_vrtn);
          a.s_vrtn.push_back(s_vrtn);
          a.e_oe.push_back(e_oe);
          a.s_oe.push_back(s_oe);
          a.source.push_back(static_cast<int>(nav.integer(k, "source")));
        }
      } catch (const std::exception& e) {
        report_error(summary, e.what());
        continue;
      }
      const std::size_t n = a.t_s.size();
      if (n == 0) continue;
      // The absolute orbit at a glance: first and final errors, how often
      // an RTN component was beyond 3 and 5 sigma, the mean position NEES.
      nlohmann::json j;
      j["initial_position_error_m"] = a.pos.front();
      j["initial_position_sigma_m"] = a.sig_pos.front();
      j["final_error_rtn_m"] = std::vector<double>(a.e_rtn.back().data(), a.e_rtn.back().data() + 3);
      j["final_sigma_rtn_m"] = std::vector<double>(a.s_rtn.back().data(), a.s_rtn.back().data() + 3);
      j["final_error_rtn_mps"] = std::vector<double>(a.e_vrtn.back().data(), a.e_vrtn.back().data() + 3);
      j["final_sigma_rtn_mps"] = std::vector<double>(a.s_vrtn.back().data(), a.s_vrtn.back().data() + 3);
      j["final_error_a_oe_m"] = std::vector<double>(a.e_oe.back().data(), a.e_oe.back().data() + 6);
      j["final_sigma_a_oe_m"] = std::vector<double>(a.s_oe.back().data(), a.s_oe.back().data() + 6);
      j["a_oe_names"] = {"a", "u", "ex", "ey", "i", "raan"};
      j["angles_only_fraction"] =
          static_cast<double>(std::count(a.source.begin(), a.source.end(), 4)) / static_cast<double>(n);
      double max_ratio = 0.0;
      for (std::size_t m = 0; m < n; ++m) {
        for (int i = 0; i < 3; ++i) {
          if (a.s_rtn[m][i] > 0.0) max_ratio = std::max(max_ratio, std::abs(a.e_rtn[m][i]) / a.s_rtn[m][i]);
        }
      }
      j["max_rtn_error_over_sigma"] = max_ratio;
      for (const double n_sigma : {3.0, 5.0}) {
        std::size_t beyond = 0, run = 0, longest = 0;
        for (std::size_t m = 0; m < n; ++m) {
          bool outside = false;
          for (int i = 0; i < 3; ++i) outside = outside || std::abs(a.e_rtn[m][i]) > n_sigma * a.s_rtn[m][i];
          beyond += outside ? 1 : 0;
          run = outside ? run + 1 : 0;
          longest = std::max(longest, run);
        }
        const std::string tag = n_sigma == 3.0 ? "3sigma" : "5sigma";
        const double step_s = n > 1 ? (a.t_s.back() - a.t_s.front()) / static_cast<double>(n - 1) : 0.0;
        j["frac_rtn_beyond_" + tag] = static_cast<double>(beyond) / static_cast<double>(n);
        j["longest_rtn_beyond_" + tag + "_orbits"] = static_cast<double>(longest) * step_s / period_s;
      }
      double nees_sum = 0.0;
      std::size_t nees_n = 0;
      for (double v : a.nees) {
        if (!std::isfinite(v)) continue;
        nees_sum += v;
        ++nees_n;
      }
      j["nees_pos_mean"] = nees_n ? nlohmann::json(nees_sum / static_cast<double>(nees_n)) : nlohmann::json(nullptr);
      // Added to the launcher's final_pos_error_m / final_pos_sigma_m (DESIGN.md).
      for (const auto& [key, value] : j.items()) summary["observers"][o.spacecraft]["absolute"][key] = value;
    }
  }
  // Targets.
  std::vector<Row> rows;
  if (fs::exists(dir / "nav" / "targets.csv")) {
    try {
      const auto tab = io::CsvTable::read((dir / "nav" / "targets.csv").string());
      for (std::size_t k = 0; k < tab.size(); ++k) {
        Row r;
        r.t = tab.integer(k, "t_tt_ns");
        r.observer = tab.text(k, "observer");
        r.target = tab.text(k, "target");
        for (int i = 0; i < 6; ++i) {
          r.roe[i] = tab.number(k, kRoeNames[i]);
          r.sigma[i] = tab.number(k, std::string("sigma_") + kRoeNames[i]);
        }
        r.local = tab.integer(k, "local_measurements");
        r.remote = tab.integer(k, "remote_measurements");
        if (tab.has("health")) r.health = tab.integer(k, "health");
        if (tab.has("bearing_nis_sum")) {
          r.nis_sum = tab.number(k, "bearing_nis_sum");
          r.nis_n = tab.integer(k, "bearing_updates");
        }
        if (tab.has("covariance_upper")) {
          const auto v = io::split_fields(tab.text(k, "covariance_upper"), ' ');
          if (v.size() != 21) {
            throw std::runtime_error(tab.path() + ":" + std::to_string(tab.line(k)) +
                                     ": covariance_upper has " + std::to_string(v.size()) + " entries, expected 21");
          }
          std::size_t n = 0;
          for (int a = 0; a < 6; ++a) {
            for (int b = a; b < 6; ++b) r.P(a, b) = r.P(b, a) = std::stod(v[n++]);
          }
          r.full_P = true;
        }
        rows.push_back(r);
      }
    } catch (const std::exception& e) {
      report_error(summary, e.what());
      rows.clear();
    }
  }
  std::ofstream out(dir / "eval" / "targets.csv");
  out << "t_utc,t_tt_ns,observer,target,range_m";
  for (const char* n : kRoeNames) out << ",err_a_" << n << "_m";
  for (const char* n : kRoeNames) out << ",sigma_a_" << n << "_m";
  out << ",local_measurements,remote_measurements,health,nees\n";
  struct Series {
    std::vector<double> t_s, range, nees, nis_sum;
    std::vector<long> nis_n;
    std::vector<long> health;
    std::vector<astro::Vec6> err, sig;
    long local = 0, remote = 0;
  };
  std::map<std::pair<std::string, std::string>, Series> series;
  for (const auto& r : rows) {
    const auto io = truth[r.observer].find(r.t);
    const auto it = truth[r.target].find(r.t);
    if (io == truth[r.observer].end() || it == truth[r.target].end()) continue;
    const astro::QnsElements qo = astro::qns_from_cartesian(io->second);
    const astro::Vec6 roe_true = astro::roe_from_qns(qo, astro::qns_from_cartesian(it->second)).as_vector();
    astro::Vec6 d = r.roe - roe_true;
    d[1] = std::remainder(d[1], 2.0 * M_PI);
    const astro::Vec6 err = qo.a_m * d;
    const astro::Vec6 sig = qo.a_m * r.sigma;
    const double range = (it->second.r_m - io->second.r_m).norm();
    double nees = std::nan("");
    if (r.full_P) {
      const Eigen::LDLT<astro::Mat6> ldlt(r.P);
      if (ldlt.info() == Eigen::Success && ldlt.isPositive()) nees = d.dot(ldlt.solve(d));
    }
    auto& s = series[{r.observer, r.target}];
    s.t_s.push_back(static_cast<double>(r.t - sc.epoch.ns_since_j2000) * 1e-9);
    s.range.push_back(range);
    s.err.push_back(err);
    s.sig.push_back(sig);
    s.nees.push_back(nees);
    s.nis_sum.push_back(r.nis_sum);
    s.nis_n.push_back(r.nis_n);
    s.health.push_back(r.health);
    s.local = r.local;
    s.remote = r.remote;
    char buf[160];
    out << astro::utc_string(astro::TimeTT{r.t}, 3) << "," << r.t << "," << r.observer << "," << r.target;
    std::snprintf(buf, sizeof buf, ",%.3f", range);
    out << buf;
    for (int i = 0; i < 6; ++i) {
      std::snprintf(buf, sizeof buf, ",%.4f", err[i]);
      out << buf;
    }
    for (int i = 0; i < 6; ++i) {
      std::snprintf(buf, sizeof buf, ",%.4f", sig[i]);
      out << buf;
    }
    std::snprintf(buf, sizeof buf, ",%ld,%ld,%ld,%.4f\n", r.local, r.remote, r.health, nees);
    out << buf;
  }
  for (auto& [key, s] : series) {
    nlohmann::json j;
    const std::size_t n = s.t_s.size();
    if (n == 0) continue;
    const double R = s.range.back();
    j["final_range_m"] = R;
    j["final_dlambda_error_pct"] = 100.0 * std::abs(s.err.back()[1]) / R;
    j["final_dlambda_sigma_pct"] = 100.0 * s.sig.back()[1] / R;
    // The first estimate (mode 2: the initialisation by BOD; modes 1 and 3:
    // the ground a-priori): when, and how good against its own 1-sigma.
    j["first_estimate_orbits"] = s.t_s.front() / period_s;
    j["initial_dlambda_error_pct"] = 100.0 * s.err.front()[1] / s.range.front();
    j["initial_dlambda_sigma_pct"] = 100.0 * s.sig.front()[1] / s.range.front();
    j["initial_within_3sigma"] = std::abs(s.err.front()[1]) <= 3.0 * s.sig.front()[1];
    j["final_error_a_roe_m"] = std::vector<double>(s.err.back().data(), s.err.back().data() + 6);
    j["final_sigma_a_roe_m"] = std::vector<double>(s.sig.back().data(), s.sig.back().data() + 6);
    // Convergence: from here on |a dlambda error| <= 1 % of range.
    std::size_t k = n;
    while (k > 0 && std::abs(s.err[k - 1][1]) <= 0.01 * s.range[k - 1]) --k;
    const bool converged = k < n;
    j["convergence_orbits"] = converged ? nlohmann::json((s.t_s[k] - s.t_s.front()) / period_s) : nlohmann::json(nullptr);
    const std::size_t from = converged ? k : n / 2;
    nlohmann::json frac;
    for (int i = 0; i < 6; ++i) {
      std::size_t in = 0;
      for (std::size_t m = from; m < n; ++m) in += std::abs(s.err[m][i]) <= 3.0 * s.sig[m][i] ? 1 : 0;
      frac[kRoeNames[i]] = n > from ? static_cast<double>(in) / static_cast<double>(n - from) : 0.0;
    }
    j["frac_within_3sigma"] = frac;
    // Over-confidence at a glance (whole run, any ROE): the fraction of
    // steps with some ROE error beyond 3 and 5 sigma, and the longest run of
    // such steps (orbits).
    for (const double n_sigma : {3.0, 5.0}) {
      std::size_t beyond = 0, run = 0, longest = 0, silent = 0, silent_run = 0, silent_longest = 0;
      for (std::size_t m = 0; m < n; ++m) {
        bool outside = false;
        for (int i = 0; i < 6; ++i) outside = outside || std::abs(s.err[m][i]) > n_sigma * s.sig[m][i];
        beyond += outside ? 1 : 0;
        run = outside ? run + 1 : 0;
        longest = std::max(longest, run);
        // Beyond while the target reports itself healthy: silent over-confidence.
        const bool quiet = outside && s.health[m] == 0;
        silent += quiet ? 1 : 0;
        silent_run = quiet ? silent_run + 1 : 0;
        silent_longest = std::max(silent_longest, silent_run);
      }
      const std::string tag = n_sigma == 3.0 ? "3sigma" : "5sigma";
      j["frac_beyond_" + tag] = static_cast<double>(beyond) / static_cast<double>(n);
      const double step_s = n > 1 ? (s.t_s.back() - s.t_s.front()) / static_cast<double>(n - 1) : 0.0;
      j["longest_beyond_" + tag + "_orbits"] = static_cast<double>(longest) * step_s / period_s;
      j["frac_beyond_" + tag + "_reported_healthy"] = static_cast<double>(silent) / static_cast<double>(n);
      j["longest_beyond_" + tag + "_reported_healthy_orbits"] = static_cast<double>(silent_longest) * step_s / period_s;
    }
    double nees_sum = 0.0;
    std::size_t nees_n = 0, nees_in = 0;
    for (std::size_t m = from; m < n; ++m) {
      if (!std::isfinite(s.nees[m])) continue;
      nees_sum += s.nees[m];
      ++nees_n;
      nees_in += (s.nees[m] >= 1.237 && s.nees[m] <= 14.449) ? 1 : 0;
    }
    j["nees_mean"] = nees_n ? nlohmann::json(nees_sum / static_cast<double>(nees_n)) : nlohmann::json(nullptr);
    j["nees_within_95"] = nees_n ? nlohmann::json(static_cast<double>(nees_in) / static_cast<double>(nees_n)) : nlohmann::json(nullptr);
    // Bearing NIS after convergence: the mean of the 2-dof normalised
    // innovation squares of every bearing update from `from` on (2 when
    // the filter's predicted bearing covariance is honest).
    const double nis0 = from > 0 ? s.nis_sum[from - 1] : 0.0;
    const long nis_n0 = from > 0 ? s.nis_n[from - 1] : 0;
    const long nis_updates = s.nis_n.back() - nis_n0;
    j["nis_mean"] = nis_updates > 0 ? nlohmann::json((s.nis_sum.back() - nis0) / static_cast<double>(nis_updates))
                                    : nlohmann::json(nullptr);
    j["nis_updates"] = nis_updates;
    j["local_measurements"] = s.local;
    j["remote_measurements"] = s.remote;
    j["estimated"] = true;
    summary["observers"][key.first]["targets"][key.second] = j;
  }
  // Targets an observer was to navigate and never estimated (mode 2: BOD
  // never had a usable batch; modes 1 and 3: no a-priori reached SOD): an
  // entry that says so, and why from the renderer's point of view.
  std::map<std::pair<std::string, std::string>, std::map<std::string, long>> seen;  // (obs, tgt) -> reason -> frames
  if (fs::exists(dir / "frames.csv")) {
    try {
      const auto frames = io::CsvTable::read((dir / "frames.csv").string());
      for (std::size_t k = 0; k < frames.size(); ++k) {
        const std::string reason = frames.text(k, "dropped") == "1" ? "dropped" : frames.text(k, "reason");
        ++seen[{frames.text(k, "observer"), frames.text(k, "target")}][reason];
      }
    } catch (const std::exception& e) {
      std::fprintf(stderr, "artms-swarm: evaluation: frames.csv unreadable (%s)\n", e.what());
    }
  }
  for (const auto& o : sc.observers) {
    if (o.mode < 1) continue;
    for (const auto& s : sc.spacecraft) {
      if (s.id == o.spacecraft) continue;
      if (!o.targets.empty() && std::find(o.targets.begin(), o.targets.end(), s.id) == o.targets.end()) continue;
      if (series.count({o.spacecraft, s.id})) continue;
      nlohmann::json j;
      j["estimated"] = false;
      j["convergence_orbits"] = nullptr;
      std::string why = "never estimated";
      const auto f = seen.find({o.spacecraft, s.id});
      if (f != seen.end()) {
        long total = 0;
        for (const auto& [r, n] : f->second) total += n;
        why += "; the camera's frames: ";
        bool first = true;
        for (const auto& [r, n] : f->second) {
          why += (first ? "" : ", ") + r + " " + std::to_string(n);
          first = false;
        }
        why += " of " + std::to_string(total);
        j["frames_visible"] = f->second.count("visible") ? f->second.at("visible") : 0L;
        j["frames"] = total;
      }
      j["why"] = why;
      summary["observers"][o.spacecraft]["targets"][s.id] = j;
    }
  }
}

}  // namespace artms::swarm
