#include "artms/imp/dbscan.hpp"

#include <algorithm>
#include <array>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>

namespace artms::imp {

void DbscanOptions::validate() const {
  if (!(eps > 0.0) || !std::isfinite(eps)) {
    throw std::invalid_argument("DbscanOptions.eps must be a positive finite number, got " +
                                std::to_string(eps));
  }
  if (min_points < 1) {
    throw std::invalid_argument("DbscanOptions.min_points must be >= 1, got " +
                                std::to_string(min_points));
  }
}

std::vector<int> DbscanResult::members(int cluster) const {
  std::vector<int> out;
  for (std::size_t i = 0; i < labels.size(); ++i) {
    if (labels[i] == cluster) out.push_back(static_cast<int>(i));
  }
  return out;
}

namespace {

constexpr std::size_t kMaxGridDims = 3;
using CellKey = std::array<std::int64_t, kMaxGridDims>;

struct CellKeyHash {
  std::size_t operator()(const CellKey& k) const noexcept {
    std::uint64_t h = 0x9E3779B97F4A7C15ULL;
    for (const std::int64_t v : k) {
      h ^= static_cast<std::uint64_t>(v) + 0x9E3779B97F4A7C15ULL + (h << 6) + (h >> 2);
    }
    return static_cast<std::size_t>(h);
  }
};

// Points stored row-major (n x dim) with a uniform grid over the first
// min(dim, 3) coordinates. Cells are a little larger than eps, so every point
// within eps of p lies in p's cell or one of its 3^g - 1 neighbours.
class GridIndex {
 public:
  GridIndex(std::vector<double> coords, std::size_t n, std::size_t dim, double eps)
      : x_(std::move(coords)), n_(n), dim_(dim), eps2_(eps * eps) {
    const std::size_t g = std::min(dim_, kMaxGridDims);
    std::array<double, kMaxGridDims> lo{}, hi{};
    double max_abs = 0.0;
    for (std::size_t k = 0; k < g; ++k) {
      lo[k] = hi[k] = (n_ > 0) ? at(0, k) : 0.0;
    }
    for (std::size_t i = 0; i < n_; ++i) {
      for (std::size_t k = 0; k < g; ++k) {
        lo[k] = std::min(lo[k], at(i, k));
        hi[k] = std::max(hi[k], at(i, k));
        max_abs = std::max(max_abs, std::abs(at(i, k)));
      }
    }
    double extent = 0.0;
    for (std::size_t k = 0; k < g; ++k) extent = std::max(extent, hi[k] - lo[k]);
    // Cell size: >= eps with margins for the rounding of (x - lo) and of the
    // quotient, and at least extent / 2^30 so the cell indices stay small.
    const double cell =
        std::max(eps, extent / 1073741824.0) * (1.0 + 1e-5) + 16.0 * DBL_EPSILON * max_abs;
    const bool single_cell = !std::isfinite(cell) || !std::isfinite(extent);

    cell_of_point_.resize(n_);
    std::unordered_map<CellKey, std::size_t, CellKeyHash> cell_ids;
    std::vector<CellKey> keys;
    std::vector<std::size_t> counts;
    for (std::size_t i = 0; i < n_; ++i) {
      CellKey key{};
      if (!single_cell) {
        for (std::size_t k = 0; k < g; ++k) {
          key[k] = static_cast<std::int64_t>(std::floor((at(i, k) - lo[k]) / cell));
        }
      }
      const auto [it, inserted] = cell_ids.try_emplace(key, keys.size());
      if (inserted) {
        keys.push_back(key);
        counts.push_back(0);
      }
      cell_of_point_[i] = it->second;
      ++counts[it->second];
    }
    // Points of each cell contiguous, ascending index within a cell.
    start_.assign(keys.size() + 1, 0);
    for (std::size_t c = 0; c < keys.size(); ++c) start_[c + 1] = start_[c] + counts[c];
    members_.resize(n_);
    std::vector<std::size_t> fill(start_.begin(), start_.end() - 1);
    for (std::size_t i = 0; i < n_; ++i) members_[fill[cell_of_point_[i]]++] = i;
    // Occupied neighbour cells of each cell (itself included).
    std::size_t offsets = 1;
    for (std::size_t k = 0; k < g; ++k) offsets *= 3;
    neighbour_cells_.resize(keys.size());
    for (std::size_t c = 0; c < keys.size(); ++c) {
      for (std::size_t o = 0; o < offsets; ++o) {
        CellKey key = keys[c];
        std::size_t rest = o;
        for (std::size_t k = 0; k < g; ++k) {
          key[k] += static_cast<std::int64_t>(rest % 3) - 1;
          rest /= 3;
        }
        const auto it = cell_ids.find(key);
        if (it != cell_ids.end()) neighbour_cells_[c].push_back(it->second);
      }
    }
  }

  [[nodiscard]] std::size_t size() const { return n_; }

  // Calls f(j) for every j with |x_i - x_j|^2 <= eps^2 (i itself included);
  // stops early when f returns false.
  template <class F>
  void for_each_neighbour(std::size_t i, F&& f) const {
    for (const std::size_t c : neighbour_cells_[cell_of_point_[i]]) {
      for (std::size_t m = start_[c]; m < start_[c + 1]; ++m) {
        const std::size_t j = members_[m];
        if (squared_distance(i, j) <= eps2_ && !f(j)) return;
      }
    }
  }

 private:
  [[nodiscard]] double at(std::size_t i, std::size_t k) const { return x_[i * dim_ + k]; }

  // Summed in coordinate order, as scikit-learn's KD-tree does.
  [[nodiscard]] double squared_distance(std::size_t i, std::size_t j) const {
    double d2 = 0.0;
    for (std::size_t k = 0; k < dim_; ++k) {
      const double d = at(i, k) - at(j, k);
      d2 += d * d;
    }
    return d2;
  }

  std::vector<double> x_;
  std::size_t n_;
  std::size_t dim_;
  double eps2_;
  std::vector<std::size_t> cell_of_point_;
  std::vector<std::size_t> start_;
  std::vector<std::size_t> members_;
  std::vector<std::vector<std::size_t>> neighbour_cells_;
};

void check_finite(const std::vector<double>& coords, std::size_t dim) {
  for (std::size_t m = 0; m < coords.size(); ++m) {
    if (!std::isfinite(coords[m])) {
      throw std::invalid_argument("dbscan: point " + std::to_string(m / dim) +
                                  " has a non-finite coordinate");
    }
  }
}

DbscanResult run(std::vector<double> coords, std::size_t n, std::size_t dim,
                 const DbscanOptions& options) {
  options.validate();
  if (n > 0 && dim == 0) throw std::invalid_argument("dbscan: points need at least one coordinate");
  check_finite(coords, dim);
  const GridIndex grid(std::move(coords), n, dim, options.eps);
  const auto min_points = static_cast<std::size_t>(options.min_points);

  DbscanResult result;
  result.labels.assign(n, -1);
  result.core.assign(n, false);
  // Pass 1: core points (neighbourhood count, stopped once it reaches min_points).
  for (std::size_t i = 0; i < n; ++i) {
    std::size_t count = 0;
    grid.for_each_neighbour(i, [&](std::size_t) { return ++count < min_points; });
    result.core[i] = count >= min_points;
  }
  // Pass 2: scikit-learn's dbscan_inner: seeds in index order, each cluster
  // grown completely (depth first) before the next seed.
  std::vector<std::size_t> stack;
  int label = 0;
  for (std::size_t seed = 0; seed < n; ++seed) {
    if (result.labels[seed] != -1 || !result.core[seed]) continue;
    int size = 0;
    stack.assign(1, seed);
    while (!stack.empty()) {
      const std::size_t i = stack.back();
      stack.pop_back();
      if (result.labels[i] != -1) continue;
      result.labels[i] = label;
      ++size;
      if (!result.core[i]) continue;  // border point: not expanded
      grid.for_each_neighbour(i, [&](std::size_t j) {
        if (result.labels[j] == -1) stack.push_back(j);
        return true;
      });
    }
    result.cluster_sizes.push_back(size);
    ++label;
  }
  result.clusters = label;
  result.noise = static_cast<int>(std::count(result.labels.begin(), result.labels.end(), -1));
  return result;
}

template <int D>
DbscanResult run_fixed(std::span<const Eigen::Matrix<double, D, 1>> points,
                       const DbscanOptions& options) {
  std::vector<double> coords;
  coords.reserve(points.size() * D);
  for (const auto& p : points) {
    for (int k = 0; k < D; ++k) coords.push_back(p[k]);
  }
  return run(std::move(coords), points.size(), D, options);
}

}  // namespace

DbscanResult dbscan(std::span<const Eigen::Vector2d> points, const DbscanOptions& options) {
  return run_fixed<2>(points, options);
}

DbscanResult dbscan(std::span<const Eigen::Vector3d> points, const DbscanOptions& options) {
  return run_fixed<3>(points, options);
}

DbscanResult dbscan(const Eigen::MatrixXd& points_rows, const DbscanOptions& options) {
  const auto n = static_cast<std::size_t>(points_rows.rows());
  const auto dim = static_cast<std::size_t>(points_rows.cols());
  std::vector<double> coords(n * dim);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t k = 0; k < dim; ++k) {
      coords[i * dim + k] = points_rows(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(k));
    }
  }
  return run(std::move(coords), n, dim, options);
}

}  // namespace artms::imp
