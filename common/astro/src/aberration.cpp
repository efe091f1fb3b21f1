#include "artms/astro/aberration.hpp"

#include <cmath>
#include <stdexcept>

namespace artms::astro {

Vec3 aberrated_direction(const Vec3& u, const Vec3& v_mps) {
  const double n = u.norm();
  if (!(n > 0.0) || !std::isfinite(n)) throw std::invalid_argument("aberrated_direction: zero or non-finite direction");
  const Vec3 b = v_mps / kSpeedOfLight_mps;
  const double b2 = b.squaredNorm();
  if (!(b2 < 1.0)) throw std::invalid_argument("aberrated_direction: speed not below c");
  const Vec3 un = u / n;
  const double gamma = 1.0 / std::sqrt(1.0 - b2);
  const double ub = un.dot(b);
  // (gamma - 1)(u . b_hat) b_hat = (gamma - 1)/b^2 (u . b) b, written without
  // b_hat so that v = 0 is not a special case: (gamma - 1)/b^2 = gamma^2/(gamma + 1).
  const Vec3 num = un + (gamma * gamma / (gamma + 1.0)) * ub * b + gamma * b;
  return num.normalized();  // the denominator gamma (1 + u . b) is a positive scale
}

}  // namespace artms::astro
