// DBSCAN: scikit-learn reference labels, edge cases, options, and agreement
// with a brute-force O(n^2) implementation on random sets.
#include "artms/imp/dbscan.hpp"

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "artms/testing/testing.hpp"

namespace artms::imp {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

// Independent reference: all-pairs neighbourhoods, breadth-first growth.
// Seeds in index order and one cluster grown completely before the next, as
// in scikit-learn (the growth order inside a cluster does not matter).
DbscanResult brute_force(const Eigen::MatrixXd& X, double eps, int min_points) {
  const auto n = static_cast<int>(X.rows());
  std::vector<std::vector<int>> nb(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      if ((X.row(i) - X.row(j)).squaredNorm() <= eps * eps)
        nb[static_cast<std::size_t>(i)].push_back(j);
    }
  }
  DbscanResult r;
  r.labels.assign(static_cast<std::size_t>(n), -1);
  r.core.assign(static_cast<std::size_t>(n), false);
  for (int i = 0; i < n; ++i) {
    r.core[static_cast<std::size_t>(i)] =
        static_cast<int>(nb[static_cast<std::size_t>(i)].size()) >= min_points;
  }
  for (int s = 0; s < n; ++s) {
    const auto us = static_cast<std::size_t>(s);
    if (r.labels[us] != -1 || !r.core[us]) continue;
    std::deque<int> queue{s};
    r.labels[us] = r.clusters;
    while (!queue.empty()) {
      const auto i = static_cast<std::size_t>(queue.front());
      queue.pop_front();
      if (!r.core[i]) continue;
      for (const int j : nb[i]) {
        if (r.labels[static_cast<std::size_t>(j)] == -1) {
          r.labels[static_cast<std::size_t>(j)] = r.clusters;
          queue.push_back(j);
        }
      }
    }
    ++r.clusters;
  }
  r.noise = static_cast<int>(std::count(r.labels.begin(), r.labels.end(), -1));
  return r;
}

Eigen::MatrixXd matrix_from_json(const nlohmann::json& X) {
  Eigen::MatrixXd M(static_cast<Eigen::Index>(X.size()), static_cast<Eigen::Index>(X[0].size()));
  for (Eigen::Index i = 0; i < M.rows(); ++i) {
    for (Eigen::Index k = 0; k < M.cols(); ++k) {
      M(i, k) = X[static_cast<std::size_t>(i)][static_cast<std::size_t>(k)].get<double>();
    }
  }
  return M;
}

TEST(Dbscan, MatchesScikitLearnReference) {
  // tests/data/dbscan_sklearn_reference.json: scikit-learn 1.2.1 labels. Its
  // meta note allows border points to differ between implementations, but
  // this one processes points in scikit-learn's order (seeds by index, each
  // cluster grown completely first), so the labels are asserted identical,
  // cluster numbering included; the noise set and core flags exactly too.
  const auto j =
      artms::testing::load_json(artms::testing::test_data_path("dbscan_sklearn_reference.json"));
  ASSERT_EQ(j["cases"].size(), 2u);
  for (const auto& c : j["cases"]) {
    SCOPED_TRACE(c["name"].get<std::string>());
    const Eigen::MatrixXd X = matrix_from_json(c["X"]);
    const DbscanOptions opt{c["eps"].get<double>(), c["min_samples"].get<int>()};
    const auto expected_labels = c["labels"].get<std::vector<int>>();
    const auto expected_core = c["is_core"].get<std::vector<bool>>();
    const DbscanResult r = dbscan(X, opt);
    EXPECT_EQ(r.labels, expected_labels);
    EXPECT_EQ(r.core, expected_core);
    EXPECT_EQ(r.clusters, c["n_clusters"].get<int>());
    EXPECT_EQ(r.noise, c["n_noise"].get<int>());
    int sum = 0;
    for (const int s : r.cluster_sizes) sum += s;
    EXPECT_EQ(sum + r.noise, static_cast<int>(X.rows()));

    // Same answer through the fixed-dimension overloads.
    DbscanResult rf;
    if (X.cols() == 2) {
      std::vector<Vector2d> p;
      for (Eigen::Index i = 0; i < X.rows(); ++i) p.emplace_back(X(i, 0), X(i, 1));
      rf = dbscan(p, opt);
    } else {
      ASSERT_EQ(X.cols(), 3);
      std::vector<Vector3d> p;
      for (Eigen::Index i = 0; i < X.rows(); ++i) p.emplace_back(X(i, 0), X(i, 1), X(i, 2));
      rf = dbscan(p, opt);
    }
    EXPECT_EQ(rf.labels, expected_labels);
    EXPECT_EQ(rf.core, expected_core);
  }
}

TEST(Dbscan, EmptyInput) {
  const DbscanResult r = dbscan(std::span<const Vector2d>{}, {1.0, 3});
  EXPECT_TRUE(r.labels.empty());
  EXPECT_TRUE(r.core.empty());
  EXPECT_EQ(r.clusters, 0);
  EXPECT_EQ(r.noise, 0);
  EXPECT_TRUE(r.cluster_sizes.empty());
  EXPECT_EQ(dbscan(Eigen::MatrixXd(0, 3), {1.0, 3}).clusters, 0);
}

TEST(Dbscan, AllNoise) {
  std::vector<Vector2d> p;
  for (int i = 0; i < 50; ++i) p.emplace_back(10.0 * i, -7.0 * i);
  const DbscanResult r = dbscan(p, {5.0, 2});
  EXPECT_EQ(r.clusters, 0);
  EXPECT_EQ(r.noise, 50);
  EXPECT_EQ(r.labels, std::vector<int>(50, -1));
  EXPECT_EQ(std::count(r.core.begin(), r.core.end(), true), 0);
  EXPECT_EQ(r.members(-1).size(), 50u);
}

TEST(Dbscan, MinPointsOneMakesEveryPointCore) {
  std::vector<Vector2d> p{{0, 0}, {100, 0}, {0.5, 0}, {200, 0}};
  const DbscanResult r = dbscan(p, {1.0, 1});
  EXPECT_EQ(r.labels, (std::vector<int>{0, 1, 0, 2}));
  EXPECT_EQ(r.core, std::vector<bool>(4, true));
  EXPECT_EQ(r.noise, 0);
  EXPECT_EQ(r.cluster_sizes, (std::vector<int>{2, 1, 1}));
}

TEST(Dbscan, OneBigCluster) {
  // 40 x 40 lattice, spacing 1, eps 1.01: every point has >= 3 neighbours.
  std::vector<Vector2d> p;
  for (int i = 0; i < 40; ++i) {
    for (int k = 0; k < 40; ++k) p.emplace_back(i, k);
  }
  const DbscanResult r = dbscan(p, {1.01, 3});
  EXPECT_EQ(r.clusters, 1);
  EXPECT_EQ(r.noise, 0);
  EXPECT_EQ(r.cluster_sizes, std::vector<int>{1600});
  EXPECT_EQ(std::count(r.core.begin(), r.core.end(), true), 1600);
  // With min_points 5 only the interior points are core; the edge points (4
  // in their neighbourhood) are border points of the one cluster, and the
  // corners (3) are noise: their two neighbours are edge points, not core.
  const DbscanResult r5 = dbscan(p, {1.01, 5});
  EXPECT_EQ(r5.clusters, 1);
  EXPECT_EQ(r5.noise, 4);
  EXPECT_EQ(r5.labels[0], -1);
  EXPECT_EQ(std::count(r5.core.begin(), r5.core.end(), true), 38 * 38);
}

TEST(Dbscan, DuplicatePoints) {
  // k copies of one position count k times: core with min_points <= k.
  std::vector<Vector3d> p(6, Vector3d(1.0, 2.0, 3.0));
  p.emplace_back(50.0, 0.0, 0.0);
  const DbscanResult r6 = dbscan(p, {0.1, 6});
  EXPECT_EQ(r6.labels, (std::vector<int>{0, 0, 0, 0, 0, 0, -1}));
  EXPECT_EQ(r6.cluster_sizes, std::vector<int>{6});
  const DbscanResult r7 = dbscan(p, {0.1, 7});
  EXPECT_EQ(r7.clusters, 0);
  EXPECT_EQ(r7.noise, 7);
}

TEST(Dbscan, NeighbourhoodIncludesDistanceEqualToEps) {
  // Exactly representable distances: 3-4-5 triangle, eps = 5.
  std::vector<Vector2d> p{{0, 0}, {3, 4}};
  EXPECT_EQ(dbscan(p, {5.0, 2}).clusters, 1);
  EXPECT_EQ(dbscan(p, {std::nextafter(5.0, 0.0), 2}).clusters, 0);
}

TEST(Dbscan, BorderPointGoesToFirstClusterThatReachesIt) {
  // Two dense groups with one point (index 0) within eps of a core point of
  // each, itself not core: it belongs to the cluster found first, which is
  // the group whose first core point comes first in the input (here the
  // right-hand group, indices 1..4), not the group listed first in space.
  std::vector<Vector2d> p{{0.0, 0.0},  {1.0, 0.0},  {1.5, 0.0},  {1.5, 0.3},  {1.5, -0.3},
                          {-1.0, 0.0}, {-1.5, 0.0}, {-1.5, 0.3}, {-1.5, -0.3}};
  const DbscanResult r = dbscan(p, {1.0, 4});
  EXPECT_FALSE(r.core[0]);
  EXPECT_TRUE(r.core[1]);
  EXPECT_TRUE(r.core[5]);
  EXPECT_EQ(r.labels, (std::vector<int>{0, 0, 0, 0, 0, 1, 1, 1, 1}));
  // Swap the groups in the input: the border point follows the first one.
  std::vector<Vector2d> q{p[0], p[5], p[6], p[7], p[8], p[1], p[2], p[3], p[4]};
  const DbscanResult s = dbscan(q, {1.0, 4});
  EXPECT_EQ(s.labels, (std::vector<int>{0, 0, 0, 0, 0, 1, 1, 1, 1}));
  EXPECT_EQ(s.members(1), (std::vector<int>{5, 6, 7, 8}));
}

TEST(Dbscan, BadOptionsThrowNamingTheField) {
  std::vector<Vector2d> p{{0, 0}};
  const auto expect_throw = [&](DbscanOptions o, const std::string& field) {
    try {
      (void)dbscan(p, o);
      ADD_FAILURE() << "no exception for " << field;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  expect_throw({0.0, 3}, "eps");
  expect_throw({-1.0, 3}, "eps");
  expect_throw({std::numeric_limits<double>::quiet_NaN(), 3}, "eps");
  expect_throw({std::numeric_limits<double>::infinity(), 3}, "eps");
  expect_throw({1.0, 0}, "min_points");
  expect_throw({1.0, -2}, "min_points");
  EXPECT_THROW(DbscanOptions({1.0, 0}).validate(), std::invalid_argument);
  EXPECT_NO_THROW(DbscanOptions{}.validate());
}

TEST(Dbscan, NonFinitePointThrowsNamingThePoint) {
  std::vector<Vector2d> p{{0, 0}, {1, std::numeric_limits<double>::quiet_NaN()}};
  try {
    (void)dbscan(p, {1.0, 2});
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("point 1"), std::string::npos) << e.what();
  }
}

TEST(Dbscan, MatchesBruteForceOnRandomSets) {
  std::mt19937_64 rng(20240607);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, 1.0);
  int compared = 0;
  for (int trial = 0; trial < 60; ++trial) {
    const int dim = 1 + trial % 5;  // 1..5: the grid covers at most 3 of them
    const double scale = std::pow(10.0, -3.0 + trial % 7);  // 1e-3 .. 1e3
    Eigen::MatrixXd X(200 + 10 * trial, dim);
    const int blobs = 1 + trial % 6;
    Eigen::MatrixXd centres =
        Eigen::MatrixXd::NullaryExpr(blobs, dim, [&] { return 100.0 * uni(rng); });
    for (Eigen::Index i = 0; i < X.rows(); ++i) {
      if (i % 4 == 0) {
        for (int k = 0; k < dim; ++k) X(i, k) = 100.0 * uni(rng);  // noise
      } else {
        const auto b = static_cast<Eigen::Index>(i % blobs);
        for (int k = 0; k < dim; ++k) X(i, k) = centres(b, k) + 1.5 * gauss(rng);
      }
    }
    X = (X.array() * scale + 7.0 * scale).matrix();
    const DbscanOptions opt{(0.5 + 2.5 * uni(rng)) * scale, 1 + trial % 9};
    const DbscanResult r = dbscan(X, opt);
    const DbscanResult ref = brute_force(X, opt.eps, opt.min_points);
    EXPECT_EQ(r.labels, ref.labels) << "trial " << trial;
    EXPECT_EQ(r.core, ref.core) << "trial " << trial;
    EXPECT_EQ(r.clusters, ref.clusters);
    EXPECT_EQ(r.noise, ref.noise);
    compared += static_cast<int>(X.rows());
  }
  std::printf("[dbscan] %d points in 60 random sets identical to brute force\n", compared);
}

TEST(Dbscan, LargeCoordinatesSmallEps) {
  // Coordinates ~1e6 with eps 1e-3: the grid's rounding margins keep pairs
  // at distance just below eps in neighbouring cells.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  Eigen::MatrixXd X(400, 2);
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    X(i, 0) = 1e6 + 0.02 * uni(rng);
    X(i, 1) = -3e6 + 0.02 * uni(rng);
  }
  const DbscanOptions opt{1e-3, 3};
  const DbscanResult r = dbscan(X, opt);
  const DbscanResult ref = brute_force(X, opt.eps, opt.min_points);
  EXPECT_EQ(r.labels, ref.labels);
  EXPECT_EQ(r.core, ref.core);
}

TEST(Dbscan, SparseLargeSetIsFast) {
  // 200k points spread over a big area: the grid keeps this linear (the
  // brute force would need 4e10 distance evaluations).
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> uni(0.0, 1e5);
  std::vector<Vector2d> p(200000);
  for (auto& x : p) x = Vector2d(uni(rng), uni(rng));
  const DbscanResult r = dbscan(p, {5.0, 3});
  EXPECT_EQ(r.labels.size(), p.size());
  EXPECT_GT(r.noise, 150000);
}

}  // namespace
}  // namespace artms::imp
