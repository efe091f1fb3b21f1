// artms-propagate: propagate one ECI J2000 state with the chosen force model
// (DESIGN.md section 7), writing CSV and optionally CCSDS OEM 2.0.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include "artms/astro/constants.hpp"
#include "artms/astro/elements.hpp"
#include "artms/io/duration.hpp"
#include "artms/io/number_list.hpp"
#include "artms/io/oem.hpp"
#include "artms/io/paths.hpp"
#include "artms/truth_propagator/cowell.hpp"

namespace {

using namespace artms;

int run(int argc, char** argv) {
  CLI::App app{
      "Propagate one spacecraft state (ECI J2000, m and m/s) with the truth propagator\n"
      "(Cowell, SUNDIALS CVODE) and write CSV (t_utc, t_tt_ns, x_m, y_m, z_m, vx_mps, vy_mps,\n"
      "vz_mps) and optionally a CCSDS OEM 2.0 file.",
      "artms-propagate"};
  std::string epoch, rv, oe, duration = "1d", step = "60s", force = "grav10,drag,sun,moon";
  std::string oem_path, out_path, name = "OBJECT";
  // Shown as --data-dir's default when found; looked up again (with the
  // places tried in the error) after parsing when not.
  std::string data_dir;
  try {
    data_dir = io::data_dir();
  } catch (const std::runtime_error&) {
  }
  dynamics::SpacecraftProperties sc;
  app.add_option("--epoch", epoch, "initial epoch, UTC (e.g. 2024-05-08T00:00:00Z)")->required();
  auto* rv_opt = app.add_option("--rv", rv, "initial state x,y,z,vx,vy,vz (m, m/s, ECI J2000)");
  auto* oe_opt = app.add_option("--oe", oe, "initial Keplerian elements a_m,e,i_deg,raan_deg,argp_deg,M_deg");
  rv_opt->excludes(oe_opt);
  app.add_option("--duration", duration, "span to propagate (90s, 30m, 6h, 1d)")->capture_default_str();
  app.add_option("--step", step, "output step (60s)")->capture_default_str();
  app.add_option("--force", force,
                 "force model: two-body | j2 | flight-like | comma list of gravN[_M],drag,drag-jacchia,sun,moon,srp")
      ->capture_default_str();
  app.add_option("--oem", oem_path, "also write a CCSDS OEM 2.0 (KVN) file");
  app.add_option("--out", out_path, "CSV output file")->required();
  app.add_option("--name", name, "object name in the OEM file")->capture_default_str();
  app.add_option("--mass", sc.mass_kg, "spacecraft mass (kg)")->capture_default_str();
  app.add_option("--drag-area", sc.drag_area_m2, "drag area (m^2)")->capture_default_str();
  app.add_option("--cd", sc.cd, "drag coefficient")->capture_default_str();
  app.add_option("--srp-area", sc.srp_area_m2, "SRP area (m^2)")->capture_default_str();
  app.add_option("--cr", sc.cr, "SRP coefficient")->capture_default_str();
  app.add_option("--data-dir", data_dir, "project data folder (gravity, atmosphere)")
      ->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  if (rv.empty() == oe.empty()) {
    std::cerr << "artms-propagate: error: give exactly one of --rv or --oe\n";
    return 2;
  }
  try {
    const astro::TimeTT t0 = astro::tt_from_utc_string(epoch);
    const double span_s = io::parse_duration_s(duration);
    const double step_s = io::parse_duration_s(step);
    if (!(step_s > 0.0)) throw std::invalid_argument("--step must be positive");
    astro::StateVector x0;
    if (!rv.empty()) {
      const auto v = io::parse_number_list(rv, 6, "--rv");
      x0 = {astro::Vec3(v[0], v[1], v[2]), astro::Vec3(v[3], v[4], v[5])};
    } else {
      const auto v = io::parse_number_list(oe, 6, "--oe");
      astro::KeplerElements k{v[0], v[1], v[2] * astro::kDegToRad, v[3] * astro::kDegToRad,
                              v[4] * astro::kDegToRad, v[5] * astro::kDegToRad};
      x0 = astro::cartesian_from_kepler(k);
    }
    sc.validate();
    if (data_dir.empty()) data_dir = io::data_dir();  // throws naming every place tried
    const auto options = dynamics::ForceModelOptions::parse(force);
    const auto forces = dynamics::ForceModel::load(options, data_dir);
    truth::CowellPropagator prop(forces, sc, t0, x0);

    std::ofstream csv(out_path);
    if (!csv) throw std::runtime_error("cannot write " + out_path);
    csv << "t_utc,t_tt_ns,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps\n";
    io::OemFile oem;
    oem.creation = t0;
    oem.segments.push_back({name, name, {}});
    const auto steps = static_cast<long>(std::floor(span_s / step_s + 1e-9));
    char line[320];
    for (long k = 0; k <= steps + 1; ++k) {
      double dt = static_cast<double>(k) * step_s;
      if (k == steps + 1) {
        if (span_s - static_cast<double>(steps) * step_s < 1e-6) break;
        dt = span_s;  // final partial step lands on the end of the span
      }
      const astro::TimeTT t = t0.plus_seconds(dt);
      const astro::StateVector x = prop.state_at(t);
      std::snprintf(line, sizeof line, "%s,%lld,%.6f,%.6f,%.6f,%.9f,%.9f,%.9f\n",
                    astro::utc_string(t, 6).c_str(), static_cast<long long>(t.ns_since_j2000),
                    x.r_m.x(), x.r_m.y(), x.r_m.z(), x.v_mps.x(), x.v_mps.y(), x.v_mps.z());
      csv << line;
      oem.segments[0].samples.push_back({t, x});
    }
    if (!csv) throw std::runtime_error("error while writing " + out_path);
    if (!oem_path.empty()) io::write_oem_file(oem_path, oem);
    const auto st = prop.stats();
    std::fprintf(stderr,
                 "artms-propagate: %zu states over %s with %s; CVODE %ld steps, %ld force "
                 "evaluations\n",
                 oem.segments[0].samples.size(), duration.c_str(), options.describe().c_str(),
                 st.steps, st.rhs_evaluations);
  } catch (const std::exception& e) {
    std::cerr << "artms-propagate: error: " << e.what() << "\n";
    return 2;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return run(argc, argv); }
