// artms-imp CAMERA.yaml FRAMES_DIR --out DIR (DESIGN.md section 7): runs the
// per-frame part of IMP offline over a folder of frames (16-bit PNG):
// detection and centroids, Pyramid star identification (tracking mode when
// the previous attitude is known), attitude; writes attitude.csv and the
// non-star detections as measurement candidates in measurements.csv.
// SAMUS tracking is not implemented yet: track_id is -1 and tracks.csv has
// only its header (issue 6 stays open for it). Corrupt or unreadable frames
// are reported and skipped.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <regex>

#include "artms/astro/bearing.hpp"
#include "artms/astro/constants.hpp"
#include "artms/imaging/camera.hpp"
#include "artms/imaging/image.hpp"
#include "artms/imaging/star_catalog.hpp"
#include "artms/imp/detection.hpp"
#include "artms/imp/star_id.hpp"

namespace {

using namespace artms;
namespace fs = std::filesystem;

int run(int argc, char** argv) {
  CLI::App app{"Run IMP's per-frame processing (detection, centroids, Pyramid star ID, attitude)\n"
               "over a folder of frames; SAMUS tracking is not implemented yet.",
               "artms-imp"};
  std::string camera_path, frames_dir, out;
  double vmag_limit = 6.5;
  app.add_option("camera", camera_path, "camera YAML (e.g. config/cameras/nst.yaml)")->required();
  app.add_option("frames", frames_dir, "folder of frame_<k>.png (16-bit), with optional frame_<k>.json")
      ->required();
  app.add_option("--out", out, "output folder")->required();
  app.add_option("--vmag-limit", vmag_limit, "faintest catalog star used for identification")
      ->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  try {
    const imaging::CameraModel cam = imaging::CameraModel::load(camera_path);
    imp::Intrinsics K;
    K.width = cam.width_px;
    K.height = cam.height_px;
    K.fx = cam.fx_px;
    K.fy = cam.fy_px;
    K.cx = cam.cx_px;
    K.cy = cam.cy_px;
    K.k1 = cam.k1;
    K.k2 = cam.k2;
    std::vector<fs::path> frames;
    const std::regex name(R"(frame_(\d+)\.png)");
    for (const auto& e : fs::directory_iterator(frames_dir)) {
      if (std::regex_match(e.path().filename().string(), name)) frames.push_back(e.path());
    }
    std::sort(frames.begin(), frames.end());
    if (frames.empty()) throw std::runtime_error("no frame_<k>.png in " + frames_dir);
    // Catalog directions at the first frame's epoch (proper motion over a
    // run is far below the identification tolerance).
    astro::TimeTT t_cat = astro::tt_from_utc_string("2000-01-01T12:00:00Z");
    {
      fs::path side = frames.front();
      side.replace_extension(".json");
      if (fs::exists(side)) {
        t_cat = astro::TimeTT{nlohmann::json::parse(std::ifstream(side)).at("t_tt_ns").get<std::int64_t>()};
      }
    }
    const auto bsc = imaging::StarCatalog::load_bsc5(std::string(ARTMS_DATA_DIR) + "/stars/bsc5.dat", vmag_limit);
    std::vector<imp::CatalogStar> stars;
    for (const auto& s : bsc.stars()) stars.push_back({s.catalog_id, s.unit_eci_at(t_cat)});
    const auto catalog = imp::StarIdCatalog::build(std::move(stars), 2.0 * K.half_diagonal_fov_rad());

    fs::create_directories(out);
    std::ofstream att(fs::path(out) / "attitude.csv"), meas(fs::path(out) / "measurements.csv"),
        tracks(fs::path(out) / "tracks.csv");
    att << "frame,t_tt_ns,status,qw,qx,qy,qz,stars_matched,residual_arcsec\n";
    meas << "frame,t_tt_ns,track_id,x_px,y_px,ux_eci,uy_eci,uz_eci,az_rad,el_rad,sigma_rad\n";
    tracks << "track_id,first_frame,last_frame,measurements\n";
    std::optional<Eigen::Quaterniond> prior;
    int solved = 0, corrupt = 0;
    char line[512];
    for (const auto& path : frames) {
      const int k = std::stoi(std::regex_replace(path.filename().string(), name, "$1"));
      std::int64_t t_ns = 0;
      fs::path side = path;
      side.replace_extension(".json");
      if (fs::exists(side)) {
        try {
          const auto j = nlohmann::json::parse(std::ifstream(side));
          t_ns = j.contains("time_tag_tt_ns") ? j.at("time_tag_tt_ns").get<std::int64_t>()
                                              : j.at("t_tt_ns").get<std::int64_t>();
        } catch (const std::exception& e) {
          std::fprintf(stderr, "artms-imp: %s: unreadable sidecar (%s); time tag 0\n", side.c_str(), e.what());
        }
      }
      imaging::Image16 img;
      try {
        img = imaging::read_png16(path.string());
        if (img.width != K.width || img.height != K.height) {
          throw std::runtime_error("size " + std::to_string(img.width) + "x" + std::to_string(img.height) +
                                   " does not match the camera");
        }
      } catch (const std::exception& e) {
        ++corrupt;
        std::fprintf(stderr, "artms-imp: skipping %s: %s\n", path.c_str(), e.what());
        std::snprintf(line, sizeof line, "%d,%lld,corrupt,,,,,0,\n", k, static_cast<long long>(t_ns));
        att << line;
        continue;
      }
      const imp::DetectionResult det = imp::detect(img.pixels, img.width, img.height, imp::DetectionOptions{});
      std::vector<std::size_t> order(det.centroids.size());
      for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
      std::sort(order.begin(), order.end(), [&](auto a, auto b) { return det.centroids[a].flux_dn > det.centroids[b].flux_dn; });
      std::vector<Eigen::Vector3d> dirs;
      for (auto i : order) dirs.push_back(K.unproject({det.centroids[i].x_px, det.centroids[i].y_px}));
      imp::StarIdResult id;
      if (det.usable && dirs.size() >= 3) {
        if (prior) id = imp::identify_with_prior(dirs, catalog, *prior, 0.2 * astro::kDegToRad);
        if (!id.usable) id = imp::identify_lost_in_space(dirs, catalog, imp::StarIdOptions{});
      }
      const std::string status = !det.usable ? "no_detections" : (id.usable ? "ok" : "not_identified");
      if (!id.usable) {
        prior.reset();
        std::snprintf(line, sizeof line, "%d,%lld,%s,,,,,%zu,\n", k, static_cast<long long>(t_ns),
                      status.c_str(), id.matches.size());
        att << line;
        continue;
      }
      ++solved;
      prior = id.q_cam_from_eci;
      const auto q = astro::wxyz_from_quaternion(id.q_cam_from_eci);
      std::snprintf(line, sizeof line, "%d,%lld,ok,%.12f,%.12f,%.12f,%.12f,%zu,%.3f\n", k,
                    static_cast<long long>(t_ns), q[0], q[1], q[2], q[3], id.matches.size(),
                    id.residual_rms_rad / astro::kArcsecToRad);
      att << line;
      // Non-star detections are measurement candidates (SAMUS will chain and
      // filter them; uncatalogued stars are not removed yet).
      std::vector<bool> is_star(order.size(), false);
      for (const auto& [idx, cat] : id.matches) is_star[static_cast<std::size_t>(idx)] = true;
      const Eigen::Matrix3d R_eci_from_cam = id.q_cam_from_eci.toRotationMatrix().transpose();
      for (std::size_t n = 0; n < order.size(); ++n) {
        if (is_star[n]) continue;
        const auto& c = det.centroids[order[n]];
        const Eigen::Vector3d u_cam = dirs[n];
        const Eigen::Vector3d u_eci = R_eci_from_cam * u_cam;
        const astro::Bearing b = astro::bearing_from_los(u_cam);
        const double sigma = std::hypot(c.sigma_px / K.fx, id.residual_rms_rad);
        std::snprintf(line, sizeof line, "%d,%lld,-1,%.4f,%.4f,%.12f,%.12f,%.12f,%.9f,%.9f,%.3e\n", k,
                      static_cast<long long>(t_ns), c.x_px, c.y_px, u_eci.x(), u_eci.y(), u_eci.z(), b.az_rad,
                      b.el_rad, sigma);
        meas << line;
      }
    }
    std::fprintf(stderr, "artms-imp: %zu frames, attitude solved on %d, %d corrupt or unreadable; "
                 "tracks.csv is empty (SAMUS tracking not implemented yet)\n",
                 frames.size(), solved, corrupt);
  } catch (const std::exception& e) {
    std::cerr << "artms-imp: error: " << e.what() << "\n";
    return 2;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return run(argc, argv); }
