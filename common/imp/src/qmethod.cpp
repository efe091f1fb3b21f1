#include "artms/imp/qmethod.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace artms::imp {

void QMethodOptions::validate() const {
  if (!(min_spread_rad >= 0.0) || !std::isfinite(min_spread_rad)) {
    throw std::invalid_argument("QMethodOptions.min_spread_rad must be a finite number >= 0, got " +
                                std::to_string(min_spread_rad));
  }
  if (!(min_relative_gap >= 0.0) || !std::isfinite(min_relative_gap)) {
    throw std::invalid_argument(
        "QMethodOptions.min_relative_gap must be a finite number >= 0, got " +
        std::to_string(min_relative_gap));
  }
}

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

AttitudeSolution unusable(int n, std::string why) {
  AttitudeSolution s;
  s.usable = false;
  s.why = std::move(why);
  s.n = n;
  s.loss = s.residual_rms_rad = s.lambda_max = s.eigen_gap = kNaN;
  s.covariance_rad2 = Eigen::Matrix3d::Constant(kNaN);
  return s;
}

bool finite(const Vec3& v) {
  return v.allFinite();
}

// sqrt of the smallest eigenvalue of sum w (I - v v^T) / sum w.
double spread(const std::vector<Vec3>& v, const std::vector<double>& w, double w_sum) {
  Eigen::Matrix3d F = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < v.size(); ++i) {
    F += w[i] * (Eigen::Matrix3d::Identity() - v[i] * v[i].transpose());
  }
  F /= w_sum;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(F, Eigen::EigenvaluesOnly);
  return std::sqrt(std::max(0.0, es.eigenvalues()[0]));
}

}  // namespace

AttitudeSolution q_method(std::span<const WeightedPair> pairs, const QMethodOptions& options) {
  options.validate();
  const int n = static_cast<int>(pairs.size());
  if (n < 2) return unusable(n, "need at least 2 vector pairs, got " + std::to_string(n));

  std::vector<Vec3> b(pairs.size()), r(pairs.size());
  std::vector<double> w(pairs.size());
  double w_sum = 0.0;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const WeightedPair& p = pairs[i];
    const std::string tag = "pair " + std::to_string(i) + ": ";
    if (!finite(p.body)) return unusable(n, tag + "non-finite body vector");
    if (!finite(p.reference)) return unusable(n, tag + "non-finite reference vector");
    if (!std::isfinite(p.weight)) return unusable(n, tag + "non-finite weight");
    if (!(p.weight > 0.0)) return unusable(n, tag + "weight must be positive");
    const double nb = p.body.norm(), nr = p.reference.norm();
    if (!(nb > 0.0) || !std::isfinite(nb)) return unusable(n, tag + "zero-length body vector");
    if (!(nr > 0.0) || !std::isfinite(nr)) {
      return unusable(n, tag + "zero-length reference vector");
    }
    b[i] = p.body / nb;
    r[i] = p.reference / nr;
    w[i] = p.weight;
    w_sum += p.weight;
  }
  if (!std::isfinite(w_sum)) return unusable(n, "sum of weights overflows");

  const double spread_ref = spread(r, w, w_sum);
  if (spread_ref < options.min_spread_rad) {
    return unusable(n, "degenerate geometry: reference vectors collinear (spread " +
                           std::to_string(spread_ref) + " rad)");
  }
  const double spread_body = spread(b, w, w_sum);
  if (spread_body < options.min_spread_rad) {
    return unusable(n, "degenerate geometry: body vectors collinear (spread " +
                           std::to_string(spread_body) + " rad)");
  }

  // Davenport's K matrix (Markley & Crassidis 2014, sec. 5.4), Shuster's
  // quaternion ordering [q1 q2 q3 q4] with q4 the scalar.
  Eigen::Matrix3d B = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < b.size(); ++i) B += w[i] * b[i] * r[i].transpose();
  const Eigen::Matrix3d S = B + B.transpose();
  const Vec3 z(B(1, 2) - B(2, 1), B(2, 0) - B(0, 2), B(0, 1) - B(1, 0));  // sum w b x r
  const double tr = B.trace();
  Eigen::Matrix4d K;
  K.topLeftCorner<3, 3>() = S - tr * Eigen::Matrix3d::Identity();
  K.topRightCorner<3, 1>() = z;
  K.bottomLeftCorner<1, 3>() = z.transpose();
  K(3, 3) = tr;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> es(K);
  if (es.info() != Eigen::Success) return unusable(n, "eigen decomposition of K failed");
  const Eigen::Vector4d lambda = es.eigenvalues();  // ascending
  const double gap = lambda[3] - lambda[2];
  if (!(gap >= options.min_relative_gap * w_sum)) {
    return unusable(n, "degenerate geometry: eigenvalue gap (lambda_max - lambda_2) / sum w = " +
                           std::to_string(gap / w_sum) + " too small");
  }
  const Eigen::Vector4d q = es.eigenvectors().col(3);  // [q1 q2 q3 q4], Shuster

  AttitudeSolution s;
  s.usable = true;
  s.n = n;
  s.lambda_max = lambda[3];
  s.eigen_gap = gap;
  // A(q_shuster) == R_eigen(w = q4, v = -q1:3).
  const Eigen::Quaterniond q0 = Eigen::Quaterniond(q[3], -q[0], -q[1], -q[2]).normalized();

  // Refinement. The eigenvector's error is ~ eps |K| / gap, large when the
  // gap is small against the weights (e.g. two close stars with very unequal
  // weights: 1e-10 rad seen). The same optimum, written in the frame of this
  // first estimate (r' = A0 r), is a small rotation given exactly by QUEST's
  // Gibbs vector (Shuster & Oh 1981): p = ((lambda + tr B') I - S')^-1 z',
  // with z' = sum w b x (r' - b) formed from the small differences r' - b
  // (no cancellation of large entries of B' or of the products in b x r'),
  // so the result lands at double precision.
  const Eigen::Matrix3d A0 = q0.toRotationMatrix();
  Eigen::Matrix3d B1 = Eigen::Matrix3d::Zero();
  Vec3 z1 = Vec3::Zero();
  for (std::size_t i = 0; i < b.size(); ++i) {
    const Vec3 r1 = A0 * r[i];
    B1 += w[i] * b[i] * r1.transpose();
    z1 += w[i] * b[i].cross(r1 - b[i]);  // = b x r1; r1 - b is small and exact
  }
  const Eigen::Matrix3d M1 =
      (lambda[3] + B1.trace()) * Eigen::Matrix3d::Identity() - (B1 + B1.transpose());
  const Vec3 p = M1.ldlt().solve(z1);                  // Shuster Gibbs vector of A A0^T
  Eigen::Quaterniond dq(1.0, -p.x(), -p.y(), -p.z());  // Eigen form, as above
  dq.normalize();
  s.q_body_from_ref = p.allFinite() ? (dq * q0).normalized() : q0;
  if (s.q_body_from_ref.w() < 0.0) s.q_body_from_ref.coeffs() *= -1.0;
  const Eigen::Matrix3d A = s.q_body_from_ref.toRotationMatrix();

  double loss = 0.0, sq_angles = 0.0;
  Eigen::Matrix3d F = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < b.size(); ++i) {
    const Vec3 ar = A * r[i];
    loss += 0.5 * w[i] * (b[i] - ar).squaredNorm();
    const double angle = std::atan2(b[i].cross(ar).norm(), b[i].dot(ar));
    sq_angles += angle * angle;
    F += w[i] * (Eigen::Matrix3d::Identity() - ar * ar.transpose());
  }
  s.loss = loss;
  s.residual_rms_rad = std::sqrt(sq_angles / static_cast<double>(n));
  s.covariance_rad2 = F.inverse();
  s.covariance_rad2 = 0.5 * (s.covariance_rad2 + s.covariance_rad2.transpose()).eval();
  return s;
}

}  // namespace artms::imp
