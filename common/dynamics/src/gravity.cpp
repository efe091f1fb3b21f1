#include "artms/dynamics/gravity.hpp"

#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace artms::dynamics {
namespace {

// Reads a floating-point token that may use a Fortran 'D' exponent.
double parse_number(std::string token, const std::string& where) {
  for (char& ch : token) {
    if (ch == 'D' || ch == 'd') ch = 'e';
  }
  std::size_t used = 0;
  double value = 0.0;
  try {
    value = std::stod(token, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != token.size()) throw std::runtime_error(where + ": '" + token + "' is not a number");
  return value;
}

}  // namespace

GravityField::GravityField(double gm, double radius, int max_degree)
    : gm_m3ps2_(gm), radius_m_(radius), max_degree_(max_degree) {
  if (max_degree < 0) throw std::invalid_argument("GravityField: max_degree must be >= 0");
  const auto n = static_cast<std::size_t>((max_degree + 1) * (max_degree + 2) / 2);
  c_.assign(n, 0.0);
  s_.assign(n, 0.0);
  c_[0] = 1.0;
}

std::size_t GravityField::index(int n, int m) const {
  if (n < 0 || m < 0 || m > n || n > max_degree_) {
    throw std::out_of_range("GravityField: (n, m) = (" + std::to_string(n) + ", " +
                            std::to_string(m) + ") outside degree " + std::to_string(max_degree_));
  }
  return static_cast<std::size_t>(n * (n + 1) / 2 + m);
}

void GravityField::set(int n, int m, double c_nm, double s_nm) {
  c_[index(n, m)] = c_nm;
  s_[index(n, m)] = s_nm;
}

GravityField GravityField::from_gfc(const std::string& path, int max_degree) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open gravity field file " + path);
  std::string line, name;
  double gm = 0.0, radius = 0.0;
  int file_degree = -1;
  int line_no = 0;
  bool in_data = false;
  GravityField field(1.0, 1.0, 0);
  int use_degree = -1;
  while (std::getline(in, line)) {
    ++line_no;
    const std::string where = path + ":" + std::to_string(line_no);
    std::istringstream ls(line);
    std::string key;
    if (!(ls >> key)) continue;
    if (!in_data) {
      std::string value;
      if (key == "end_of_head") {
        if (gm <= 0.0 || radius <= 0.0 || file_degree < 0) {
          throw std::runtime_error(where + ": header lacks earth_gravity_constant, radius or max_degree");
        }
        use_degree = max_degree < 0 ? file_degree : max_degree;
        if (use_degree > file_degree) {
          throw std::runtime_error(path + ": degree " + std::to_string(use_degree) +
                                   " requested but the file has only " +
                                   std::to_string(file_degree));
        }
        field = GravityField(gm, radius, use_degree);
        field.name_ = name;
        in_data = true;
      } else if (key == "modelname" && (ls >> value)) {
        name = value;
      } else if (key == "earth_gravity_constant" && (ls >> value)) {
        gm = parse_number(value, where);
      } else if (key == "radius" && (ls >> value)) {
        radius = parse_number(value, where);
      } else if (key == "max_degree" && (ls >> value)) {
        file_degree = static_cast<int>(parse_number(value, where));
      }
      continue;
    }
    if (key != "gfc") continue;
    std::string sn, sm, sc, ss;
    if (!(ls >> sn >> sm >> sc >> ss)) {
      throw std::runtime_error(where + ": expected 'gfc n m C S [sigmaC sigmaS]'");
    }
    const double dn = parse_number(sn, where), dm = parse_number(sm, where);
    const int n = static_cast<int>(dn), m = static_cast<int>(dm);
    if (n != dn || m != dm || n < 0 || m < 0 || m > n) {
      throw std::runtime_error(where + ": invalid degree/order " + sn + " " + sm);
    }
    if (n > use_degree) continue;
    field.set(n, m, parse_number(sc, where), parse_number(ss, where));
  }
  if (!in_data) throw std::runtime_error(path + ": no end_of_head line (not an ICGEM .gfc file?)");
  return field;
}

SphericalHarmonicGravity::SphericalHarmonicGravity(const GravityField& field, int degree,
                                                   int order)
    : gm_(field.gm_m3ps2()), radius_(field.radius_m()), degree_(degree), order_(order) {
  if (degree < 0 || order < 0 || order > degree || degree > field.max_degree()) {
    throw std::invalid_argument("SphericalHarmonicGravity: degree " + std::to_string(degree) +
                                ", order " + std::to_string(order) + " not available in field " +
                                field.name() + " (max degree " +
                                std::to_string(field.max_degree()) + ")");
  }
  const int N = degree + 1;  // V, W are needed to degree + 1
  stride_ = static_cast<std::size_t>(N + 2);
  const std::size_t size = stride_ * stride_;
  c_.assign(size, 0.0);
  s_.assign(size, 0.0);
  diag_.assign(size, 0.0);
  a_.assign(size, 0.0);
  b_.assign(size, 0.0);
  f_pp_.assign(size, 0.0);
  f_pm_.assign(size, 0.0);
  f_z_.assign(size, 0.0);
  const auto at = [&](int n, int m) { return static_cast<std::size_t>(n) * stride_ + static_cast<std::size_t>(m); };
  for (int n = 0; n <= degree; ++n) {
    for (int m = 0; m <= std::min(n, order); ++m) {
      c_[at(n, m)] = field.c(n, m);
      s_[at(n, m)] = field.s(n, m);
    }
  }
  for (int n = 0; n <= N; ++n) {
    const double dn = n;
    for (int m = 0; m <= n; ++m) {
      const double dm = m;
      if (m == n && n >= 1) {
        // Normalised sectorial step: sqrt((2m+1) / ((2 - delta_{m-1,0}) m)).
        diag_[at(n, m)] = std::sqrt((2.0 * dm + 1.0) / ((m == 1 ? 1.0 : 2.0) * dm));
      } else if (m < n) {
        a_[at(n, m)] = std::sqrt((2.0 * dn - 1.0) * (2.0 * dn + 1.0) / ((dn - dm) * (dn + dm)));
        if (n >= m + 2) {
          b_[at(n, m)] = std::sqrt((2.0 * dn + 1.0) * (dn + dm - 1.0) * (dn - dm - 1.0) /
                                   ((2.0 * dn - 3.0) * (dn + dm) * (dn - dm)));
        }
      }
    }
  }
  // Factors turning M&G's unnormalised acceleration sums into normalised
  // ones: ratios N_nm / N_{n+1,k} of the normalisation constants.
  for (int n = 0; n <= degree; ++n) {
    const double dn = n;
    for (int m = 0; m <= n; ++m) {
      const double dm = m;
      const double dm0 = m == 0 ? 1.0 : 2.0;  // 2 - delta_{m0}
      f_pp_[at(n, m)] = std::sqrt(dm0 * (2.0 * dn + 1.0) * (dn + dm + 2.0) * (dn + dm + 1.0) /
                                  (2.0 * (2.0 * dn + 3.0)));
      if (m >= 1) {
        const double dm1 = m == 1 ? 1.0 : 2.0;  // 2 - delta_{m1}
        f_pm_[at(n, m)] = std::sqrt(2.0 * (2.0 * dn + 1.0) * (dn - dm + 2.0) * (dn - dm + 1.0) /
                                    (dm1 * (2.0 * dn + 3.0)));
      }
      f_z_[at(n, m)] =
          std::sqrt((2.0 * dn + 1.0) * (dn + dm + 1.0) * (dn - dm + 1.0) / (2.0 * dn + 3.0));
    }
  }
}

Vec3 SphericalHarmonicGravity::evaluate(const Vec3& r, bool include_central) const {
  const int N = degree_ + 1;
  const double r2 = r.squaredNorm();
  const double rho = radius_ * radius_ / r2;
  const double x0 = radius_ * r.x() / r2, y0 = radius_ * r.y() / r2, z0 = radius_ * r.z() / r2;
  // Stack buffers: degree <= 120 keeps this small enough (V, W to degree 121).
  thread_local std::vector<double> V, W;
  V.assign(stride_ * stride_, 0.0);
  W.assign(stride_ * stride_, 0.0);
  const auto at = [&](int n, int m) { return static_cast<std::size_t>(n) * stride_ + static_cast<std::size_t>(m); };
  V[at(0, 0)] = radius_ / std::sqrt(r2);
  W[at(0, 0)] = 0.0;
  const int m_max = std::min(N, order_ + 1);
  for (int m = 0; m <= m_max; ++m) {
    if (m > 0) {
      // Sectorial terms (M&G eq. 3.30, normalised).
      const double vp = V[at(m - 1, m - 1)], wp = W[at(m - 1, m - 1)];
      V[at(m, m)] = diag_[at(m, m)] * (x0 * vp - y0 * wp);
      W[at(m, m)] = diag_[at(m, m)] * (x0 * wp + y0 * vp);
    }
    // Zonal/tesseral terms (M&G eq. 3.31, normalised).
    for (int n = m + 1; n <= N; ++n) {
      double v = a_[at(n, m)] * z0 * V[at(n - 1, m)];
      double w = a_[at(n, m)] * z0 * W[at(n - 1, m)];
      if (n >= m + 2) {
        v -= b_[at(n, m)] * rho * V[at(n - 2, m)];
        w -= b_[at(n, m)] * rho * W[at(n - 2, m)];
      }
      V[at(n, m)] = v;
      W[at(n, m)] = w;
    }
  }
  // Accelerations (M&G eq. 3.33) with the normalisation ratios.
  double ax = 0.0, ay = 0.0, az = 0.0;
  for (int n = include_central ? 0 : 1; n <= degree_; ++n) {
    for (int m = 0; m <= std::min(n, order_); ++m) {
      const double C = c_[at(n, m)], S = s_[at(n, m)];
      if (C == 0.0 && S == 0.0) continue;
      if (m == 0) {
        ax -= f_pp_[at(n, 0)] * C * V[at(n + 1, 1)];
        ay -= f_pp_[at(n, 0)] * C * W[at(n + 1, 1)];
      } else {
        const double pp = f_pp_[at(n, m)], pm = f_pm_[at(n, m)];
        ax += 0.5 * (pp * (-C * V[at(n + 1, m + 1)] - S * W[at(n + 1, m + 1)]) +
                     pm * (C * V[at(n + 1, m - 1)] + S * W[at(n + 1, m - 1)]));
        ay += 0.5 * (pp * (-C * W[at(n + 1, m + 1)] + S * V[at(n + 1, m + 1)]) +
                     pm * (-C * W[at(n + 1, m - 1)] + S * V[at(n + 1, m - 1)]));
      }
      az += f_z_[at(n, m)] * (-C * V[at(n + 1, m)] - S * W[at(n + 1, m)]);
    }
  }
  const double k = gm_ / (radius_ * radius_);
  return {k * ax, k * ay, k * az};
}

Vec3 SphericalHarmonicGravity::acceleration_ecef(const Vec3& r) const { return evaluate(r, true); }

Vec3 SphericalHarmonicGravity::perturbation_ecef(const Vec3& r) const {
  return evaluate(r, false);
}

Vec3 SphericalHarmonicGravity::acceleration_eci(const Vec3& r_eci, const Mat3& R) const {
  return R.transpose() * acceleration_ecef(R * r_eci);
}

}  // namespace artms::dynamics
