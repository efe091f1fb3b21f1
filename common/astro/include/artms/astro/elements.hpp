// Orbit elements: Keplerian, quasi-nonsingular (paper eq. 3), conversions to
// and from Cartesian ECI states. Angles in radians, lengths in meters.
#pragma once

#include "artms/astro/constants.hpp"
#include "artms/astro/frames.hpp"

namespace artms::astro {

// Classical Keplerian elements, elliptical orbits only (0 <= e < 1).
// Conventions for the singular cases (docs/conventions.md):
//  - equatorial (sin i ~ 0): raan_rad = 0, the node line is the x axis;
//  - circular (e ~ 0): argp_rad = 0, anomalies are measured from the node.
struct KeplerElements {
  double a_m = 0.0;
  double e = 0.0;
  double i_rad = 0.0;
  double raan_rad = 0.0;
  double argp_rad = 0.0;
  double M_rad = 0.0;  // mean anomaly
};

// Quasi-nonsingular elements alpha = [a, ex, ey, i, RAAN, u] with
// ex = e cos(argp), ey = e sin(argp), u = argp + M (paper eq. 3).
struct QnsElements {
  double a_m = 0.0;
  double ex = 0.0;
  double ey = 0.0;
  double i_rad = 0.0;
  double raan_rad = 0.0;
  double u_rad = 0.0;  // mean argument of latitude
  [[nodiscard]] Vec6 as_vector() const;
  static QnsElements from_vector(const Vec6& v);
};

// Kepler's equation M = E - e sin E by Newton iteration to 1e-15 rad.
// Returns E in the same revolution as M. Requires 0 <= e < 1.
double eccentric_from_mean_anomaly(double M_rad, double e);
double mean_from_eccentric_anomaly(double E_rad, double e);
double true_from_eccentric_anomaly(double E_rad, double e);
double eccentric_from_true_anomaly(double nu_rad, double e);
double true_from_mean_anomaly(double M_rad, double e);
double mean_from_true_anomaly(double nu_rad, double e);

// Wraps an angle to [0, 2pi) and to (-pi, pi].
double wrap_two_pi(double angle_rad);
double wrap_pi(double angle_rad);

double mean_motion_radps(double a_m, double gm_m3ps2 = kGmEarth_m3ps2);
double orbit_period_s(double a_m, double gm_m3ps2 = kGmEarth_m3ps2);

// Keplerian <-> Cartesian (two-body). Throw std::invalid_argument for
// hyperbolic/parabolic states, e outside [0, 1) or a <= 0.
StateVector cartesian_from_kepler(const KeplerElements& oe, double gm_m3ps2 = kGmEarth_m3ps2);
KeplerElements kepler_from_cartesian(const StateVector& x_eci,
                                     double gm_m3ps2 = kGmEarth_m3ps2);

// Quasi-nonsingular <-> Keplerian (exact; argp = 0 when e = 0) and Cartesian.
QnsElements qns_from_kepler(const KeplerElements& oe);
KeplerElements kepler_from_qns(const QnsElements& oe);
StateVector cartesian_from_qns(const QnsElements& oe, double gm_m3ps2 = kGmEarth_m3ps2);
QnsElements qns_from_cartesian(const StateVector& x_eci, double gm_m3ps2 = kGmEarth_m3ps2);
// d qns / d (r, v) by central differences (1 m, 1 mm/s steps; the RAAN and u
// differences wrapped to (-pi, pi]): maps a GNSS fix's covariance onto the
// elements.
Mat6 jacobian_qns_from_cartesian(const StateVector& x_eci, double gm_m3ps2 = kGmEarth_m3ps2);

}  // namespace artms::astro
