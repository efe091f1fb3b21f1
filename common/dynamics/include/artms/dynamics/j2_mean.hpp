// Analytic mean-element model with J2 (what ARTMS uses where speed matters:
// SAMUS tracking and BOD). Quasi-nonsingular elements and ROE as in
// common/astro (paper eqs. 3 and 4).
#pragma once

#include "artms/astro/constants.hpp"
#include "artms/astro/elements.hpp"
#include "artms/astro/roe.hpp"

namespace artms::dynamics {

using astro::Mat6;
using astro::QnsElements;
using astro::Roe;

struct J2Constants {
  double gm_m3ps2 = astro::kGmEarth_m3ps2;
  double radius_m = astro::kRadiusEarth_m;
  double j2 = astro::kJ2Earth;
};

// Secular J2 rates of the mean elements (Brouwer first order):
// d(RAAN)/dt, d(argp)/dt, d(M)/dt in rad/s; a, e, i constant.
struct J2SecularRates {
  double raan_dot_radps;
  double argp_dot_radps;
  double mean_anomaly_dot_radps;  // includes the Keplerian mean motion
};
J2SecularRates j2_secular_rates(const QnsElements& mean, const J2Constants& c = {});

// Propagates mean QNS elements by dt_s under secular J2 (ex, ey rotate with
// argp_dot; u advances with argp_dot + M_dot).
QnsElements propagate_mean_j2(const QnsElements& mean, double dt_s, const J2Constants& c = {});

// State transition matrix of the mean quasi-nonsingular ROE under J2
// (Koenig, Guffanti, D'Amico 2017, JGCD 40(7), "New State Transition Matrices
// for Spacecraft Relative Motion in Perturbed Orbits", the J2 STM in
// quasi-nonsingular ROE, eq. (A6)/(A7) family), for chief mean elements at
// the start of the interval: roe(t0 + dt) = Phi * roe(t0).
// This is the published closed form valid for arbitrary eccentricity (their
// Appendix A, eq. A6). It is exactly the Jacobian, at roe = 0, of the map
// roe(t0) -> roe(t0 + dt) that propagate_mean_j2 induces on chief and deputy
// (the tests check this against central differences); see
// docs/j2_mean_model.md for the derivation. Valid for any e < 1 and any
// inclination (no singularity at the critical inclination or at e = 0).
Mat6 roe_stm_j2(const QnsElements& chief_mean, double dt_s, const J2Constants& c = {});

// Keplerian (J2-free) STM of the same ROE: identity plus the along-track drift
// d(dlambda) = -1.5 n da dt (the Keplerian STM of Koenig et al. 2017).
Mat6 roe_stm_kepler(const QnsElements& chief_mean, double dt_s,
                    double gm_m3ps2 = astro::kGmEarth_m3ps2);

// First-order J2 osculating <-> mean conversion (Brouwer-Lyddane short- and
// long-period terms to first order in J2, in a form regular for e -> 0, as in
// Schaub & Junkins, Analytical Mechanics of Space Systems, Appendix F).
// mean_from_osculating inverts osculating_from_mean by fixed-point iteration.
// "Osculating" means the two-body elements of the Cartesian state
// (qns_from_cartesian); "mean" means Brouwer mean elements, whose only J2
// variation is the secular drift of propagate_mean_j2.
// Implementation: Schaub & Junkins App. F, eqs. (F.1)-(F.22), evaluated with
// argp = atan2(ey, ex) (0 for e = 0) and returning ex, ey through Lyddane's
// d1, d2 (F.14)-(F.15), which keeps the result smooth in (ex, ey) through
// e = 0. osculating_from_mean returns RAAN and u on the same revolution as
// its input; mean_from_osculating wraps them to (-pi, pi].
// Limits of first-order Brouwer theory: throws std::invalid_argument for e
// outside [0, 1), a <= 0, near-equatorial orbits (sin i < 1e-6) and within
// ~0.05 deg of the critical inclination (|1 - 5 cos^2 i| < 1e-3), where the
// long-period terms are singular.
// mean_from_osculating throws std::runtime_error if the iteration does not
// converge (it converges by ~1e-3 per step for LEO, 1e-13 in ~5 steps).
QnsElements osculating_from_mean(const QnsElements& mean, const J2Constants& c = {});
QnsElements mean_from_osculating(const QnsElements& osc, const J2Constants& c = {});

}  // namespace artms::dynamics
