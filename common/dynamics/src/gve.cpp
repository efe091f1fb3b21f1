#include "artms/dynamics/gve.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace artms::dynamics {

Mat63 gve_matrix(const QnsElements& oe, double gm) {
  const double a = oe.a_m, ex = oe.ex, ey = oe.ey;
  const double e2 = ex * ex + ey * ey;
  const double e = std::sqrt(e2);
  const double eta = std::sqrt(1.0 - e2);
  const double p = a * (1.0 - e2);
  const double h = std::sqrt(gm * p);
  // True argument of latitude theta = argp + nu from the mean one.
  const double argp = e > 0.0 ? std::atan2(ey, ex) : 0.0;
  const double nu = astro::true_from_mean_anomaly(oe.u_rad - argp, e);
  const double theta = argp + nu;
  const double ct = std::cos(theta), st = std::sin(theta);
  const double ecn = ex * ct + ey * st;  // e cos(nu)
  const double esn = ex * st - ey * ct;  // e sin(nu)
  const double r = p / (1.0 + ecn);
  const double si = std::sin(oe.i_rad), ci = std::cos(oe.i_rad);
  const double cot_i = ci / si;
  Mat63 G = Mat63::Zero();
  // a (Vallado eq. 9-24).
  G(0, 0) = 2.0 * a * a / h * esn;
  G(0, 1) = 2.0 * a * a / h * p / r;
  // ex = e cos(argp), ey = e sin(argp): e_dot and e*argp_dot combined.
  G(1, 0) = p * st / h;
  G(1, 1) = ((p + r) * ct + r * ex) / h;
  G(1, 2) = ey * r * st * cot_i / h;
  G(2, 0) = -p * ct / h;
  G(2, 1) = ((p + r) * st + r * ey) / h;
  G(2, 2) = -ex * r * st * cot_i / h;
  // i and RAAN.
  G(3, 2) = r * ct / h;
  G(4, 2) = r * st / (h * si);
  // u = argp + M, with (eta - 1)/e = -e/(1 + eta) to remove the 1/e.
  G(5, 0) = (-(p * ecn) / (1.0 + eta) - 2.0 * eta * r) / h;
  G(5, 1) = ((p + r) * esn / (1.0 + eta)) / h;
  G(5, 2) = -r * st * cot_i / h;
  return G;
}

Vec6 qns_rates(const QnsElements& oe, const Vec3& d_rtn, double gm) {
  Vec6 rates = gve_matrix(oe, gm) * d_rtn;
  rates[5] += astro::mean_motion_radps(oe.a_m, gm);
  return rates;
}

void GvePropagatorOptions::validate() const {
  if (!(step_s > 0.0) || !std::isfinite(step_s)) {
    throw std::invalid_argument("GVE propagator: step_s must be positive, got " +
                                std::to_string(step_s));
  }
}

GveRk4Propagator::GveRk4Propagator(const ForceModel& forces, const SpacecraftProperties& sc,
                                   GvePropagatorOptions options)
    : forces_(forces), sc_(sc), options_(options) {
  options_.validate();
  sc_.validate();
}

Vec6 GveRk4Propagator::derivative(const Vec6& alpha, astro::TimeTT t) const {
  const QnsElements oe = QnsElements::from_vector(alpha);
  const double gm = forces_.gm_m3ps2();
  const astro::StateVector x = astro::cartesian_from_qns(oe, gm);
  const Vec3 d_eci = forces_.perturbation_eci(t, x, sc_);
  const Vec3 d_rtn = astro::R_rtn_from_eci(x) * d_eci;
  return qns_rates(oe, d_rtn, gm);
}

Vec6 GveRk4Propagator::step(const Vec6& y, astro::TimeTT t, double h) const {
  const astro::TimeTT t_half = t.plus_seconds(0.5 * h);
  const Vec6 k1 = derivative(y, t);
  const Vec6 k2 = derivative(y + 0.5 * h * k1, t_half);
  const Vec6 k3 = derivative(y + 0.5 * h * k2, t_half);
  const Vec6 k4 = derivative(y + h * k3, t.plus_seconds(h));
  return y + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
}

QnsElements GveRk4Propagator::propagate(const QnsElements& oe0, astro::TimeTT t0,
                                        astro::TimeTT t1,
                                        const std::vector<ImpulsiveManeuver>& maneuvers) const {
  const double dir = t1 >= t0 ? 1.0 : -1.0;
  // Maneuver epochs strictly inside the interval, in the direction of travel.
  std::vector<ImpulsiveManeuver> todo;
  for (const auto& m : maneuvers) {
    const bool inside = dir > 0 ? (m.t > t0 && m.t <= t1) : (m.t < t0 && m.t >= t1);
    if (inside) todo.push_back(m);
  }
  std::sort(todo.begin(), todo.end(), [dir](const auto& x, const auto& y) {
    return dir > 0 ? x.t < y.t : x.t > y.t;
  });
  Vec6 y = oe0.as_vector();
  astro::TimeTT t = t0;
  std::size_t next = 0;
  while (t != t1) {
    const astro::TimeTT stop = next < todo.size() ? todo[next].t : t1;
    double remaining = astro::seconds_between(t, stop) * dir;
    while (remaining > 0.0) {
      const double h = std::min(options_.step_s, remaining);
      const astro::TimeTT t_next =
          h == remaining ? stop : t.plus_seconds(dir * h);  // land exactly on stop
      y = step(y, t, astro::seconds_between(t, t_next));
      t = t_next;
      remaining = astro::seconds_between(t, stop) * dir;
    }
    if (next < todo.size()) {
      const double gm = forces_.gm_m3ps2();
      const astro::StateVector x = astro::cartesian_from_qns(QnsElements::from_vector(y), gm);
      QnsElements after = astro::qns_from_cartesian(apply_maneuver(x, todo[next].dv_rtn_mps), gm);
      // Keep u continuous across the maneuver.
      after.u_rad = y[5] + astro::wrap_pi(after.u_rad - y[5]);
      y = after.as_vector();
      ++next;
    }
  }
  QnsElements out = QnsElements::from_vector(y);
  out.u_rad = astro::wrap_two_pi(out.u_rad);
  out.raan_rad = astro::wrap_two_pi(out.raan_rad);
  return out;
}

}  // namespace artms::dynamics
