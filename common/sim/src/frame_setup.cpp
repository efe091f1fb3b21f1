#include "artms/render/frame_setup.hpp"

#include <cmath>
#include <stdexcept>

#include "artms/astro/constants.hpp"
#include "artms/io/paths.hpp"

namespace artms::render {
namespace {

// Small rotation of angle sigma * N(0,1) about a random axis, from hashes.
Eigen::Quaterniond random_rotation(std::uint64_t seed, std::uint64_t index, double sigma_rad) {
  if (!(sigma_rad > 0.0)) return Eigen::Quaterniond::Identity();
  Eigen::Vector3d axis(imaging::hashed_normal(seed, index, 11), imaging::hashed_normal(seed, index, 12),
                       imaging::hashed_normal(seed, index, 13));
  if (axis.norm() < 1e-12) axis = Eigen::Vector3d::UnitX();
  const double angle = sigma_rad * imaging::hashed_normal(seed, index, 14);
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis.normalized()));
}

}  // namespace

Eigen::Quaterniond FrameSetup::attitude(const astro::StateVector& x, std::uint64_t frame_index) const {
  const Eigen::Quaterniond nominal(astro::R_v_from_eci(x, camera_config.boresight));
  const Eigen::Quaterniond jitter =
      random_rotation(seed ^ 0x717E5ULL, frame_index, camera_config.jitter_deg * astro::kDegToRad);
  return (jitter * pointing_error * nominal).normalized();
}

FrameSetup make_frame_setup(const config::Scenario& s, const std::string& observer,
                            const std::string& camera_path, bool flight_like, bool noise_free) {
  const config::ObserverConfig* obs = nullptr;
  for (const auto& o : s.observers) {
    if (o.spacecraft == observer) obs = &o;
  }
  if (!obs) throw std::invalid_argument("'" + observer + "' is not an observer of scenario " + s.name);
  const std::string cam_path =
      camera_path.empty() ? io::config_dir() + "/cameras/" + obs->camera.model + ".yaml" : camera_path;
  imaging::CameraModel camera = imaging::CameraModel::load(cam_path);
  imaging::StarCatalog catalog =
      imaging::StarCatalog::load_bsc5(io::data_dir() + "/stars/bsc5.dat", 99.0);
  imaging::RenderOptions options;
  options.profile = flight_like ? imaging::TargetProfile::flight_like() : imaging::TargetProfile::nominal();
  if (noise_free) {
    options.noise = imaging::NoiseOptions::noise_free();
    options.faint_stars = false;
  }
  options.sky_seed = 20240508;  // one sky for every run: the same faint stars
  options.noise_seed = s.seed;
  options.fault_epoch = s.epoch;
  options.stellar_aberration = obs->camera.stellar_aberration;
  for (const auto& f : s.faults) {
    if (f.observer.empty() || f.observer == observer) {
      options.faults.dropout_probability = f.frame_dropout_probability;
      options.faults.time_tag_offset_s = f.time_tag_offset_total_s();
      options.faults.time_tag_drift_ppm = f.time_tag_drift_total_ppm();
    }
  }
  FrameSetup setup{imaging::FrameRenderer(std::move(camera), std::move(catalog), options), observer,
                   obs->camera, Eigen::Quaterniond::Identity(), s.seed};
  setup.pointing_error = random_rotation(s.seed ^ 0x901A7ULL, 0, obs->camera.pointing_error_deg * astro::kDegToRad);
  return setup;
}

}  // namespace artms::render

#include "artms/render/camera_calibration.hpp"

namespace artms::render {

config::CameraCalibration calibration_from(const imaging::CameraModel& cam) {
  config::CameraCalibration c;
  c.width_px = cam.width_px;
  c.height_px = cam.height_px;
  c.fx_px = cam.fx_px;
  c.fy_px = cam.fy_px;
  c.cx_px = cam.cx_px;
  c.cy_px = cam.cy_px;
  c.k1 = cam.k1;
  c.k2 = cam.k2;
  c.p1 = cam.p1;
  c.p2 = cam.p2;
  c.psf_sigma_px = cam.psf_sigma_px;
  c.gain_e_per_dn = cam.gain_e_per_dn;
  c.saturation_dn = cam.max_dn();
  c.dn_shift_bits = cam.dn_shift_bits;
  c.match_tolerance_rad = cam.match_tolerance_rad;
  c.centroid_gaussian_fit = cam.centroid_gaussian_fit;
  return c;
}

config::CameraCalibration calibration_of_model(const std::string& model) {
  return calibration_from(imaging::CameraModel::load(io::config_dir() + "/cameras/" + model + ".yaml"));
}

}  // namespace artms::render
