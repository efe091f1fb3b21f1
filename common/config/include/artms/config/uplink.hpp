// What the ground uplinks to one observer, and everything an observer process
// may know: its own configuration, the ARTMS tuning, the force model of its
// onboard propagator and the run's clock. No truth: no orbit of any
// spacecraft (the a-priori of mode 1 will be added here as ground estimates
// with their errors, never the true states).
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "artms/config/scenario.hpp"

namespace artms::config {

// The onboard sensor model (the ground calibration of the camera): what IMP
// needs to turn pixels into lines of sight. Zero width: not uplinked.
struct CameraCalibration {
  int width_px = 0;
  int height_px = 0;
  double fx_px = 0.0, fy_px = 0.0, cx_px = 0.0, cy_px = 0.0;
  double k1 = 0.0, k2 = 0.0;
  double p1 = 0.0, p2 = 0.0;  // tangential distortion (camera file optics.p1, optics.p2)
  double psf_sigma_px = 1.2;
  double gain_e_per_dn = 2.4;
  double saturation_dn = 4095.0;
  int dn_shift_bits = 0;             // stored value = DN * 2^dn_shift_bits (camera file sensor.dn_shift_bits)
  double match_tolerance_rad = 0.0;  // star identification; 0: IMP's default
  bool centroid_gaussian_fit = false;  // camera file centroid.method: gaussian_fit (else iwcog)
  [[nodiscard]] bool present() const { return width_px > 0 && height_px > 0 && fx_px > 0.0 && fy_px > 0.0; }
};

// Ground a-priori of one target (navigation mode 1): its ROE relative to
// the observer at the uplink epoch, from a ground orbit determination
// apriori_age_days old, with the covariance that age implies (sod::apriori);
// the launcher draws the error from that covariance with the run's seed.
// Never the true state.
struct TargetApriori {
  std::string target;
  astro::Vec6 roe = astro::Vec6::Zero();      // dimensionless, astro::Roe order
  astro::Mat6 P_roe = astro::Mat6::Identity();  // covariance of roe
};

struct ObserverUplink {
  std::string scenario_name;
  astro::TimeTT epoch;
  double duration_s = 0.0;
  double step_s = 60.0;
  std::uint64_t seed = 1;
  dynamics::ForceModelOptions force_model;
  ObserverConfig observer;
  ArtmsTuning tuning;
  bool crosslink_enabled = true;
  double isl_period_s = 60.0;
  double isl_latency_s = 0.0;          // crosslink latency (scenario crosslink.latency)
  // Longest camera cadence of any observer of the swarm (the ground's
  // configuration, not truth): with IMP's decision lag it bounds how old a
  // remote bearing can be when it arrives (navigator.hpp, remote hold).
  double swarm_max_cadence_s = 0.0;
  bool use_remote_gnss = false;
  std::vector<std::string> swarm_ids;  // every spacecraft id (no orbits)
  CameraCalibration camera_calibration;
  // Onboard star catalog (CSV catalog_id,ux,uy,uz: unit ECI J2000 directions
  // at the scenario epoch), relative to the uplink file's folder; empty: none.
  std::string star_catalog_file;
  double apriori_age_days = 0.0;
  std::vector<TargetApriori> apriori;  // empty: no ground a-priori uplinked
  // Nominal physical properties of the observer and every swarm member, as
  // the ground knows them (scenario spacecraft[].onboard), by id.
  std::map<std::string, dynamics::SpacecraftProperties> onboard_properties_by_id;
  // The observer's own planned maneuvers (scenario maneuvers[] with planned:
  // true): commanded delta-v and the 1-sigma fraction of its execution error.
  struct PlannedManeuver {
    astro::TimeTT t;
    astro::Vec3 dv_rtn_mps = astro::Vec3::Zero();
    double execution_sigma_fraction = 0.0;
  };
  std::vector<PlannedManeuver> planned_maneuvers;
  // Navigation mode 4: the coarse ground orbit of the observer (a degraded
  // orbit determination, paper "Absolute Navigation") and its covariance;
  // SOD starts from it and never sees a GNSS fix.
  struct CoarseOrbit {
    astro::TimeTT t;
    astro::StateVector x_eci;
    Eigen::Matrix<double, 6, 6> P_rv = Eigen::Matrix<double, 6, 6>::Zero();
  };
  std::optional<CoarseOrbit> coarse_orbit;
  // The nominal properties of `id`; SpacecraftProperties{} for an id the
  // uplink does not list (uplink files written before they were carried).
  [[nodiscard]] dynamics::SpacecraftProperties onboard_properties(const std::string& id) const;
};

// Throws std::out_of_range if `spacecraft` is not an observer of s.
ObserverUplink make_uplink(const Scenario& s, const std::string& spacecraft);
// JSON file; read_uplink throws std::runtime_error naming the file and the key.
void write_uplink(const ObserverUplink& u, const std::string& path);
ObserverUplink read_uplink(const std::string& path);

}  // namespace artms::config
