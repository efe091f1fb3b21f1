// Shared helpers of the detection and star-identification tests: the NST
// camera, BSC5, frames rendered by the truth-side renderer (tests only: the
// IMP library never links it), random attitudes.
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "artms/astro/time.hpp"
#include "artms/imaging/camera.hpp"
#include "artms/imaging/image.hpp"
#include "artms/imaging/renderer.hpp"
#include "artms/imaging/star_catalog.hpp"
#include "artms/imp/detection.hpp"
#include "artms/imp/star_id.hpp"

namespace artms::imp::testing {

// The NST without the real-hardware effects (nst_ideal.yaml): the unit
// tests measure IMP against a known image model; the effects' cost is
// measured end to end (docs/imaging.md, "Real-camera effects").
inline imaging::CameraModel nst_camera() {
  return imaging::CameraModel::load(std::string(ARTMS_CONFIG_DIR) + "/cameras/nst_ideal.yaml");
}

// BSC5 down to vmag_limit (the whole catalogue with 99).
inline const imaging::StarCatalog& bsc5(double vmag_limit = 99.0) {
  static const imaging::StarCatalog all =
      imaging::StarCatalog::load_bsc5(std::string(ARTMS_DATA_DIR) + "/stars/bsc5.dat", 99.0);
  static const imaging::StarCatalog bright =
      imaging::StarCatalog::load_bsc5(std::string(ARTMS_DATA_DIR) + "/stars/bsc5.dat", 6.5);
  return vmag_limit >= 99.0 ? all : bright;
}

inline Intrinsics intrinsics_of(const imaging::CameraModel& cam) {
  Intrinsics k;
  k.width = cam.width_px;
  k.height = cam.height_px;
  k.fx = cam.fx_px;
  k.fy = cam.fy_px;
  k.cx = cam.cx_px;
  k.cy = cam.cy_px;
  k.k1 = cam.k1;
  k.k2 = cam.k2;
  k.p1 = cam.p1;
  k.p2 = cam.p2;
  return k;
}

// Uniformly distributed rotation (normalised 4-D Gaussian).
inline Eigen::Quaterniond random_attitude(std::mt19937_64& rng) {
  std::normal_distribution<double> n01;
  Eigen::Quaterniond q(n01(rng), n01(rng), n01(rng), n01(rng));
  return q.normalized();
}

inline astro::TimeTT frame_epoch() {
  return astro::tt_from_utc_string("2024-05-08T00:00:00Z");
}

// The star-ID catalog: BSC5 stars with V <= vmag_limit, directions at t.
inline StarIdCatalog star_id_catalog(astro::TimeTT t, double vmag_limit,
                                     double max_pair_angle_rad) {
  std::vector<CatalogStar> stars;
  for (const auto& s : bsc5().stars()) {
    if (s.vmag <= vmag_limit) stars.push_back({s.catalog_id, s.unit_eci_at(t)});
  }
  return StarIdCatalog::build(std::move(stars), max_pair_angle_rad);
}

// A full-noise frame from the truth-side FrameRenderer (catalog stars, the
// faint uncatalogued sky, hot pixels, every noise term) at a random attitude
// that no exclusion zone (Sun, Moon, Earth limb) touches, for an observer
// in LEO.
struct RenderedSky {
  imaging::RenderedFrame frame;
  Eigen::Quaterniond q_cam_from_eci;
};
inline RenderedSky render_random_sky(const imaging::FrameRenderer& renderer, std::mt19937_64& rng,
                                     std::uint64_t frame_index) {
  imaging::RenderRequest req;
  req.observer = "SV4";
  req.frame_index = frame_index;
  req.t = frame_epoch();
  req.observer_eci.r_m = astro::Vec3(4000e3, -5000e3, 2500e3);
  req.observer_eci.v_mps = astro::Vec3(5.0e3, 4.0e3, 0.5e3).normalized() * 7.5e3;
  for (int tries = 0; tries < 1000; ++tries) {
    req.q_cam_from_eci = random_attitude(rng);
    imaging::RenderedFrame f = renderer.render(req);
    if (!f.exclusion.excluded && !f.dropped) return {std::move(f), req.q_cam_from_eci};
  }
  throw std::runtime_error("no attitude clear of the exclusion zones");
}

// Small-angle rotation vector of q_est * q_true^-1 in camera axes (rad):
// x, y are the cross-boresight errors, z the roll about the boresight.
inline Eigen::Vector3d attitude_error_cam(const Eigen::Quaterniond& q_est,
                                          const Eigen::Quaterniond& q_true) {
  const Eigen::AngleAxisd aa(q_est * q_true.inverse());
  Eigen::Vector3d v = aa.axis() * aa.angle();
  if (aa.angle() > M_PI) v = aa.axis() * (aa.angle() - 2.0 * M_PI);
  return v;
}

}  // namespace artms::imp::testing
