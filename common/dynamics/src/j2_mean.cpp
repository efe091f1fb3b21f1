#include "artms/dynamics/j2_mean.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace artms::dynamics {

using astro::wrap_pi;

namespace {

void check_mean_elements(const QnsElements& oe, const char* where) {
  const double e = std::hypot(oe.ex, oe.ey);
  if (!(oe.a_m > 0.0) || !(e < 1.0)) {
    throw std::invalid_argument(std::string(where) + ": needs a > 0 and 0 <= e < 1");
  }
}

// kappa = 3/4 J2 R^2 sqrt(mu) / (a^{7/2} eta^4) (Koenig et al. 2017, as in eq. A6).
double kappa(double a, double eta, const J2Constants& c) {
  const double eta2 = eta * eta;
  return 0.75 * c.j2 * c.radius_m * c.radius_m * std::sqrt(c.gm_m3ps2) /
         (std::pow(a, 3.5) * eta2 * eta2);
}

}  // namespace

J2SecularRates j2_secular_rates(const QnsElements& mean, const J2Constants& c) {
  check_mean_elements(mean, "j2_secular_rates");
  const double e2 = mean.ex * mean.ex + mean.ey * mean.ey;
  const double eta = std::sqrt(1.0 - e2);
  const double k = kappa(mean.a_m, eta, c);
  const double ci = std::cos(mean.i_rad);
  const double ci2 = ci * ci;
  // Brouwer first-order secular rates (as used by Koenig et al. 2017):
  //   RAAN' = -2 k cos i,  argp' = k (5 cos^2 i - 1),  M' = n + k eta (3 cos^2 i - 1).
  return {-2.0 * k * ci, k * (5.0 * ci2 - 1.0),
          astro::mean_motion_radps(mean.a_m, c.gm_m3ps2) + k * eta * (3.0 * ci2 - 1.0)};
}

QnsElements propagate_mean_j2(const QnsElements& mean, double dt_s, const J2Constants& c) {
  const J2SecularRates r = j2_secular_rates(mean, c);
  const double dw = r.argp_dot_radps * dt_s;
  const double cw = std::cos(dw), sw = std::sin(dw);
  QnsElements out = mean;
  // a, e, i constant; the eccentricity vector rotates with argp'.
  out.ex = cw * mean.ex - sw * mean.ey;
  out.ey = sw * mean.ex + cw * mean.ey;
  out.raan_rad = wrap_pi(mean.raan_rad + r.raan_dot_radps * dt_s);
  out.u_rad = wrap_pi(mean.u_rad + (r.argp_dot_radps + r.mean_anomaly_dot_radps) * dt_s);
  return out;
}

Mat6 roe_stm_j2(const QnsElements& chief, double dt_s, const J2Constants& c) {
  check_mean_elements(chief, "roe_stm_j2");
  const double tau = dt_s;
  const double exi = chief.ex, eyi = chief.ey;
  const double e2 = exi * exi + eyi * eyi;
  const double eta = std::sqrt(1.0 - e2);
  const double n = astro::mean_motion_radps(chief.a_m, c.gm_m3ps2);
  const double k = kappa(chief.a_m, eta, c);
  // Auxiliary quantities of Koenig et al. (2017) used in eq. (A6).
  const double E = 1.0 + eta;
  const double F = 4.0 + 3.0 * eta;
  const double G = 1.0 / (eta * eta);
  const double ci = std::cos(chief.i_rad), si = std::sin(chief.i_rad);
  const double P = 3.0 * ci * ci - 1.0;
  const double Q = 5.0 * ci * ci - 1.0;
  const double S = std::sin(2.0 * chief.i_rad);
  const double T = si * si;
  // Chief eccentricity vector at the end of the interval: rotated by argp' tau.
  const double dw = k * Q * tau;
  const double cw = std::cos(dw), sw = std::sin(dw);
  const double exf = cw * exi - sw * eyi;
  const double eyf = sw * exi + cw * eyi;

  // Koenig et al. (2017), Appendix A, eq. (A6): J2 STM of the QNS ROE.
  Mat6 phi = Mat6::Identity();
  // d(dlambda): Keplerian drift plus the J2 differential rates of u + RAAN cos i.
  phi(1, 0) = -(1.5 * n + 3.5 * k * E * P) * tau;
  phi(1, 2) = k * exi * F * G * P * tau;
  phi(1, 3) = k * eyi * F * G * P * tau;
  phi(1, 4) = -k * F * S * tau;
  // d(dex), d(dey): rotation by argp' tau plus the differential argp' acting
  // on the chief's final eccentricity vector.
  phi(2, 0) = 3.5 * k * eyf * Q * tau;
  phi(2, 2) = cw - 4.0 * k * exi * eyf * G * Q * tau;
  phi(2, 3) = -sw - 4.0 * k * eyi * eyf * G * Q * tau;
  phi(2, 4) = 5.0 * k * eyf * S * tau;
  phi(3, 0) = -3.5 * k * exf * Q * tau;
  phi(3, 2) = sw + 4.0 * k * exi * exf * G * Q * tau;
  phi(3, 3) = cw + 4.0 * k * eyi * exf * G * Q * tau;
  phi(3, 4) = -5.0 * k * exf * S * tau;
  // d(diy): differential nodal regression times sin i.
  phi(5, 0) = 3.5 * k * S * tau;
  phi(5, 2) = -4.0 * k * exi * G * S * tau;
  phi(5, 3) = -4.0 * k * eyi * G * S * tau;
  phi(5, 4) = 2.0 * k * T * tau;
  return phi;
}

Mat6 roe_stm_kepler(const QnsElements& chief, double dt_s, double gm_m3ps2) {
  check_mean_elements(chief, "roe_stm_kepler");
  Mat6 phi = Mat6::Identity();
  phi(1, 0) = -1.5 * astro::mean_motion_radps(chief.a_m, gm_m3ps2) * dt_s;
  return phi;
}

QnsElements osculating_from_mean(const QnsElements& mean, const J2Constants& c) {
  check_mean_elements(mean, "osculating_from_mean");
  const double a = mean.a_m;
  const double e = std::hypot(mean.ex, mean.ey);
  const double i = mean.i_rad;
  const double ci = std::cos(i), si = std::sin(i);
  if (std::abs(si) < 1e-6) {
    throw std::invalid_argument("osculating_from_mean: near-equatorial orbit (sin i < 1e-6)");
  }
  const double ci2 = ci * ci, ci4 = ci2 * ci2, ci6 = ci4 * ci2;
  const double s2 = 1.0 - ci2;  // sin^2 i
  const double crit = 1.0 - 5.0 * ci2;
  if (std::abs(crit) < 1e-3) {
    throw std::invalid_argument("osculating_from_mean: too close to the critical inclination");
  }
  const double w = e > 0.0 ? std::atan2(mean.ey, mean.ex) : 0.0;  // argp (0 for e = 0)
  const double M = mean.u_rad - w;
  const double f = astro::true_from_mean_anomaly(M, e);
  const double eoc = wrap_pi(f - M) + e * std::sin(f);  // f - M + e sin f

  const double e2 = e * e;
  const double eta = std::sqrt(1.0 - e2);
  const double eta2 = eta * eta, eta3 = eta2 * eta, eta6 = eta3 * eta3;
  const double g2 = 0.5 * c.j2 * (c.radius_m / a) * (c.radius_m / a);  // (F.1)
  const double g2p = g2 / (eta2 * eta2);                               // (F.3)
  const double ar = (1.0 + e * std::cos(f)) / eta2;                    // a/r (F.6)
  const double ar3 = ar * ar * ar;
  const double cf = std::cos(f);
  const double c2w = std::cos(2.0 * w), s2w = std::sin(2.0 * w);
  const double c2wf = std::cos(2.0 * w + f), s2wf = std::sin(2.0 * w + f);
  const double c2w2f = std::cos(2.0 * w + 2.0 * f), s2w2f = std::sin(2.0 * w + 2.0 * f);
  const double c2w3f = std::cos(2.0 * w + 3.0 * f), s2w3f = std::sin(2.0 * w + 3.0 * f);
  const double lp = 1.0 - 11.0 * ci2 - 40.0 * ci4 / crit;  // long-period factor

  // (F.7) semi-major axis.
  const double a_osc =
      a + a * g2 * ((3.0 * ci2 - 1.0) * (ar3 - 1.0 / eta3) + 3.0 * s2 * ar3 * c2w2f);
  // (F.8), (F.9) eccentricity.
  const double de1 = g2p / 8.0 * e * eta2 * lp * c2w;
  const double cubic = 3.0 * cf + 3.0 * e * cf * cf + e2 * cf * cf * cf;
  const double de =
      de1 + 0.5 * eta2 *
                (g2 * ((3.0 * ci2 - 1.0) / eta6 * (e * eta + e / (1.0 + eta) + cubic) +
                       3.0 * s2 / eta6 * (e + cubic) * c2w2f) -
                 g2p * s2 * (3.0 * c2wf + c2w3f));
  // (F.10) inclination (e de1 / tan i written with sin i in the denominator).
  const double di = -e * de1 * ci / (eta2 * si) +
                    0.5 * g2p * ci * si * (3.0 * c2w2f + 3.0 * e * c2wf + e * c2w3f);
  // (F.13) RAAN.
  const double long_node = 11.0 + 80.0 * ci2 / crit + 200.0 * ci4 / (crit * crit);
  const double sp = 3.0 * s2w2f + 3.0 * e * s2wf + e * s2w3f;
  const double dOmega = -g2p / 8.0 * e2 * ci * long_node * s2w - 0.5 * g2p * ci * (6.0 * eoc - sp);
  // (F.11) the correction to M + argp + RAAN (its last two terms equal dOmega).
  const double dL = g2p / 8.0 * eta3 * lp * s2w -
                    g2p / 16.0 *
                        (2.0 + e2 - 11.0 * (2.0 + 3.0 * e2) * ci2 -
                         40.0 * (2.0 + 5.0 * e2) * ci4 / crit - 400.0 * e2 * ci6 / (crit * crit)) *
                        s2w +
                    0.25 * g2p * (-6.0 * crit * eoc + (3.0 - 5.0 * ci2) * sp) + dOmega;
  // (F.12) e dM.
  const double are2 = ar * eta * ar * eta;
  const double edM = g2p / 8.0 * e * eta3 * lp * s2w -
                     0.25 * g2p * eta3 *
                         (2.0 * (3.0 * ci2 - 1.0) * (are2 + ar + 1.0) * std::sin(f) +
                          3.0 * s2 * ((-are2 - ar + 1.0) * s2wf + (are2 + ar + 1.0 / 3.0) * s2w3f));

  // Lyddane's nonsingular recombination (F.14)-(F.21).
  const double sM = std::sin(M), cM = std::cos(M);
  const double d1 = (e + de) * sM + edM * cM;  // e' sin M'
  const double d2 = (e + de) * cM - edM * sM;  // e' cos M'
  const double sh = std::sin(0.5 * i), ch = std::cos(0.5 * i);
  const double sO = std::sin(mean.raan_rad), cO = std::cos(mean.raan_rad);
  const double d3 = (sh + ch * di / 2.0) * sO + sh * dOmega * cO;
  const double d4 = (sh + ch * di / 2.0) * cO - sh * dOmega * sO;

  QnsElements osc;
  osc.a_m = a_osc;
  osc.raan_rad = mean.raan_rad + wrap_pi(std::atan2(d3, d4) - mean.raan_rad);
  osc.i_rad = 2.0 * std::asin(std::min(1.0, std::hypot(d3, d4)));
  // u' = (M' + argp' + RAAN') - RAAN' (F.22); the eccentricity vector
  // e' (cos argp', sin argp') with argp' = u' - M' follows from d1, d2 without
  // forming M' or argp' (regular at e = 0).
  osc.u_rad = mean.u_rad + dL - (osc.raan_rad - mean.raan_rad);
  const double cu = std::cos(osc.u_rad), su = std::sin(osc.u_rad);
  osc.ex = d2 * cu + d1 * su;
  osc.ey = d2 * su - d1 * cu;
  return osc;
}

QnsElements mean_from_osculating(const QnsElements& osc, const J2Constants& c) {
  check_mean_elements(osc, "mean_from_osculating");
  // Fixed point of mean = mean + (osc - osculating_from_mean(mean)), starting
  // from mean = osc; the map contracts by O(J2 (R/a)^2).
  QnsElements mean = osc;
  double step = 0.0;
  for (int it = 0; it < 50; ++it) {
    const QnsElements o = osculating_from_mean(mean, c);
    const double da = osc.a_m - o.a_m;
    const double dex = osc.ex - o.ex;
    const double dey = osc.ey - o.ey;
    const double di = osc.i_rad - o.i_rad;
    const double dO = wrap_pi(osc.raan_rad - o.raan_rad);
    const double du = wrap_pi(osc.u_rad - o.u_rad);
    mean.a_m += da;
    mean.ex += dex;
    mean.ey += dey;
    mean.i_rad += di;
    mean.raan_rad += dO;
    mean.u_rad += du;
    step = std::max({std::abs(da) / osc.a_m, std::abs(dex), std::abs(dey), std::abs(di),
                     std::abs(dO), std::abs(du)});
    if (step < 1e-14) break;
  }
  if (!(step < 1e-11)) {
    throw std::runtime_error("mean_from_osculating: fixed-point iteration did not converge");
  }
  mean.raan_rad = wrap_pi(mean.raan_rad);
  mean.u_rad = wrap_pi(mean.u_rad);
  return mean;
}

}  // namespace artms::dynamics
