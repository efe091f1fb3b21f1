// A coarse observer orbit from a CSV (columns t_tt_ns, x_m, y_m, z_m, vx_mps,
// vy_mps, vz_mps, in any order among others: artms-render's
// observer_orbit.csv, artms-propagate's output, a run's nav/<id>.csv), with
// cubic Hermite interpolation between samples (position and velocity).
#pragma once

#include <cmath>
#include <cstdint>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "artms/astro/frames.hpp"
#include "artms/io/csv.hpp"

namespace artms {

class OrbitTable {
 public:
  // Rows with an empty or non-finite state (e.g. nav health 2, no
  // solution) are skipped; a malformed file is an error naming its line.
  static OrbitTable load(const std::string& path) {
    const auto tab = io::CsvTable::read(path);
    const char* names[] = {"x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps"};
    for (const char* n : {"t_tt_ns", "x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps"}) (void)tab.column(n);
    OrbitTable t;
    for (std::size_t r = 0; r < tab.size(); ++r) {
      bool empty = false;
      for (const char* n : names) empty = empty || tab.text(r, n).empty();
      if (empty) continue;
      astro::StateVector x;
      for (int k = 0; k < 3; ++k) {
        x.r_m[k] = tab.number(r, names[k]);
        x.v_mps[k] = tab.number(r, names[3 + k]);
      }
      if (x.r_m.allFinite() && x.v_mps.allFinite() && x.r_m.norm() > 6.3e6) t.samples_[tab.integer(r, "t_tt_ns")] = x;
    }
    if (t.samples_.size() < 2) throw std::runtime_error(path + ": fewer than two usable orbit rows");
    return t;
  }

  // Interpolated state; within 60 s beyond either end, a two-body Taylor
  // step from the end sample (time tags offset from the frame epochs);
  // nullopt further out or across a gap > 600 s.
  [[nodiscard]] std::optional<astro::StateVector> at(std::int64_t t_ns) const {
    auto hi = samples_.lower_bound(t_ns);
    if (hi != samples_.end() && hi->first == t_ns) return hi->second;
    if (hi == samples_.end() || hi == samples_.begin()) {
      const auto& [t_end, x_end] = hi == samples_.end() ? *samples_.rbegin() : *samples_.begin();
      const double dt = static_cast<double>(t_ns - t_end) * 1e-9;
      if (std::abs(dt) > 60.0) return std::nullopt;
      const double r = x_end.r_m.norm();
      const Eigen::Vector3d acc = -3.986004418e14 / (r * r * r) * x_end.r_m;
      return astro::StateVector{x_end.r_m + x_end.v_mps * dt + 0.5 * acc * dt * dt, x_end.v_mps + acc * dt};
    }
    auto lo = std::prev(hi);
    const double h = static_cast<double>(hi->first - lo->first) * 1e-9;
    if (h > 600.0) return std::nullopt;
    const double s = static_cast<double>(t_ns - lo->first) * 1e-9 / h;
    const auto& a = lo->second;
    const auto& b = hi->second;
    // Cubic Hermite basis and its derivative.
    const double h00 = 2 * s * s * s - 3 * s * s + 1, h10 = s * s * s - 2 * s * s + s;
    const double h01 = -2 * s * s * s + 3 * s * s, h11 = s * s * s - s * s;
    const double d00 = (6 * s * s - 6 * s) / h, d10 = 3 * s * s - 4 * s + 1;
    const double d01 = (-6 * s * s + 6 * s) / h, d11 = 3 * s * s - 2 * s;
    astro::StateVector x;
    x.r_m = h00 * a.r_m + h10 * h * a.v_mps + h01 * b.r_m + h11 * h * b.v_mps;
    x.v_mps = d00 * a.r_m + d10 * a.v_mps + d01 * b.r_m + d11 * b.v_mps;
    return x;
  }

 private:
  std::map<std::int64_t, astro::StateVector> samples_;
};

}  // namespace artms
