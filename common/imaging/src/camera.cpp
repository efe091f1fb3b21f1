// Camera model: YAML loading with located errors, projection and its inverse.
#include "artms/imaging/camera.hpp"

#include <yaml-cpp/yaml.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <vector>

namespace artms::imaging {

namespace {

// Reads one YAML document with every error located as file:line:column.
class Reader {
 public:
  explicit Reader(std::string source) : source_(std::move(source)) {}

  [[noreturn]] void fail(const YAML::Mark& mark, const std::string& key,
                         const std::string& what) const {
    std::string where = source_;
    if (!mark.is_null()) {
      where += ':' + std::to_string(mark.line + 1) + ':' + std::to_string(mark.column + 1);
    }
    throw std::runtime_error(where + ": " + (key.empty() ? "" : key + ": ") + what);
  }

  // The entries of a mapping by key, checked against the allowed keys
  // (unknown and repeated keys are errors).
  struct Entry {
    YAML::Node key;
    YAML::Node value;
  };
  using Entries = std::map<std::string, Entry, std::less<>>;

  Entries entries(const YAML::Node& map, const std::string& path,
                  std::initializer_list<std::string_view> allowed) const {
    if (!map.IsMap()) fail(map.Mark(), path.empty() ? "document" : path, "expected a mapping");
    Entries out;
    for (auto it = map.begin(); it != map.end(); ++it) {
      const YAML::Node k = it->first;
      if (!k.IsScalar()) fail(k.Mark(), path, "keys must be plain names");
      const std::string name = k.Scalar();
      const std::string full = join(path, name);
      if (std::find(allowed.begin(), allowed.end(), name) == allowed.end()) {
        std::string list;
        for (const auto a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
        fail(k.Mark(), full, "unknown key (expected one of: " + list + ")");
      }
      if (out.contains(name)) fail(k.Mark(), full, "repeated key");
      out.emplace(name, Entry{k, it->second});
    }
    return out;
  }

  static std::string join(const std::string& path, std::string_view key) {
    return path.empty() ? std::string(key) : path + "." + std::string(key);
  }

  // A finite number; `ok` checks the range and `range` says what it is.
  std::optional<double> number(const Entries& e, const YAML::Node& map, const std::string& path,
                               std::string_view key, bool required,
                               const std::function<bool(double)>& ok = {},
                               std::string_view range = {}) const {
    const std::string full = join(path, key);
    const auto it = e.find(key);
    if (it == e.end()) {
      if (required) fail(map.Mark(), full, "missing (required)");
      return std::nullopt;
    }
    const YAML::Node& v = it->second.value;
    double x = std::numeric_limits<double>::quiet_NaN();
    bool parsed = v.IsScalar();
    if (parsed) {
      try {
        x = v.as<double>();
      } catch (const YAML::Exception&) {
        parsed = false;
      }
    }
    if (!parsed || !std::isfinite(x)) {
      fail(v.Mark(), full, "expected a finite number, got " + describe(v));
    }
    if (ok && !ok(x)) {
      fail(v.Mark(), full, "expected a number " + std::string(range) + ", got " + v.Scalar());
    }
    return x;
  }

  // An integer in [lo, hi].
  std::optional<long long> integer(const Entries& e, const YAML::Node& map, const std::string& path,
                                   std::string_view key, bool required, long long lo,
                                   long long hi) const {
    const std::string full = join(path, key);
    const auto it = e.find(key);
    if (it == e.end()) {
      if (required) fail(map.Mark(), full, "missing (required)");
      return std::nullopt;
    }
    const YAML::Node& v = it->second.value;
    long long x = 0;
    bool parsed = v.IsScalar();
    if (parsed) {
      try {
        x = v.as<long long>();
      } catch (const YAML::Exception&) {
        parsed = false;
      }
    }
    if (!parsed) fail(v.Mark(), full, "expected an integer, got " + describe(v));
    if (x < lo || x > hi) {
      fail(v.Mark(), full,
           "expected an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " +
               v.Scalar());
    }
    return x;
  }

  std::optional<std::string> text(const Entries& e, const std::string& path,
                                  std::string_view key) const {
    const auto it = e.find(key);
    if (it == e.end()) return std::nullopt;
    const YAML::Node& v = it->second.value;
    if (!v.IsScalar() || v.Scalar().empty()) {
      fail(v.Mark(), join(path, key), "expected a name, got " + describe(v));
    }
    return v.Scalar();
  }

  // true or false.
  std::optional<bool> boolean(const Entries& e, const std::string& path, std::string_view key) const {
    const auto it = e.find(key);
    if (it == e.end()) return std::nullopt;
    const YAML::Node& v = it->second.value;
    bool x = false;
    bool parsed = v.IsScalar();
    if (parsed) {
      try {
        x = v.as<bool>();
      } catch (const YAML::Exception&) {
        parsed = false;
      }
    }
    if (!parsed) fail(v.Mark(), join(path, key), "expected true or false, got " + describe(v));
    return x;
  }

  // The value node of an optional sub-mapping (undefined node if absent).
  static YAML::Node child(const Entries& e, std::string_view key) {
    const auto it = e.find(key);
    return it == e.end() ? YAML::Node(YAML::NodeType::Undefined) : it->second.value;
  }

 private:
  static std::string describe(const YAML::Node& n) {
    switch (n.Type()) {
      case YAML::NodeType::Map:
        return "a mapping";
      case YAML::NodeType::Sequence:
        return "a list";
      case YAML::NodeType::Null:
      case YAML::NodeType::Undefined:
        return "nothing";
      case YAML::NodeType::Scalar:
        break;
    }
    return "'" + n.Scalar() + "'";
  }

  std::string source_;
};

bool positive(double x) {
  return x > 0.0;
}
bool non_negative(double x) {
  return x >= 0.0;
}

}  // namespace

CameraModel CameraModel::parse(const std::string& yaml_text, const std::string& source_name) {
  const Reader rd(source_name);
  YAML::Node doc;
  try {
    doc = YAML::Load(yaml_text);
  } catch (const YAML::ParserException& ex) {
    rd.fail(ex.mark, "", "YAML syntax error: " + ex.msg);
  }
  if (!doc.IsDefined() || doc.IsNull()) rd.fail(YAML::Mark::null_mark(), "", "empty camera file");

  CameraModel cam;
  const auto top = rd.entries(
      doc, "", {"name", "sensor", "optics", "photometry", "hot_pixels", "exclusion_deg", "star_id", "stray_light",
                     "centroid"});
  if (auto name = rd.text(top, "", "name")) cam.name = *name;

  // sensor: geometry (required) and detector parameters.
  {
    const YAML::Node node = Reader::child(top, "sensor");
    if (!node.IsDefined()) rd.fail(doc.Mark(), "sensor", "missing (required)");
    const std::string p = "sensor";
    const auto e =
        rd.entries(node, p,
                   {"width_px", "height_px", "pixel_pitch_um", "bit_depth", "dn_shift_bits", "gain_e_per_dn",
                    "full_well_e", "bias_dn", "read_noise_e", "dark_current_e_per_s", "blooming"});
    cam.width_px = static_cast<int>(*rd.integer(e, node, p, "width_px", true, 1, 100000));
    cam.height_px = static_cast<int>(*rd.integer(e, node, p, "height_px", true, 1, 100000));
    cam.pixel_pitch_m = *rd.number(e, node, p, "pixel_pitch_um", true, positive, "> 0") * 1e-6;
    cam.bit_depth = static_cast<int>(*rd.integer(e, node, p, "bit_depth", true, 1, 16));
    cam.dn_shift_bits = static_cast<int>(
        rd.integer(e, node, p, "dn_shift_bits", false, 0, 16 - cam.bit_depth).value_or(0));
    cam.gain_e_per_dn =
        rd.number(e, node, p, "gain_e_per_dn", false, positive, "> 0").value_or(cam.gain_e_per_dn);
    cam.full_well_e =
        rd.number(e, node, p, "full_well_e", false, positive, "> 0").value_or(cam.full_well_e);
    cam.bias_dn =
        rd.number(e, node, p, "bias_dn", false, non_negative, ">= 0").value_or(cam.bias_dn);
    cam.read_noise_e = rd.number(e, node, p, "read_noise_e", false, non_negative, ">= 0")
                           .value_or(cam.read_noise_e);
    cam.dark_current_e_per_s =
        rd.number(e, node, p, "dark_current_e_per_s", false, non_negative, ">= 0")
            .value_or(cam.dark_current_e_per_s);
    cam.blooming = rd.boolean(e, p, "blooming").value_or(false);
  }

  // optics: focal length (required), intrinsics, distortion, aperture, PSF.
  {
    const YAML::Node node = Reader::child(top, "optics");
    if (!node.IsDefined()) rd.fail(doc.Mark(), "optics", "missing (required)");
    const std::string p = "optics";
    const auto e = rd.entries(node, p,
                              {"focal_length_mm", "fx_px", "fy_px", "cx_px", "cy_px", "k1", "k2", "p1", "p2",
                               "aperture_diameter_mm", "throughput_qe", "psf_sigma_px", "vignetting_corner_loss",
                               "psf_growth_corner", "psf_colour_slope_per_mag"});
    cam.focal_length_m = *rd.number(e, node, p, "focal_length_mm", true, positive, "> 0") * 1e-3;
    const double f_px = cam.focal_length_m / cam.pixel_pitch_m;
    cam.fx_px = rd.number(e, node, p, "fx_px", false, positive, "> 0").value_or(f_px);
    cam.fy_px = rd.number(e, node, p, "fy_px", false, positive, "> 0").value_or(f_px);
    cam.cx_px = rd.number(e, node, p, "cx_px", false).value_or((cam.width_px - 1) / 2.0);
    cam.cy_px = rd.number(e, node, p, "cy_px", false).value_or((cam.height_px - 1) / 2.0);
    cam.k1 = rd.number(e, node, p, "k1", false).value_or(0.0);
    cam.k2 = rd.number(e, node, p, "k2", false).value_or(0.0);
    const auto small = [](double x) { return std::abs(x) <= 0.1; };
    cam.p1 = rd.number(e, node, p, "p1", false, small, "in [-0.1, 0.1]").value_or(0.0);
    cam.p2 = rd.number(e, node, p, "p2", false, small, "in [-0.1, 0.1]").value_or(0.0);
    if (auto d = rd.number(e, node, p, "aperture_diameter_mm", false, positive, "> 0")) {
      cam.aperture_diameter_m = *d * 1e-3;
    }
    cam.throughput_qe = rd.number(
                              e, node, p, "throughput_qe", false,
                              [](double x) { return x > 0 && x <= 1; }, "in (0, 1]")
                            .value_or(cam.throughput_qe);
    cam.psf_sigma_px = rd.number(
                             e, node, p, "psf_sigma_px", false,
                             [](double x) { return x >= 0.1 && x <= 50; }, "in [0.1, 50]")
                           .value_or(cam.psf_sigma_px);
    cam.vignetting_corner_loss =
        rd.number(e, node, p, "vignetting_corner_loss", false, [](double x) { return x >= 0.0 && x < 1.0; },
                  "in [0, 1)")
            .value_or(0.0);
    cam.psf_growth_corner =
        rd.number(e, node, p, "psf_growth_corner", false, [](double x) { return x >= 0.0 && x <= 5.0; },
                  "in [0, 5]")
            .value_or(0.0);
    cam.psf_colour_slope_per_mag =
        rd.number(e, node, p, "psf_colour_slope_per_mag", false, [](double x) { return x >= -0.5 && x <= 0.5; },
                  "in [-0.5, 0.5]")
            .value_or(0.0);
  }

  if (const YAML::Node node = Reader::child(top, "stray_light"); node.IsDefined()) {
    const std::string p = "stray_light";
    const auto e = rd.entries(node, p,
                              {"sun_edge_e_per_px_per_s", "moon_edge_e_per_px_per_s", "earth_edge_e_per_px_per_s",
                               "falloff_deg"});
    cam.stray_sun_edge_e_per_px_per_s =
        rd.number(e, node, p, "sun_edge_e_per_px_per_s", false, non_negative, ">= 0").value_or(0.0);
    cam.stray_moon_edge_e_per_px_per_s =
        rd.number(e, node, p, "moon_edge_e_per_px_per_s", false, non_negative, ">= 0").value_or(0.0);
    cam.stray_earth_edge_e_per_px_per_s =
        rd.number(e, node, p, "earth_edge_e_per_px_per_s", false, non_negative, ">= 0").value_or(0.0);
    if (auto f = rd.number(e, node, p, "falloff_deg", false, [](double x) { return x > 0.0 && x <= 90.0; },
                           "in (0, 90]")) {
      cam.stray_falloff_rad = *f * astro::kDegToRad;
    }
  }

  if (const YAML::Node node = Reader::child(top, "photometry"); node.IsDefined()) {
    const std::string p = "photometry";
    const auto e =
        rd.entries(node, p, {"exposure_s", "v0_photon_flux_per_s_m2", "background_e_per_px_per_s", "background_gradient"});
    cam.exposure_s =
        rd.number(e, node, p, "exposure_s", false, positive, "> 0").value_or(cam.exposure_s);
    cam.v0_photon_flux_per_s_m2 =
        rd.number(e, node, p, "v0_photon_flux_per_s_m2", false, positive, "> 0")
            .value_or(cam.v0_photon_flux_per_s_m2);
    cam.background_e_per_px_per_s =
        rd.number(e, node, p, "background_e_per_px_per_s", false, non_negative, ">= 0")
            .value_or(cam.background_e_per_px_per_s);
    cam.background_gradient =
        rd.number(e, node, p, "background_gradient", false, [](double x) { return x > -1.0 && x < 1.0; },
                  "in (-1, 1)")
            .value_or(0.0);
  }

  if (const YAML::Node node = Reader::child(top, "hot_pixels"); node.IsDefined()) {
    const std::string p = "hot_pixels";
    const auto e = rd.entries(node, p, {"count", "dark_min_e_per_s", "dark_max_e_per_s", "seed"});
    const long long n_px = static_cast<long long>(cam.width_px) * cam.height_px;
    cam.hot_pixel_count =
        static_cast<int>(rd.integer(e, node, p, "count", false, 0, std::min(n_px, 1000000LL))
                             .value_or(cam.hot_pixel_count));
    cam.hot_pixel_dark_min_e_per_s =
        rd.number(e, node, p, "dark_min_e_per_s", false, positive, "> 0")
            .value_or(cam.hot_pixel_dark_min_e_per_s);
    const double lo = cam.hot_pixel_dark_min_e_per_s;
    cam.hot_pixel_dark_max_e_per_s =
        rd.number(
              e, node, p, "dark_max_e_per_s", false, [lo](double x) { return x >= lo; },
              ">= dark_min_e_per_s")
            .value_or(std::max(lo, cam.hot_pixel_dark_max_e_per_s));
    cam.hot_pixel_seed = static_cast<std::uint64_t>(
        rd.integer(e, node, p, "seed", false, 0, std::numeric_limits<long long>::max())
            .value_or(static_cast<long long>(cam.hot_pixel_seed)));
  }

  if (const YAML::Node node = Reader::child(top, "star_id"); node.IsDefined()) {
    const std::string p = "star_id";
    const auto e = rd.entries(node, p, {"match_tolerance_arcsec"});
    if (auto a = rd.number(e, node, p, "match_tolerance_arcsec", false,
                           [](double x) { return x > 0.0 && x <= 3600.0; }, "in (0, 3600]")) {
      cam.match_tolerance_rad = *a * astro::kArcsecToRad;
    }
  }

  if (const YAML::Node node = Reader::child(top, "centroid"); node.IsDefined()) {
    const std::string p = "centroid";
    const auto e = rd.entries(node, p, {"method"});
    if (auto m = rd.text(e, p, "method")) {
      if (*m != "iwcog" && *m != "gaussian_fit") {
        rd.fail(e.find("method")->second.value.Mark(), "centroid.method", "expected iwcog or gaussian_fit, got " + *m);
      }
      cam.centroid_gaussian_fit = *m == "gaussian_fit";
    }
  }

  if (const YAML::Node node = Reader::child(top, "exclusion_deg"); node.IsDefined()) {
    const std::string p = "exclusion_deg";
    const auto e = rd.entries(node, p, {"sun", "moon", "earth_limb"});
    const auto angle = [](double x) { return x >= 0.0 && x < 180.0; };
    if (auto a = rd.number(e, node, p, "sun", false, angle, "in [0, 180)")) {
      cam.sun_exclusion_rad = *a * astro::kDegToRad;
    }
    if (auto a = rd.number(e, node, p, "moon", false, angle, "in [0, 180)")) {
      cam.moon_exclusion_rad = *a * astro::kDegToRad;
    }
    if (auto a = rd.number(e, node, p, "earth_limb", false, angle, "in [0, 180)")) {
      cam.earth_limb_exclusion_rad = *a * astro::kDegToRad;
    }
  }
  return cam;
}

CameraModel CameraModel::load(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open camera file");
  std::ostringstream text;
  text << in.rdbuf();
  return parse(text.str(), path);
}

double CameraModel::zero_point_e_per_s() const {
  const double area_m2 = astro::kPi / 4.0 * aperture_diameter_m * aperture_diameter_m;
  return v0_photon_flux_per_s_m2 * area_m2 * throughput_qe;
}

double CameraModel::electrons_from_vmag(double vmag) const {
  return zero_point_e_per_s() * std::pow(10.0, -0.4 * vmag) * exposure_s;
}

namespace {
// Brown's distortion of normalised coordinates (camera.hpp).
Vec2 distort(const Vec2& n, double k1, double k2, double p1, double p2) {
  const double x = n.x(), y = n.y(), r2 = x * x + y * y;
  const double s = 1.0 + r2 * (k1 + k2 * r2);
  return {x * s + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x), y * s + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y};
}
}  // namespace

Vec2 CameraModel::pixel_from_normalized(const Vec2& xn) const {
  const Vec2 d = distort(xn, k1, k2, p1, p2);
  return {cx_px + fx_px * d.x(), cy_px + fy_px * d.y()};
}

Vec2 CameraModel::normalized_from_pixel(const Vec2& px) const {
  const Vec2 xd((px.x() - cx_px) / fx_px, (px.y() - cy_px) / fy_px);
  if (p1 != 0.0 || p2 != 0.0) {
    // Newton in 2-D on distort(n) = xd from n = xd.
    Vec2 n = xd;
    for (int it = 0; it < 50; ++it) {
      const double x = n.x(), y = n.y(), r2 = x * x + y * y;
      const double s = 1.0 + r2 * (k1 + k2 * r2);
      const double ds = 2.0 * (k1 + 2.0 * k2 * r2);  // d s / d x = ds x, d s / d y = ds y
      Eigen::Matrix2d J;
      J << s + ds * x * x + 2.0 * p1 * y + 6.0 * p2 * x, ds * x * y + 2.0 * p1 * x + 2.0 * p2 * y,
          ds * x * y + 2.0 * p1 * x + 2.0 * p2 * y, s + ds * y * y + 6.0 * p1 * y + 2.0 * p2 * x;
      const Vec2 step = J.inverse() * (distort(n, k1, k2, p1, p2) - xd);
      if (!step.allFinite()) break;
      n -= step;
      if (step.norm() <= 1e-16 * std::max(1.0, n.norm())) break;
    }
    return n;
  }
  const double rd = xd.norm();
  if (rd == 0.0 || (k1 == 0.0 && k2 == 0.0)) return xd;
  // Solve g(r) = r (1 + k1 r^2 + k2 r^4) - rd = 0 for the undistorted radius
  // by Newton's method from r = rd; the direction is unchanged (radial model).
  double r = rd;
  for (int it = 0; it < 50; ++it) {
    const double r2 = r * r;
    const double g = r * (1.0 + r2 * (k1 + k2 * r2)) - rd;
    const double dg = 1.0 + r2 * (3.0 * k1 + 5.0 * k2 * r2);
    if (dg <= 0.0) break;  // past the turning point of the distortion
    const double step = g / dg;
    r -= step;
    if (std::abs(step) <= 1e-16 * std::max(1.0, r)) break;
  }
  return xd * (r / rd);
}

std::optional<Vec2> CameraModel::project_unbounded(const Vec3& v_cam) const {
  if (!(v_cam.z() > 0.0)) return std::nullopt;
  return pixel_from_normalized(Vec2(v_cam.x() / v_cam.z(), v_cam.y() / v_cam.z()));
}

std::optional<Vec2> CameraModel::project(const Vec3& v_cam, double margin_px) const {
  auto px = project_unbounded(v_cam);
  if (!px || !on_sensor(*px, margin_px)) return std::nullopt;
  return px;
}

Vec3 CameraModel::unproject(const Vec2& px) const {
  const Vec2 xn = normalized_from_pixel(px);
  return Vec3(xn.x(), xn.y(), 1.0).normalized();
}

bool CameraModel::on_sensor(const Vec2& px, double margin_px) const {
  return px.x() >= -0.5 - margin_px && px.x() <= width_px - 0.5 + margin_px &&
         px.y() >= -0.5 - margin_px && px.y() <= height_px - 0.5 + margin_px;
}

double CameraModel::fov_x_rad() const {
  return std::atan((cx_px + 0.5) / fx_px) + std::atan((width_px - 0.5 - cx_px) / fx_px);
}

double CameraModel::fov_y_rad() const {
  return std::atan((cy_px + 0.5) / fy_px) + std::atan((height_px - 0.5 - cy_px) / fy_px);
}

double CameraModel::half_diagonal_fov_rad() const {
  double worst = 0.0;
  for (const double x : {-0.5, width_px - 0.5}) {
    for (const double y : {-0.5, height_px - 0.5}) {
      const Vec3 u = unproject(Vec2(x, y));
      worst = std::max(worst, off_boresight_rad(u));
    }
  }
  return worst;
}

}  // namespace artms::imaging
