// Spherical-harmonic gravity from fully normalised coefficients (ICGEM .gfc),
// evaluated in the Earth-fixed frame with the normalised Cunningham V/W
// recursion (Montenbruck & Gill 2000, eqs. 3.29-3.33, normalised).
#pragma once

#include <string>
#include <vector>

#include "artms/astro/frames.hpp"
#include "artms/astro/time.hpp"

namespace artms::dynamics {

using astro::Mat3;
using astro::TimeTT;
using astro::Vec3;

// Fully normalised Stokes coefficients C_nm, S_nm up to max_degree.
class GravityField {
 public:
  // Reads an ICGEM .gfc file up to max_degree (-1 = all). Accepts Fortran 'D'
  // exponents. Throws std::runtime_error naming the file and line on malformed
  // input or when the file's degree is below max_degree.
  static GravityField from_gfc(const std::string& path, int max_degree = -1);
  // A field with GM, radius and given normalised coefficients, for tests.
  GravityField(double gm_m3ps2, double radius_m, int max_degree);

  [[nodiscard]] int max_degree() const { return max_degree_; }
  [[nodiscard]] double gm_m3ps2() const { return gm_m3ps2_; }
  [[nodiscard]] double radius_m() const { return radius_m_; }
  [[nodiscard]] double c(int n, int m) const { return c_[index(n, m)]; }
  [[nodiscard]] double s(int n, int m) const { return s_[index(n, m)]; }
  void set(int n, int m, double c_nm, double s_nm);
  [[nodiscard]] const std::string& name() const { return name_; }

 private:
  [[nodiscard]] std::size_t index(int n, int m) const;
  std::string name_;
  double gm_m3ps2_;
  double radius_m_;
  int max_degree_;
  std::vector<double> c_, s_;
};

// Evaluates the acceleration of a field truncated at (degree, order).
// Pre-computes the normalisation ratios once; evaluation allocates nothing.
class SphericalHarmonicGravity {
 public:
  // Throws std::invalid_argument if degree/order exceed the field's degree or
  // order > degree.
  SphericalHarmonicGravity(const GravityField& field, int degree, int order);

  // Acceleration in ECEF components (m/s^2) at ECEF position r_ecef_m,
  // including the central term (C00 = 1).
  [[nodiscard]] Vec3 acceleration_ecef(const Vec3& r_ecef_m) const;
  // Same, without the central GM/r^2 term (the perturbation only).
  [[nodiscard]] Vec3 perturbation_ecef(const Vec3& r_ecef_m) const;
  // ECI wrapper: rotates r into ECEF with R_ecef_from_eci, evaluates there
  // (the tesseral terms rotate with the Earth) and rotates back.
  [[nodiscard]] Vec3 acceleration_eci(const Vec3& r_eci_m, const Mat3& R_ecef_from_eci) const;

  [[nodiscard]] int degree() const { return degree_; }
  [[nodiscard]] int order() const { return order_; }
  [[nodiscard]] double gm_m3ps2() const { return gm_; }
  [[nodiscard]] double radius_m() const { return radius_; }

 private:
  [[nodiscard]] Vec3 evaluate(const Vec3& r, bool include_central) const;
  double gm_, radius_;
  int degree_, order_;
  std::vector<double> c_, s_;  // normalised coefficients, [n][m] packed
  // Recursion and acceleration factors, packed like c_ up to degree + 1.
  std::vector<double> diag_, a_, b_, f_pp_, f_pm_, f_z_;
  std::size_t stride_;
};

}  // namespace artms::dynamics
