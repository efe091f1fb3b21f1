// Layout of the SOD state vector (paper, "System State" and "Sequential Orbit
// Determination"):
//   x = [ alpha_o (6) | droe_1 (6) | ... | droe_N (6) | aux (n_aux) ]
// alpha_o: the observer's osculating quasi-nonsingular elements in the order of
//          astro::QnsElements::as_vector(): [a (m), ex, ey, i, RAAN, u (rad)].
// droe_k:  target k's osculating ROE (paper eq. 4), DIMENSIONLESS, in the
//          order of astro::Roe: [da, dlambda, dex, dey, dix, diy]. Multiply by
//          the observer's a for the "a*droe" meters of docs/conventions.md.
// aux:     auxiliary states appended last (paper, "System State"), in this
//          order: n_aux generic states (constant, random walk); the observer's
//          camera time-tag offset (s) and, with n_time_tag = 2, its drift
//          (s/s); with `ballistic`, one differential ballistic coefficient
//          per target (m^2/kg, the target's Cd A/m minus the onboard nominal);
//          then n_remote_clock time-tag offsets (s), one per remote observer
//          whose bearings arrive over the ISL (its camera's clock as this
//          filter sees it).
// The observer block comes first so that the lower-triangular Cholesky factor
// leaves the observer untouched by every sigma point built from a target
// column (Stacey & D'Amico 2018): see SodFilter::time_update.
#pragma once

#include <cassert>

namespace artms::sod {

struct StateLayout {
  int n_targets = 0;
  int n_aux = 0;
  int n_time_tag = 0;      // 0: none, 1: offset, 2: offset and drift
  bool ballistic = false;  // one differential ballistic coefficient per target
  int n_remote_clock = 0;  // time-tag offsets of remote observers' cameras

  static constexpr int kBlock = 6;
  // Observer element indices inside its block (QnsElements::as_vector order).
  static constexpr int kA = 0, kEx = 1, kEy = 2, kI = 3, kRaan = 4, kU = 5;
  // ROE indices inside a target block (astro::Roe order).
  static constexpr int kDa = 0, kDlambda = 1, kDex = 2, kDey = 3, kDix = 4, kDiy = 5;

  [[nodiscard]] static constexpr int observer_offset() { return 0; }
  [[nodiscard]] constexpr int target_offset(int k) const {
    assert(k >= 0 && k < n_targets);
    return kBlock * (1 + k);
  }
  [[nodiscard]] constexpr int aux_offset() const { return kBlock * (1 + n_targets); }
  [[nodiscard]] constexpr int time_tag_offset() const { return aux_offset() + n_aux; }
  [[nodiscard]] constexpr int time_tag_drift() const { return time_tag_offset() + 1; }
  [[nodiscard]] constexpr int ballistic_offset() const { return time_tag_offset() + n_time_tag; }
  [[nodiscard]] constexpr int ballistic_index(int k) const {
    assert(ballistic && k >= 0 && k < n_targets);
    return ballistic_offset() + k;
  }
  [[nodiscard]] constexpr int remote_clock_offset() const { return ballistic_offset() + (ballistic ? n_targets : 0); }
  [[nodiscard]] constexpr int remote_clock_index(int j) const {
    assert(j >= 0 && j < n_remote_clock);
    return remote_clock_offset() + j;
  }
  [[nodiscard]] constexpr int size() const { return remote_clock_offset() + n_remote_clock; }
  // True for the components that are angles whose differences are wrapped to
  // (-pi, pi]: RAAN and u of the observer, dlambda of every target.
  [[nodiscard]] constexpr bool is_angle(int index) const {
    if (index == kRaan || index == kU) return true;
    if (index >= kBlock && index < aux_offset()) return (index - kBlock) % kBlock == kDlambda;
    return false;
  }
};

}  // namespace artms::sod
