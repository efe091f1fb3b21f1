#include "artms/config/uplink.hpp"

#include <algorithm>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>

namespace artms::config {

using nlohmann::json;

namespace {

const char* atmosphere_name(dynamics::AtmosphereModel m) {
  return m == dynamics::AtmosphereModel::kHarrisPriester ? "harris-priester" : "jacchia-scaled-harris-priester";
}

json properties_json(const dynamics::SpacecraftProperties& p) {
  return {{"mass_kg", p.mass_kg}, {"drag_area_m2", p.drag_area_m2}, {"cd", p.cd},
          {"srp_area_m2", p.srp_area_m2}, {"cr", p.cr}};
}

dynamics::SpacecraftProperties properties_from(const json& j) {
  dynamics::SpacecraftProperties p;
  p.mass_kg = j.at("mass_kg").get<double>();
  p.drag_area_m2 = j.at("drag_area_m2").get<double>();
  p.cd = j.at("cd").get<double>();
  p.srp_area_m2 = j.at("srp_area_m2").get<double>();
  p.cr = j.at("cr").get<double>();
  return p;
}

json space_weather_json(const dynamics::SpaceWeather& w) {
  json daily = json::array();
  for (const auto& d : w.daily) daily.push_back({{"f107_sfu", d.f107_sfu}, {"kp", d.kp}});
  return {{"f107_sfu", w.f107_sfu},
          {"f107_81day_sfu", w.f107_81day_sfu},
          {"kp", w.kp},
          {"daily", daily},
          {"start_tt_ns", w.start.ns_since_j2000},
          {"f107_daily_sigma_sfu", w.f107_daily_sigma_sfu},
          {"kp_daily_sigma", w.kp_daily_sigma},
          {"density_error_sigma", w.density_error_sigma},
          {"density_error_time_s", w.density_error_time_s},
          {"seed", w.seed}};
}

dynamics::SpaceWeather space_weather_from(const json& j) {
  dynamics::SpaceWeather w;
  w.f107_sfu = j.at("f107_sfu").get<double>();
  w.f107_81day_sfu = j.at("f107_81day_sfu").get<double>();
  w.kp = j.at("kp").get<double>();
  for (const auto& d : j.at("daily")) w.daily.push_back({d.at("f107_sfu").get<double>(), d.at("kp").get<double>()});
  w.start = astro::TimeTT{j.at("start_tt_ns").get<std::int64_t>()};
  w.f107_daily_sigma_sfu = j.at("f107_daily_sigma_sfu").get<double>();
  w.kp_daily_sigma = j.at("kp_daily_sigma").get<double>();
  // Absent from uplinks written before the key existed (run folders replayed later).
  w.density_error_sigma = j.value("density_error_sigma", 0.0);
  w.density_error_time_s = j.value("density_error_time_s", dynamics::SpaceWeather{}.density_error_time_s);
  w.seed = j.at("seed").get<std::uint64_t>();
  return w;
}

}  // namespace

dynamics::SpacecraftProperties ObserverUplink::onboard_properties(const std::string& id) const {
  const auto it = onboard_properties_by_id.find(id);
  return it == onboard_properties_by_id.end() ? dynamics::SpacecraftProperties{} : it->second;
}

ObserverUplink make_uplink(const Scenario& s, const std::string& spacecraft) {
  ObserverUplink u;
  const ObserverConfig* obs = nullptr;
  for (const auto& o : s.observers) {
    if (o.spacecraft == spacecraft) obs = &o;
  }
  if (!obs) throw std::out_of_range("make_uplink: " + spacecraft + " is not an observer");
  u.scenario_name = s.name;
  u.epoch = s.epoch;
  u.duration_s = s.duration_s;
  u.step_s = s.step_s;
  u.seed = s.seed;
  u.force_model = s.onboard_force_model;  // what the spacecraft flies, not the world
  u.observer = *obs;
  u.tuning = s.tuning;
  u.crosslink_enabled = s.crosslink.enabled;
  u.isl_period_s = s.crosslink.period_s;
  u.isl_latency_s = s.crosslink.latency_s;
  for (const auto& o : s.observers) u.swarm_max_cadence_s = std::max(u.swarm_max_cadence_s, o.camera.cadence_s);
  u.use_remote_gnss = s.crosslink.use_remote_gnss;
  for (const auto& sc : s.spacecraft) {
    u.swarm_ids.push_back(sc.id);
    u.onboard_properties_by_id[sc.id] = sc.onboard_properties;
  }
  for (const auto& m : s.maneuvers) {
    if (m.planned && m.spacecraft == spacecraft) u.planned_maneuvers.push_back({m.epoch, m.dv_rtn_mps, m.execution_sigma_fraction});
  }
  return u;
}

void write_uplink(const ObserverUplink& u, const std::string& path) {
  const auto& f = u.force_model;
  const auto& o = u.observer;
  json apriori = json::array();
  for (const auto& a : u.apriori) {
    std::vector<double> roe(a.roe.data(), a.roe.data() + 6), P(a.P_roe.data(), a.P_roe.data() + 36);
    apriori.push_back({{"target", a.target}, {"roe", roe}, {"covariance_roe", P}});
  }
  json onboard = json::object();
  for (const auto& [id, p] : u.onboard_properties_by_id) onboard[id] = properties_json(p);
  json planned = json::array();
  for (const auto& m : u.planned_maneuvers) {
    planned.push_back({{"t_tt_ns", m.t.ns_since_j2000},
                       {"dv_rtn_mps", {m.dv_rtn_mps[0], m.dv_rtn_mps[1], m.dv_rtn_mps[2]}},
                       {"execution_sigma_fraction", m.execution_sigma_fraction}});
  }
  json coarse = nullptr;
  if (u.coarse_orbit) {
    const auto& c = *u.coarse_orbit;
    const auto& x = c.x_eci;
    coarse = {{"t_tt_ns", c.t.ns_since_j2000},
              {"r_eci_m", {x.r_m[0], x.r_m[1], x.r_m[2]}},
              {"v_eci_mps", {x.v_mps[0], x.v_mps[1], x.v_mps[2]}},
              {"covariance_rv", std::vector<double>(c.P_rv.data(), c.P_rv.data() + 36)}};
  }
  json outages = json::array();
  for (const auto& w : o.gnss.outages) outages.push_back({w.start.ns_since_j2000, w.end.ns_since_j2000});
  json gravity_periodic = json::object();
  for (const auto& [id, v] : o.target_gravity_periodic_a_roe_m) gravity_periodic[id] = {v[0], v[1], v[2], v[3], v[4], v[5]};
  const json j = {
      {"scenario", u.scenario_name},
      {"epoch_tt_ns", u.epoch.ns_since_j2000},
      {"duration_s", u.duration_s},
      {"step_s", u.step_s},
      {"seed", u.seed},
      {"force_model",
       {{"gravity_degree", f.gravity_degree}, {"gravity_order", f.gravity_order}, {"drag", f.drag},
        {"sun", f.sun}, {"moon", f.moon}, {"srp", f.srp},
        {"conical_shadow", f.shadow == dynamics::ShadowModel::kConical},
        {"hp_exponent", f.atmosphere.cosine_exponent}, {"hp_lag_rad", f.atmosphere.lag_angle_rad},
        {"atmosphere", atmosphere_name(f.atmosphere_model)},
        {"space_weather", space_weather_json(f.space_weather)},
        {"jacchia_reference_temperature_K", f.jacchia.reference_temperature_K},
        {"jacchia_semiannual", f.jacchia.semiannual}}},
      {"observer",
       {{"spacecraft", o.spacecraft},
        {"mode", o.mode},
        {"camera",
         {{"model", o.camera.model},
          {"boresight_plus_velocity", o.camera.boresight == astro::Boresight::kPlusVelocity},
          {"cadence_s", o.camera.cadence_s},
          {"time_tag_correction_s", o.camera.time_tag_correction_s}}},
        {"gnss",
         {{"enabled", o.gnss.enabled}, {"period_s", o.gnss.period_s},
          {"sigma_position_m", o.gnss.sigma_position_m},
          {"sigma_velocity_mps", o.gnss.sigma_velocity_mps}, {"outages_tt_ns", outages}}},
        {"apriori_age_days", o.apriori.age_days},
        {"targets", o.targets},
        {"target_ranges_m", o.target_ranges_m},
        {"target_gravity_periodic_sigma_m", gravity_periodic}}},
      {"tuning",
       {{"imp",
         {{"detection_sigma", u.tuning.imp.detection_sigma},
          {"dbscan_min_points", u.tuning.imp.dbscan_min_points},
          {"dbscan_radius_px", u.tuning.imp.dbscan_radius_px},
          {"dbscan_frames", u.tuning.imp.dbscan_frames},
          {"aided_detection_snr", u.tuning.imp.aided_detection_snr},
          {"aided_false_alarms", u.tuning.imp.aided_false_alarms},
          {"aberration_correction", u.tuning.imp.aberration_correction},
          {"signal_history", u.tuning.imp.signal_history},
          {"aided_stack_frames", u.tuning.imp.aided_stack_frames}}},
        {"bod",
         {{"enabled", u.tuning.bod.enabled}, {"period_s", u.tuning.bod.period_s},
          {"samples", u.tuning.bod.samples}, {"max_iterations", u.tuning.bod.max_iterations},
          {"range_min_m", u.tuning.bod.range_min_m}, {"range_max_m", u.tuning.bod.range_max_m},
          {"min_measurements", u.tuning.bod.min_measurements}, {"max_measurements", u.tuning.bod.max_measurements},
          {"batch_orbits", u.tuning.bod.batch_orbits},
          {"max_sigma_range_fraction", u.tuning.bod.max_sigma_range_fraction},
          {"max_residual_arcsec", u.tuning.bod.max_residual_arcsec}, {"check_chi2", u.tuning.bod.check_chi2},
          {"max_fit_ratio", u.tuning.bod.max_fit_ratio}, {"reinit_after_check5", u.tuning.bod.reinit_after_check5},
          {"model_correction", u.tuning.bod.model_correction}}},
        {"sod",
         {{"period_s", u.tuning.sod.period_s},
          {"bearing_sigma_arcsec", u.tuning.sod.bearing_sigma_arcsec},
          {"eps_assign", u.tuning.sod.eps_assign}, {"eps_ambig", u.tuning.sod.eps_ambig},
          {"max_steps_without_update", u.tuning.sod.max_steps_without_update},
          {"max_large_residuals", u.tuning.sod.max_large_residuals},
          {"underweighting", u.tuning.sod.underweighting},
          {"underweighting_nonlinearity", u.tuning.sod.underweighting_nonlinearity},
          {"adaptive_process_noise", u.tuning.sod.adaptive_process_noise},
          {"adaptive_targets", u.tuning.sod.adaptive_targets},
          {"adaptive_form", u.tuning.sod.adaptive_form == SodTuning::AdaptiveForm::kBlock ? "block" : "diagonal"},
          {"adaptive_average",
           u.tuning.sod.adaptive_average == SodTuning::AdaptiveAverage::kUnclamped ? "unclamped" : "clamped"},
          {"adaptive_time_constant_s", u.tuning.sod.adaptive_time_constant_s},
          {"process_noise_scale", u.tuning.sod.process_noise_scale},
          {"drag_density_error", u.tuning.sod.drag_density_error},
          {"nis_window", u.tuning.sod.nis_window},
          {"nis_false_alarm", u.tuning.sod.nis_false_alarm},
          {"time_tag", static_cast<int>(u.tuning.sod.time_tag)},
          {"time_tag_sigma_s", u.tuning.sod.time_tag_sigma_s},
          {"time_tag_drift_sigma_ppm", u.tuning.sod.time_tag_drift_sigma_ppm},
          {"time_tag_senders", u.tuning.sod.time_tag_senders},
          {"time_tag_senders_sigma_s", u.tuning.sod.time_tag_senders_sigma_s},
          {"estimate_ballistic", u.tuning.sod.estimate_ballistic},
          {"ballistic_sigma_fraction", u.tuning.sod.ballistic_sigma_fraction},
          {"ballistic_walk_fraction_per_day", u.tuning.sod.ballistic_walk()},
          {"ballistic_density_change_per_day", u.tuning.sod.ballistic_density_change_per_day},
          {"observer_acceleration_sigma_mps2", u.tuning.sod.observer_acceleration_sigma_mps2},
          {"target_lines", u.tuning.sod.target_lines == SodTuning::TargetLines::kConsiderObserver
                               ? "consider_observer"
                               : "update_observer"}}}}},
      {"crosslink",
       {{"enabled", u.crosslink_enabled}, {"period_s", u.isl_period_s},
        {"latency_s", u.isl_latency_s}, {"swarm_max_cadence_s", u.swarm_max_cadence_s},
        {"use_remote_gnss", u.use_remote_gnss}}},
      {"swarm_ids", u.swarm_ids},
      {"camera_calibration",
       {{"width_px", u.camera_calibration.width_px}, {"height_px", u.camera_calibration.height_px},
        {"fx_px", u.camera_calibration.fx_px}, {"fy_px", u.camera_calibration.fy_px},
        {"cx_px", u.camera_calibration.cx_px}, {"cy_px", u.camera_calibration.cy_px},
        {"k1", u.camera_calibration.k1}, {"k2", u.camera_calibration.k2},
        {"p1", u.camera_calibration.p1}, {"p2", u.camera_calibration.p2},
        {"psf_sigma_px", u.camera_calibration.psf_sigma_px},
        {"gain_e_per_dn", u.camera_calibration.gain_e_per_dn},
        {"saturation_dn", u.camera_calibration.saturation_dn},
        {"dn_shift_bits", u.camera_calibration.dn_shift_bits},
        {"match_tolerance_rad", u.camera_calibration.match_tolerance_rad},
        {"centroid_gaussian_fit", u.camera_calibration.centroid_gaussian_fit}}},
      {"star_catalog_file", u.star_catalog_file},
      {"apriori_age_days", u.apriori_age_days},
      {"coarse_orbit", coarse},
      {"apriori", apriori},
      {"onboard_properties", onboard},
      {"planned_maneuvers", planned},
  };
  std::ofstream out(path);
  if (!out) throw std::runtime_error("cannot write uplink file " + path);
  out << j.dump(2) << "\n";
}

ObserverUplink read_uplink(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open uplink file " + path);
  json j;
  try {
    j = json::parse(in);
  } catch (const json::exception& e) {
    throw std::runtime_error(path + ": not valid JSON: " + e.what());
  }
  try {
    ObserverUplink u;
    u.scenario_name = j.at("scenario").get<std::string>();
    u.epoch = astro::TimeTT{j.at("epoch_tt_ns").get<std::int64_t>()};
    u.duration_s = j.at("duration_s").get<double>();
    u.step_s = j.at("step_s").get<double>();
    u.seed = j.at("seed").get<std::uint64_t>();
    const auto& f = j.at("force_model");
    u.force_model.gravity_degree = f.at("gravity_degree").get<int>();
    u.force_model.gravity_order = f.at("gravity_order").get<int>();
    u.force_model.drag = f.at("drag").get<bool>();
    u.force_model.sun = f.at("sun").get<bool>();
    u.force_model.moon = f.at("moon").get<bool>();
    u.force_model.srp = f.at("srp").get<bool>();
    u.force_model.shadow = f.at("conical_shadow").get<bool>() ? dynamics::ShadowModel::kConical
                                                             : dynamics::ShadowModel::kCylindrical;
    u.force_model.atmosphere.cosine_exponent = f.at("hp_exponent").get<double>();
    u.force_model.atmosphere.lag_angle_rad = f.at("hp_lag_rad").get<double>();
    if (f.contains("atmosphere")) {  // older uplinks: Harris-Priester
      const auto name = f.at("atmosphere").get<std::string>();
      if (name == "jacchia-scaled-harris-priester") {
        u.force_model.atmosphere_model = dynamics::AtmosphereModel::kJacchiaScaledHarrisPriester;
      } else if (name != "harris-priester") {
        throw std::runtime_error(path + ": force_model.atmosphere: unknown model '" + name + "'");
      }
      u.force_model.space_weather = space_weather_from(f.at("space_weather"));
      u.force_model.jacchia.reference_temperature_K = f.at("jacchia_reference_temperature_K").get<double>();
      u.force_model.jacchia.semiannual = f.at("jacchia_semiannual").get<bool>();
    }
    const auto& o = j.at("observer");
    u.observer.spacecraft = o.at("spacecraft").get<std::string>();
    u.observer.mode = o.at("mode").get<int>();
    u.observer.camera.model = o.at("camera").at("model").get<std::string>();
    u.observer.camera.boresight = o.at("camera").at("boresight_plus_velocity").get<bool>()
                                      ? astro::Boresight::kPlusVelocity
                                      : astro::Boresight::kMinusVelocity;
    u.observer.camera.cadence_s = o.at("camera").at("cadence_s").get<double>();
    u.observer.camera.time_tag_correction_s = o.at("camera").at("time_tag_correction_s").get<double>();
    const auto& g = o.at("gnss");
    u.observer.gnss.enabled = g.at("enabled").get<bool>();
    u.observer.gnss.period_s = g.at("period_s").get<double>();
    u.observer.gnss.sigma_position_m = g.at("sigma_position_m").get<double>();
    u.observer.gnss.sigma_velocity_mps = g.at("sigma_velocity_mps").get<double>();
    for (const auto& w : g.at("outages_tt_ns")) {
      u.observer.gnss.outages.push_back(
          {astro::TimeTT{w.at(0).get<std::int64_t>()}, astro::TimeTT{w.at(1).get<std::int64_t>()}});
    }
    u.observer.apriori.age_days = o.at("apriori_age_days").get<double>();
    u.observer.targets = o.at("targets").get<std::vector<std::string>>();
    u.observer.target_ranges_m = o.at("target_ranges_m").get<std::vector<std::array<double, 2>>>();
    if (u.observer.target_ranges_m.size() != u.observer.targets.size()) {
      throw std::runtime_error(path + ": observer.target_ranges_m needs one [min, max] per target");
    }
    if (o.contains("target_gravity_periodic_sigma_m")) {  // older uplinks: none
      for (const auto& [id, v] : o.at("target_gravity_periodic_sigma_m").items()) {
        const auto sg = v.get<std::array<double, 6>>();
        const astro::Vec6 sig = Eigen::Map<const astro::Vec6>(sg.data());
        if (!sig.allFinite() || (sig.array() < 0.0).any()) {
          throw std::runtime_error(path + ": observer.target_gravity_periodic_sigma_m." + id +
                                   " must be finite and >= 0");
        }
        u.observer.target_gravity_periodic_a_roe_m[id] = sig;
      }
    }
    const auto& t = j.at("tuning");
    u.tuning.imp.detection_sigma = t.at("imp").at("detection_sigma").get<double>();
    u.tuning.imp.dbscan_min_points = t.at("imp").at("dbscan_min_points").get<int>();
    u.tuning.imp.dbscan_radius_px = t.at("imp").at("dbscan_radius_px").get<double>();
    u.tuning.imp.dbscan_frames = t.at("imp").at("dbscan_frames").get<int>();
    u.tuning.imp.aided_detection_snr = t.at("imp").at("aided_detection_snr").get<double>();
    u.tuning.imp.aided_false_alarms = t.at("imp").value("aided_false_alarms", 0.0);  // older: the fixed threshold
    if (!(u.tuning.imp.aided_false_alarms >= 0.0 && u.tuning.imp.aided_false_alarms <= 0.1)) {
      throw std::runtime_error(path + ": tuning.imp.aided_false_alarms must be in [0, 0.1]");
    }
    u.tuning.imp.aberration_correction = t.at("imp").value("aberration_correction", false);  // older: none
    u.tuning.imp.signal_history = t.at("imp").value("signal_history", false);  // older: each detection's own
    u.tuning.imp.aided_stack_frames = t.at("imp").value("aided_stack_frames", 0);  // older: none
    if (u.tuning.imp.aided_stack_frames < 0 || u.tuning.imp.aided_stack_frames > 5) {
      throw std::runtime_error(path + ": tuning.imp.aided_stack_frames must be in [0, 5]");
    }
    const auto& bod = t.at("bod");
    u.tuning.bod.enabled = bod.at("enabled").get<bool>();
    u.tuning.bod.period_s = bod.at("period_s").get<double>();
    u.tuning.bod.samples = bod.at("samples").get<int>();
    u.tuning.bod.max_iterations = bod.at("max_iterations").get<int>();
    u.tuning.bod.range_min_m = bod.at("range_min_m").get<double>();
    u.tuning.bod.range_max_m = bod.at("range_max_m").get<double>();
    u.tuning.bod.min_measurements = bod.at("min_measurements").get<int>();
    u.tuning.bod.max_measurements = bod.at("max_measurements").get<int>();
    u.tuning.bod.batch_orbits = bod.at("batch_orbits").get<double>();
    u.tuning.bod.max_sigma_range_fraction = bod.at("max_sigma_range_fraction").get<double>();
    u.tuning.bod.max_residual_arcsec = bod.at("max_residual_arcsec").get<double>();
    u.tuning.bod.check_chi2 = bod.at("check_chi2").get<double>();
    u.tuning.bod.max_fit_ratio = bod.value("max_fit_ratio", BodTuning{}.max_fit_ratio);  // older uplinks: the default
    u.tuning.bod.reinit_after_check5 = bod.at("reinit_after_check5").get<bool>();
    u.tuning.bod.model_correction = bod.value("model_correction", BodTuning{}.model_correction);
    const auto& sod = t.at("sod");
    u.tuning.sod.period_s = sod.at("period_s").get<double>();
    u.tuning.sod.bearing_sigma_arcsec = sod.at("bearing_sigma_arcsec").get<double>();
    u.tuning.sod.eps_assign = sod.at("eps_assign").get<double>();
    u.tuning.sod.eps_ambig = sod.at("eps_ambig").get<double>();
    u.tuning.sod.max_steps_without_update = sod.at("max_steps_without_update").get<int>();
    u.tuning.sod.max_large_residuals = sod.at("max_large_residuals").get<int>();
    u.tuning.sod.underweighting = sod.at("underweighting").get<double>();
    u.tuning.sod.underweighting_nonlinearity = sod.value("underweighting_nonlinearity", 0.0);  // older uplinks: off
    u.tuning.sod.adaptive_process_noise = sod.at("adaptive_process_noise").get<bool>();
    u.tuning.sod.adaptive_targets = sod.value("adaptive_targets", true);  // older uplinks: the default
    const std::string form = sod.value("adaptive_form", std::string("diagonal"));  // older uplinks: the default
    if (form == "diagonal") u.tuning.sod.adaptive_form = SodTuning::AdaptiveForm::kDiagonal;
    else if (form == "block") u.tuning.sod.adaptive_form = SodTuning::AdaptiveForm::kBlock;
    else throw std::runtime_error(path + ": tuning.sod.adaptive_form must be diagonal or block, got " + form);
    const std::string average = sod.value("adaptive_average", std::string("clamped"));
    if (average == "clamped") u.tuning.sod.adaptive_average = SodTuning::AdaptiveAverage::kClamped;
    else if (average == "unclamped") u.tuning.sod.adaptive_average = SodTuning::AdaptiveAverage::kUnclamped;
    else throw std::runtime_error(path + ": tuning.sod.adaptive_average must be clamped or unclamped, got " + average);
    u.tuning.sod.adaptive_time_constant_s =
        sod.value("adaptive_time_constant_s", SodTuning{}.adaptive_time_constant_s);  // older uplinks: the default
    if (!(u.tuning.sod.adaptive_time_constant_s > 0.0 &&
          u.tuning.sod.adaptive_time_constant_s <= SodTuning::kMaxAdaptiveTimeConstantS))
      throw std::runtime_error(path + ": tuning.sod.adaptive_time_constant_s must be in (0, 2592000]");
    u.tuning.sod.process_noise_scale = sod.at("process_noise_scale").get<double>();
    u.tuning.sod.drag_density_error = sod.value("drag_density_error", 0.0);  // older uplinks: off
    if (!(u.tuning.sod.drag_density_error >= 0.0 && u.tuning.sod.drag_density_error <= 10.0))
      throw std::runtime_error(path + ": tuning.sod.drag_density_error must be in [0, 10]");
    u.tuning.sod.nis_window = sod.at("nis_window").get<int>();
    u.tuning.sod.nis_false_alarm = sod.at("nis_false_alarm").get<double>();
    const int tt = sod.at("time_tag").get<int>();
    if (tt < 0 || tt > 2) throw std::runtime_error(path + ": tuning.sod.time_tag must be 0, 1 or 2");
    u.tuning.sod.time_tag = static_cast<SodTuning::TimeTagEstimation>(tt);
    u.tuning.sod.time_tag_sigma_s = sod.at("time_tag_sigma_s").get<double>();
    u.tuning.sod.time_tag_drift_sigma_ppm = sod.at("time_tag_drift_sigma_ppm").get<double>();
    u.tuning.sod.time_tag_senders = sod.value("time_tag_senders", false);  // older uplinks: off
    u.tuning.sod.time_tag_senders_sigma_s = sod.value("time_tag_senders_sigma_s", 1.0);
    u.tuning.sod.estimate_ballistic = sod.at("estimate_ballistic").get<bool>();
    u.tuning.sod.ballistic_sigma_fraction = sod.at("ballistic_sigma_fraction").get<double>();
    if (sod.contains("ballistic_walk_fraction_per_day")) {  // older uplinks: the walk is sigma_fraction
      u.tuning.sod.ballistic_walk_fraction_per_day = sod.at("ballistic_walk_fraction_per_day").get<double>();
    }
    u.tuning.sod.ballistic_density_change_per_day = sod.value("ballistic_density_change_per_day", 0.0);  // older: off
    if (!(u.tuning.sod.ballistic_density_change_per_day >= 0.0 && u.tuning.sod.ballistic_density_change_per_day <= 10.0))
      throw std::runtime_error(path + ": tuning.sod.ballistic_density_change_per_day must be in [0, 10]");
    u.tuning.sod.observer_acceleration_sigma_mps2 = sod.value("observer_acceleration_sigma_mps2", 0.0);
    const std::string lines = sod.value("target_lines", std::string("consider_observer"));
    if (lines == "consider_observer") u.tuning.sod.target_lines = SodTuning::TargetLines::kConsiderObserver;
    else if (lines == "update_observer") u.tuning.sod.target_lines = SodTuning::TargetLines::kUpdateObserver;
    else throw std::runtime_error(path + ": tuning.sod.target_lines must be consider_observer or update_observer, got " + lines);
    const auto& c = j.at("crosslink");
    u.crosslink_enabled = c.at("enabled").get<bool>();
    u.isl_period_s = c.at("period_s").get<double>();
    u.isl_latency_s = c.at("latency_s").get<double>();
    u.swarm_max_cadence_s = c.at("swarm_max_cadence_s").get<double>();
    u.use_remote_gnss = c.at("use_remote_gnss").get<bool>();
    u.swarm_ids = j.at("swarm_ids").get<std::vector<std::string>>();
    if (j.contains("camera_calibration")) {
      const auto& k = j.at("camera_calibration");
      auto& cal = u.camera_calibration;
      cal.width_px = k.at("width_px").get<int>();
      cal.height_px = k.at("height_px").get<int>();
      cal.fx_px = k.at("fx_px").get<double>();
      cal.fy_px = k.at("fy_px").get<double>();
      cal.cx_px = k.at("cx_px").get<double>();
      cal.cy_px = k.at("cy_px").get<double>();
      cal.k1 = k.at("k1").get<double>();
      cal.k2 = k.at("k2").get<double>();
      cal.p1 = k.value("p1", 0.0);
      cal.p2 = k.value("p2", 0.0);
      cal.psf_sigma_px = k.at("psf_sigma_px").get<double>();
      cal.gain_e_per_dn = k.at("gain_e_per_dn").get<double>();
      cal.saturation_dn = k.at("saturation_dn").get<double>();
      cal.dn_shift_bits = k.value("dn_shift_bits", 0);
      cal.match_tolerance_rad = k.value("match_tolerance_rad", 0.0);
      cal.centroid_gaussian_fit = k.value("centroid_gaussian_fit", false);
    }
    if (j.contains("star_catalog_file")) u.star_catalog_file = j.at("star_catalog_file").get<std::string>();
    if (j.contains("apriori_age_days")) u.apriori_age_days = j.at("apriori_age_days").get<double>();
    if (j.contains("apriori")) {
      for (const auto& a : j.at("apriori")) {
        TargetApriori ta;
        ta.target = a.at("target").get<std::string>();
        const auto roe = a.at("roe").get<std::vector<double>>();
        const auto P = a.at("covariance_roe").get<std::vector<double>>();
        if (roe.size() != 6 || P.size() != 36) {
          throw std::runtime_error(path + ": apriori of " + ta.target + ": roe needs 6 values, covariance_roe 36");
        }
        for (int i = 0; i < 6; ++i) ta.roe[i] = roe[static_cast<std::size_t>(i)];
        for (int i = 0; i < 36; ++i) ta.P_roe.data()[i] = P[static_cast<std::size_t>(i)];
        if (!ta.roe.allFinite() || !ta.P_roe.allFinite()) {
          throw std::runtime_error(path + ": apriori of " + ta.target + ": non-finite value");
        }
        u.apriori.push_back(ta);
      }
    }
    if (j.contains("coarse_orbit") && !j.at("coarse_orbit").is_null()) {
      const auto& jc = j.at("coarse_orbit");
      ObserverUplink::CoarseOrbit co;
      co.t = astro::TimeTT{jc.at("t_tt_ns").get<std::int64_t>()};
      const auto r = jc.at("r_eci_m").get<std::vector<double>>();
      const auto v = jc.at("v_eci_mps").get<std::vector<double>>();
      const auto P = jc.at("covariance_rv").get<std::vector<double>>();
      if (r.size() != 3 || v.size() != 3 || P.size() != 36) {
        throw std::runtime_error(path + ": coarse_orbit: r_eci_m and v_eci_mps need 3 values, covariance_rv 36");
      }
      co.x_eci.r_m = astro::Vec3(r[0], r[1], r[2]);
      co.x_eci.v_mps = astro::Vec3(v[0], v[1], v[2]);
      for (int i = 0; i < 36; ++i) co.P_rv.data()[i] = P[static_cast<std::size_t>(i)];
      if (!co.x_eci.r_m.allFinite() || !co.x_eci.v_mps.allFinite() || !co.P_rv.allFinite() ||
          (co.P_rv.diagonal().array() <= 0.0).any()) {
        throw std::runtime_error(path + ": coarse_orbit: non-finite value or a variance <= 0");
      }
      u.coarse_orbit = co;
    }
    if (j.contains("planned_maneuvers")) {
      for (const auto& m : j.at("planned_maneuvers")) {
        ObserverUplink::PlannedManeuver pm;
        pm.t = astro::TimeTT{m.at("t_tt_ns").get<std::int64_t>()};
        const auto dv = m.at("dv_rtn_mps").get<std::vector<double>>();
        if (dv.size() != 3) throw std::runtime_error(path + ": planned_maneuvers: dv_rtn_mps needs 3 values");
        pm.dv_rtn_mps = astro::Vec3(dv[0], dv[1], dv[2]);
        pm.execution_sigma_fraction = m.at("execution_sigma_fraction").get<double>();
        if (!pm.dv_rtn_mps.allFinite() || !(pm.execution_sigma_fraction >= 0.0)) {
          throw std::runtime_error(path + ": planned_maneuvers: non-finite or negative value");
        }
        u.planned_maneuvers.push_back(pm);
      }
    }
    if (j.contains("onboard_properties")) {
      for (const auto& item : j.at("onboard_properties").items()) {
        const std::string& id = item.key();
        u.onboard_properties_by_id[id] = properties_from(item.value());
        try {
          u.onboard_properties_by_id[id].validate();
        } catch (const std::invalid_argument& e) {
          throw std::runtime_error(path + ": onboard_properties." + id + ": " + e.what());
        }
      }
    }
    return u;
  } catch (const json::exception& e) {
    throw std::runtime_error(path + ": malformed uplink: " + e.what());
  }
}

}  // namespace artms::config
