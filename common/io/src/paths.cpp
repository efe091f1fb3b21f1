#include "artms/io/paths.hpp"

#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <system_error>
#include <vector>

#ifndef ARTMS_INSTALL_SHARE_DIR
#error "ARTMS_INSTALL_SHARE_DIR (<CMAKE_INSTALL_PREFIX>/share/artms) must be defined by the build"
#endif

namespace artms::io {
namespace {

namespace fs = std::filesystem;

bool holds(const fs::path& dir, const char* probe) {
  std::error_code ec;
  return fs::is_regular_file(dir / probe, ec);
}

std::string as_dir(const fs::path& p) {
  std::string s = p.lexically_normal().string();
  while (s.size() > 1 && s.back() == '/') s.pop_back();
  return s;
}

// what: "data" or "config"; env: the override's name; probe: the file that
// must be there (relative to the folder).
std::string resolve(const char* what, const char* env, const char* probe) {
  const char* override_dir = std::getenv(env);
  if (override_dir != nullptr && *override_dir != '\0') {
    if (holds(override_dir, probe)) return as_dir(override_dir);
    throw std::runtime_error(std::string("artms ") + what + " folder: " + env + "=" + override_dir +
                             " does not hold " + probe + " (unset it to use the installed " + what + ")");
  }
  std::vector<std::string> tried{std::string(env) + " (not set)"};
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec && !exe.empty()) {
    const fs::path beside = exe.parent_path() / ".." / "share" / "artms" / what;
    if (holds(beside, probe)) return as_dir(beside);
    tried.push_back(as_dir(beside) + " (beside the executable " + exe.string() + ")");
  } else {
    tried.push_back("beside the executable (/proc/self/exe unreadable: " + ec.message() + ")");
  }
  const fs::path installed = fs::path(ARTMS_INSTALL_SHARE_DIR) / what;
  if (holds(installed, probe)) return as_dir(installed);
  tried.push_back(as_dir(installed) + " (the install prefix)");
  std::string msg = std::string("artms ") + what + " folder not found: no " + probe + " in";
  for (std::size_t i = 0; i < tried.size(); ++i) msg += (i == 0 ? " " : "; ") + tried[i];
  throw std::runtime_error(msg);
}

}  // namespace

std::string data_dir() { return resolve("data", "ARTMS_DATA_DIR", "gravity/GGM01S.gfc"); }

std::string config_dir() { return resolve("config", "ARTMS_CONFIG_DIR", "cyclonedds-loopback.xml"); }

}  // namespace artms::io
