#include "artms/dynamics/atmosphere.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include "artms/astro/constants.hpp"

namespace artms::dynamics {

namespace {

// WGS84 ellipsoid (NIMA TR8350.2).
constexpr double kWgs84A_m = 6378137.0;
constexpr double kWgs84F = 1.0 / 298.257223563;

// Table units: g/km^3 = 1e-3 kg / 1e9 m^3 = 1e-12 kg/m^3.
constexpr double kKgpm3PerGpkm3 = 1e-12;

constexpr std::string_view kHeader = "height_km,rho_min_g_per_km3,rho_max_g_per_km3";

std::string_view trim(std::string_view s) {
  const auto first = s.find_first_not_of(" \t\r\n");
  if (first == std::string_view::npos) return {};
  const auto last = s.find_last_not_of(" \t\r\n");
  return s.substr(first, last - first + 1);
}

[[noreturn]] void fail(const std::string& path, int line, const std::string& what) {
  throw std::runtime_error("Harris-Priester table " + path + ":" + std::to_string(line) + ": " +
                           what);
}

double parse_number(std::string_view field, const std::string& path, int line) {
  const std::string_view f = trim(field);
  double value = 0.0;
  const auto [end, ec] = std::from_chars(f.data(), f.data() + f.size(), value);
  if (f.empty() || ec != std::errc() || end != f.data() + f.size() || !std::isfinite(value)) {
    fail(path, line, "not a number: '" + std::string(field) + "'");
  }
  return value;
}

}  // namespace

HarrisPriester HarrisPriester::from_file(const std::string& csv_path,
                                         const HarrisPriesterOptions& options) {
  std::ifstream in(csv_path);
  if (!in) throw std::runtime_error("cannot open Harris-Priester table " + csv_path);
  if (!(options.cosine_exponent > 0.0)) {
    throw std::invalid_argument("Harris-Priester cosine exponent must be positive");
  }

  HarrisPriester hp;
  hp.options_ = options;
  bool header_seen = false;
  int line_no = 0;
  std::string line;
  while (std::getline(in, line)) {
    ++line_no;
    const std::string_view text = trim(line);
    if (text.empty() || text.front() == '#') continue;
    if (!header_seen) {
      if (text != kHeader) {
        fail(csv_path, line_no, "expected header '" + std::string(kHeader) + "'");
      }
      header_seen = true;
      continue;
    }
    std::vector<std::string_view> fields;
    std::size_t start = 0;
    while (true) {
      const auto comma = text.find(',', start);
      fields.push_back(text.substr(start, comma == std::string_view::npos ? comma : comma - start));
      if (comma == std::string_view::npos) break;
      start = comma + 1;
    }
    if (fields.size() != 3) {
      fail(csv_path, line_no, "expected 3 fields, found " + std::to_string(fields.size()));
    }
    const double h_km = parse_number(fields[0], csv_path, line_no);
    const double rho_min = parse_number(fields[1], csv_path, line_no) * kKgpm3PerGpkm3;
    const double rho_max = parse_number(fields[2], csv_path, line_no) * kKgpm3PerGpkm3;
    if (!(rho_min > 0.0) || rho_max < rho_min) {
      fail(csv_path, line_no, "densities must satisfy 0 < rho_min <= rho_max");
    }
    if (!hp.height_m_.empty()) {
      // Exponential interpolation needs increasing heights and densities that
      // fall strictly with height (finite, positive scale heights).
      if (!(h_km * 1e3 > hp.height_m_.back())) fail(csv_path, line_no, "heights must increase");
      if (!(rho_min < hp.rho_min_.back()) || !(rho_max < hp.rho_max_.back())) {
        fail(csv_path, line_no, "densities must decrease with height");
      }
    }
    hp.height_m_.push_back(h_km * 1e3);
    hp.rho_min_.push_back(rho_min);
    hp.rho_max_.push_back(rho_max);
  }
  if (!header_seen) fail(csv_path, line_no, "missing header '" + std::string(kHeader) + "'");
  if (hp.height_m_.size() < 2) fail(csv_path, line_no, "fewer than two table rows");
  return hp;
}

HarrisPriester::Densities HarrisPriester::table_densities(double h) const {
  if (h >= height_m_.back()) return {};
  if (h < height_m_.front()) {
    throw std::out_of_range("Harris-Priester: height " + std::to_string(h * 1e-3) +
                            " km is below the table's bottom (orbit decayed)");
  }

  // Table interval [h_i, h_i+1) holding h.
  const auto upper = std::upper_bound(height_m_.begin(), height_m_.end(), h);
  const auto i = static_cast<std::size_t>(std::distance(height_m_.begin(), upper) - 1);
  const double h0 = height_m_[i], h1 = height_m_[i + 1];

  // M&G section 3.5.2: exponential interpolation with scale heights
  // H = (h_i - h_i+1) / ln(rho_i+1 / rho_i), rho(h) = rho_i exp((h_i - h) / H).
  const double H_min = (h0 - h1) / std::log(rho_min_[i + 1] / rho_min_[i]);
  const double H_max = (h0 - h1) / std::log(rho_max_[i + 1] / rho_max_[i]);
  return {rho_min_[i] * std::exp((h0 - h) / H_min), rho_max_[i] * std::exp((h0 - h) / H_max)};
}

double HarrisPriester::density_kgpm3(const Vec3& r_eci_m, const Vec3& r_ecef_m,
                                     const Vec3& r_sun_eci_m) const {
  const double h = geodetic_height_m(r_ecef_m);
  const Densities d = table_densities(h);
  if (d.max_kgpm3 == 0.0) return 0.0;
  const double rho_min = d.min_kgpm3;
  const double rho_max = d.max_kgpm3;

  // Apex of the diurnal bulge at the Sun's declination
  // and the Sun's right ascension plus the lag angle.
  const double ra_sun = std::atan2(r_sun_eci_m.y(), r_sun_eci_m.x());
  const double dec_sun = std::atan2(r_sun_eci_m.z(), r_sun_eci_m.head<2>().norm());
  const double ra_apex = ra_sun + options_.lag_angle_rad;
  const Vec3 e_bulge(std::cos(dec_sun) * std::cos(ra_apex), std::cos(dec_sun) * std::sin(ra_apex),
                     std::sin(dec_sun));
  // cos^2(psi/2) = (1 + cos psi) / 2 with cos psi = e_r . e_bulge, so
  // cos^n(psi/2) = ((1 + cos psi)/2)^(n/2).
  const double cos2_half_psi =
      std::clamp(0.5 + 0.5 * r_eci_m.dot(e_bulge) / r_eci_m.norm(), 0.0, 1.0);
  const double weight = std::pow(cos2_half_psi, 0.5 * options_.cosine_exponent);

  // rho = rho_m + (rho_M - rho_m) cos^n(psi/2).
  return rho_min + (rho_max - rho_min) * weight;
}

double geodetic_height_m(const Vec3& r_ecef_m) {
  // Iteration on the ellipsoidal correction dZ = N e^2 sin(phi) of the
  // z coordinate (M&G section 5.5.1), converging to ~1e-9 m in a
  // handful of steps for any point outside the Earth's core.
  const double e2 = kWgs84F * (2.0 - kWgs84F);
  const double x = r_ecef_m.x(), y = r_ecef_m.y(), z = r_ecef_m.z();
  const double rho2 = x * x + y * y;
  if (rho2 + z * z == 0.0) throw std::invalid_argument("geodetic_height_m: zero position vector");
  double dz = e2 * z;
  double n = kWgs84A_m;
  double nh = 0.0;
  for (int iter = 0; iter < 50; ++iter) {
    const double zdz = z + dz;
    nh = std::sqrt(rho2 + zdz * zdz);
    const double sin_phi = zdz / nh;
    n = kWgs84A_m / std::sqrt(1.0 - e2 * sin_phi * sin_phi);
    const double dz_new = n * e2 * sin_phi;
    const bool converged = std::abs(dz_new - dz) < 1e-10;
    dz = dz_new;
    if (converged) break;
  }
  const double zdz = z + dz;
  nh = std::sqrt(rho2 + zdz * zdz);
  const double sin_phi = zdz / nh;
  n = kWgs84A_m / std::sqrt(1.0 - e2 * sin_phi * sin_phi);
  return nh - n;
}

Vec3 drag_acceleration_mps2(const Vec3& r_eci_m, const Vec3& v_eci_mps, double density_kgpm3,
                            double cd, double area_to_mass_m2pkg) {
  // M&G section 3.5.1: a = -1/2 Cd (A/m) rho |v_r| v_r, with the velocity
  // relative to an atmosphere co-rotating with the Earth, v_r = v - omega x r.
  // The rotation axis is taken as the ECI z axis (precession since J2000
  // tilts it by < 0.2 deg before 2040: < 2 m/s, < 0.03 % of v_r in LEO).
  const Vec3 omega(0.0, 0.0, astro::kEarthRotation_radps);
  const Vec3 v_rel = v_eci_mps - omega.cross(r_eci_m);
  return -0.5 * cd * area_to_mass_m2pkg * density_kgpm3 * v_rel.norm() * v_rel;
}

}  // namespace artms::dynamics
