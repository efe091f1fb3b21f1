#include "artms/astro/roe.hpp"

#include <cmath>
#include <stdexcept>

namespace artms::astro {

Vec6 Roe::as_vector() const {
  Vec6 v;
  v << da, dlambda, dex, dey, dix, diy;
  return v;
}

Roe Roe::from_vector(const Vec6& v) { return {v[0], v[1], v[2], v[3], v[4], v[5]}; }

Roe Roe::from_scaled_m(const Vec6& a_droe_m, double a_observer_m) {
  return from_vector(a_droe_m / a_observer_m);
}

Roe roe_from_qns(const QnsElements& o, const QnsElements& t) {
  if (!(o.a_m > 0.0)) throw std::invalid_argument("roe_from_qns: observer a must be > 0");
  const double d_raan = wrap_pi(t.raan_rad - o.raan_rad);
  Roe r;
  r.da = (t.a_m - o.a_m) / o.a_m;
  r.dlambda = wrap_pi(wrap_pi(t.u_rad - o.u_rad) + d_raan * std::cos(o.i_rad));
  r.dex = t.ex - o.ex;
  r.dey = t.ey - o.ey;
  r.dix = t.i_rad - o.i_rad;
  r.diy = d_raan * std::sin(o.i_rad);
  return r;
}

QnsElements qns_from_roe(const QnsElements& o, const Roe& r) {
  const double si = std::sin(o.i_rad);
  if (std::abs(si) < 1e-9) {
    throw std::invalid_argument(
        "qns_from_roe: observer orbit is equatorial (sin i ~ 0); diy does not determine RAAN");
  }
  const double d_raan = r.diy / si;
  QnsElements t;
  t.a_m = o.a_m * (1.0 + r.da);
  t.ex = o.ex + r.dex;
  t.ey = o.ey + r.dey;
  t.i_rad = o.i_rad + r.dix;
  t.raan_rad = wrap_two_pi(o.raan_rad + d_raan);
  t.u_rad = wrap_two_pi(o.u_rad + r.dlambda - d_raan * std::cos(o.i_rad));
  return t;
}

Mat6 rtn_from_roe_linear_jacobian(double a, double u, double gm) {
  const double n = mean_motion_radps(a, gm);
  const double c = std::cos(u), s = std::sin(u);
  Mat6 J;
  // Columns: da, dlambda, dex, dey, dix, diy.
  J << 1, 0, -c, -s, 0, 0,         //
      0, 1, 2 * s, -2 * c, 0, 0,   //
      0, 0, 0, 0, s, -c,           //
      0, 0, s, -c, 0, 0,           //
      -1.5, 0, 2 * c, 2 * s, 0, 0, //
      0, 0, 0, 0, c, s;
  J.topRows<3>() *= a;
  J.bottomRows<3>() *= a * n;
  return J;
}

StateVector rtn_from_roe_linear(const Roe& roe, double a, double u, double gm) {
  return StateVector::from_stacked(rtn_from_roe_linear_jacobian(a, u, gm) * roe.as_vector());
}

Vec3 rectilinear_from_curvilinear(const Vec3& curv, double r_o) {
  // Paper eq. (7) with Theta = curv_T / r_o, Phi = curv_N / r_o.
  const double rt = r_o + curv.x();
  const double theta = curv.y() / r_o, phi = curv.z() / r_o;
  return {rt * std::cos(theta) * std::cos(phi) - r_o, rt * std::sin(theta) * std::cos(phi),
          rt * std::sin(phi)};
}

Vec3 curvilinear_from_rectilinear(const Vec3& rect, double r_o) {
  const Vec3 p(r_o + rect.x(), rect.y(), rect.z());  // target from Earth centre, observer RTN
  const double rt = p.norm();
  const double theta = std::atan2(p.y(), p.x());
  const double phi = std::asin(p.z() / rt);
  return {rt - r_o, r_o * theta, r_o * phi};
}

Vec3 relative_rtn_rectilinear(const StateVector& o, const StateVector& t) {
  return R_rtn_from_eci(o) * (t.r_m - o.r_m);
}

Vec3 relative_rtn_curvilinear(const StateVector& o, const StateVector& t) {
  return curvilinear_from_rectilinear(relative_rtn_rectilinear(o, t), o.r_m.norm());
}

}  // namespace artms::astro
