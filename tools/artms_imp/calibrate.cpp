// artms-calibrate CAMERA.yaml IMP_OUT... --out CAMERA_FIT.yaml: fits a
// camera's focal length (fx = fy), radial distortion k1 (and, on request,
// k2, the principal point and the tangential p1, p2) to the stars artms-imp identified in solved
// frames (its attitude.csv and stars.csv), each frame's attitude fitted
// with them, and writes the camera file with the fitted values.
//
// Model (the one IMP inverts, imaging::CameraModel): a catalog direction
// u_eci (BSC5 at the frames' epoch, proper motion applied) in camera axes
// v = R_f u_eci, R_f = exp([d_f]x) R_f0 (R_f0: artms-imp's attitude,
// d_f: a small rotation fitted per frame); x_n = (v_x / v_z, v_y / v_z);
// pixel = c + f D(x_n), D Brown's radial and tangential distortion
// (imaging/camera.hpp). Least squares on the pixel
// residuals by Gauss-Newton with Levenberg damping and a numerical
// Jacobian; the parameters' 1-sigma from (J^T J)^-1 scaled by the residual
// variance. Exit 0 on a fit, 2 on an error, 3 when fewer than 8 stars or
// no convergence.
#include <CLI/CLI.hpp>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "artms/astro/constants.hpp"
#include "artms/astro/time.hpp"
#include "artms/imaging/camera.hpp"
#include "artms/imaging/star_catalog.hpp"
#include "artms/io/csv.hpp"
#include "artms/io/paths.hpp"

namespace {

using namespace artms;
namespace fs = std::filesystem;
using Eigen::MatrixXd;
using Eigen::Vector3d;
using Eigen::VectorXd;

struct Obs {
  int frame;        // index into frames
  double x_px, y_px;
  Vector3d u_eci;
};

Eigen::Matrix3d rotation(const Vector3d& d) {
  const double a = d.norm();
  if (a < 1e-15) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(a, d / a).toRotationMatrix();
}

int run(int argc, char** argv) {
  CLI::App app{"Fit a camera's focal length and distortion (and, on request, its principal point) to the stars\n"
               "artms-imp identified in solved frames; write the fitted camera file.",
               "artms-calibrate"};
  std::string camera_path, out, time_utc;
  std::vector<std::string> runs;
  bool fit_k2 = false, fit_principal = false, fit_tangential = false;
  double vmag_limit = 6.5;
  app.add_option("camera", camera_path, "the camera file artms-imp ran with")->required();
  app.add_option("imp_out", runs, "artms-imp output folders (attitude.csv, stars.csv)")->required();
  app.add_option("--out", out, "camera file to write")->required();
  app.add_option("--time", time_utc, "UTC of the frames (the catalog's proper-motion epoch), as given to artms-imp")
      ->required();
  app.add_flag("--fit-k2", fit_k2, "also fit k2");
  app.add_flag("--fit-tangential", fit_tangential, "also fit the tangential (decentring) distortion p1, p2");
  app.add_flag("--fit-principal-point", fit_principal,
               "also fit cx, cy (nearly the same as a rotation in a narrow field: needs many frames)");
  app.add_option("--vmag-limit", vmag_limit, "faintest catalog star read")->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  try {
    imaging::CameraModel cam = imaging::CameraModel::load(camera_path);
    const astro::TimeTT t = astro::tt_from_utc_string(time_utc);
    const auto bsc = imaging::StarCatalog::load_bsc5(io::data_dir() + "/stars/bsc5.dat", std::max(vmag_limit, 8.0));
    std::vector<Eigen::Matrix3d> R0;
    std::vector<Obs> obs;
    for (const auto& dir : runs) {
      const auto att = io::CsvTable::read((fs::path(dir) / "attitude.csv").string());
      const auto st = io::CsvTable::read((fs::path(dir) / "stars.csv").string());
      std::map<std::string, int> frame_of;  // "frame" text -> index into R0
      for (std::size_t k = 0; k < att.size(); ++k) {
        if (att.text(k, "status") != "ok") continue;
        const Eigen::Quaterniond q(att.number(k, "qw"), att.number(k, "qx"), att.number(k, "qy"), att.number(k, "qz"));
        frame_of[dir + "#" + att.text(k, "frame")] = static_cast<int>(R0.size());
        R0.push_back(q.normalized().toRotationMatrix());
      }
      for (std::size_t k = 0; k < st.size(); ++k) {
        const auto it = frame_of.find(dir + "#" + st.text(k, "frame"));
        if (it == frame_of.end()) continue;
        const int id = static_cast<int>(st.integer(k, "catalog_id"));
        const imaging::Star* s = bsc.find(id);
        if (!s) {
          throw std::runtime_error(st.path() + ":" + std::to_string(st.line(k)) + ": catalog_id " + std::to_string(id) +
                                   " is not in BSC5 (V <= " + std::to_string(std::max(vmag_limit, 8.0)) + ")");
        }
        obs.push_back({it->second, st.number(k, "x_px"), st.number(k, "y_px"), s->unit_eci_at(t)});
      }
    }
    const int F = static_cast<int>(R0.size());
    const int n_obs = static_cast<int>(obs.size());
    std::fprintf(stderr, "artms-calibrate: %d solved frames, %d identified stars\n", F, n_obs);
    if (n_obs < 8) {
      std::fprintf(stderr, "artms-calibrate: fewer than 8 identified stars: nothing fitted\n");
      return 3;
    }
    // Parameters: f, k1, [k2], [cx, cy], [p1, p2], then 3 per frame.
    std::vector<std::string> names = {"f_px", "k1"};
    int i_k2 = -1, i_c = -1, i_p = -1;
    if (fit_k2) {
      i_k2 = static_cast<int>(names.size());
      names.push_back("k2");
    }
    if (fit_principal) {
      i_c = static_cast<int>(names.size());
      names.push_back("cx_px");
      names.push_back("cy_px");
    }
    if (fit_tangential) {
      i_p = static_cast<int>(names.size());
      names.push_back("p1");
      names.push_back("p2");
    }
    const int n_cam = static_cast<int>(names.size());
    const int n = n_cam + 3 * F;
    VectorXd p = VectorXd::Zero(n);
    p[0] = 0.5 * (cam.fx_px + cam.fy_px);
    p[1] = cam.k1;
    if (i_k2 >= 0) p[i_k2] = cam.k2;
    if (i_c >= 0) {
      p[i_c] = cam.cx_px;
      p[i_c + 1] = cam.cy_px;
    }
    if (i_p >= 0) {
      p[i_p] = cam.p1;
      p[i_p + 1] = cam.p2;
    }
    const auto camera_at = [&](const VectorXd& x) {
      imaging::CameraModel c = cam;
      c.fx_px = c.fy_px = x[0];
      c.k1 = x[1];
      if (i_k2 >= 0) c.k2 = x[i_k2];
      if (i_c >= 0) {
        c.cx_px = x[i_c];
        c.cy_px = x[i_c + 1];
      }
      if (i_p >= 0) {
        c.p1 = x[i_p];
        c.p2 = x[i_p + 1];
      }
      return c;
    };
    const auto residuals = [&](const VectorXd& x) {
      VectorXd r(2 * n_obs);
      const imaging::CameraModel c = camera_at(x);
      for (int j = 0; j < n_obs; ++j) {
        const Obs& o = obs[static_cast<std::size_t>(j)];
        const Vector3d v =
            rotation(x.segment<3>(n_cam + 3 * o.frame)) * R0[static_cast<std::size_t>(o.frame)] * o.u_eci;
        const Eigen::Vector2d px = c.pixel_from_normalized({v.x() / v.z(), v.y() / v.z()});
        r[2 * j] = px.x() - o.x_px;
        r[2 * j + 1] = px.y() - o.y_px;
      }
      return r;
    };
    const auto jacobian = [&](const VectorXd& x) {
      MatrixXd J(2 * n_obs, n);
      for (int k = 0; k < n; ++k) {
        const double h = k == 0 ? 1e-3 : (k >= n_cam ? 1e-8 : (k == i_c || k == i_c + 1 ? 1e-3 : 1e-6));
        VectorXd a = x, b = x;
        a[k] += h;
        b[k] -= h;
        J.col(k) = (residuals(a) - residuals(b)) / (2.0 * h);
      }
      return J;
    };
    double lambda = 1e-3;
    VectorXd r = residuals(p);
    double cost = r.squaredNorm();
    const double cost0 = cost;
    bool converged = false;
    int it = 0;
    for (; it < 100; ++it) {
      const MatrixXd J = jacobian(p);
      const MatrixXd A = J.transpose() * J;
      const VectorXd g = J.transpose() * r;
      MatrixXd Ad = A;
      Ad.diagonal() += lambda * A.diagonal().cwiseMax(1e-12);
      const VectorXd dp = -Ad.ldlt().solve(g);
      const VectorXd pn = p + dp;
      const VectorXd rn = residuals(pn);
      const double cn = rn.squaredNorm();
      if (cn < cost) {
        const bool small = cost - cn < 1e-12 * cost || dp.cwiseAbs().maxCoeff() < 1e-10;
        p = pn;
        r = rn;
        cost = cn;
        lambda = std::max(lambda / 10.0, 1e-9);
        if (small) {
          converged = true;
          break;
        }
      } else {
        lambda *= 10.0;
        if (lambda > 1e8) {
          converged = true;  // no step lowers the cost: at the minimum
          break;
        }
      }
    }
    if (!converged) {
      std::fprintf(stderr, "artms-calibrate: no convergence in %d iterations\n", it);
      return 3;
    }
    const int dof = 2 * n_obs - n;
    const double var = dof > 0 ? cost / dof : cost;
    const MatrixXd J = jacobian(p);
    const MatrixXd P = (J.transpose() * J).ldlt().solve(MatrixXd::Identity(n, n)) * var;
    std::printf("artms-calibrate: %d frames, %d stars; pixel residual RMS %.3f px (before %.3f px)\n", F, n_obs,
                std::sqrt(cost / (2.0 * n_obs)), std::sqrt(cost0 / (2.0 * n_obs)));
    for (int k = 0; k < n_cam; ++k) {
      std::printf("  %-6s %.6g +- %.3g\n", names[static_cast<std::size_t>(k)].c_str(), p[k], std::sqrt(P(k, k)));
    }
    cam = camera_at(p);
    std::ofstream f(out);
    if (!f) throw std::runtime_error(out + ": cannot write");
    char buf[1024];
    f << "# Written by artms-calibrate from " << camera_path << ": " << F << " frames, " << n_obs
      << " identified stars.\n";
    std::snprintf(buf, sizeof buf, "# Pixel residual RMS %.3f px; f %.3f +- %.3f px, k1 %.4g +- %.2g.\n",
                  std::sqrt(cost / (2.0 * n_obs)), p[0], std::sqrt(P(0, 0)), p[1], std::sqrt(P(1, 1)));
    f << buf << "name: " << cam.name << "-calibrated\n\nsensor:\n";
    std::snprintf(buf, sizeof buf,
                  "  width_px: %d\n  height_px: %d\n  pixel_pitch_um: %.9g\n  bit_depth: %d\n  dn_shift_bits: %d\n"
                  "  gain_e_per_dn: %.9g\n  full_well_e: %.9g\n  bias_dn: %.9g\n  read_noise_e: %.9g\n",
                  cam.width_px, cam.height_px, cam.pixel_pitch_m * 1e6, cam.bit_depth, cam.dn_shift_bits,
                  cam.gain_e_per_dn, cam.full_well_e, cam.bias_dn, cam.read_noise_e);
    f << buf;
    std::snprintf(buf, sizeof buf, "  dark_current_e_per_s: %.9g\n  blooming: %s\n\noptics:\n  focal_length_mm: %.9g\n",
                  cam.dark_current_e_per_s, cam.blooming ? "true" : "false", cam.fx_px * cam.pixel_pitch_m * 1e3);
    f << buf;
    std::snprintf(buf, sizeof buf,
                  "  fx_px: %.6f\n  fy_px: %.6f\n  cx_px: %.6f\n  cy_px: %.6f\n  k1: %.9g\n  k2: %.9g\n  p1: %.9g\n"
                  "  p2: %.9g\n  aperture_diameter_mm: %.9g\n  throughput_qe: %.9g\n  psf_sigma_px: %.9g\n",
                  cam.fx_px, cam.fy_px, cam.cx_px, cam.cy_px, cam.k1, cam.k2, cam.p1, cam.p2, cam.aperture_diameter_m * 1e3,
                  cam.throughput_qe, cam.psf_sigma_px);
    f << buf;
    std::snprintf(buf, sizeof buf,
                  "  vignetting_corner_loss: %.9g\n  psf_growth_corner: %.9g\n  psf_colour_slope_per_mag: %.9g\n",
                  cam.vignetting_corner_loss, cam.psf_growth_corner, cam.psf_colour_slope_per_mag);
    f << buf;
    std::snprintf(buf, sizeof buf,
                  "\nphotometry:\n  exposure_s: %.9g\n  v0_photon_flux_per_s_m2: %.9g\n  background_e_per_px_per_s: %.9g\n"
                  "  background_gradient: %.9g\n",
                  cam.exposure_s, cam.v0_photon_flux_per_s_m2, cam.background_e_per_px_per_s, cam.background_gradient);
    f << buf;
    std::snprintf(buf, sizeof buf,
                  "\nstray_light:\n  sun_edge_e_per_px_per_s: %.9g\n  moon_edge_e_per_px_per_s: %.9g\n"
                  "  earth_edge_e_per_px_per_s: %.9g\n  falloff_deg: %.9g\n",
                  cam.stray_sun_edge_e_per_px_per_s, cam.stray_moon_edge_e_per_px_per_s,
                  cam.stray_earth_edge_e_per_px_per_s, cam.stray_falloff_rad / astro::kDegToRad);
    f << buf;
    std::snprintf(buf, sizeof buf, "\nhot_pixels:\n  count: %d\n  dark_min_e_per_s: %.9g\n  dark_max_e_per_s: %.9g\n  seed: %llu\n",
                  cam.hot_pixel_count, cam.hot_pixel_dark_min_e_per_s, cam.hot_pixel_dark_max_e_per_s,
                  static_cast<unsigned long long>(cam.hot_pixel_seed));
    f << buf;
    std::snprintf(buf, sizeof buf, "\nexclusion_deg:\n  sun: %.9g\n  moon: %.9g\n  earth_limb: %.9g\n",
                  cam.sun_exclusion_rad / astro::kDegToRad, cam.moon_exclusion_rad / astro::kDegToRad,
                  cam.earth_limb_exclusion_rad / astro::kDegToRad);
    f << buf;
    if (cam.match_tolerance_rad > 0.0) {
      std::snprintf(buf, sizeof buf, "\nstar_id:\n  match_tolerance_arcsec: %.9g\n",
                    cam.match_tolerance_rad / astro::kArcsecToRad);
      f << buf;
    }
    if (cam.centroid_gaussian_fit) f << "\ncentroid:\n  method: gaussian_fit\n";
    f.close();
    imaging::CameraModel::load(out);  // what was written loads
    std::printf("camera file: %s\n", out.c_str());
  } catch (const std::exception& e) {
    std::cerr << "artms-calibrate: error: " << e.what() << "\n";
    return 2;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return run(argc, argv); }
