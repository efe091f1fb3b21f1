// BOD: one attempt (paper, "Batch Orbit Determination") with 100 dlambda
// samples over [2, 200] km and 150 bearings over 1.5 orbits of a target
// ~50 km ahead (5 arcsec noise), on one core. Target (issue 16): median
// <= 50 ms. The bearings come from the mean J2 model itself (the benchmark
// times the solver, not the world). BM_BodAttemptWithModelCorrection adds
// what runs on board since stop 33: the correction for the onboard 10x10
// model (two numerical propagations over the batch and a second solve near
// the first range; docs/bod.md "Model correction").
#include <benchmark/benchmark.h>

#include <random>

#include "artms/astro/bearing.hpp"
#include "artms/astro/constants.hpp"
#include "artms/bod/bod.hpp"

namespace {

using namespace artms;

void run_attempt(benchmark::State& state, const dynamics::ForceModel* onboard) {
  const astro::TimeTT t0 = astro::tt_from_utc_string("2024-05-08T00:00:00Z");
  const astro::QnsElements mean0{astro::kRadiusEarth_m + 500e3, 2e-4, 9e-4, 97.6 * astro::kDegToRad, 0.5, 0.3};
  const astro::Vec6 roe = (astro::Vec6() << 3.0, 50e3, 300.0, -200.0, 250.0, 400.0).finished() / mean0.a_m;
  const double span_s = 1.5 * astro::orbit_period_s(mean0.a_m);
  std::mt19937_64 rng(7);
  std::normal_distribution<double> n01;
  std::vector<bod::Measurement> batch;
  for (int j = 0; j < 150; ++j) {
    const double dt = span_s * j / 149.0;
    const auto o = dynamics::propagate_mean_j2(mean0, dt);
    const auto d = astro::qns_from_roe(o, astro::Roe::from_vector(dynamics::roe_stm_j2(mean0, dt) * roe));
    const auto xo = astro::cartesian_from_qns(dynamics::osculating_from_mean(o));
    const auto xd = astro::cartesian_from_qns(dynamics::osculating_from_mean(d));
    bod::Measurement m;
    m.t = t0.plus_seconds(dt);
    m.R_v_from_eci = astro::R_v_from_eci(xo, astro::Boresight::kPlusVelocity);
    astro::Bearing b = astro::bearing_from_los(m.R_v_from_eci * (xd.r_m - xo.r_m));
    b.az_rad += 5.0 * astro::kArcsecToRad * n01(rng);
    b.el_rad += 5.0 * astro::kArcsecToRad * n01(rng);
    m.u_eci = m.R_v_from_eci.transpose() * astro::unit_los_from_bearing(b);
    batch.push_back(m);
  }
  bod::ObserverPrior prior;
  prior.t_est = batch.back().t;
  prior.mean = dynamics::propagate_mean_j2(mean0, span_s);
  prior.P_prior = bod::Mat5::Identity() * 2e-12;
  bod::Options opt;
  opt.samples = 100;
  opt.max_measurements = 200;
  opt.onboard_forces = onboard;
  bod::Result r;
  for (auto _ : state) {
    r = bod::solve(batch, prior, opt);
    benchmark::DoNotOptimize(r);
  }
  state.counters["range_km"] = r.range_m / 1e3;
  state.counters["usable"] = r.usable() ? 1.0 : 0.0;
  int iterations = 0;
  for (const auto& s : r.curve) iterations += s.iterations;
  state.counters["iterations"] = iterations;
}

void BM_BodAttempt100Samples150Bearings(benchmark::State& state) { run_attempt(state, nullptr); }
BENCHMARK(BM_BodAttempt100Samples150Bearings)->Unit(benchmark::kMillisecond)->Repetitions(5)->ReportAggregatesOnly(true);

void BM_BodAttemptWithModelCorrection(benchmark::State& state) {
  static const dynamics::ForceModel onboard =
      dynamics::ForceModel::load(dynamics::ForceModelOptions::parse("grav10,drag,sun,moon"), ARTMS_DATA_DIR);
  run_attempt(state, &onboard);
}
BENCHMARK(BM_BodAttemptWithModelCorrection)->Unit(benchmark::kMillisecond)->Repetitions(5)->ReportAggregatesOnly(true);

}  // namespace

BENCHMARK_MAIN();
