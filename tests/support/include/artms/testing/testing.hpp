// Shared test helpers: matchers, numerical derivatives, golden data.
#pragma once

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

namespace artms::testing {

// Path of a golden file in tests/data/ (see tests/data/README.md).
inline std::string test_data_path(const std::string& name) {
  return std::string(ARTMS_TEST_DATA_DIR) + "/" + name;
}

inline nlohmann::json load_json(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open test data file " + path);
  return nlohmann::json::parse(in);
}

// Central-difference Jacobian of f: R^n -> R^m at x with step h per component.
template <int M, int N>
Eigen::Matrix<double, M, N> numerical_jacobian(
    const std::function<Eigen::Matrix<double, M, 1>(const Eigen::Matrix<double, N, 1>&)>& f,
    const Eigen::Matrix<double, N, 1>& x, const Eigen::Matrix<double, N, 1>& h) {
  Eigen::Matrix<double, M, N> J;
  for (int k = 0; k < N; ++k) {
    Eigen::Matrix<double, N, 1> xp = x, xm = x;
    xp[k] += h[k];
    xm[k] -= h[k];
    J.col(k) = (f(xp) - f(xm)) / (2.0 * h[k]);
  }
  return J;
}

// Quaternions equal up to sign, within tol_rad of rotation angle.
MATCHER_P2(IsNearQuaternion, expected, tol_rad, "") {
  const double angle = arg.angularDistance(expected);
  *result_listener << "angular distance " << angle << " rad";
  return angle <= tol_rad;
}

MATCHER_P2(IsNearMatrix, expected, tol, "") {
  const double err = (arg - expected).cwiseAbs().maxCoeff();
  *result_listener << "max abs difference " << err;
  return err <= tol;
}

MATCHER_P(IsSymmetricPositiveDefinite, tol, "") {
  if ((arg - arg.transpose()).cwiseAbs().maxCoeff() > tol) {
    *result_listener << "not symmetric";
    return false;
  }
  Eigen::LLT<Eigen::MatrixXd> llt(arg);
  if (llt.info() != Eigen::Success) {
    *result_listener << "Cholesky failed";
    return false;
  }
  return true;
}

// Relative Jacobian agreement: max |A - N| <= tol * max(1, max |N|).
MATCHER_P2(IsNearJacobian, numerical, rel_tol, "") {
  const double scale = std::max(1e-300, numerical.cwiseAbs().maxCoeff());
  const double err = (arg - numerical).cwiseAbs().maxCoeff();
  *result_listener << "max abs difference " << err << " (scale " << scale << ")";
  return err <= rel_tol * scale;
}

}  // namespace artms::testing
