#include "artms/astro/elements.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace artms::astro {
namespace {

// Below this, an orbit is treated as circular / equatorial for the angle
// conventions (the state itself is still reproduced exactly).
constexpr double kCircularTol = 1e-13;
constexpr double kEquatorialTol = 1e-13;

void check_ellipse(double a_m, double e, const char* where) {
  if (!(a_m > 0.0) || !(e >= 0.0) || !(e < 1.0)) {
    throw std::invalid_argument(std::string(where) +
                                ": need a > 0 and 0 <= e < 1 (elliptical orbit), got a = " +
                                std::to_string(a_m) + " m, e = " + std::to_string(e));
  }
}

}  // namespace

Vec6 QnsElements::as_vector() const {
  Vec6 v;
  v << a_m, ex, ey, i_rad, raan_rad, u_rad;
  return v;
}

QnsElements QnsElements::from_vector(const Vec6& v) { return {v[0], v[1], v[2], v[3], v[4], v[5]}; }

double wrap_two_pi(double a) {
  double w = std::fmod(a, kTwoPi);
  if (w < 0.0) w += kTwoPi;
  return w >= kTwoPi ? 0.0 : w;
}

double wrap_pi(double a) {
  double w = wrap_two_pi(a);
  return w > kPi ? w - kTwoPi : w;
}

double eccentric_from_mean_anomaly(double M_rad, double e) {
  if (!(e >= 0.0 && e < 1.0)) throw std::invalid_argument("Kepler's equation needs 0 <= e < 1");
  // Solve for the wrapped anomaly, then restore the revolution of M.
  const double base = M_rad - wrap_pi(M_rad);
  const double M = wrap_pi(M_rad);
  double E = e < 0.8 ? M + e * std::sin(M) : (M >= 0.0 ? kPi : -kPi);
  for (int k = 0; k < 60; ++k) {
    const double f = E - e * std::sin(E) - M;
    const double dE = -f / (1.0 - e * std::cos(E));
    E += dE;
    if (std::abs(dE) < 1e-15) break;
  }
  return base + E;
}

double mean_from_eccentric_anomaly(double E_rad, double e) { return E_rad - e * std::sin(E_rad); }

double true_from_eccentric_anomaly(double E_rad, double e) {
  // Half-angle form keeps the revolution: nu - E is small and continuous.
  const double beta = e / (1.0 + std::sqrt(1.0 - e * e));
  return E_rad + 2.0 * std::atan2(beta * std::sin(E_rad), 1.0 - beta * std::cos(E_rad));
}

double eccentric_from_true_anomaly(double nu_rad, double e) {
  const double beta = e / (1.0 + std::sqrt(1.0 - e * e));
  return nu_rad - 2.0 * std::atan2(beta * std::sin(nu_rad), 1.0 + beta * std::cos(nu_rad));
}

double true_from_mean_anomaly(double M_rad, double e) {
  return true_from_eccentric_anomaly(eccentric_from_mean_anomaly(M_rad, e), e);
}

double mean_from_true_anomaly(double nu_rad, double e) {
  return mean_from_eccentric_anomaly(eccentric_from_true_anomaly(nu_rad, e), e);
}

double mean_motion_radps(double a_m, double gm) { return std::sqrt(gm / (a_m * a_m * a_m)); }

double orbit_period_s(double a_m, double gm) { return kTwoPi / mean_motion_radps(a_m, gm); }

StateVector cartesian_from_kepler(const KeplerElements& oe, double gm) {
  check_ellipse(oe.a_m, oe.e, "cartesian_from_kepler");
  const double E = eccentric_from_mean_anomaly(oe.M_rad, oe.e);
  const double cE = std::cos(E), sE = std::sin(E);
  const double sq = std::sqrt(1.0 - oe.e * oe.e);
  // Perifocal position and velocity from the eccentric anomaly.
  const double r = oe.a_m * (1.0 - oe.e * cE);
  const double xp = oe.a_m * (cE - oe.e);
  const double yp = oe.a_m * sq * sE;
  const double k = std::sqrt(gm * oe.a_m) / r;
  const double vxp = -k * sE;
  const double vyp = k * sq * cE;
  const Mat3 R_eci_from_pqw =
      (rot3(oe.argp_rad) * rot1(oe.i_rad) * rot3(oe.raan_rad)).transpose();
  StateVector x;
  x.r_m = R_eci_from_pqw * Vec3(xp, yp, 0.0);
  x.v_mps = R_eci_from_pqw * Vec3(vxp, vyp, 0.0);
  return x;
}

namespace {

// Node line, in-plane basis and angles shared by the Keplerian and
// quasi-nonsingular conversions.
struct PlaneGeometry {
  double i_rad;
  double raan_rad;
  Vec3 node_hat;  // unit vector to the ascending node (x axis if equatorial)
  Vec3 perp_hat;  // h_hat x node_hat
  Vec3 h_hat;
};

PlaneGeometry plane_geometry(const Vec3& h) {
  PlaneGeometry g;
  g.h_hat = h.normalized();
  g.i_rad = std::atan2(std::hypot(h.x(), h.y()), h.z());
  const Vec3 n(-h.y(), h.x(), 0.0);  // z x h
  if (n.norm() <= kEquatorialTol * h.norm()) {
    g.raan_rad = 0.0;
    g.node_hat = Vec3::UnitX();
  } else {
    g.node_hat = n.normalized();
    g.raan_rad = wrap_two_pi(std::atan2(n.y(), n.x()));
  }
  g.perp_hat = g.h_hat.cross(g.node_hat);
  return g;
}

struct InPlane {
  PlaneGeometry g;
  double a_m;
  double ex;     // eccentricity vector along the node line
  double ey;     // ... and along perp_hat
  double theta;  // true argument of latitude of the position
};

InPlane in_plane(const StateVector& x, double gm) {
  const Vec3& r = x.r_m;
  const Vec3& v = x.v_mps;
  const double rn = r.norm();
  const Vec3 h = r.cross(v);
  if (!(rn > 0.0) || !(h.norm() > 0.0)) {
    throw std::invalid_argument("orbit elements: position zero or parallel to velocity");
  }
  const double energy = 0.5 * v.squaredNorm() - gm / rn;
  if (!(energy < 0.0)) {
    throw std::invalid_argument("orbit elements: state is not on an elliptical orbit (energy >= 0)");
  }
  InPlane p;
  p.g = plane_geometry(h);
  p.a_m = -gm / (2.0 * energy);
  const Vec3 evec = v.cross(h) / gm - r / rn;
  p.ex = evec.dot(p.g.node_hat);
  p.ey = evec.dot(p.g.perp_hat);
  p.theta = wrap_two_pi(std::atan2(r.dot(p.g.perp_hat), r.dot(p.g.node_hat)));
  return p;
}

}  // namespace

KeplerElements kepler_from_cartesian(const StateVector& x, double gm) {
  const InPlane p = in_plane(x, gm);
  KeplerElements oe;
  oe.a_m = p.a_m;
  oe.e = std::hypot(p.ex, p.ey);
  check_ellipse(oe.a_m, oe.e, "kepler_from_cartesian");
  oe.i_rad = p.g.i_rad;
  oe.raan_rad = p.g.raan_rad;
  oe.argp_rad = oe.e <= kCircularTol ? 0.0 : wrap_two_pi(std::atan2(p.ey, p.ex));
  const double nu = p.theta - oe.argp_rad;
  oe.M_rad = wrap_two_pi(mean_from_true_anomaly(nu, oe.e));
  return oe;
}

QnsElements qns_from_kepler(const KeplerElements& oe) {
  QnsElements q;
  q.a_m = oe.a_m;
  q.ex = oe.e * std::cos(oe.argp_rad);
  q.ey = oe.e * std::sin(oe.argp_rad);
  q.i_rad = oe.i_rad;
  q.raan_rad = oe.raan_rad;
  q.u_rad = wrap_two_pi(oe.argp_rad + oe.M_rad);
  return q;
}

KeplerElements kepler_from_qns(const QnsElements& q) {
  KeplerElements oe;
  oe.a_m = q.a_m;
  oe.e = std::hypot(q.ex, q.ey);
  oe.i_rad = q.i_rad;
  oe.raan_rad = q.raan_rad;
  oe.argp_rad = oe.e == 0.0 ? 0.0 : std::atan2(q.ey, q.ex);
  oe.M_rad = q.u_rad - oe.argp_rad;
  return oe;
}

StateVector cartesian_from_qns(const QnsElements& q, double gm) {
  return cartesian_from_kepler(kepler_from_qns(q), gm);
}

QnsElements qns_from_cartesian(const StateVector& x, double gm) {
  const InPlane p = in_plane(x, gm);
  const double e = std::hypot(p.ex, p.ey);
  check_ellipse(p.a_m, e, "qns_from_cartesian");
  QnsElements q;
  q.a_m = p.a_m;
  q.ex = p.ex;
  q.ey = p.ey;
  q.i_rad = p.g.i_rad;
  q.raan_rad = p.g.raan_rad;
  // u = argp + M = theta - (nu - M); nu - M -> 0 smoothly as e -> 0, so u is
  // well defined even where argp is not.
  const double argp = e == 0.0 ? 0.0 : std::atan2(p.ey, p.ex);
  const double nu = p.theta - argp;
  q.u_rad = wrap_two_pi(p.theta - (nu - mean_from_true_anomaly(nu, e)));
  return q;
}

Mat6 jacobian_qns_from_cartesian(const StateVector& x_eci, double gm) {
  Mat6 J;
  for (int j = 0; j < 6; ++j) {
    const double h = j < 3 ? 1.0 : 1e-3;
    StateVector a = x_eci, b = x_eci;
    if (j < 3) {
      a.r_m[j] += h;
      b.r_m[j] -= h;
    } else {
      a.v_mps[j - 3] += h;
      b.v_mps[j - 3] -= h;
    }
    Vec6 d = qns_from_cartesian(a, gm).as_vector() - qns_from_cartesian(b, gm).as_vector();
    d[4] = std::remainder(d[4], 2.0 * M_PI);
    d[5] = std::remainder(d[5], 2.0 * M_PI);
    J.col(j) = d / (2.0 * h);
  }
  return J;
}

}  // namespace artms::astro
