// Where the shipped data (gravity field, star catalog, atmosphere) and the
// configuration files (Cyclone DDS loopback config, cameras, scenarios) are
// found at run time; nothing from the source tree is compiled in.
//
// Each function takes the first of, in order:
//  (a) the environment: ARTMS_DATA_DIR / ARTMS_CONFIG_DIR. When set (and not
//      empty) it must hold the expected file: a wrong override is an error,
//      never silently replaced by another folder;
//  (b) beside the running executable (/proc/self/exe):
//      <exe_dir>/../share/artms/data and <exe_dir>/../share/artms/config.
//      The build tree has build/share/artms/{data,config} as symlinks to the
//      source's data/ and config/, an install has them under <prefix>;
//  (c) the install prefix chosen at configure time:
//      <CMAKE_INSTALL_PREFIX>/share/artms/data and .../config.
// A folder qualifies when it holds gravity/GGM01S.gfc (data) or
// cyclonedds-loopback.xml (config). Throws std::runtime_error naming every
// place tried when none does. The result has no trailing '/'.
#pragma once

#include <string>

namespace artms::io {

std::string data_dir();
std::string config_dir();

}  // namespace artms::io
