// Ground a-priori of a target's ROE whose ground orbit solution is `age`
// days old (docs/sod.md, "A-priori error model"). Errors in a_o * ROE meters.
//
// Errors at the epoch of the ground solution are independent and zero-mean;
// afterwards the relative semi-major axis error drifts with an uncertain
// differential drag rate and the mean-argument-of-latitude error integrates
// it (Keplerian drift d(dlambda)/dt = -1.5 n da, D'Amico 2010):
//   da(t)      = da0 + dadot t
//   dlambda(t) = dlambda0 - 1.5 n (da0 t + dadot t^2 / 2)
//   de(t), di(t) = e0, i0 + random-walk-like growth (rate * t)
// so sigma_dlambda ~ 1.5 n sigma_da0 t dominates after a few hours.
#pragma once

#include <random>

#include "artms/astro/elements.hpp"
#include "artms/astro/frames.hpp"

namespace artms::sod {

struct AprioriErrorModel {
  // 1-sigma at the epoch of the ground solution, a_o * ROE meters. 15 m of
  // a*da is da ~ 2e-6 (ground OD from GNSS telemetry: 1e-6..1e-5).
  double sigma_a_da0_m = 15.0;
  double sigma_a_dlambda0_m = 100.0;
  double sigma_a_de0_m = 30.0;  // per component (dex, dey)
  double sigma_a_di0_m = 30.0;  // per component (dix, diy)
  // Growth per day: a*da from differential drag (~10 % of ~35 m/day decay of
  // a 6U CubeSat at 500 km), de and di from unmodelled J2/drag differences.
  double sigma_a_da_rate_mpd = 3.0;
  double sigma_a_de_rate_mpd = 2.0;
  double sigma_a_di_rate_mpd = 1.0;
  // Throws std::invalid_argument naming the field (all must be >= 0, finite).
  void validate() const;
};

struct AprioriRoe {
  astro::Vec6 sigma_a_roe_m = astro::Vec6::Zero();  // sqrt(diag(P_a_roe_m2))
  astro::Mat6 P_a_roe_m2 = astro::Mat6::Zero();     // includes the da-dlambda correlation
  astro::Mat6 P_roe = astro::Mat6::Zero();          // dimensionless (divided by a_o^2)
};

// Throws std::invalid_argument for age_days < 0, a_observer_m <= 0 or a bad model.
AprioriRoe apriori_from_age(double age_days, double a_observer_m,
                            const AprioriErrorModel& model = {});

// One draw of the a-priori error (a_o * ROE meters) from N(0, P_a_roe_m2).
astro::Vec6 draw_apriori_error_a_roe_m(const AprioriRoe& apriori, std::mt19937_64& rng);

// An uplinked a-priori (dimensionless ROE and covariance at its epoch)
// carried dt_s later with the Keplerian relative drift
// d(dlambda)/dt = -1.5 n da (D'Amico 2010), n from the observer's a:
// what the observer starts from, and re-initialises from.
astro::Vec6 apriori_roe_drifted(const astro::Vec6& roe, double a_observer_m, double dt_s);
astro::Mat6 apriori_covariance_drifted(const astro::Mat6& P_roe, double a_observer_m, double dt_s);
// The same carried with the J2 state transition matrix of mean ROE (Koenig,
// Guffanti & D'Amico 2017; dynamics::roe_stm_j2) for the observer's mean
// elements: besides the along-track drift, the relative eccentricity vector
// turns at the argument of perigee's rate (~1.6 m per hour for the
// Starling PSE's 700 m) and diy drifts with dix. The uplinked osculating ROE
// keep the short-period J2 part of their epoch.
astro::Vec6 apriori_roe_drifted(const astro::Vec6& roe, const astro::QnsElements& observer_mean, double dt_s);
astro::Mat6 apriori_covariance_drifted(const astro::Mat6& P_roe, const astro::QnsElements& observer_mean, double dt_s);
// What the navigator starts and re-initialises from: the J2 drift above for
// the observer's mean elements (dynamics::mean_from_osculating of
// observer_osc; its osculating elements where the mean model refuses them),
// the uplinked values themselves at dt_s = 0.
astro::Vec6 apriori_roe_at(const astro::Vec6& roe, const astro::QnsElements& observer_osc, double dt_s);
astro::Mat6 apriori_covariance_at(const astro::Mat6& P_roe, const astro::QnsElements& observer_osc, double dt_s);

// Navigation mode 4's coarse ground orbit (paper, "Absolute Navigation":
// "artificially degraded orbit knowledge"): its error is the quasi-nonsingular
// ROE of the true orbit relative to the uplinked one, 1-sigma sigma_a_roe_m
// (times a, m), independent per component.
struct CoarseOrbit {
  astro::StateVector x_eci;  // the uplinked (degraded) orbit
  astro::Mat6 P_rv = astro::Mat6::Zero();
  astro::Vec6 error_a_roe_m = astro::Vec6::Zero();  // the drawn error (truth relative to x_eci), for the record
};
// The covariance in ECI position/velocity of an orbit x_eci whose error has
// the 1-sigma sigma_a_roe_m (first order: the Jacobian of the orbit displaced
// by a ROE, central differences). Throws std::invalid_argument for a
// non-positive or non-finite sigma.
astro::Mat6 coarse_orbit_covariance_rv(const astro::StateVector& x_eci, const astro::Vec6& sigma_a_roe_m);
// One draw: the true orbit displaced by minus an error drawn from
// N(0, diag(sigma_a_roe_m^2)) / a, with the covariance above.
CoarseOrbit draw_coarse_orbit(const astro::StateVector& truth_eci, const astro::Vec6& sigma_a_roe_m,
                              std::mt19937_64& rng);
// The same with a given error (a * ROE of truth relative to the result, m).
CoarseOrbit coarse_orbit_with_error(const astro::StateVector& truth_eci, const astro::Vec6& sigma_a_roe_m,
                                    const astro::Vec6& error_a_roe_m);

}  // namespace artms::sod
