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
Mat6 roe_stm_j2(const QnsElements& chief_mean, double dt_s, const J2Constants& c = {});

// First-order J2 osculating <-> mean conversion (Brouwer-Lyddane short- and
// long-period terms to first order in J2, in a form regular for e -> 0, as in
// Schaub & Junkins, Analytical Mechanics of Space Systems, Appendix F).
// mean_from_osculating inverts osculating_from_mean by fixed-point iteration.
QnsElements osculating_from_mean(const QnsElements& mean, const J2Constants& c = {});
QnsElements mean_from_osculating(const QnsElements& osc, const J2Constants& c = {});

}  // namespace artms::dynamics
