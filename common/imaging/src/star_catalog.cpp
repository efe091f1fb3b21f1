// Yale Bright Star Catalogue (BSC5) reader and cone queries.
#include "artms/imaging/star_catalog.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <optional>
#include <stdexcept>
#include <string_view>
#include <system_error>

#include "artms/astro/constants.hpp"

namespace artms::imaging {

namespace {

constexpr double kDaysPerJulianYear = 365.25;

// Unit vector and the local east (increasing RA) and north (increasing Dec)
// unit vectors of the tangent plane at (ra, dec).
struct Tangent {
  Eigen::Vector3d u, e_ra, e_dec;
};
Tangent tangent_at(double ra, double dec) {
  const double ca = std::cos(ra), sa = std::sin(ra), cd = std::cos(dec), sd = std::sin(dec);
  return {{cd * ca, cd * sa, sd}, {-sa, ca, 0.0}, {-sd * ca, -sd * sa, cd}};
}

std::string_view trim(std::string_view s) {
  const auto b = s.find_first_not_of(' ');
  if (b == std::string_view::npos) return {};
  const auto e = s.find_last_not_of(' ');
  return s.substr(b, e - b + 1);
}

// Bytes [first, last] (1-based, inclusive) of a line, empty past its end.
std::string_view bytes(std::string_view line, std::size_t first, std::size_t last) {
  if (line.size() < first) return {};
  return line.substr(first - 1, std::min(last, line.size()) - first + 1);
}

class LineParser {
 public:
  LineParser(const std::string& source, std::size_t line_no, std::string_view line)
      : source_(source), line_no_(line_no), line_(line) {}

  void set_hr(int hr) { hr_ = hr; }

  [[noreturn]] void fail(std::string_view field, std::size_t first, std::size_t last,
                         const std::string& problem) const {
    std::string msg = source_ + ":" + std::to_string(line_no_) + ": ";
    if (hr_ > 0) msg += "HR " + std::to_string(hr_) + ": ";
    msg += std::string(field) + " (bytes " + std::to_string(first) + "-" + std::to_string(last) +
           "): " + problem;
    throw std::runtime_error(msg);
  }

  // A number in bytes [first, last]; nullopt when blank.
  std::optional<double> number(std::string_view field, std::size_t first, std::size_t last) const {
    std::string_view s = trim(bytes(line_, first, last));
    if (s.empty()) return std::nullopt;
    const std::string raw(s);
    if (s.front() == '+') s.remove_prefix(1);
    double x = 0.0;
    const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), x);
    if (ec != std::errc() || end != s.data() + s.size() || !std::isfinite(x)) {
      fail(field, first, last, "not a number: '" + raw + "'");
    }
    return x;
  }

  double required(std::string_view field, std::size_t first, std::size_t last, double lo,
                  double hi) const {
    const auto x = number(field, first, last);
    if (!x) fail(field, first, last, "blank");
    if (*x < lo || *x >= hi) {
      fail(field, first, last,
           "out of range [" + std::to_string(lo) + ", " + std::to_string(hi) +
               "): " + std::string(trim(bytes(line_, first, last))));
    }
    return *x;
  }

  [[nodiscard]] std::string_view line() const { return line_; }

 private:
  const std::string& source_;
  std::size_t line_no_;
  std::string_view line_;
  int hr_ = 0;
};

}  // namespace

Eigen::Vector3d Star::unit_eci_j2000() const {
  return tangent_at(ra_rad, dec_rad).u;
}

Eigen::Vector3d Star::unit_eci_at(astro::TimeTT t) const {
  const Tangent tp = tangent_at(ra_rad, dec_rad);
  const double dt_yr = t.seconds_since_j2000() / (astro::kSecondsPerDay * kDaysPerJulianYear);
  return (tp.u + (pm_ra_cosdec_radpyr * tp.e_ra + pm_dec_radpyr * tp.e_dec) * dt_yr).normalized();
}

StarCatalog::StarCatalog(std::vector<Star> stars) : stars_(std::move(stars)) {
  u_j2000_.reserve(stars_.size());
  for (const Star& s : stars_) {
    u_j2000_.push_back(s.unit_eci_j2000());
    max_pm_radpyr_ = std::max(max_pm_radpyr_, std::hypot(s.pm_ra_cosdec_radpyr, s.pm_dec_radpyr));
  }
}

StarCatalog StarCatalog::parse_bsc5(std::istream& in, const std::string& source_name,
                                    double vmag_limit) {
  constexpr double kArcsec = astro::kArcsecToRad;
  std::vector<Star> stars;
  std::string raw;
  std::size_t line_no = 0;
  while (std::getline(in, raw)) {
    ++line_no;
    std::string_view line = raw;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (trim(line).empty()) continue;
    LineParser p(source_name, line_no, line);

    const auto hr = p.number("HR", 1, 4);
    if (!hr || *hr < 1 || *hr != std::floor(*hr)) {
      p.fail("HR", 1, 4,
             "expected a positive integer, got '" + std::string(bytes(line, 1, 4)) + "'");
    }
    Star s;
    s.catalog_id = static_cast<int>(*hr);
    p.set_hr(s.catalog_id);

    // Removed entries keep their HR number with the position left blank.
    if (trim(bytes(line, 76, 90)).empty()) continue;

    const double ra_h = p.required("RAh", 76, 77, 0, 24);
    const double ra_m = p.required("RAm", 78, 79, 0, 60);
    const double ra_s = p.required("RAs", 80, 83, 0, 60);
    const std::string_view sign = bytes(line, 84, 84);
    if (sign != "+" && sign != "-") {
      p.fail("DE-", 84, 84, "expected '+' or '-', got '" + std::string(sign) + "'");
    }
    const double de_d = p.required("DEd", 85, 86, 0, 91);
    const double de_m = p.required("DEm", 87, 88, 0, 60);
    const double de_s = p.required("DEs", 89, 90, 0, 60);
    const double dec_deg = (sign == "-" ? -1.0 : 1.0) * (de_d + de_m / 60.0 + de_s / 3600.0);
    if (std::abs(dec_deg) > 90.0) p.fail("Dec", 84, 90, "beyond the pole");
    s.ra_rad = (ra_h + ra_m / 60.0 + ra_s / 3600.0) * 15.0 * astro::kDegToRad;
    s.dec_rad = dec_deg * astro::kDegToRad;
    s.vmag = p.required("Vmag", 103, 107, -2.0, 20.0);
    s.b_minus_v = p.number("B-V", 110, 114).value_or(0.65);
    s.pm_ra_cosdec_radpyr = p.number("pmRA", 149, 154).value_or(0.0) * kArcsec;
    s.pm_dec_radpyr = p.number("pmDE", 155, 160).value_or(0.0) * kArcsec;
    if (s.vmag <= vmag_limit) stars.push_back(s);
  }
  if (in.bad()) throw std::runtime_error(source_name + ": read error");
  return StarCatalog(std::move(stars));
}

StarCatalog StarCatalog::load_bsc5(const std::string& path, double vmag_limit) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open star catalog");
  return parse_bsc5(in, path, vmag_limit);
}

const Star* StarCatalog::find(int catalog_id) const {
  for (const Star& s : stars_) {
    if (s.catalog_id == catalog_id) return &s;
  }
  return nullptr;
}

std::vector<const Star*> StarCatalog::in_cone(const Eigen::Vector3d& dir_eci, double half_angle_rad,
                                              astro::TimeTT t) const {
  std::vector<const Star*> out;
  const double n = dir_eci.norm();
  if (!(n > 0.0)) return out;
  const Eigen::Vector3d d = dir_eci / n;
  const double dt_yr =
      std::abs(t.seconds_since_j2000()) / (astro::kSecondsPerDay * kDaysPerJulianYear);
  // A star moves at most atan(max_pm dt) from its J2000 direction.
  const double widened = half_angle_rad + std::atan(max_pm_radpyr_ * dt_yr) + 1e-9;
  const double cos_pre = widened >= astro::kPi ? -2.0 : std::cos(widened);
  const double cos_cone = std::cos(half_angle_rad);
  for (std::size_t k = 0; k < stars_.size(); ++k) {
    if (u_j2000_[k].dot(d) < cos_pre) continue;
    if (stars_[k].unit_eci_at(t).dot(d) >= cos_cone) out.push_back(&stars_[k]);
  }
  return out;
}

}  // namespace artms::imaging
