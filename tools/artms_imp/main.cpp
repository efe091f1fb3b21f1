// artms-imp CAMERA.yaml FRAMES... --out DIR (DESIGN.md section 7): runs IMP
// offline over frames (8- or 16-bit PNG or TIFF; a folder, files, or a
// shell glob), stored as the camera file's sensor.bit_depth and
// sensor.dn_shift_bits say: per frame, detection,
// Pyramid star identification, attitude and the removal of hot pixels and
// uncatalogued stars (imp::FrameProcessor); across frames, SAMUS tracking
// (imp::Samus) with the observer orbit of --observer-orbit. Writes
// attitude.csv, measurements.csv (every candidate; track_id -1 when no track
// took it), stars.csv (each identified star: centroid, catalog id,
// residual) and tracks.csv. Corrupt or unreadable frames are reported with
// their reason and skipped. When the camera file's focal length fails and
// the search fits one per frame, every frame is solved again with the one
// common to the solved frames (--per-frame-focal keeps theirs). Exit status
// 0 when at least one frame is solved, 3 when none is, 2 on an error.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <map>
#include <optional>
#include <regex>

#include "artms/astro/bearing.hpp"
#include "artms/astro/constants.hpp"
#include "artms/dynamics/ephemeris.hpp"
#include "artms/imaging/camera.hpp"
#include "artms/imaging/image.hpp"
#include "artms/imaging/star_catalog.hpp"
#include "artms/imp/detection.hpp"
#include "artms/imp/frame_processor.hpp"
#include "artms/imp/samus.hpp"
#include "artms/fsw/observer.hpp"
#include "artms/render/camera_calibration.hpp"
#include "artms/imp/star_id.hpp"
#include "artms/io/paths.hpp"
#include "fits.hpp"
#include "orbit_table.hpp"

namespace {

using namespace artms;
namespace fs = std::filesystem;

// A CSV field without separators or line breaks (reasons and file names).
std::string csv_text(std::string s) {
  for (char& c : s) {
    if (c == ',' || c == '\n' || c == '\r' || c == '"') c = ';';
  }
  return s;
}

int run(int argc, char** argv) {
  CLI::App app{"Run IMP's per-frame processing (detection, centroids, Pyramid star ID, attitude)\n"
               "over a folder of frames, then SAMUS tracking (with --observer-orbit).",
               "artms-imp"};
  std::string camera_path, out, time_utc;
  std::vector<std::string> inputs;
  double vmag_limit = 6.5;
  app.add_option("camera", camera_path, "camera YAML (e.g. config/cameras/nst.yaml)")->required();
  app.add_option("frames", inputs,
                 "frames: folders (every .png/.tif/.tiff/.fits in them; only frame_<k>.png where there are such)\nand/or files: 8- or 16-bit gray PNG or TIFF, FITS (time from DATE-OBS + EXPTIME / 2); a frame "
                 "<name>.png may have a sidecar <name>.json with t_tt_ns (or time_tag_tt_ns)")
      ->required();
  app.add_option("--time", time_utc,
                 "UTC of frames without a sidecar (e.g. 2019-07-29T20:47:26Z): the catalog's proper motion\n"
                 "epoch and the time tag; without it and without sidecars the catalog stays at J2000 (warned)");
  app.add_option("--out", out, "output folder")->required();
  app.add_option("--vmag-limit", vmag_limit, "faintest catalog star used for identification")
      ->capture_default_str();
  std::string fits_rows = "bottom-first";
  app.add_option("--fits-rows", fits_rows,
                 "FITS row order: bottom-first (the FITS standard: row 1 at the bottom of the picture) or\n"
                 "top-first (a camera that writes its first readout row as row 1); a wrong order mirrors the\n"
                 "frame and nothing is identified")
      ->check(CLI::IsMember({"bottom-first", "top-first"}))
      ->capture_default_str();
  bool learn_psf = false;
  app.add_option("--learn-psf", learn_psf,
                 "learn the PSF width from the solved frames' bright stars (the camera file's psf_sigma_px is\n"
                 "the start; written as psf_sigma_px per frame)")
      ->capture_default_str();
  double focal_search_percent = 3.0;
  app.add_option("--focal-search-percent", focal_search_percent,
                 "lost-in-space also with the focal length scaled by up to +-this % when the camera file's\n"
                 "fails (refined, kept for the next frames, written as focal_px); 0: off")
      ->check(CLI::Range(0.0, 20.0))
      ->capture_default_str();
  bool per_frame_focal = false;
  app.add_flag("--per-frame-focal", per_frame_focal,
               "when the focal-length search was needed, keep each frame's own fitted focal length (a zoom lens,\n"
               "a camera whose focal length drifts) instead of re-solving every frame with the one common to the\n"
               "solved frames");
  std::string orbit_path;
  app.add_option("--observer-orbit", orbit_path,
                 "CSV with t_tt_ns,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps: a coarse observer orbit for SAMUS\n"
                 "(artms-render's observer_orbit.csv, or a run's nav/<id>.csv); without it no tracking");
  std::string aberration = "auto";
  app.add_option("--aberration", aberration,
                 "stellar aberration of the catalog before the attitude is solved: off (an astrometric attitude, as\n"
                 "tetra3's and most ground solutions), earth (the Earth's velocity about the Sun at the frame time: a\n"
                 "ground camera), orbit (the Earth's plus --observer-orbit's: a spacecraft); auto: orbit with\n"
                 "--observer-orbit, otherwise off")
      ->check(CLI::IsMember({"auto", "off", "earth", "orbit"}))
      ->capture_default_str();
  imp::SamusOptions samus_opt;
  app.add_option("--dbscan-min-points", samus_opt.dbscan_min_points, "n_D")->capture_default_str();
  double eps_px = 20.0;
  app.add_option("--dbscan-radius-px", eps_px, "eps_D (pixels)")->capture_default_str();
  app.add_option("--fit-window", samus_opt.fit_window, "measurements in the eq. (9) fit")->capture_default_str();
  double floor_arcsec = 15.0;
  app.add_option("--model-floor-arcsec", floor_arcsec, "eq. (9) model error per axis")->capture_default_str();
  app.add_option("--dbscan-frames", samus_opt.dbscan_frames, "frames of unassigned candidates clustered")
      ->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  try {
    const imaging::CameraModel cam = imaging::CameraModel::load(camera_path);
    // The camera file mapped exactly as the launcher uplinks it and the
    // observer builds IMP from it (geometry, PSF, gain, saturation).
    const config::CameraCalibration calib = render::calibration_from(cam);
    const imp::Intrinsics K = fsw::intrinsics_from(calib);
    std::vector<fs::path> frames;
    const std::regex name(R"(frame_(\d+)\.png)");
    const auto is_image = [](const fs::path& p) {
      std::string ext = p.extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
      return ext == ".png" || ext == ".tif" || ext == ".tiff" || ext == ".fits" || ext == ".fit" || ext == ".fts";
    };
    for (const auto& in : inputs) {
      if (fs::is_directory(in)) {
        std::vector<fs::path> here;
        for (const auto& e : fs::directory_iterator(in)) {
          if (e.is_regular_file() && is_image(e.path())) here.push_back(e.path());
        }
        // A folder of artms-render's output (frame_<k>.png beside 8-bit
        // preview_<k>.png): its frames only.
        if (std::any_of(here.begin(), here.end(),
                        [&](const fs::path& p) { return std::regex_match(p.filename().string(), name); })) {
          std::erase_if(here, [&](const fs::path& p) { return !std::regex_match(p.filename().string(), name); });
        }
        std::sort(here.begin(), here.end());
        frames.insert(frames.end(), here.begin(), here.end());
      } else {
        frames.emplace_back(in);  // a missing or unreadable file is reported as its frame's reason
      }
    }
    if (frames.empty()) throw std::runtime_error("no frames (.png, .tif, .tiff, .fits) in the given folders or files");
    // Frame numbers: <k> of frame_<k>.png when every name has it, else the
    // order given (folders sorted by name).
    const bool numbered = std::all_of(frames.begin(), frames.end(), [&](const fs::path& p) {
      return std::regex_match(p.filename().string(), name);
    });
    std::optional<astro::TimeTT> t_cli;
    if (!time_utc.empty()) t_cli = astro::tt_from_utc_string(time_utc);
    const auto sidecar_time = [&](const fs::path& path) -> std::optional<std::int64_t> {
      fs::path side = path;
      side.replace_extension(".json");
      if (!fs::exists(side)) return std::nullopt;
      try {
        const auto j = nlohmann::json::parse(std::ifstream(side));
        return j.contains("time_tag_tt_ns") ? j.at("time_tag_tt_ns").get<std::int64_t>()
                                            : j.at("t_tt_ns").get<std::int64_t>();
      } catch (const std::exception& e) {
        std::fprintf(stderr, "artms-imp: %s: unreadable sidecar (%s)\n", side.c_str(), e.what());
        return std::nullopt;
      }
    };
    const auto is_fits = [](const fs::path& p) {
      std::string ext = p.extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
      return ext == ".fits" || ext == ".fit" || ext == ".fts";
    };
    // A FITS header's time (DATE-OBS, EXPTIME), read once per frame below;
    // for the catalog epoch, the first frame's.
    const auto fits_time = [&](const fs::path& path) -> std::optional<std::int64_t> {
      if (!is_fits(path)) return std::nullopt;
      try {
        const auto fr = imp_tool::read_fits(path.string(), fits_rows == "bottom-first");
        if (fr.t_mid) return fr.t_mid->ns_since_j2000;
      } catch (const std::exception&) {
      }
      return std::nullopt;
    };
    // Catalog directions at the first frame's epoch (proper motion over a
    // run is far below the identification tolerance).
    astro::TimeTT t_cat = astro::tt_from_utc_string("2000-01-01T12:00:00Z");
    if (const auto t0 = sidecar_time(frames.front())) {
      t_cat = astro::TimeTT{*t0};
    } else if (const auto tf = fits_time(frames.front())) {
      t_cat = astro::TimeTT{*tf};
    } else if (t_cli) {
      t_cat = *t_cli;
    } else {
      std::fprintf(stderr,
                   "artms-imp: warning: no time for the frames (no sidecar, FITS DATE-OBS or --time): the catalog stays at "
                   "J2000 and time tags are 0; proper motion since then can cost tens of arcsec of roll\n");
    }
    const int shift = calib.dn_shift_bits;
    const auto bsc = imaging::StarCatalog::load_bsc5(io::data_dir() + "/stars/bsc5.dat", vmag_limit);
    std::vector<imp::CatalogStar> stars;
    for (const auto& s : bsc.stars()) stars.push_back({s.catalog_id, s.unit_eci_at(t_cat)});
    const auto catalog = imp::StarIdCatalog::build(std::move(stars), 2.0 * K.half_diagonal_fov_rad());

    samus_opt.dbscan_radius_rad = eps_px / K.fx;
    samus_opt.model_floor_rad = floor_arcsec * astro::kArcsecToRad;
    std::optional<OrbitTable> orbit;
    if (!orbit_path.empty()) orbit = OrbitTable::load(orbit_path);
    if (aberration == "auto") {
      aberration = orbit ? "orbit" : "off";
      if (!orbit) {
        std::fprintf(stderr,
                     "artms-imp: stellar aberration left in the attitude (an astrometric attitude, up to ~26\" from the "
                     "true pointing; --aberration earth for a ground camera, --observer-orbit for a spacecraft)\n");
      }
    }
    if (aberration == "orbit" && !orbit) throw std::runtime_error("--aberration orbit needs --observer-orbit");
    // The observer's velocity about the solar-system barycentre at a frame
    // time (nullopt: no aberration). A frame the orbit does not cover gets
    // the Earth's alone (its orbital part, <= 5", is then left in it).
    const auto observer_velocity = [&](std::int64_t t_ns) -> std::optional<Eigen::Vector3d> {
      if (aberration == "off") return std::nullopt;
      Eigen::Vector3d v = dynamics::earth_velocity_bcrs_mps(astro::TimeTT{t_ns});
      if (aberration == "orbit") {
        if (const auto x = orbit->at(t_ns)) v += x->v_mps;
      }
      return v;
    };
    imp::FrameProcessorOptions fpo = fsw::frame_processor_options(calib, config::ImpTuning{});
    fpo.focal_search_fraction = focal_search_percent / 100.0;
    fpo.learn_psf = learn_psf;
    // One camera, one focal length: when the camera file's failed and the
    // search fitted a focal length per frame, every frame is solved again
    // with the one common to the solved frames, so that a frame with few
    // stars does not carry its own scale error into its attitude: the least
    // squares scale of all their stars together, sum I_k s_k / sum I_k with
    // I_k each frame's FrameSummary::focal_scale_information (the matched
    // stars' count weighs a frame whose stars sit near the centre, and fix
    // the scale poorly, as much as one whose stars span the field).
    imp::Intrinsics K_use = K;
    std::vector<std::pair<double, double>> frame_scales;  // (focal_scale, its information) of the solved frames
    for (int pass = 0; pass < 2; ++pass) {
      if (pass == 1) {
        double sw = 0.0, w = 0.0, lo = 1e9, hi = 0.0;
        for (const auto& [s, info] : frame_scales) {
          sw += s * info;
          w += info;
          lo = std::min(lo, s);
          hi = std::max(hi, s);
        }
        const bool searched = std::any_of(frame_scales.begin(), frame_scales.end(),
                                          [](const auto& fsn) { return fsn.first != 1.0; });
        if (per_frame_focal || frame_scales.size() < 2 || !searched || !(w > 0.0)) break;
        K_use.fx = K.fx * sw / w;
        K_use.fy = K.fy * sw / w;
        std::fprintf(stderr,
                     "artms-imp: focal length common to the %zu solved frames %.2f px (theirs %.2f to %.2f px; the "
                     "camera file's %.2f px); every frame solved again with it (--per-frame-focal: keep theirs)\n",
                     frame_scales.size(), K_use.fx, K.fx * lo, K.fx * hi, K.fx);
      }
      std::optional<imp::Samus> samus;
      if (orbit) samus.emplace(samus_opt);
      imp::FrameProcessor processor(K_use, catalog, fpo);

      fs::create_directories(out);
      std::ofstream att(fs::path(out) / "attitude.csv"), meas(fs::path(out) / "measurements.csv"),
          tracks(fs::path(out) / "tracks.csv");
      std::ofstream star_rows(fs::path(out) / "stars.csv");
      att << "frame,file,t_tt_ns,status,qw,qx,qy,qz,stars_matched,residual_arcsec,attitude_sigma_arcsec,focal_px,psf_sigma_px,why\n";
      star_rows << "frame,file,x_px,y_px,catalog_id,residual_arcsec,saturated,sigma_px\n";
      meas << "frame,t_tt_ns,track_id,x_px,y_px,ux_eci,uy_eci,uz_eci,az_rad,el_rad,sigma_rad\n";
      tracks << "track_id,first_frame,last_frame,measurements,segments,fit_rms_arcsec\n";
      // Candidates per frame; the track that took each (SAMUS decides later).
      struct Row {
        int frame;
        std::int64_t t_ns;
        imp::Candidate c;
        int track = -1;
      };
      std::vector<Row> rows;
      std::map<std::pair<int, int>, std::size_t> row_of;  // (frame, candidate) -> rows index
      auto take = [&](const std::vector<imp::TrackedMeasurement>& released) {
        for (const auto& m : released) {
          const auto it = row_of.find({static_cast<int>(m.frame), m.candidate});
          if (it != row_of.end()) rows[it->second].track = m.track_id;
        }
      };
      int solved = 0, corrupt = 0, hot = 0, uncatalogued = 0, no_orbit = 0;
      char line[512];
      for (std::size_t fi = 0; fi < frames.size(); ++fi) {
        const auto& path = frames[fi];
        const int k = numbered ? std::stoi(std::regex_replace(path.filename().string(), name, "$1"))
                               : static_cast<int>(fi);
        const std::string file = csv_text(path.filename().string());
        std::int64_t t_ns = t_cli ? t_cli->ns_since_j2000 : 0;
        imaging::Image16 img;
        try {
          if (is_fits(path)) {
            imp_tool::FitsFrame fr = imp_tool::read_fits(path.string(), fits_rows == "bottom-first");
            img = std::move(fr.image);
            if (fr.t_mid) t_ns = fr.t_mid->ns_since_j2000;
          } else {
            img = imaging::read_png16(path.string());
          }
          if (const auto ts = sidecar_time(path)) t_ns = *ts;
          if (shift > 0) {
            for (auto& v : img.pixels) v = static_cast<std::uint16_t>(v >> shift);
          }
          if (img.width != K.width || img.height != K.height) {
            throw std::runtime_error("size " + std::to_string(img.width) + "x" + std::to_string(img.height) +
                                     " does not match the camera");
          }
        } catch (const std::exception& e) {
          ++corrupt;
          std::fprintf(stderr, "artms-imp: skipping %s: %s\n", path.c_str(), e.what());
          std::snprintf(line, sizeof line, "%d,%s,%lld,corrupt,,,,,0,,,,,", k, file.c_str(), static_cast<long long>(t_ns));
          att << line << csv_text(e.what()) << "\n";
          continue;
        }
        const imp::FrameSummary fr = processor.process(img.pixels, astro::TimeTT{t_ns}, observer_velocity(t_ns));
        hot += fr.hot_pixels_removed;
        uncatalogued += fr.uncatalogued_stars_removed;
        if (!fr.attitude_usable) {
          std::snprintf(line, sizeof line, "%d,%s,%lld,%s,,,,,%d,,,,%.3f,", k, file.c_str(), static_cast<long long>(t_ns),
                        fr.status.c_str(), fr.stars_matched, fr.psf_sigma_px);
          att << line << csv_text(fr.why) << "\n";
          std::fprintf(stderr, "artms-imp: %s: %s (%s)\n", path.filename().c_str(), fr.status.c_str(), fr.why.c_str());
          continue;
        }
        ++solved;
        const auto q = astro::wxyz_from_quaternion(fr.q_cam_from_eci);
        std::snprintf(line, sizeof line, "%d,%s,%lld,ok,%.12f,%.12f,%.12f,%.12f,%d,%.3f,%.3f,%.3f,%.3f,\n", k,
                      file.c_str(), static_cast<long long>(t_ns), q[0], q[1], q[2], q[3], fr.stars_matched,
                      fr.residual_rms_rad / astro::kArcsecToRad, fr.attitude_sigma_rad / astro::kArcsecToRad,
                      K_use.fx * fr.focal_scale, fr.psf_sigma_px);
        att << line;
        if (pass == 0) frame_scales.emplace_back(K_use.fx * fr.focal_scale / K.fx, fr.focal_scale_information);
        for (const auto& st : fr.stars) {
          std::snprintf(line, sizeof line, "%d,%s,%.4f,%.4f,%d,%.3f,%d,%.4f\n", k, file.c_str(), st.x_px, st.y_px,
                        st.catalog_id, st.residual_rad / astro::kArcsecToRad, st.saturated ? 1 : 0, st.sigma_px);
          star_rows << line;
        }
        for (std::size_t i = 0; i < fr.candidates.size(); ++i) {
          row_of[{k, static_cast<int>(i)}] = rows.size();
          rows.push_back({k, t_ns, fr.candidates[i], -1});
        }
        if (samus) {
          const auto x = orbit->at(t_ns);
          if (!x) {
            ++no_orbit;
            continue;
          }
          imp::TrackerInput in;
          in.frame = k;
          in.t = astro::TimeTT{t_ns};
          in.observer_eci = *x;
          in.boresight_eci = fr.q_cam_from_eci.toRotationMatrix().transpose().col(2);
          in.candidates = fr.candidates;
          take(samus->process(in).released);
        }
        if (frames.size() >= 100 && (fi + 1) % (frames.size() / 10) == 0) {
          std::fprintf(stderr, "artms-imp: %zu / %zu frames\n", fi + 1, frames.size());
        }
      }
      int tracked = 0;
      if (samus) {
        take(samus->flush());
        for (const auto& t : samus->tracks()) {
          std::snprintf(line, sizeof line, "%d,%lld,%lld,%d,%d,%.2f\n", t.track_id, static_cast<long long>(t.first_frame),
                        static_cast<long long>(t.last_frame), t.measurements, t.segments,
                        t.fit_rms_rad / astro::kArcsecToRad);
          tracks << line;
        }
      }
      for (const auto& r : rows) {
        const Eigen::Vector3d& u = r.c.u_eci;
        const astro::Bearing b = astro::bearing_from_los(r.c.u_cam);
        std::snprintf(line, sizeof line, "%d,%lld,%d,%.4f,%.4f,%.12f,%.12f,%.12f,%.9f,%.9f,%.3e\n", r.frame,
                      static_cast<long long>(r.t_ns), r.track, r.c.x_px, r.c.y_px, u.x(), u.y(), u.z(), b.az_rad,
                      b.el_rad, r.c.sigma_rad);
        meas << line;
        if (r.track >= 0) ++tracked;
      }
      std::fprintf(stderr,
                   "artms-imp: %zu frames, attitude solved on %d, %d corrupt or unreadable; removed %d hot pixels and %d "
                   "uncatalogued stars; %zu candidates, %d in tracks (%s)\n",
                   frames.size(), solved, corrupt, hot, uncatalogued, rows.size(), tracked,
                   samus ? (std::to_string(samus->tracks().size()) + " tracks").c_str()
                         : "no --observer-orbit: SAMUS tracking off");
      if (no_orbit > 0) std::fprintf(stderr, "artms-imp: %d frames outside the observer orbit file: not tracked\n", no_orbit);
      if (solved == 0) {
        std::fprintf(stderr, "artms-imp: no frame solved (attitude.csv gives each frame's reason)\n");
        return 3;
      }
    }
  } catch (const std::exception& e) {
    std::cerr << "artms-imp: error: " << e.what() << "\n";
    return 2;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return run(argc, argv); }
