// Everything needed to render one observer's frames from a scenario: the
// camera model, catalog, render options (profile, faults, seeds) and the
// attitude law (boresight along +-velocity, a fixed pointing error and a
// per-frame jitter). Shared by the camera renderer service and artms-render.
#pragma once

#include <string>

#include "artms/config/scenario.hpp"
#include "artms/imaging/renderer.hpp"

namespace artms::render {

struct FrameSetup {
  imaging::FrameRenderer renderer;
  std::string observer;
  config::CameraConfig camera_config;
  Eigen::Quaterniond pointing_error = Eigen::Quaterniond::Identity();  // fixed per run
  std::uint64_t seed = 1;
  // q_cam_from_eci of frame `frame_index`: jitter * pointing error * nominal
  // (camera V frame of the observer's truth state, docs/conventions.md).
  [[nodiscard]] Eigen::Quaterniond attitude(const astro::StateVector& observer_eci,
                                            std::uint64_t frame_index) const;
};

// camera_path empty: config/cameras/<model>.yaml of the observer's camera.
// Throws std::invalid_argument naming an unknown observer.
FrameSetup make_frame_setup(const config::Scenario& s, const std::string& observer,
                            const std::string& camera_path, bool flight_like, bool noise_free);

}  // namespace artms::render
