// DBSCAN (Ester, Kriegel, Sander, Xu 1996), the variant ARTMS uses to
// initiate tracks (paper, "Image Processing": a cluster needs >= n_D points
// within radius eps_D). IMP clusters pixel positions (2-D) and time-stamped
// positions (3-D: x, y and time scaled into the same unit by the caller).
//
// Semantics are those of scikit-learn's sklearn.cluster.DBSCAN with the
// euclidean metric, so the labels are identical to scikit-learn's:
//   - the eps-neighbourhood of a point is every point at distance <= eps
//     (tested as the squared distance <= eps^2), the point itself included;
//   - a point is core when its neighbourhood holds >= min_points points
//     (min_points counts the point itself, like min_samples);
//   - clusters are numbered 0..k-1 in the order of their first core point
//     when scanning the input 0..n-1; each cluster is grown completely before
//     the next one starts, so a border point (non-core, within eps of a core
//     point) belongs to the first cluster that reaches it;
//   - every other point is noise (label -1).
// Neighbours are found with a uniform grid of cell size ~eps over (up to) the
// first three coordinates: O(n) time and memory for sparse sets.
#pragma once

#include <Eigen/Core>
#include <span>
#include <vector>

namespace artms::imp {

struct DbscanOptions {
  // Neighbourhood radius eps_D, in the unit of the points (> 0, finite).
  double eps = 0.5;
  // n_D: points within eps, the point itself included, for a core point (>= 1).
  // The defaults are scikit-learn's; IMP sets both from its configuration.
  int min_points = 5;
  // Throws std::invalid_argument naming the offending field.
  void validate() const;
};

struct DbscanResult {
  std::vector<int> labels;         // per input point: -1 noise, else cluster 0..clusters-1
  std::vector<bool> core;          // per input point: core point
  int clusters = 0;                // number of clusters found
  int noise = 0;                   // number of points labelled -1
  std::vector<int> cluster_sizes;  // points (core + border) per cluster

  // Indices of the points of one cluster, ascending (label == -1: the noise).
  [[nodiscard]] std::vector<int> members(int cluster) const;
};

// Points as 2-D or 3-D vectors. Throws std::invalid_argument for invalid
// options or a non-finite coordinate (naming the point).
DbscanResult dbscan(std::span<const Eigen::Vector2d> points, const DbscanOptions& options);
DbscanResult dbscan(std::span<const Eigen::Vector3d> points, const DbscanOptions& options);
// Any dimension >= 1: one point per row (scikit-learn's X). The grid uses the
// first min(cols, 3) coordinates; distances use all of them.
DbscanResult dbscan(const Eigen::MatrixXd& points_rows, const DbscanOptions& options);

}  // namespace artms::imp
