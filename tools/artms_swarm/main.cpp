// artms-swarm: validates scenarios and runs a swarm (DESIGN.md section 7):
// starts truth, camera renderer, crosslink emulator, one observer per
// observer and the recorder; supervises them (a child that dies is named, the
// others are stopped cleanly, the exit status is non-zero, no orphans); shows
// progress; writes summary.json and timing.json into the run folder.
#include <algorithm>
#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "artms/config/uplink.hpp"
#include "artms/imaging/camera.hpp"
#include "artms/imaging/star_catalog.hpp"
#include "artms/io/duration.hpp"
#include "artms/sod/apriori.hpp"
#include "artms/astro/roe.hpp"
#include <random>
#include "artms/io/csv.hpp"
#include "artms/io/oem.hpp"
#include "artms/io/paths.hpp"
#include "artms/render/camera_calibration.hpp"
#include "artms/runtime/runtime.hpp"
#include "evaluation.hpp"
#include "in_process.hpp"
#include "memory.hpp"

namespace {

// Navigation mode 1: the ground a-priori of every other spacecraft, as a
// ground orbit determination o.apriori.age_days old would give it (paper:
// "initialized using stale information from the ground (approximately 3-4
// days old)"): the true osculating ROE at the epoch plus an error drawn from
// the covariance that age implies (sod::apriori_from_age), seeded by the run
// seed and the observer id so that runs are reproducible.
void add_ground_apriori(const artms::config::Scenario& sc, const artms::config::ObserverConfig& o,
                        artms::config::ObserverUplink& up) {
  using namespace artms;
  const astro::QnsElements obs = astro::qns_from_cartesian(sc.initial_state_eci(o.spacecraft));
  const sod::AprioriRoe ap = sod::apriori_from_age(o.apriori.age_days, obs.a_m);
  std::uint64_t h = sc.seed * 0x9E3779B97F4A7C15ULL;
  for (char c : o.spacecraft) h = (h ^ static_cast<unsigned char>(c)) * 0x100000001B3ULL;
  std::mt19937_64 rng(h);
  up.apriori_age_days = o.apriori.age_days;
  for (const auto& s : sc.spacecraft) {
    if (s.id == o.spacecraft) continue;
    if (!o.targets.empty() && std::find(o.targets.begin(), o.targets.end(), s.id) == o.targets.end()) continue;
    const astro::Roe truth = astro::roe_from_qns(obs, astro::qns_from_cartesian(sc.initial_state_eci(s.id)));
    config::TargetApriori t;
    t.target = s.id;
    t.roe = truth.as_vector() + sod::draw_apriori_error_a_roe_m(ap, rng) / obs.a_m;
    t.P_roe = ap.P_roe;
    up.apriori.push_back(t);
  }
}

// Navigation mode 4: the coarse ground orbit of the observer (paper,
// "Absolute Navigation": "artificially degraded orbit knowledge"): its true
// initial orbit displaced by an error drawn from o.coarse_orbit_sigma_a_roe_m
// (seeded by the run seed and the observer id, a stream apart from the
// a-priori's) or the scenario's own error, uplinked with that covariance.
void add_coarse_orbit(const artms::config::Scenario& sc, const artms::config::ObserverConfig& o,
                      artms::config::ObserverUplink& up) {
  using namespace artms;
  std::uint64_t h = (sc.seed + 0x51ED270B2A7C1F3DULL) * 0x9E3779B97F4A7C15ULL;
  for (char c : o.spacecraft) h = (h ^ static_cast<unsigned char>(c)) * 0x100000001B3ULL;
  std::mt19937_64 rng(h);
  const astro::StateVector truth = sc.initial_state_eci(o.spacecraft);
  const sod::CoarseOrbit c =
      o.coarse_orbit_error_a_roe_m
          ? sod::coarse_orbit_with_error(truth, o.coarse_orbit_sigma_a_roe_m, *o.coarse_orbit_error_a_roe_m)
          : sod::draw_coarse_orbit(truth, o.coarse_orbit_sigma_a_roe_m, rng);
  up.coarse_orbit = config::ObserverUplink::CoarseOrbit{sc.epoch, c.x_eci, c.P_rv};
}

void write_onboard_star_catalog(const std::filesystem::path& path, artms::astro::TimeTT epoch) {
  // Every BSC5 star with its magnitude: the observer identifies with the
  // brighter ones (fsw::kStarIdVmagLimit) and checks blends with all.
  const auto bsc = artms::imaging::StarCatalog::load_bsc5(artms::io::data_dir() + "/stars/bsc5.dat", 99.0);
  std::ofstream out(path);
  if (!out) throw std::runtime_error("cannot write " + path.string());
  out << "catalog_id,ux_eci,uy_eci,uz_eci,vmag\n";
  char line[192];
  for (const auto& s : bsc.stars()) {
    const auto u = s.unit_eci_at(epoch);
    std::snprintf(line, sizeof line, "%d,%.15f,%.15f,%.15f,%.2f\n", s.catalog_id, u.x(), u.y(), u.z(), s.vmag);
    out << line;
  }
}


using namespace artms;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

volatile sig_atomic_t g_signal = 0;
void on_signal(int s) { g_signal = s; }

fs::path self_dir() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::current_path() : exe.parent_path();
}

struct Child {
  std::string name;
  pid_t pid = -1;
  bool running = false;
  int exit_code = 0;     // exit status, or 128 + signal
  bool expected_stop = false;
};

std::string binary_for(const std::string& service) {
  if (service == "truth") return "artms-truth";
  if (service == "camera-renderer") return "artms-camera-renderer";
  if (service == "crosslink-emulator") return "artms-crosslink-emulator";
  if (service == "recorder") return "artms-recorder";
  if (service.rfind("observer-", 0) == 0) return "artms-observer";
  throw std::logic_error("no binary for service " + service);
}

pid_t spawn(const fs::path& bin, const std::vector<std::string>& args, const fs::path& log) {
  const pid_t pid = fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {
    // Child: die with the launcher (no orphans), log to the run folder.
    prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (getppid() == 1) _exit(126);
    const int fd = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
      dup2(fd, STDOUT_FILENO);
      dup2(fd, STDERR_FILENO);
      close(fd);
    }
    std::vector<char*> argv;
    std::string b = bin.string();
    argv.push_back(b.data());
    std::vector<std::string> copy = args;
    for (auto& a : copy) argv.push_back(a.data());
    argv.push_back(nullptr);
    execv(b.c_str(), argv.data());
    std::perror("execv");
    _exit(127);
  }
  return pid;
}

// Seconds as text that parses back to the same double (a child draws its epoch from it).
std::string exact_seconds(double s) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", s);
  return buf;
}

std::string hms(double s) {
  const long t = static_cast<long>(std::llround(s));
  char buf[32];
  std::snprintf(buf, sizeof buf, "%02ld:%02ld:%02ld", t / 3600, (t / 60) % 60, t % 60);
  return buf;
}

// A run-folder CSV (io::CsvTable), or nullopt when it is missing; a
// malformed one is reported in summary.json's "evaluation_errors".
std::optional<io::CsvTable> read_table(const fs::path& path, nlohmann::json& j) {
  if (!fs::exists(path)) return std::nullopt;
  try {
    auto t = io::CsvTable::read(path.string());
    if (t.truncated_line() > 0) {
      const std::string what = path.string() + ":" + std::to_string(t.truncated_line()) +
                               ": unfinished last line left out (a process stopped while writing it)";
      std::fprintf(stderr, "artms-swarm: %s\n", what.c_str());
      j["evaluation_errors"].push_back(what);
    }
    return t;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "artms-swarm: %s\n", e.what());
    j["evaluation_errors"].push_back(e.what());
    return std::nullopt;
  }
}

nlohmann::json make_summary(const config::Scenario& sc, const fs::path& dir,
                            const std::vector<Child>& children, double sim_s) {
  nlohmann::json j;
  j["scenario"] = sc.name;
  j["seed"] = sc.seed;
  // The run's epoch (drawn from the seed within epoch_window_s after the file's when that is > 0).
  j["epoch"] = {{"utc", astro::utc_string(sc.epoch)},
                {"tt_ns", sc.epoch.ns_since_j2000},
                {"nominal_utc", astro::utc_string(sc.epoch_nominal)},
                {"window_s", sc.epoch_window_s},
                {"offset_s", sc.epoch_offset_s}};
  // The orbit phase (drawn from the seed within window_deg when that is > 0).
  j["orbit_phase"] = {{"window_deg", sc.phase_window_deg}, {"offset_deg", sc.phase_offset_deg}};
  // The camera clocks' faults as the world has them: the file's offset and
  // drift plus the residuals drawn from the seed (time_tag_*_sigma).
  j["camera_clock_faults"] = nlohmann::json::array();
  for (const auto& f : sc.faults) {
    if (f.time_tag_offset_total_s() == 0.0 && f.time_tag_drift_total_ppm() == 0.0) continue;
    j["camera_clock_faults"].push_back({{"observer", f.observer.empty() ? "all" : f.observer},
                                        {"offset_s", f.time_tag_offset_total_s()},
                                        {"drift_ppm", f.time_tag_drift_total_ppm()},
                                        {"offset_drawn_s", f.time_tag_offset_drawn_s},
                                        {"drift_drawn_ppm", f.time_tag_drift_drawn_ppm}});
  }
  j["sim_duration_s"] = sim_s;
  j["orbits"] = sim_s / sc.reference_period_s();
  // Whether the world is richer than the onboard model (issue 17): the two
  // force models side by side.
  const auto fm = [](const dynamics::ForceModelOptions& f) {
    return nlohmann::json{{"gravity_degree", f.gravity_degree}, {"gravity_order", f.gravity_order}, {"drag", f.drag},
                          {"atmosphere", f.atmosphere_model == dynamics::AtmosphereModel::kHarrisPriester
                                             ? "harris-priester"
                                             : "jacchia-scaled-harris-priester"},
                          {"sun", f.sun}, {"moon", f.moon}, {"srp", f.srp}, {"description", f.describe()}};
  };
  j["force_models"] = {{"truth", fm(sc.force_model)}, {"onboard", fm(sc.onboard_force_model)},
                       {"agree", sc.force_models_agree()}};
  j["processes"] = nlohmann::json::array();
  for (const auto& c : children) j["processes"].push_back({{"name", c.name}, {"exit_code", c.exit_code}});
  std::map<std::string, io::OemSegment> truth;
  if (fs::exists(dir / "truth.oem")) {
    for (auto& s : io::read_oem_file((dir / "truth.oem").string()).segments) truth[s.object_name] = s;
  }
  j["observers"] = nlohmann::json::object();
  std::map<std::string, std::optional<io::CsvTable>> nav;
  for (const auto& o : sc.observers) nav[o.spacecraft] = read_table(dir / "nav" / (o.spacecraft + ".csv"), j);
  for (const auto& o : sc.observers) {
    nlohmann::json obs;
    const auto& tab = nav[o.spacecraft];
    const bool any = tab && !tab->empty();
    const std::size_t last = any ? tab->size() - 1 : 0;
    obs["mode"] = any ? static_cast<int>(tab->integer(last, "mode")) : o.mode;
    obs["mode_requested"] = o.mode;
    nlohmann::json abs = {{"final_pos_error_m", nullptr}, {"final_pos_sigma_m", nullptr}};
    if (any && tab->text(last, "health") == "0") {
      const astro::TimeTT t{tab->integer(last, "t_tt_ns")};
      const astro::Vec3 r(tab->number(last, "x_m"), tab->number(last, "y_m"), tab->number(last, "z_m"));
      const double sigma = std::sqrt(std::pow(tab->number(last, "sigma_x_m"), 2) +
                                     std::pow(tab->number(last, "sigma_y_m"), 2) +
                                     std::pow(tab->number(last, "sigma_z_m"), 2));
      abs["final_pos_sigma_m"] = sigma;
      auto it = truth.find(o.spacecraft);
      if (it != truth.end()) {
        for (const auto& smp : it->second.samples) {
          if (smp.t == t) abs["final_pos_error_m"] = (smp.x_eci.r_m - r).norm();
        }
      }
    }
    obs["absolute"] = abs;
    obs["targets"] = nlohmann::json::object();
    j["observers"][o.spacecraft] = obs;
  }
  // Camera: frames scheduled / dropped (frame truth), received (observer).
  {
    std::map<std::string, std::map<std::string, std::pair<bool, bool>>> seen;  // obs -> frame -> (dropped, excluded)
    if (const auto frames = read_table(dir / "frames.csv", j)) {
      for (std::size_t k = 0; k < frames->size(); ++k) {
        seen[frames->text(k, "observer")][frames->text(k, "frame")] = {frames->text(k, "dropped") == "1",
                                                                        frames->text(k, "exclusion") != "none"};
      }
    }
    j["camera"] = nlohmann::json::object();
    for (const auto& o : sc.observers) {
      long scheduled = 0, dropped = 0, excluded = 0;
      for (const auto& [frame, fl] : seen[o.spacecraft]) {
        ++scheduled;
        dropped += fl.first ? 1 : 0;
        excluded += fl.second ? 1 : 0;
      }
      const auto& tab = nav[o.spacecraft];
      const long received = tab && !tab->empty() ? static_cast<long>(tab->integer(tab->size() - 1, "frames_received")) : 0;
      j["camera"][o.spacecraft] = {{"cadence_s", o.camera.cadence_s},
                                   {"frames_scheduled", scheduled},
                                   {"frames_dropped", dropped},
                                   {"frames_excluded", excluded},
                                   {"frames_received", received},
                                   {"dropout_rate", scheduled > 0 ? static_cast<double>(dropped) / static_cast<double>(scheduled) : 0.0}};
    }
  }
  // Crosslink accounting: isl.csv holds one row per (broadcast, directed
  // link) with its outcome (delivered, or dropped with a reason), so that
  // per link sent = delivered + dropped holds by construction.
  {
    const std::vector<std::string> reasons = {"outage", "loss", "range", "disabled", "end_of_run", "no_receiver"};
    const auto zero = [&]() {
      nlohmann::json d = nlohmann::json::object();
      for (const auto& r : reasons) d[r] = 0;
      return nlohmann::json{{"sent", 0}, {"delivered", 0}, {"dropped", d}};
    };
    nlohmann::json total = zero();
    nlohmann::json per_link = nlohmann::json::object();
    for (const auto& a : sc.observers) {
      for (const auto& b : sc.observers) {
        if (a.spacecraft != b.spacecraft) per_link[a.spacecraft + "->" + b.spacecraft] = zero();
      }
    }
    const auto isl = read_table(dir / "isl.csv", j);
    for (std::size_t k = 0; isl && k < isl->size(); ++k) {
      const std::string key = isl->text(k, "sender") + "->" + isl->text(k, "receiver");
      if (!per_link.contains(key)) per_link[key] = zero();
      for (nlohmann::json* acc : {&total, &per_link[key]}) {
        (*acc)["sent"] = (*acc)["sent"].get<long>() + 1;
        if (isl->text(k, "status") == "delivered") {
          (*acc)["delivered"] = (*acc)["delivered"].get<long>() + 1;
        } else {
          auto& d = (*acc)["dropped"];
          d[isl->text(k, "reason")] = d.value(isl->text(k, "reason"), 0L) + 1;
        }
      }
    }
    total["per_link"] = per_link;
    j["isl"] = total;
  }
  return j;
}

int cmd_validate(const std::string& path) {
  const auto diags = config::validate_scenario_file(path);
  for (const auto& d : diags) std::cerr << d.format() << "\n";
  if (!diags.empty()) {
    std::cerr << "artms-swarm: " << path << ": " << diags.size() << " error(s)\n";
    return 1;
  }
  std::cout << path << ": valid\n";
  return 0;
}

int cmd_run(const std::string& scenario_path, const std::string& duration, double orbits,
            std::optional<std::uint64_t> seed, const std::string& epoch_window,
            std::optional<double> phase_window_deg, const std::string& rate_text,
            std::string out,
            double step_timeout_s, bool in_process, bool report) {
  config::Scenario sc;
  try {
    sc = config::load_scenario(scenario_path);
  } catch (const config::ScenarioError& e) {
    std::cerr << e.what();
    return 2;
  }
  if (!duration.empty()) sc.duration_s = io::parse_duration_s(duration);
  if (orbits > 0.0) sc.duration_s = std::round(orbits * sc.reference_period_s() / sc.step_s) * sc.step_s;
  if (!epoch_window.empty()) config::set_epoch_window(sc, io::parse_duration_s(epoch_window));
  if (phase_window_deg) config::set_phase_window(sc, *phase_window_deg);
  if (seed) config::set_seed(sc, *seed);
  double rate = 0.0;
  if (rate_text != "max") {
    char* end = nullptr;
    rate = std::strtod(rate_text.c_str(), &end);
    if (*end != '\0' || !(rate > 0.0)) {
      std::cerr << "artms-swarm: --rate must be 'max' or a positive number, got '" << rate_text << "'\n";
      return 2;
    }
  }
  if (in_process && rate > 0.0) {
    std::cerr << "artms-swarm: --in-process runs in lock step as fast as possible; --rate " << rate_text
              << " needs the DDS run\n";
    return 2;
  }
  if (out.empty()) {
    char stamp[32];
    const std::time_t now = std::time(nullptr);
    std::strftime(stamp, sizeof stamp, "%Y%m%d-%H%M%S", std::gmtime(&now));
    out = "runs/" + sc.name + "-" + stamp;
  }
  const fs::path dir = fs::absolute(out);
  fs::create_directories(dir / "logs");
  for (const char* stale : {"summary.json", "timing.json", "truth.oem"}) fs::remove(dir / stale);

  const std::vector<std::string> services = config::services(sc);
  std::vector<Child> children;
  const std::string dur = std::to_string(sc.duration_s);
  const fs::path bin_dir = self_dir();
  const auto wall0 = Clock::now();
  // Observers get only what the ground uplinks (no truth); the rest read the scenario.
  fs::create_directories(dir / "uplink");
  // The onboard star catalog (V <= 6.5 BSC5 directions at the epoch) and
  // each camera's calibration go up with the uplink: IMP needs both and
  // never reads the renderer's files.
  write_onboard_star_catalog(dir / "uplink" / "star_catalog.csv", sc.epoch);
  for (const auto& o : sc.observers) {
    config::ObserverUplink up = config::make_uplink(sc, o.spacecraft);
    up.camera_calibration = render::calibration_of_model(o.camera.model);
    up.star_catalog_file = "star_catalog.csv";
    if (o.mode == 1 || o.mode == 3 || o.mode == 4) add_ground_apriori(sc, o, up);
    if (o.mode == 4) add_coarse_orbit(sc, o, up);
    config::write_uplink(up, (dir / "uplink" / (o.spacecraft + ".json")).string());
  }
  struct sigaction sa{};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);

  const bool tty = isatty(STDERR_FILENO) != 0;
  double sim_s = 0.0;
  std::string failure;
  swarm::MemorySampler memory;
  auto last_print = Clock::now() - std::chrono::seconds(10);
  const auto show_progress = [&]() {
    const auto now = Clock::now();
    if (now - last_print <= std::chrono::milliseconds(tty ? 200 : 5000)) return;
    last_print = now;
    const double wall = std::chrono::duration<double>(now - wall0).count();
    const double rtf = wall > 0 ? sim_s / wall : 0.0;
    const double frac = sc.duration_s > 0 ? sim_s / sc.duration_s : 1.0;
    const double eta = rtf > 0 ? (sc.duration_s - sim_s) / rtf : 0.0;
    if (tty) {
      const int width = 30, filled = static_cast<int>(frac * width);
      std::fprintf(stderr, "\r[%s%s] %5.1f%%  sim %s / %s  %.0fx real time  ETA %s   ",
                   std::string(static_cast<std::size_t>(filled), '#').c_str(),
                   std::string(static_cast<std::size_t>(width - filled), '.').c_str(), 100 * frac, hms(sim_s).c_str(),
                   hms(sc.duration_s).c_str(), rtf, hms(eta).c_str());
    } else {
      std::fprintf(stderr, "artms-swarm: sim %s / %s (%.0f%%), %.0fx real time, ETA %s\n", hms(sim_s).c_str(),
                   hms(sc.duration_s).c_str(), 100 * frac, rtf, hms(eta).c_str());
    }
  };
  if (in_process) {
    // The same objects in this process, no DDS (in_process.hpp); the
    // processes of summary.json are the components that stand for them.
    for (const auto& name : services) children.push_back({name, -1, false, 0, false});
    std::fprintf(stderr, "artms-swarm: %s, %zu components in one process (--in-process), %s simulated, seed %llu\n",
                 sc.name.c_str(), children.size(), hms(sc.duration_s).c_str(), static_cast<unsigned long long>(sc.seed));
    const swarm::InProcessResult r = swarm::run_in_process(
        sc, dir,
        [&](double s) {
          sim_s = s;
          show_progress();
        },
        [&]() { return g_signal != 0; });
    if (!r.ok) {
      failure = g_signal != 0 ? std::string("interrupted by signal ") + std::to_string(g_signal) : r.failure;
      for (auto& c : children) {
        if (c.name == r.failed) c.exit_code = 1;
      }
      std::fprintf(stderr, "%sartms-swarm: %s\n", tty ? "\n" : "", failure.c_str());
    }
  } else {
  // Each run gets its own DDS domain so that concurrent runs never meet.
  if (std::getenv("ARTMS_DDS_DOMAIN") == nullptr) {
    setenv("ARTMS_DDS_DOMAIN", std::to_string(1 + getpid() % 200).c_str(), 1);
  }
  dds::ensure_loopback_config();
  // The launcher follows the clock for progress (a reader of the tick topic).
  dds::Participant participant(dds::domain_from_environment());
  runtime::TopicSet topics(participant);
  dds::Reader<artms_msg_ClockTick> ticks(participant, topics.clock_tick, runtime::clock_qos());
  dds::WaitSet ws(participant);
  ws.attach(ticks.handle());
  for (const auto& name : services) {
    const bool observer = name.rfind("observer-", 0) == 0;
    const std::string input = observer ? (dir / "uplink" / (name.substr(9) + ".json")).string()
                                       : fs::absolute(scenario_path).string();
    std::vector<std::string> args = {observer ? "--uplink" : "--scenario", input,
                                     "--out",      dir.string(),
                                     "--name",     name,
                                     "--duration", dur,
                                     "--seed",     std::to_string(sc.seed),
                                     "--epoch-window", exact_seconds(sc.epoch_window_s),
                                     "--phase-window-deg", exact_seconds(sc.phase_window_deg),
                                     "--step-timeout", std::to_string(step_timeout_s)};
    if (rate > 0.0) {
      args.push_back("--rate");
      args.push_back(std::to_string(rate));
    }
    Child c;
    c.name = name;
    c.pid = spawn(bin_dir / binary_for(name), args, dir / "logs" / (name + ".log"));
    c.running = true;
    children.push_back(c);
  }
  std::fprintf(stderr, "artms-swarm: %s, %zu processes, %s simulated, seed %llu, DDS domain %s\n",
               sc.name.c_str(), children.size(), hms(sc.duration_s).c_str(),
               static_cast<unsigned long long>(sc.seed), std::getenv("ARTMS_DDS_DOMAIN"));

  const auto stop_all = [&](int sig) {
    for (auto& c : children) {
      if (c.running) {
        c.expected_stop = true;
        kill(c.pid, sig);
      }
    }
  };
  bool stopping = false;
  Clock::time_point stop_deadline{};
  for (;;) {
    // Reap children.
    int status = 0;
    pid_t pid;
    while ((pid = waitpid(-1, &status, WNOHANG)) > 0) {
      for (auto& c : children) {
        if (c.pid != pid) continue;
        c.running = false;
        c.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
        if (c.exit_code != 0 && failure.empty() && !stopping) {
          failure = c.name + (WIFEXITED(status) ? " exited with code " + std::to_string(c.exit_code)
                                                : " was killed by signal " + std::to_string(WTERMSIG(status)));
          std::fprintf(stderr, "%sartms-swarm: %s; stopping the other processes\n", tty ? "\n" : "",
                       failure.c_str());
          stopping = true;
          stop_deadline = Clock::now() + std::chrono::seconds(15);
          stop_all(SIGTERM);
        }
      }
    }
    bool any = false;
    for (const auto& c : children) any = any || c.running;
    if (!any) break;
    if (g_signal != 0 && !stopping) {
      failure = std::string("interrupted by signal ") + std::to_string(g_signal);
      std::fprintf(stderr, "%sartms-swarm: %s; stopping every process (outputs are flushed)\n",
                   tty ? "\n" : "", failure.c_str());
      stopping = true;
      stop_deadline = Clock::now() + std::chrono::seconds(15);
      stop_all(SIGTERM);
    }
    if (stopping && Clock::now() > stop_deadline) stop_all(SIGKILL);
    // Progress from the clock.
    ticks.take_each([&](const artms_msg_ClockTick& t) {
      sim_s = std::max(sim_s, astro::seconds_between(sc.epoch, astro::TimeTT{t.t_tt_ns}));
    });
    memory.sample(children, sim_s);
    show_progress();
    ws.wait(0.1);
  }
  }
  const double wall = std::chrono::duration<double>(Clock::now() - wall0).count();
  if (tty) std::fprintf(stderr, "\n");

  bool ok = failure.empty();
  for (const auto& c : children) ok = ok && c.exit_code == 0;
  nlohmann::json summary = make_summary(sc, dir, children, ok ? sc.duration_s : sim_s);
  swarm::evaluate_run(sc, dir, summary);
  std::ofstream(dir / "summary.json") << summary.dump(2) << "\n";
  const nlohmann::json timing = {{"wall_time_s", wall},
                                 {"sim_time_s", ok ? sc.duration_s : sim_s},
                                 {"real_time_factor", wall > 0 ? (ok ? sc.duration_s : sim_s) / wall : 0.0},
                                 {"processes", in_process ? std::size_t{1} : children.size()},
                                 {"runtime", in_process ? "in-process" : "dds"},
                                 {"rss_kb", memory.to_json()}};
  std::ofstream(dir / "timing.json") << timing.dump(2) << "\n";

  // Summary table.
  std::printf("\n%-22s %s\n", "process", "exit");
  for (const auto& c : children) std::printf("%-22s %d\n", c.name.c_str(), c.exit_code);
  std::printf("\n%-8s %-6s %-18s %-18s\n", "observer", "mode", "final pos err [m]", "final pos 1-sigma [m]");
  for (const auto& [id, o] : summary["observers"].items()) {
    const auto& a = o["absolute"];
    std::printf("%-8s %-6d %-18s %-18s\n", id.c_str(), o["mode"].get<int>(),
                a["final_pos_error_m"].is_null() ? "-" : std::to_string(a["final_pos_error_m"].get<double>()).c_str(),
                a["final_pos_sigma_m"].is_null() ? "-" : std::to_string(a["final_pos_sigma_m"].get<double>()).c_str());
  }
  std::printf("\n%-8s %-7s %-12s %-16s %-16s %-11s %-9s\n", "observer", "target", "range [km]", "dlambda err [%]",
              "dlambda 1-sig [%]", "conv [orb]", "bearings");
  for (const auto& [id, o] : summary["observers"].items()) {
    if (!o.contains("targets")) continue;
    for (const auto& [tid, t] : o["targets"].items()) {
      if (!t.value("estimated", true)) {
        std::printf("%-8s %-7s %s\n", id.c_str(), tid.c_str(), t.value("why", std::string("never estimated")).c_str());
        continue;
      }
      std::printf("%-8s %-7s %-12.1f %-16.2f %-16.2f %-11s %-9ld\n", id.c_str(), tid.c_str(),
                  t["final_range_m"].get<double>() / 1e3, t["final_dlambda_error_pct"].get<double>(),
                  t["final_dlambda_sigma_pct"].get<double>(),
                  t["convergence_orbits"].is_null() ? "-" : std::to_string(t["convergence_orbits"].get<double>()).substr(0, 5).c_str(),
                  t["local_measurements"].get<long>() + t["remote_measurements"].get<long>());
    }
  }
  // Plots (artms-report): failures are reported, never fatal.
  if (report && fs::exists(bin_dir / "artms-report")) {
    const pid_t rp = spawn(bin_dir / "artms-report", {dir.string()}, dir / "logs" / "report.log");
    int st = 0;
    waitpid(rp, &st, 0);
    if (!WIFEXITED(st) || WEXITSTATUS(st) != 0) {
      std::fprintf(stderr, "artms-swarm: artms-report failed (see %s)\n", (dir / "logs" / "report.log").c_str());
    } else {
      std::printf("\nplots: %s\n", (dir / "plots").c_str());
    }
  }
  std::printf("\nsimulated %s in %.1f s (%.0fx real time)\nrun folder: %s\n", hms(sim_s).c_str(), wall,
              wall > 0 ? sim_s / wall : 0.0, dir.c_str());
  if (!ok) {
    std::fprintf(stderr, "artms-swarm: run failed: %s\n",
                 failure.empty() ? "a process exited with a non-zero code" : failure.c_str());
    return g_signal != 0 ? 130 : 1;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ARTMS swarm emulator: validate scenarios and run swarms of ARTMS observers.",
               "artms-swarm"};
  app.require_subcommand(1);
  auto* validate = app.add_subcommand("validate", "check a scenario file; every error names file, line, column and field");
  std::string vpath;
  validate->add_option("scenario", vpath, "scenario YAML")->required();
  auto* run = app.add_subcommand("run", "run a scenario end to end and record it");
  std::string rpath, duration, out, rate = "max";
  double orbits = 0.0, step_timeout = 120.0;
  std::uint64_t seed = 0;
  run->add_option("scenario", rpath, "scenario YAML")->required();
  auto* d = run->add_option("--duration", duration, "simulated span (6h, 1d, seconds)");
  auto* o = run->add_option("--orbits", orbits, "simulated span in orbits of the first observer");
  d->excludes(o);
  auto* s = run->add_option("--seed", seed, "random seed (overrides the scenario)");
  std::string epoch_window;
  run->add_option("--epoch-window", epoch_window,
                  "draw the run's epoch from the seed within this span after the scenario's (overrides its "
                  "epoch_window; 24h: each seed over its own part of the geopotential)");
  double phase_window_deg = 0.0;
  auto* pw = run->add_option("--phase-window-deg", phase_window_deg,
                             "draw the orbit phase from the seed within this angle (overrides the scenario's "
                             "phase_window_deg; 360: each seed from its own point of the orbit)")
                 ->check(CLI::Range(0.0, 360.0));
  run->add_option("--rate", rate, "max (lock-step, as fast as possible) or X times real time")->capture_default_str();
  run->add_option("--out", out, "run folder (default runs/<scenario>-<UTC time>)");
  run->add_option("--step-timeout", step_timeout, "seconds a process may take for one step")->capture_default_str();
  bool in_process = false;
  run->add_flag("--in-process", in_process,
                "step the same objects in this one process without DDS (campaigns; same run folder as the DDS run)");
  bool no_report = false;
  run->add_flag("--no-report", no_report, "do not draw the run's plots (artms-report) at the end (campaigns draw their own)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  try {
    if (*validate) return cmd_validate(vpath);
    return cmd_run(rpath, duration, orbits, s->count() ? std::optional<std::uint64_t>(seed) : std::nullopt,
                   epoch_window, pw->count() ? std::optional<double>(phase_window_deg) : std::nullopt, rate, out, step_timeout, in_process, !no_report);
  } catch (const std::exception& e) {
    std::cerr << "artms-swarm: error: " << e.what() << "\n";
    return 2;
  }
}
