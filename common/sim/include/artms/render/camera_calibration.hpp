// The ground calibration of a camera model as it is uplinked
// (config::CameraCalibration, what IMP needs): one mapping from a camera
// file, used by the launcher's uplink and by artms-imp, so that offline IMP
// and the observer run with the same settings (fsw::frame_processor_options).
#pragma once

#include <string>

#include "artms/config/uplink.hpp"
#include "artms/imaging/camera.hpp"

namespace artms::render {

config::CameraCalibration calibration_from(const imaging::CameraModel& cam);
// config/cameras/<model>.yaml.
config::CameraCalibration calibration_of_model(const std::string& model);

}  // namespace artms::render
