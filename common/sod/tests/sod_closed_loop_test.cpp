// Closed-loop tests of the SOD UKF: truth -> bearings + GNSS -> filter ->
// compare with truth (STYLE.md, "Tests close the loop").
#include <gtest/gtest.h>

#include <cstdio>
#include <sstream>

#include "artms/sod/sod_filter.hpp"
#include "artms/testing/testing.hpp"
#include "sod_scenario.hpp"

namespace artms::sod {
namespace {

using testing::InitialGuess;
using testing::Truth;

constexpr double kStep_s = 60.0;

struct RunResult {
  std::vector<Vec6> err_a_roe_m, sigma_a_roe_m;
  Vec6 err_obs, sigma_obs;
  double mean_nees = 0.0;
  int nees_samples = 0;
  int rejected = 0;
  bool health_ok = true;
};

RunResult run(int orbits, double bearing_sigma_rad, double bearing_noise_rad, double gnss_sigma_r,
              double gnss_sigma_v, bool noisy, std::uint64_t seed, int n_targets,
              SodOptions options = {}) {
  const TimeTT t0 = astro::tt_from_utc_string("2024-05-08T00:00:00Z");
  const astro::QnsElements obs0 = testing::observer_at_start();
  std::vector<Vec6> a_roe = testing::starling_a_roe_m();
  a_roe.resize(n_targets);
  Truth truth(t0, obs0, a_roe);
  SodFilter filter(testing::j2_forces(), dynamics::SpacecraftProperties{},
                   dynamics::SpacecraftProperties{}, StateLayout{n_targets, 0}, options);
  const InitialGuess g = testing::shifted_initial_guess(obs0, a_roe, 0.05, 100.0);
  filter.initialize(t0, g.x, g.P);
  std::mt19937_64 rng(seed);
  const int steps = static_cast<int>(orbits * astro::orbit_period_s(obs0.a_m) / kStep_s);
  RunResult r;
  double nees_sum = 0.0;
  for (int s = 1; s <= steps; ++s) {
    truth.advance_to(t0.plus_seconds(kStep_s * s));
    const TimeUpdateSummary tu = filter.time_update(truth.t());
    EXPECT_TRUE(tu.usable) << tu.why;
    const UpdateSummary ug = filter.update_gnss(truth.gnss(gnss_sigma_r, gnss_sigma_v, noisy, &rng));
    EXPECT_TRUE(ug.usable) << ug.brief_report();
    for (int k = 0; k < n_targets; ++k) {
      const UpdateSummary ub = filter.update_bearing(
          truth.bearing(k, bearing_sigma_rad, noisy ? bearing_noise_rad : 0.0, &rng));
      EXPECT_TRUE(ub.usable) << "step " << s << " " << ub.brief_report();
    }
    if (s > steps / 2) {
      nees_sum += filter.nees(truth.state());
      ++r.nees_samples;
    }
    if (!filter.health().healthy()) r.health_ok = false;
  }
  r.mean_nees = nees_sum / r.nees_samples;
  for (int k = 0; k < n_targets; ++k) {
    r.err_a_roe_m.push_back(filter.a_roe_m(k) - truth.a_roe_m(k));
    r.sigma_a_roe_m.push_back(filter.a_roe_sigma_m(k));
  }
  r.err_obs = filter.state_difference(filter.state(), truth.state()).head<6>();
  r.sigma_obs = filter.covariance().diagonal().head<6>().cwiseSqrt();
  r.rejected = filter.rejected_total();
  return r;
}

void print(const char* name, const RunResult& r) {
  for (std::size_t k = 0; k < r.err_a_roe_m.size(); ++k) {
    std::printf("%s target %zu a*ROE error (m): %s\n", name, k,
                (std::ostringstream() << r.err_a_roe_m[k].transpose()).str().c_str());
    std::printf("%s target %zu a*ROE sigma (m): %s\n", name, k,
                (std::ostringstream() << r.sigma_a_roe_m[k].transpose()).str().c_str());
  }
  std::printf("%s observer error: %s\n", name,
              (std::ostringstream() << r.err_obs.transpose()).str().c_str());
  std::printf("%s mean NEES (second half): %.2f over %d samples\n", name, r.mean_nees,
              r.nees_samples);
}

// Noise-free, 10 orbits: perfect bearings every 60 s and perfect GNSS, started
// with a*dlambda 5 % off and the other a*ROE 100 m off (Orekit's testShiftedPV).
TEST(SodClosedLoop, NoiseFreeConvergesToTruthFromShiftedStart) {
  constexpr double kRangeFrac = 0.005;  // a*dlambda within 0.5 % of range
  constexpr double kOtherRoeTol_m = 5.0;
  constexpr double kObsATol_m = 0.5;
  const std::vector<double> range_m = {50e3, 80e3};
  const RunResult r = run(10, 5.0 * astro::kArcsecToRad, 0.0, 2.0, 0.01, false, 1, 2);
  print("noise-free", r);
  for (int k = 0; k < 2; ++k) {
    EXPECT_LT(std::abs(r.err_a_roe_m[k][1]), kRangeFrac * range_m[k]) << "target " << k;
    for (int i : {0, 2, 3, 4, 5})
      EXPECT_LT(std::abs(r.err_a_roe_m[k][i]), kOtherRoeTol_m) << "target " << k << " roe " << i;
  }
  EXPECT_LT(std::abs(r.err_obs[0]), kObsATol_m);
  EXPECT_EQ(r.rejected, 0);
  EXPECT_TRUE(r.health_ok);
}

// Noisy (seeded): 30 arcsec bearings, 3 m / 1 cm/s GNSS. Final errors within
// 3 sigma and the mean NEES of the second half inside a loose chi-square band.
TEST(SodClosedLoop, NoisyErrorsWithinThreeSigmaAndNeesConsistent) {
  const double sigma = 30.0 * astro::kArcsecToRad;
  const RunResult r = run(8, sigma, sigma, 3.0, 0.01, true, 20240508, 2);
  print("noisy", r);
  for (int k = 0; k < 2; ++k)
    for (int i = 0; i < 6; ++i)
      EXPECT_LT(std::abs(r.err_a_roe_m[k][i]), 3.0 * r.sigma_a_roe_m[k][i])
          << "target " << k << " roe " << i;
  for (int i = 0; i < 6; ++i) EXPECT_LT(std::abs(r.err_obs[i]), 3.0 * r.sigma_obs[i]) << i;
  // n = 18. Chi-square(18) 0.1 % and 99.9 % quantiles (5.9, 42.3): a loose band
  // for a time average of correlated samples from one run.
  EXPECT_GT(r.mean_nees, 5.9);
  EXPECT_LT(r.mean_nees, 42.3);
}

}  // namespace
}  // namespace artms::sod
