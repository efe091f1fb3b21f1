// Davenport's q-method for Wahba's problem (Markley & Crassidis 2014,
// "Fundamentals of Spacecraft Attitude Determination and Control", sec. 5.4):
// the VBS attitude from identified stars (paper, "Image Processing").
//
// Minimises Wahba's loss L(A) = 1/2 sum_i w_i |b_i - A r_i|^2 over rotations
// A = R_body_from_ref, i.e. the model is body = R_body_from_ref * reference.
// With B = sum w_i b_i r_i^T, S = B + B^T, z = sum w_i b_i x r_i, Davenport's
//   K = [ S - tr(B) I   z     ]
//       [ z^T           tr(B) ]
// and the optimal quaternion (Shuster's convention [q_1:3, q_4], A(q) =
// (q4^2 - |q|^2) I + 2 q q^T - 2 q4 [q x]) is the eigenvector of K's largest
// eigenvalue lambda_max (Eigen::SelfAdjointEigenSolver); L = sum w_i -
// lambda_max for unit vectors. One QUEST step (Shuster & Oh 1981) in the frame
// of that eigenvector then removes the eigensolver's error, ~eps |K| / gap,
// which reaches 1e-10 rad for close vectors with very unequal weights: the
// result is the same optimum to double precision. It is returned in the
// project's convention (docs/conventions.md): q_body_from_ref.toRotationMatrix()
// == A, i.e. Eigen (w, x, y, z) = (q4, -q1, -q2, -q3).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <span>
#include <string>

#include "artms/astro/frames.hpp"

namespace artms::imp {

using astro::Vec3;

struct WeightedPair {
  Vec3 body = Vec3::UnitZ();       // observed direction, body (sensor) frame
  Vec3 reference = Vec3::UnitZ();  // same direction in the reference frame (e.g. ECI)
  // > 0. For covariance_rad2 in rad^2 use w = 1 / sigma^2 with sigma the
  // per-axis direction noise in rad; relative weights scale the covariance.
  double weight = 1.0;
};

struct QMethodOptions {
  // Smallest spread of the directions: sqrt of the smallest eigenvalue of
  // sum w (I - v v^T) / sum w, for the body and for the reference vectors
  // (for two vectors sin(theta / 2), theta their separation). Below it the
  // rotation about the common direction is unobservable: "collinear".
  double min_spread_rad = 1e-6;
  // (lambda_max - lambda_2) / sum w below this: the eigenvector is ill defined.
  double min_relative_gap = 1e-12;
  void validate() const;  // throws std::invalid_argument naming the field
};

struct AttitudeSolution {
  Eigen::Quaterniond q_body_from_ref = Eigen::Quaterniond::Identity();  // w >= 0
  bool usable = false;
  std::string why;  // empty when usable, else the reason
  // Wahba loss 1/2 sum w |b - A r|^2 (vectors normalised), computed directly.
  double loss = 0.0;
  double residual_rms_rad = 0.0;  // unweighted RMS of angle(b_i, A r_i)
  int n = 0;                      // number of pairs
  double lambda_max = 0.0;        // largest eigenvalue of K
  double eigen_gap = 0.0;         // lambda_max - lambda_2
  // Covariance of the small-angle attitude error in body axes,
  // q_true = dq(dtheta) * q_est, from Shuster's QUEST measurement model:
  // P = [sum w_i (I - b_i b_i^T)]^-1 with b_i = A r_i.
  Eigen::Matrix3d covariance_rad2 = Eigen::Matrix3d::Zero();
};

// Input vectors need not be unit: each is normalised first. Never throws for
// bad data: usable = false with a reason for < 2 pairs, non-finite input,
// zero-length vectors, weights <= 0, collinear directions or an eigenvalue
// gap too small. When not usable the other fields are not meaningful
// (identity, NaN). Throws std::invalid_argument only for invalid options.
AttitudeSolution q_method(std::span<const WeightedPair> pairs, const QMethodOptions& options = {});

}  // namespace artms::imp
