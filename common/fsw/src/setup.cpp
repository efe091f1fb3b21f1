// Reading what the observer is built from (the only file I/O of common/fsw;
// the Observer itself reads nothing).
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "artms/fsw/observer.hpp"

namespace artms::fsw {

std::vector<imp::CatalogStar> read_star_catalog(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open the onboard star catalog " + path);
  std::string line;
  std::getline(in, line);
  std::vector<imp::CatalogStar> out;
  int lineno = 1;
  while (std::getline(in, line)) {
    ++lineno;
    std::stringstream ss(line);
    std::string f[5];
    for (auto& x : f) std::getline(ss, x, ',');
    try {
      imp::CatalogStar s{std::stoi(f[0]), Eigen::Vector3d(std::stod(f[1]), std::stod(f[2]), std::stod(f[3])),
                         f[4].empty() ? 0.0 : std::stod(f[4])};
      if (!std::isfinite(s.vmag)) throw std::invalid_argument("vmag not finite");
      if (!s.u_eci.allFinite() || std::abs(s.u_eci.norm() - 1.0) > 1e-6) throw std::invalid_argument("not a unit vector");
      out.push_back(s);
    } catch (const std::exception& e) {
      throw std::runtime_error(path + ":" + std::to_string(lineno) + ": bad star row (" + e.what() + ")");
    }
  }
  return out;
}

ObserverSetup load_observer_setup(const std::string& uplink_path, const std::string& data_dir) {
  ObserverSetup s;
  s.uplink = config::read_uplink(uplink_path);
  if (s.uplink.camera_calibration.present() && !s.uplink.star_catalog_file.empty()) {
    s.star_catalog = read_star_catalog(
        (std::filesystem::path(uplink_path).parent_path() / s.uplink.star_catalog_file).string());
  }
  s.forces = std::make_shared<const dynamics::ForceModel>(dynamics::ForceModel::load(s.uplink.force_model, data_dir));
  return s;
}

}  // namespace artms::fsw
