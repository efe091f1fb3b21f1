// artms-sod-replay: runs SOD again, offline, on what a run folder recorded
// for one observer (its GNSS fixes and IMP's bearings), started exactly as
// the observer starts it (first fix, uplinked a-priori) with the scenario's
// SOD tuning, and reports each target's consistency against the truth.
// It answers "is it the filter or the measurements?": with --bearings
// synthetic every bearing keeps its time and recorded 1-sigma but its error
// is drawn white from that 1-sigma around the true line of sight; with
// --bearings pixel it keeps only the centroid's error (measured minus true
// pixel), without the attitude's.
//
// An evaluation tool: it reads truth.oem and frames.csv (bearings are given
// to the target whose true pixel in the same frame is within 3 px, where the
// observer associates them itself), never onboard. Bearings keep IMP's time
// tag plus the uplinked correction, as the navigator fuses them; synthetic
// ones are drawn about the line of sight at the frame's true time. The filter
// has the scenario's auxiliary states (time tags, ballistic coefficients)
// with their uplinked priors, but none of the navigator's health checks, BOD
// or re-initialisations. Modes 1 and 3 replay the
// observer's own GNSS fixes and bearings; mode 4 (no GNSS) starts from the
// uplinked coarse orbit and fuses every observer's recorded bearings (its own
// as bearings, the others' as remote lines of sight, as the crosslink would
// carry them) and reports the observer's own absolute consistency too.
#include <CLI/CLI.hpp>

#include "artms/fsw/navigator.hpp"
#include "artms/io/csv.hpp"
#include "artms/io/number_list.hpp"
#include "artms/io/oem.hpp"
#include "artms/io/paths.hpp"
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "artms/astro/elements.hpp"
#include "artms/astro/frames.hpp"
#include "artms/astro/roe.hpp"
#include "artms/astro/time.hpp"
#include "artms/config/uplink.hpp"
#include "artms/dynamics/forces.hpp"
#include "artms/sod/apriori.hpp"
#include "artms/sod/sod_filter.hpp"

namespace {

using namespace artms;
using Eigen::MatrixXd;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;

// truth.oem: ECI states per object at each sample (TT ns), with the
// project's one OEM reader.
std::map<std::int64_t, std::map<std::string, astro::StateVector>> read_truth(const std::string& path) {
  std::map<std::int64_t, std::map<std::string, astro::StateVector>> out;
  for (const auto& seg : io::read_oem_file(path).segments) {
    for (const auto& smp : seg.samples) out[smp.t.ns_since_j2000][seg.object_name] = smp.x_eci;
  }
  return out;
}

// --gravity-periodic-roe-m: the uplink's budgets, replaced per target by
// "ID=da,dlambda,dex,dey,dix,diy" (a*ROE metres, each in [0, 1e4] as the
// scenario key), or all dropped by "none".
std::map<std::string, Vec6> gravity_periodic_budgets(const std::map<std::string, astro::Vec6>& uplinked,
                                                     const std::vector<std::string>& args,
                                                     const std::vector<std::string>& ids) {
  std::map<std::string, Vec6> out(uplinked.begin(), uplinked.end());
  for (const auto& arg : args) {
    if (arg == "none") {
      if (args.size() != 1) throw std::runtime_error("--gravity-periodic-roe-m none: given with other entries");
      out.clear();
      continue;
    }
    const auto eq = arg.find('=');
    const std::string id = arg.substr(0, eq);
    if (eq == std::string::npos || std::find(ids.begin(), ids.end(), id) == ids.end()) {
      throw std::runtime_error("--gravity-periodic-roe-m " + arg + ": expected ID=da,dlambda,dex,dey,dix,diy with ID one "
                               "of the observer's targets");
    }
    const std::string what = "--gravity-periodic-roe-m " + arg;
    const std::vector<double> x = io::parse_number_list(arg.substr(eq + 1), 6, what);
    if (!std::all_of(x.begin(), x.end(), [](double xi) { return xi >= 0.0 && xi <= 1e4; })) {
      throw std::runtime_error(what + ": six numbers in [0, 1e4] m expected");
    }
    const Vec6 v = Eigen::Map<const Vec6>(x.data());
    out[id] = v;
  }
  return out;
}

struct Bearing {
  int target;
  Eigen::Vector3d u_eci;
  double sigma_rad;
};

// A frame whose z axis is the line of sight (angles well conditioned).
Eigen::Matrix3d frame_about(const Eigen::Vector3d& u_eci) {
  Eigen::Matrix3d R;
  const Eigen::Vector3d ex = u_eci.unitOrthogonal();
  R.row(0) = ex;
  R.row(1) = u_eci.cross(ex);
  R.row(2) = u_eci;
  return R;
}

// Bearings of every observer in the run, each given to the body (observer or
// target) whose true pixel is within 3 px: t -> (sender, body, u_eci, sigma).
struct Los {
  std::string from, to;
  Eigen::Vector3d u_eci;
  double sigma_rad;
};

std::map<std::int64_t, std::vector<Los>> read_all_bearings(
    const std::string& run_dir, const std::map<std::int64_t, std::map<std::string, astro::StateVector>>& truth,
    const std::string& mode, double noise_scale, std::mt19937_64& rng, int& unassigned) {
  std::map<std::string, std::map<std::int64_t, std::map<std::string, Eigen::Vector2d>>> true_px;
  const auto frames = io::CsvTable::read(run_dir + "/frames.csv");
  for (std::size_t r = 0; r < frames.size(); ++r) {
    if (frames.text(r, "x_px").empty()) continue;
    true_px[frames.text(r, "observer")][frames.integer(r, "t_tt_ns")][frames.text(r, "target")] =
        Eigen::Vector2d(frames.number(r, "x_px"), frames.number(r, "y_px"));
  }
  std::normal_distribution<double> normal;
  std::map<std::int64_t, std::vector<Los>> out;
  for (const auto& [sender, px] : true_px) {
    const std::string path = run_dir + "/imp/" + sender + "/measurements.csv";
    if (!std::filesystem::exists(path)) continue;
    const auto m = io::CsvTable::read(path);
    std::set<std::tuple<std::int64_t, double, double>> seen;  // a row recorded twice is fused once (as above)
    for (std::size_t r = 0; r < m.size(); ++r) {
      const std::int64_t t = m.integer(r, "t_tt_ns");
      const Eigen::Vector2d p(m.number(r, "x_px"), m.number(r, "y_px"));
      if (!seen.emplace(t, p.x(), p.y()).second) continue;
      std::string body;
      double best_d = 3.0;
      const auto frame = px.find(t);
      if (frame != px.end()) {
        for (const auto& [id, q] : frame->second) {
          if ((q - p).norm() < best_d) {
            best_d = (q - p).norm();
            body = id;
          }
        }
      }
      if (body.empty()) {
        ++unassigned;
        continue;
      }
      Eigen::Vector3d u(m.number(r, "ux_eci"), m.number(r, "uy_eci"), m.number(r, "uz_eci"));
      const double sigma = m.number(r, "sigma_rad");
      if (mode == "synthetic") {
        const auto sample = truth.find(t);
        if (sample == truth.end() || !sample->second.count(body) || !sample->second.count(sender)) {
          throw std::runtime_error(path + " line " + std::to_string(r + 2) + ": no truth.oem sample of " + sender +
                                   " and " + body + " at its t_tt_ns " + std::to_string(t));
        }
        const Eigen::Vector3d u_true = (sample->second.at(body).r_m - sample->second.at(sender).r_m).normalized();
        const Eigen::Vector3d e1 = u_true.unitOrthogonal(), e2 = u_true.cross(e1);
        u = (u_true + noise_scale * sigma * (normal(rng) * e1 + normal(rng) * e2)).normalized();
      }
      out[t].push_back({sender, body, u, sigma});
    }
  }
  return out;
}

// Navigation mode 4 (docs/sod.md): SOD from the uplinked coarse orbit, the
// ground a-priori drifted to it, every observer's bearings, no GNSS.
struct ReplayOptions {
  std::string bearings_mode = "measured";
  std::uint64_t seed = 1;
  double sigma_scale = 1.0, after_orbits = 4.0, noise_scale = 1.0;
  std::string csv_out;
  std::vector<std::string> leave_out;  // mode 4: "FROM>TO"
  bool start_roe_truth = false;        // mode 4: the targets start at their true ROE
};

int replay_mode4(const std::string& run_dir, const std::string& observer, const config::ObserverUplink& up,
                 const config::SodTuning& tuning, const ReplayOptions& o) {
  const std::string& bearings_mode = o.bearings_mode;
  const double sigma_scale = o.sigma_scale, after_orbits = o.after_orbits;
  const std::string& csv_out = o.csv_out;
  const std::vector<std::string>& leave_out = o.leave_out;
  if (!up.coarse_orbit) throw std::runtime_error(run_dir + ": mode 4 without an uplinked coarse orbit");
  if (bearings_mode == "pixel") throw std::runtime_error("--bearings pixel: modes 1 and 3 only");
  const auto forces = dynamics::ForceModel::load(up.force_model, io::data_dir());
  std::vector<std::string> ids;
  for (const auto& a : up.apriori) ids.push_back(a.target);
  const int n = static_cast<int>(ids.size());
  const auto index_of = [&](const std::string& id) {
    if (id == observer) return sod::LineOfSightMeasurement::kObserver;
    for (int k = 0; k < n; ++k)
      if (ids[static_cast<std::size_t>(k)] == id) return k;
    return sod::LineOfSightMeasurement::kExternal;
  };
  const auto truth = read_truth(run_dir + "/truth.oem");
  std::mt19937_64 rng(o.seed);
  int unassigned = 0;
  const auto bearings = read_all_bearings(run_dir, truth, bearings_mode, o.noise_scale, rng, unassigned);

  // As the navigator starts mode 4 (navigator.cpp, initialise_at).
  const auto& c = *up.coarse_orbit;
  const astro::QnsElements obs0 = astro::qns_from_cartesian(c.x_eci);
  const Mat6 J0 = astro::jacobian_qns_from_cartesian(c.x_eci);
  const sod::StateLayout layout = fsw::sod_layout(tuning, n);
  sod::SodFilter f(forces, up.onboard_properties(observer), layout, fsw::target_nominal_properties(up, ids),
                   fsw::sod_options(tuning, obs0));
  MatrixXd P = MatrixXd::Zero(layout.size(), layout.size());
  P.topLeftCorner<6, 6>() = J0 * c.P_rv * J0.transpose() + Mat6::Identity() * 1e-20;
  std::vector<astro::Roe> roes;
  for (int k = 0; k < n; ++k) {
    const auto& ap = up.apriori[static_cast<std::size_t>(k)];
    const double dt = astro::seconds_between(up.epoch, c.t);
    roes.push_back(astro::Roe::from_vector(sod::apriori_roe_at(ap.roe, obs0, dt)));
    P.block<6, 6>(6 * (k + 1), 6 * (k + 1)) = sod::apriori_covariance_at(ap.P_roe, obs0, dt);
  }
  const Eigen::VectorXd aux_var = fsw::auxiliary_prior_variance(tuning, layout);
  const Eigen::VectorXd aux = Eigen::VectorXd::Zero(aux_var.size());
  P.bottomRightCorner(aux_var.size(), aux_var.size()) = aux_var.asDiagonal();
  if (o.start_roe_truth) {
    // Evaluation only: the relative orbits known exactly at the start (the
    // a-priori covariance kept), to tell their error's part from the rest.
    const auto& bodies = truth.at(c.t.ns_since_j2000);
    const astro::QnsElements o_true = astro::qns_from_cartesian(bodies.at(observer));
    for (int k = 0; k < n; ++k) {
      roes[static_cast<std::size_t>(k)] =
          astro::roe_from_qns(o_true, astro::qns_from_cartesian(bodies.at(ids[static_cast<std::size_t>(k)])));
    }
  }
  f.initialize(c.t, f.make_state(obs0, roes, aux), P);
  const double a_m = obs0.a_m, period_s = astro::orbit_period_s(a_m);

  std::FILE* csv = nullptr;
  if (!csv_out.empty()) {
    csv = std::fopen(csv_out.c_str(), "w");
    if (!csv) throw std::runtime_error("cannot write " + csv_out);
    std::fprintf(csv, "t_tt_ns,err_r_m,err_t_m,err_n_m,sigma_r_m,sigma_t_m,sigma_n_m,nees_pos,err_a_di_m,sigma_a_di_m,"
                      "err_a_raan_m,sigma_a_raan_m\n");
  }
  int fused_local = 0, fused_remote = 0, offered_local = 0, offered_remote = 0, external = 0, left_out = 0;
  double nees_sum = 0.0, z_di_sum = 0.0;
  int steps = 0, beyond3 = 0;
  auto next = bearings.begin();
  double last_err_m = 0.0, last_sigma_m = 0.0, last_z_di = 0.0;
  for (const auto& [t_ns, bodies] : truth) {
    if (t_ns < c.t.ns_since_j2000 || !bodies.count(observer)) continue;
    for (; next != bearings.end() && next->first <= t_ns; ++next) {
      if (next->first < f.epoch().ns_since_j2000) continue;
      const astro::TimeTT t{next->first};
      for (const auto& b : next->second) {
        if (std::find(leave_out.begin(), leave_out.end(), b.from + ">" + b.to) != leave_out.end()) {
          ++left_out;
          continue;
        }
        const int from = index_of(b.from), to = index_of(b.to);
        if (b.from == observer) {
          if (to < 0) continue;
          ++offered_local;
          const double sigma = b.sigma_rad * sigma_scale;
          fused_local += f.update_bearing(
                              sod::bearing_measurement_from_unit_eci(t, to, b.u_eci, sigma, frame_about(b.u_eci)))
                             .usable;
        } else {
          if (from == sod::LineOfSightMeasurement::kExternal || to == sod::LineOfSightMeasurement::kExternal) {
            ++external;  // a sender or body this filter does not estimate
            continue;
          }
          sod::LineOfSightMeasurement m;
          m.t = t;
          m.from = from;
          m.to = to;
          m.los_eci = b.u_eci;
          m.sigma_rad = b.sigma_rad * sigma_scale;
          ++offered_remote;
          fused_remote += f.update_line_of_sight(m).usable;
        }
      }
    }
    const astro::TimeTT t{t_ns};
    if (t_ns > f.epoch().ns_since_j2000) f.time_update(t);
    if (t_ns != f.epoch().ns_since_j2000) continue;
    // The observer's own orbit against truth: RTN position error and its
    // covariance (d cartesian / d qns as the inverse of d qns / d cartesian).
    const astro::StateVector x_true = bodies.at(observer);
    const astro::QnsElements est = f.observer(), tru = astro::qns_from_cartesian(x_true);
    const astro::StateVector x_est = astro::cartesian_from_qns(est);
    const Mat6 Jc = astro::jacobian_qns_from_cartesian(x_est).inverse();
    const Mat6 Pc = Jc * f.covariance().topLeftCorner<6, 6>() * Jc.transpose();
    const Eigen::Matrix3d R_rtn = astro::R_rtn_from_eci(x_true);
    const Eigen::Vector3d e_rtn = R_rtn * (x_est.r_m - x_true.r_m);
    const Eigen::Matrix3d P_rtn = R_rtn * Pc.topLeftCorner<3, 3>() * R_rtn.transpose();
    const double nees = e_rtn.dot(P_rtn.ldlt().solve(e_rtn));
    const double e_di = (est.i_rad - tru.i_rad) * a_m, s_di = std::sqrt(f.covariance()(3, 3)) * a_m;
    const double e_dr = std::remainder(est.raan_rad - tru.raan_rad, 2.0 * M_PI) * a_m * std::sin(tru.i_rad);
    const double s_dr = std::sqrt(f.covariance()(4, 4)) * a_m * std::sin(tru.i_rad);
    const double orbits = static_cast<double>(t_ns - c.t.ns_since_j2000) * 1e-9 / period_s;
    if (orbits >= after_orbits) {
      nees_sum += nees;
      z_di_sum += (e_di / s_di) * (e_di / s_di);
      ++steps;
      bool out = false;
      for (int j = 0; j < 3; ++j) out = out || std::abs(e_rtn[j]) > 3.0 * std::sqrt(P_rtn(j, j));
      beyond3 += out;
    }
    last_err_m = e_rtn.norm();
    last_sigma_m = std::sqrt(P_rtn.trace());
    last_z_di = e_di / s_di;
    if (csv) {
      std::fprintf(csv, "%lld,%.2f,%.2f,%.2f,%.2f,%.2f,%.2f,%.4f,%.2f,%.2f,%.2f,%.2f\n", static_cast<long long>(t_ns),
                   e_rtn[0], e_rtn[1], e_rtn[2], std::sqrt(P_rtn(0, 0)), std::sqrt(P_rtn(1, 1)),
                   std::sqrt(P_rtn(2, 2)), nees, e_di, s_di, e_dr, s_dr);
    }
  }
  if (csv) std::fclose(csv);
  std::printf("%s, observer %s (mode 4), bearings %s (seed %llu, sigma x %.2f); %d recorded bearings not within 3 px "
              "of a body, %d of a body or sender this filter does not estimate\n",
              run_dir.c_str(), observer.c_str(), bearings_mode.c_str(), static_cast<unsigned long long>(o.seed),
              sigma_scale, unassigned, external);
  if (o.start_roe_truth) std::printf("  targets started at their true ROE (--start-roe truth)\n");
  std::printf("  own bearings fused %d of %d, remote %d of %d, %d left out (--leave-out); target-to-target lines: %s\n",
              fused_local, offered_local, fused_remote, offered_remote, left_out,
              tuning.target_lines == config::SodTuning::TargetLines::kConsiderObserver ? "consider_observer"
                                                                                       : "update_observer");
  std::printf("  own position after orbit %.1f (%d steps): NEES mean %.2f (3 dof), RTN beyond 3 sigma on %.1f %% of "
              "steps, a*di mean z^2 %.2f; final error %.0f m (RSS 1-sigma %.0f m), a*di z %+.2f\n",
              after_orbits, steps, steps ? nees_sum / steps : std::nan(""), steps ? 100.0 * beyond3 / steps : 0.0,
              steps ? z_di_sum / steps : std::nan(""), last_err_m, last_sigma_m, last_z_di);
  return 0;
}

int run(int argc, char** argv) {
  CLI::App app{"Run SOD again, offline, on a run folder's recorded GNSS fixes and IMP bearings of one observer,\n"
               "and report each target's consistency against the truth (an evaluation tool: reads truth).",
               "artms-sod-replay"};
  std::string run_dir, observer = "SV4", bearings_mode = "measured", csv_out, innovations_out;
  std::uint64_t seed = 1;
  double sigma_scale = 1.0, after_orbits = 4.0, min_separation_px = 0.0, report_ahead_s = 0.0;
  app.add_option("run", run_dir, "run folder (artms-swarm run --out)")->required();
  app.add_option("--observer", observer, "observer id (mode 1, 3 or 4)")->capture_default_str();
  app.add_option("--bearings", bearings_mode,
                 "measured: as recorded; synthetic: true line of sight + white noise of the recorded 1-sigma;\n"
                 "pixel: true line of sight + the centroid's recorded error only")
      ->check(CLI::IsMember({"measured", "synthetic", "pixel"}))
      ->capture_default_str();
  app.add_option("--seed", seed, "noise seed of --bearings synthetic")->capture_default_str();
  app.add_option("--sigma-scale", sigma_scale, "multiplies every bearing 1-sigma given to the filter")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--min-separation-px", min_separation_px,
                 "leave out the bearings of frames where another target's true pixel is this close (blended spots)")
      ->capture_default_str();
  app.add_option("--after-orbits", after_orbits, "NEES averaged from this many orbits on")->capture_default_str();
  std::optional<double> underweighting, underweighting_nonlinearity, q_scale;
  std::optional<bool> adaptive;
  app.add_option("--underweighting", underweighting, "override tuning.sod.underweighting (beta >= 0)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--underweighting-nonlinearity", underweighting_nonlinearity,
                 "override tuning.sod.underweighting_nonlinearity (>= 0; 0: the predicted spread alone decides)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--process-noise-scale", q_scale, "override tuning.sod.process_noise_scale")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--adaptive-process-noise", adaptive, "override tuning.sod.adaptive_process_noise (true/false)");
  std::optional<bool> adaptive_targets;
  app.add_option("--adaptive-targets", adaptive_targets,
                 "override tuning.sod.adaptive_targets (true/false; false: only the observer's own rates adapt)");
  std::string adaptive_form, adaptive_average;
  app.add_option("--adaptive-form", adaptive_form, "override tuning.sod.adaptive_form")
      ->check(CLI::IsMember({"diagonal", "block"}));
  app.add_option("--adaptive-average", adaptive_average, "override tuning.sod.adaptive_average")
      ->check(CLI::IsMember({"clamped", "unclamped"}));
  std::optional<double> drag_density_error, adaptive_time_constant_s, ballistic_sigma_fraction, ballistic_walk,
      density_change;
  std::optional<double> aided_sigma_arcsec;
  app.add_option("--adaptive-time-constant-s", adaptive_time_constant_s,
                 "override tuning.sod.adaptive_time_constant (s)")
      ->check(CLI::Range(0.0, config::SodTuning::kMaxAdaptiveTimeConstantS));
  app.add_option("--drag-density-error", drag_density_error, "override tuning.sod.drag_density_error")
      ->check(CLI::Range(0.0, 10.0));
  app.add_option("--ballistic-sigma-fraction", ballistic_sigma_fraction,
                 "override tuning.sod.ballistic.sigma_fraction (each target's differential ballistic coefficient's "
                 "initial 1-sigma as a fraction of the nominal Cd A/m; also its random walk per day where the "
                 "scenario sets no ballistic.walk_fraction_per_day)")
      ->check(CLI::Range(1e-6, 10.0));
  app.add_option("--ballistic-walk-fraction-per-day", ballistic_walk,
                 "override tuning.sod.ballistic.walk_fraction_per_day (the differential ballistic coefficient's random "
                 "walk per day as a fraction of the nominal Cd A/m)")
      ->check(CLI::Range(0.0, 10.0));
  app.add_option("--ballistic-density-change-per-day", density_change,
                 "override tuning.sod.ballistic.density_change_per_day (the density's relative change per day: "
                 "dB walks by this x its estimated |dB| per day)")
      ->check(CLI::Range(0.0, 10.0));
  app.add_option("--aided-sigma-arcsec", aided_sigma_arcsec,
                 "modes 1 and 3, a study: every SOD-aided single detection (measurements.csv track_id -2 - k) "
                 "given this 1-sigma (arcsec, attitude included) instead of IMP's")
      ->check(CLI::Range(0.1, 3600.0));
  std::string target_lines;
  app.add_option("--target-lines", target_lines,
                 "override tuning.sod.target_lines: another observer's bearing of a target updates the relative orbits "
                 "only (consider_observer) or the observer's own orbit too (update_observer)")
      ->check(CLI::IsMember({"consider_observer", "update_observer"}));
  std::vector<std::string> leave_out;
  app.add_option("--leave-out", leave_out,
                 "mode 4: leave out the bearings taken by FROM of TO, given as FROM>TO (e.g. SV2>SV3); repeatable");
  double noise_scale = 1.0;
  app.add_option("--noise-scale", noise_scale,
                 "--bearings synthetic: the drawn error times this (0: noise-free; the filter keeps the 1-sigma)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  std::string start_roe = "apriori";
  app.add_option("--start-roe", start_roe,
                 "mode 4: the targets' initial ROE: apriori (as the observer) or truth (a-priori covariance kept)")
      ->check(CLI::IsMember({"apriori", "truth"}))
      ->capture_default_str();
  app.add_option("--report-ahead-s", report_ahead_s,
                 "modes 1 and 3: evaluate the filter's linearised prediction this far ahead of each fix, as the "
                 "navigator's telemetry reports it while its filter lags the clock (at most max_lag_s, 600 s)")
      ->check(CLI::Range(0.0, 3600.0))
      ->capture_default_str();
  std::vector<std::string> gravity_periodic_args;
  app.add_option("--gravity-periodic-roe-m", gravity_periodic_args,
                 "modes 1 and 3: the onboard gravity's short-periodic 1-sigma per target, added to the reported "
                 "covariance as the navigator adds the uplink's (observers[].targets[].gravity_periodic_roe_m): "
                 "ID=da,dlambda,dex,dey,dix,diy in a*ROE metres, repeatable, replacing the uplink's for that "
                 "target; 'none' drops every target's (default: the uplink's)");
  app.add_option("--csv", csv_out, "per step and target: t_tt_ns, target, a*ROE errors (m), 1-sigmas (m), NEES, the reported "
                 "covariance's upper triangle (m^2, space-separated), the true range (m)");
  app.add_option("--innovations", innovations_out,
                 "modes 1 and 3: per bearing offered: t_tt_ns, target, its pre-fit innovation whitened by its "
                 "innovation covariance (taken as isotropic: the innovation times sqrt(NIS) / |innovation|) in the "
                 "filter's own RTN frame of the observer (w_r, w_t, w_n), NIS, fused (1/0), gated (1/0)");
  CLI11_PARSE(app, argc, argv);

  const std::string up_path = run_dir + "/uplink/" + observer + ".json";
  const config::ObserverUplink up = config::read_uplink(up_path);
  if (up.apriori.empty()) throw std::runtime_error(up_path + ": no ground a-priori (not a mode 1, 3 or 4 observer)");
  if ((!leave_out.empty() || start_roe != "apriori") && up.observer.mode != 4)
    throw std::runtime_error("--leave-out and --start-roe: navigation mode 4 only (" + observer + " ran mode " +
                             std::to_string(up.observer.mode) + ")");
  // The scenario's SOD tuning with the command line's overrides.
  config::SodTuning tuning = up.tuning.sod;
  tuning.underweighting = underweighting.value_or(tuning.underweighting);
  tuning.underweighting_nonlinearity = underweighting_nonlinearity.value_or(tuning.underweighting_nonlinearity);
  tuning.adaptive_process_noise = adaptive.value_or(tuning.adaptive_process_noise);
  tuning.adaptive_targets = adaptive_targets.value_or(tuning.adaptive_targets);
  tuning.process_noise_scale = q_scale.value_or(tuning.process_noise_scale);
  tuning.drag_density_error = drag_density_error.value_or(tuning.drag_density_error);
  tuning.ballistic_sigma_fraction = ballistic_sigma_fraction.value_or(tuning.ballistic_sigma_fraction);
  if (ballistic_walk) tuning.ballistic_walk_fraction_per_day = *ballistic_walk;
  if (density_change) tuning.ballistic_density_change_per_day = *density_change;
  if (adaptive_time_constant_s && !(*adaptive_time_constant_s > 0.0))
    throw std::runtime_error("--adaptive-time-constant-s must be > 0 s (and at most 30 days), got 0");
  tuning.adaptive_time_constant_s = adaptive_time_constant_s.value_or(tuning.adaptive_time_constant_s);
  if (!adaptive_form.empty())
    tuning.adaptive_form = adaptive_form == "block" ? config::SodTuning::AdaptiveForm::kBlock
                                                    : config::SodTuning::AdaptiveForm::kDiagonal;
  if (!adaptive_average.empty())
    tuning.adaptive_average = adaptive_average == "unclamped" ? config::SodTuning::AdaptiveAverage::kUnclamped
                                                              : config::SodTuning::AdaptiveAverage::kClamped;
  if (!target_lines.empty()) {
    tuning.target_lines = target_lines == "consider_observer" ? config::SodTuning::TargetLines::kConsiderObserver
                                                              : config::SodTuning::TargetLines::kUpdateObserver;
  }
  if (up.observer.mode == 4 && !innovations_out.empty())
    throw std::runtime_error("--innovations: modes 1 and 3 only (" + observer + " ran mode 4)");
  if (up.observer.mode == 4) {
    ReplayOptions ro;
    ro.bearings_mode = bearings_mode;
    ro.seed = seed;
    ro.sigma_scale = sigma_scale;
    ro.after_orbits = after_orbits;
    ro.noise_scale = noise_scale;
    ro.csv_out = csv_out;
    ro.leave_out = leave_out;
    ro.start_roe_truth = start_roe == "truth";
    return replay_mode4(run_dir, observer, up, tuning, ro);
  }
  if (up.observer.mode == 3) {
    // Remote bearings are not in the run folder (isl.csv has the outcomes,
    // not the payloads): a mode-3 replay is a local-bearings-only replay.
    std::fprintf(stderr,
                 "artms-sod-replay: warning: %s ran navigation mode 3; its remote bearings are not recorded, so "
                 "this replay fuses its own GNSS fixes and local bearings only (mode 1)\n",
                 observer.c_str());
  }
  const auto forces = dynamics::ForceModel::load(up.force_model, io::data_dir());
  std::vector<std::string> ids;
  for (const auto& a : up.apriori) ids.push_back(a.target);
  const int n = static_cast<int>(ids.size());
  const std::map<std::string, Vec6> gravity_periodic =
      gravity_periodic_budgets(up.observer.target_gravity_periodic_a_roe_m, gravity_periodic_args, ids);
  const auto truth = read_truth(run_dir + "/truth.oem");

  // True pixels and true times per frame. IMP tags a bearing with the
  // frame's time tag (off by any time-tag fault); the frame index joins it
  // to the truth, and the filter sees the tag plus the uplinked correction,
  // as the navigator does.
  struct FrameTruth {
    std::int64_t t_true_ns = 0;
    std::map<std::string, Eigen::Vector2d> px;
  };
  std::map<std::int64_t, FrameTruth> frame_truth;
  {
    const auto frames = io::CsvTable::read(run_dir + "/frames.csv");
    for (std::size_t r = 0; r < frames.size(); ++r) {
      if (frames.text(r, "observer") != observer) continue;
      FrameTruth& ft = frame_truth[frames.integer(r, "frame")];
      ft.t_true_ns = frames.integer(r, "t_tt_ns");
      if (!frames.text(r, "x_px").empty())
        ft.px[frames.text(r, "target")] = Eigen::Vector2d(frames.number(r, "x_px"), frames.number(r, "y_px"));
    }
  }
  const double correction_s = up.observer.camera.time_tag_correction_s;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  struct TimedBearing {
    astro::TimeTT t;  // the tag plus the uplinked correction
    Bearing b;
  };
  std::vector<TimedBearing> bearings;
  int unassigned = 0, blended = 0, repeated = 0;
  {
    const auto m = io::CsvTable::read(run_dir + "/imp/" + observer + "/measurements.csv");
    std::set<std::tuple<std::int64_t, double, double>> seen;
    for (std::size_t r = 0; r < m.size(); ++r) {
      // IMP reports a SOD-aided single detection that is also a track's
      // bearing twice; the navigator fuses it once (Navigator::direct_assigned).
      if (!seen.emplace(m.integer(r, "frame"), m.number(r, "x_px"), m.number(r, "y_px")).second) {
        ++repeated;
        continue;
      }
      const auto fit = frame_truth.find(m.integer(r, "frame"));
      if (fit == frame_truth.end()) {
        ++unassigned;
        continue;
      }
      const FrameTruth& ft = fit->second;
      const Eigen::Vector2d p(m.number(r, "x_px"), m.number(r, "y_px"));
      int best = -1;
      double best_d = 3.0;
      for (int k = 0; k < n; ++k) {
        const auto it = ft.px.find(ids[static_cast<std::size_t>(k)]);
        if (it != ft.px.end() && (it->second - p).norm() < best_d) {
          best_d = (it->second - p).norm();
          best = k;
        }
      }
      if (best < 0) {
        ++unassigned;  // a star, a hot pixel, or a target more than 3 px off
        continue;
      }
      const std::string& best_id = ids[static_cast<std::size_t>(best)];
      if (min_separation_px > 0.0) {
        const Eigen::Vector2d q = ft.px.at(best_id);
        bool near = false;
        for (const auto& [id, other] : ft.px)
          if (id != best_id && (other - q).norm() < min_separation_px) near = true;
        if (near) {
          ++blended;
          continue;
        }
      }
      Eigen::Vector3d u(m.number(r, "ux_eci"), m.number(r, "uy_eci"), m.number(r, "uz_eci"));
      double sigma = m.number(r, "sigma_rad");
      // A study: SOD-aided single detections (track_id -2 - k) with one 1-sigma of the command line's.
      if (aided_sigma_arcsec && m.integer(r, "track_id") <= -2) sigma = *aided_sigma_arcsec * M_PI / (180.0 * 3600.0);
      if (bearings_mode != "measured") {
        const auto tt = truth.find(ft.t_true_ns);
        if (tt == truth.end() || !tt->second.count(observer) || !tt->second.count(best_id))
          throw std::runtime_error(run_dir + "/truth.oem: no state of " + observer + " and " + best_id +
                                   " at frame " + std::to_string(fit->first) + "'s time");
        const auto& o = tt->second.at(observer);
        const auto& g = tt->second.at(best_id);
        const Eigen::Vector3d u_true = (g.r_m - o.r_m).normalized();
        // (e1, e2): perpendicular to the line of sight, e1 towards the zenith.
        const Eigen::Vector3d e1 = (o.r_m.normalized() - u_true * u_true.dot(o.r_m.normalized())).normalized();
        const Eigen::Vector3d e2 = u_true.cross(e1);
        if (bearings_mode == "synthetic") {
          u = (u_true + noise_scale * sigma * (normal(rng) * e1 + normal(rng) * e2)).normalized();
        } else {  // pixel: the centroid's error, small-angle, pixel axes onto (e1, e2)
          const Eigen::Vector2d dp = p - ft.px.at(best_id);
          u = (u_true + dp.x() / up.camera_calibration.fx_px * e1 + dp.y() / up.camera_calibration.fy_px * e2)
                  .normalized();
        }
      }
      bearings.push_back({astro::TimeTT{m.integer(r, "t_tt_ns")}.plus_seconds(correction_s), {best, u, sigma * sigma_scale}});
    }
  }
  std::stable_sort(bearings.begin(), bearings.end(),
                   [](const TimedBearing& x, const TimedBearing& y) { return x.t.ns_since_j2000 < y.t.ns_since_j2000; });

  // The filter, as the navigator starts it (navigator.cpp, initialise): the
  // scenario's layout (auxiliary states) with their uplinked priors.
  const sod::StateLayout layout = fsw::sod_layout(tuning, n);
  const Eigen::VectorXd aux_var = fsw::auxiliary_prior_variance(tuning, layout);
  std::unique_ptr<sod::SodFilter> filter;
  const double sigma_r = up.observer.gnss.sigma_position_m, sigma_v = up.observer.gnss.sigma_velocity_mps;
  std::FILE* csv = nullptr;
  if (!csv_out.empty()) {
    csv = std::fopen(csv_out.c_str(), "w");
    if (!csv) throw std::runtime_error("cannot write " + csv_out);
    std::fprintf(csv, "t_tt_ns,target,err_a_da_m,err_a_dlambda_m,err_a_dex_m,err_a_dey_m,err_a_dix_m,err_a_diy_m,"
                      "sigma_a_da_m,sigma_a_dlambda_m,sigma_a_dex_m,sigma_a_dey_m,sigma_a_dix_m,sigma_a_diy_m,nees,"
                      "cov_upper_m2,range_m\n");
  }
  std::FILE* innovations = nullptr;
  if (!innovations_out.empty()) {
    innovations = std::fopen(innovations_out.c_str(), "w");
    if (!innovations) throw std::runtime_error("cannot write " + innovations_out);
    std::fprintf(innovations, "t_tt_ns,target,w_r,w_t,w_n,nis,fused,gated\n");
  }
  std::int64_t t0 = 0;
  double period_s = 0.0, a_m = 0.0;
  std::vector<double> nees_sum(static_cast<std::size_t>(n), 0.0);
  std::vector<int> nees_steps(static_cast<std::size_t>(n), 0), fused(static_cast<std::size_t>(n), 0),
      offered(static_cast<std::size_t>(n), 0);
  // Convergence as summary.json counts it (evaluation.hpp): the first step
  // after which the a*dlambda error stays within 1 % of the true range.
  std::vector<int> steps_after_outside(static_cast<std::size_t>(n), 0);
  std::vector<double> first_step_after_outside(static_cast<std::size_t>(n), 0.0);
  std::size_t next_bearing = 0;
  const auto gnss = io::CsvTable::read(run_dir + "/gnss.csv");
  for (std::size_t r = 0; r < gnss.size(); ++r) {
    if (gnss.text(r, "spacecraft") != observer || gnss.text(r, "valid") != "1") continue;
    sod::GnssMeasurement g;
    g.t = astro::TimeTT{gnss.integer(r, "t_tt_ns")};
    g.x_eci.r_m << gnss.number(r, "x_m"), gnss.number(r, "y_m"), gnss.number(r, "z_m");
    g.x_eci.v_mps << gnss.number(r, "vx_mps"), gnss.number(r, "vy_mps"), gnss.number(r, "vz_mps");
    g.sigma_r_m = sigma_r;
    g.sigma_v_mps = sigma_v;
    if (!filter) {
      const astro::QnsElements obs = astro::qns_from_cartesian(g.x_eci);
      sod::SodOptions options = fsw::sod_options(tuning, obs);
      // The observer's and each target's uplinked nominal properties, as the navigator flies them.
      filter = std::make_unique<sod::SodFilter>(forces, up.onboard_properties(observer), layout,
                                                fsw::target_nominal_properties(up, ids), options);
      Vec6 var_rv;
      var_rv << Eigen::Vector3d::Constant(sigma_r * sigma_r), Eigen::Vector3d::Constant(sigma_v * sigma_v);
      const Mat6 J = astro::jacobian_qns_from_cartesian(g.x_eci);
      MatrixXd P = MatrixXd::Zero(layout.size(), layout.size());
      P.topLeftCorner<6, 6>() = J * var_rv.asDiagonal() * J.transpose() + Mat6::Identity() * 1e-20;
      const double dt = astro::seconds_between(up.epoch, g.t);
      std::vector<astro::Roe> roes;
      for (int k = 0; k < n; ++k) {
        // The a-priori's drift to the fix, as the navigator does.
        const auto& ap = up.apriori[static_cast<std::size_t>(k)];
        roes.push_back(astro::Roe::from_vector(sod::apriori_roe_at(ap.roe, obs, dt)));
        P.block<6, 6>(layout.target_offset(k), layout.target_offset(k)) = sod::apriori_covariance_at(ap.P_roe, obs, dt);
      }
      const int n_aux = layout.size() - layout.aux_offset();
      if (n_aux > 0) P.bottomRightCorner(n_aux, n_aux) = aux_var.asDiagonal();
      filter->initialize(g.t, filter->make_state(obs, roes), P);
      t0 = g.t.ns_since_j2000;
      period_s = astro::orbit_period_s(obs.a_m);
      a_m = obs.a_m;
      while (next_bearing < bearings.size() && bearings[next_bearing].t.ns_since_j2000 < t0) ++next_bearing;
      continue;
    }
    // Bearings up to this fix in time order (at the fix's own time: after it).
    const auto fuse_until = [&](std::int64_t t_ns, bool inclusive) {
      for (; next_bearing < bearings.size(); ++next_bearing) {
        const TimedBearing& tb = bearings[next_bearing];
        if (tb.t.ns_since_j2000 > t_ns || (!inclusive && tb.t.ns_since_j2000 == t_ns)) break;
        ++offered[static_cast<std::size_t>(tb.b.target)];
        const Eigen::Matrix3d R = frame_about(tb.b.u_eci);
        const sod::UpdateSummary us =
            filter->update_bearing(sod::bearing_measurement_from_unit_eci(tb.t, tb.b.target, tb.b.u_eci, tb.b.sigma_rad, R));
        if (us.usable) ++fused[static_cast<std::size_t>(tb.b.target)];
        if (innovations && us.prefit_residual.size() == 2 && std::isfinite(us.nis)) {
          // Near the line of sight (R's z axis): az ~ the offset along R's y axis, el along its x axis (eq. 2).
          const Eigen::Vector3d nu_eci =
              us.prefit_residual[0] * R.row(1).transpose() + us.prefit_residual[1] * R.row(0).transpose();
          const double nu_norm = nu_eci.norm();
          const Eigen::Vector3d w_rtn =
              astro::R_rtn_from_eci(astro::cartesian_from_qns(filter->observer())) *
              (nu_norm > 0.0 ? Eigen::Vector3d(nu_eci * std::sqrt(us.nis) / nu_norm) : Eigen::Vector3d::Zero());
          std::fprintf(innovations, "%lld,%s,%.6f,%.6f,%.6f,%.6f,%d,%d\n", static_cast<long long>(tb.t.ns_since_j2000),
                       ids[static_cast<std::size_t>(tb.b.target)].c_str(), w_rtn.x(), w_rtn.y(), w_rtn.z(), us.nis,
                       us.usable ? 1 : 0, us.gated ? 1 : 0);
        }
      }
    };
    fuse_until(g.t.ns_since_j2000, false);
    filter->time_update(g.t);
    filter->update_gnss(g);
    fuse_until(g.t.ns_since_j2000, true);
    sod::SodFilter f0 = *filter;
    // --report-ahead-s: what the navigator's telemetry reports while its
    // filter is that far behind the clock (its linearised prediction).
    const astro::TimeTT t_rep = g.t.plus_seconds(report_ahead_s);
    if (report_ahead_s > 0.0) (void)f0.predict_linearised(t_rep);
    sod::SodFilter& f = f0;
    const auto it = truth.find(t_rep.ns_since_j2000);
    if (it == truth.end() || !it->second.count(observer)) continue;
    const astro::QnsElements obs_true = astro::qns_from_cartesian(it->second.at(observer));
    const double orbits = static_cast<double>(t_rep.ns_since_j2000 - t0) * 1e-9 / period_s;
    const double a_obs_m = astro::QnsElements::from_vector(f.state().head<6>()).a_m;  // the navigator's a_o
    for (int k = 0; k < n; ++k) {
      const auto& id = ids[static_cast<std::size_t>(k)];
      if (!it->second.count(id)) continue;
      const Vec6 roe_true = astro::roe_from_qns(obs_true, astro::qns_from_cartesian(it->second.at(id))).as_vector();
      const int off = f.layout().target_offset(k);
      Vec6 d = f.state().segment<6>(off) - roe_true;
      d[1] = std::remainder(d[1], 2.0 * M_PI);
      Mat6 Pk = f.covariance().block<6, 6>(off, off);
      // What the navigator reports: the gravity budget in the covariance, not in the filter.
      if (const auto gp = gravity_periodic.find(id); gp != gravity_periodic.end()) {
        Pk.diagonal() += (gp->second / a_obs_m).cwiseAbs2();
      }
      const double nees = d.dot(Pk.ldlt().solve(d));
      const auto ku = static_cast<std::size_t>(k);
      const double range_m = (it->second.at(id).r_m - it->second.at(observer).r_m).norm();
      if (std::abs(d[1] * a_m) > 0.01 * range_m) {
        steps_after_outside[ku] = 0;
      } else if (steps_after_outside[ku]++ == 0) {
        first_step_after_outside[ku] = orbits;
      }
      if (orbits >= after_orbits) {
        nees_sum[static_cast<std::size_t>(k)] += nees;
        ++nees_steps[static_cast<std::size_t>(k)];
      }
      if (csv) {
        std::fprintf(csv, "%lld,%s", static_cast<long long>(g.t.ns_since_j2000), id.c_str());
        for (int j = 0; j < 6; ++j) std::fprintf(csv, ",%.4f", d[j] * a_m);
        for (int j = 0; j < 6; ++j) std::fprintf(csv, ",%.4f", std::sqrt(Pk(j, j)) * a_m);
        // The reported a*ROE covariance (m^2), upper triangle row by row, for studies by principal direction.
        std::fprintf(csv, ",%.4f,", nees);
        for (int i = 0; i < 6; ++i)
          for (int j = i; j < 6; ++j) std::fprintf(csv, "%s%.10e", i + j ? " " : "", Pk(i, j) * a_m * a_m);
        std::fprintf(csv, ",%.3f\n", range_m);
      }
    }
  }
  if (csv) std::fclose(csv);
  if (innovations) std::fclose(innovations);
  if (!filter) throw std::runtime_error(run_dir + "/gnss.csv: no valid fix of " + observer);
  if (!bearings.empty() && std::all_of(offered.begin(), offered.end(), [](int c) { return c == 0; }))
    throw std::runtime_error(run_dir + ": none of the " + std::to_string(bearings.size()) + " bearings of " + observer +
                             " given to a target fell within the GNSS fixes; nothing to replay");
  if (bearings.empty())
    throw std::runtime_error(run_dir + "/imp/" + observer + "/measurements.csv: none of its " +
                             std::to_string(unassigned) + " bearings lies within 3 px of a target's true pixel in "
                             "its frame (frames.csv); nothing to replay");
  const sod::SodFilter& f = *filter;
  std::printf("%s, observer %s, bearings %s (seed %llu, sigma x %.2f); %d recorded bearings not within 3 px of a "
              "target, %d left out as blended, %d recorded twice fused once; orbits of %.1f s from the first fix\n",
              run_dir.c_str(), observer.c_str(), bearings_mode.c_str(), static_cast<unsigned long long>(seed),
              sigma_scale, unassigned, blended, repeated, period_s);
  for (int k = 0; k < n; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    char converged[64] = "never";
    if (steps_after_outside[ku] > 0)
      std::snprintf(converged, sizeof converged, "%.2f orbits", first_step_after_outside[ku]);
    std::printf("  %s: %d of %d bearings fused; average NEES after orbit %.1f: %.2f (%d steps); final a*dlambda "
                "1-sigma %.0f m; within 1 %% of range from %s on\n",
                ids[ku].c_str(), fused[ku], offered[ku], after_orbits,
                nees_steps[ku] ? nees_sum[ku] / nees_steps[ku] : std::nan(""), nees_steps[ku], f.a_roe_sigma_m(k)[1],
                converged);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "artms-sod-replay: %s\n", e.what());
    return 1;
  }
}
