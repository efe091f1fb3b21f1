// IMP oracles (gen_imp_oracle.py):
//  - DBSCAN labels identical to python3-sklearn's DBSCAN on the same sets;
//  - q-method attitude versus scipy's Rotation.align_vectors within 1e-9 rad.
#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "artms/imp/dbscan.hpp"
#include "artms/imp/qmethod.hpp"
#include "artms/testing/testing.hpp"

namespace artms::imp {
namespace {

constexpr double kAttitudeTol_rad = 1e-9;

std::string oracle_path(const std::string& name) {
  const char* dir = std::getenv("ARTMS_ORACLE_DIR");
  return std::string(dir ? dir : ".") + "/" + name;
}

Vec3 vec3(const nlohmann::json& a) {
  return {a[0].get<double>(), a[1].get<double>(), a[2].get<double>()};
}

TEST(OracleImp, DbscanLabelsIdenticalToSklearn) {
  const std::string path = oracle_path("imp_dbscan_sklearn.json");
  if (!std::filesystem::exists(path)) {
    GTEST_SKIP() << "oracle cases missing: the sklearn generator did not run (see "
                    "oracle.imp.generate)";
  }
  const auto j = artms::testing::load_json(path);
  ASSERT_GE(j["cases"].size(), 30u);
  int points = 0, identical = 0, n_core = 0, n_border = 0, n_noise = 0, border_differ = 0;
  for (const auto& c : j["cases"]) {
    SCOPED_TRACE(c["name"].get<std::string>());
    const auto& Xj = c["X"];
    const auto n = static_cast<Eigen::Index>(Xj.size());
    const auto dim = static_cast<Eigen::Index>(Xj[0].size());
    Eigen::MatrixXd X(n, dim);
    for (Eigen::Index i = 0; i < n; ++i) {
      for (Eigen::Index k = 0; k < dim; ++k) {
        X(i, k) = Xj[static_cast<std::size_t>(i)][static_cast<std::size_t>(k)].get<double>();
      }
    }
    const DbscanOptions opt{c["eps"].get<double>(), c["min_samples"].get<int>()};
    DbscanResult r;
    if (dim == 2) {  // the fixed-size overloads, as IMP calls them
      std::vector<Eigen::Vector2d> p;
      for (Eigen::Index i = 0; i < n; ++i) p.emplace_back(X.row(i).transpose());
      r = dbscan(p, opt);
    } else {
      ASSERT_EQ(dim, 3);
      std::vector<Eigen::Vector3d> p;
      for (Eigen::Index i = 0; i < n; ++i) p.emplace_back(X.row(i).transpose());
      r = dbscan(p, opt);
    }
    EXPECT_EQ(r.labels, dbscan(X, opt).labels);  // the generic overload agrees
    const auto expected = c["labels"].get<std::vector<int>>();
    std::vector<bool> expected_core(static_cast<std::size_t>(n), false);
    for (const int i : c["core_sample_indices"].get<std::vector<int>>()) {
      expected_core[static_cast<std::size_t>(i)] = true;
    }
    ASSERT_EQ(r.labels.size(), expected.size());
    EXPECT_EQ(r.core, expected_core);
    EXPECT_EQ(r.clusters, c["n_clusters"].get<int>());
    for (std::size_t i = 0; i < expected.size(); ++i) {
      ++points;
      if (r.labels[i] == expected[i]) ++identical;
      if (expected[i] == -1) {
        ++n_noise;
        EXPECT_EQ(r.labels[i], -1) << "noise point " << i;
      } else if (expected_core[i]) {
        ++n_core;
        EXPECT_EQ(r.labels[i], expected[i]) << "core point " << i;
      } else {
        // Border point: any cluster with a core point within eps would be a
        // valid DBSCAN answer; scikit-learn's order picks one, and so do we.
        ++n_border;
        if (r.labels[i] != expected[i]) ++border_differ;
        bool reached = false;
        for (Eigen::Index k = 0; k < n; ++k) {
          const auto uk = static_cast<std::size_t>(k);
          if (r.core[uk] && r.labels[uk] == r.labels[i] &&
              (X.row(k) - X.row(static_cast<Eigen::Index>(i))).squaredNorm() <= opt.eps * opt.eps) {
            reached = true;
          }
        }
        EXPECT_TRUE(reached) << "border point " << i
                             << " not within eps of a core point of cluster " << r.labels[i];
      }
    }
  }
  std::printf(
      "[oracle-dbscan] %zu sets vs %s: labels identical for %d/%d points "
      "(core %d, border %d, noise %d); border points differing: %d\n",
      j["cases"].size(), j["source"].get<std::string>().c_str(), identical, points, n_core,
      n_border, n_noise, border_differ);
  EXPECT_EQ(identical, points);
  EXPECT_EQ(border_differ, 0);
}

TEST(OracleImp, QMethodMatchesScipyAlignVectors) {
  const std::string path = oracle_path("imp_wahba_scipy.json");
  if (!std::filesystem::exists(path)) {
    GTEST_SKIP() << "oracle cases missing: the scipy generator did not run (see "
                    "oracle.imp.generate)";
  }
  const auto j = artms::testing::load_json(path);
  ASSERT_GE(j["cases"].size(), 50u);
  double worst = 0.0, worst_true = 0.0;
  std::string worst_name;
  for (const auto& c : j["cases"]) {
    const std::string name = c["name"].get<std::string>();
    SCOPED_TRACE(name);
    std::vector<WeightedPair> pairs;
    for (std::size_t i = 0; i < c["weights"].size(); ++i) {
      pairs.push_back({vec3(c["body"][i]), vec3(c["reference"][i]), c["weights"][i].get<double>()});
    }
    const AttitudeSolution s = q_method(pairs);
    ASSERT_TRUE(s.usable) << s.why;
    // scipy as_quat() is [x, y, z, w]; the generator also wrote [w, x, y, z].
    const auto& xyzw = c["scipy_as_quat_xyzw"];
    const Eigen::Quaterniond q_scipy(xyzw[3].get<double>(), xyzw[0].get<double>(),
                                     xyzw[1].get<double>(), xyzw[2].get<double>());
    const auto wxyz = c["q_body_from_ref_wxyz"].get<std::array<double, 4>>();
    EXPECT_THAT(astro::quaternion_from_wxyz(wxyz), artms::testing::IsNearQuaternion(q_scipy, 0.0));
    const double angle = s.q_body_from_ref.angularDistance(q_scipy);
    EXPECT_LE(angle, kAttitudeTol_rad);
    if (angle > worst) {
      worst = angle;
      worst_name = name;
    }
    const auto wt = c["q_true_body_from_ref_wxyz"].get<std::array<double, 4>>();
    worst_true =
        std::max(worst_true, s.q_body_from_ref.angularDistance(astro::quaternion_from_wxyz(wt)));
    const double loss = c["wahba_loss"].get<double>();
    EXPECT_NEAR(s.loss, loss, 1e-9 * loss + 1e-300);
  }
  std::printf(
      "[oracle-qmethod] %zu sets vs %s: max attitude difference %.3e rad (%s); "
      "max error vs truth (noise) %.3e rad\n",
      j["cases"].size(), j["source"].get<std::string>().c_str(), worst, worst_name.c_str(),
      worst_true);
}

}  // namespace
}  // namespace artms::imp
