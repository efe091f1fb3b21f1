// SOD: one UKF time update over 60 s plus one bearing measurement update with
// 3 targets (n = 24 states, 49 sigma points), with the flight force model
// (10x10 GGM01S, Harris-Priester drag, Sun, Moon; 30 s RK4) and with J2 only.
// Report: the median of the repetitions.
#include <benchmark/benchmark.h>

#include <string>

#include "artms/sod/sod_filter.hpp"

namespace {

using namespace artms;

void BM_SodTimeAndBearingUpdate3Targets(benchmark::State& state, const std::string& force_spec) {
  const auto forces = dynamics::ForceModel::load(dynamics::ForceModelOptions::parse(force_spec),
                                                 ARTMS_DATA_DIR);
  const sod::StateLayout layout{3, 0};
  sod::SodFilter filter(forces, {}, {}, layout);
  const astro::QnsElements obs{astro::kRadiusEarth_m + 500e3, 2e-4, 9e-4,
                               97.6 * astro::kDegToRad, 0.5, 0.3};
  const double a = obs.a_m;
  const std::vector<astro::Roe> roe = {
      astro::Roe::from_scaled_m((astro::Vec6() << 2, -50e3, 300, -200, 250, 400).finished(), a),
      astro::Roe::from_scaled_m((astro::Vec6() << -3, 80e3, -400, 250, -300, 350).finished(), a),
      astro::Roe::from_scaled_m((astro::Vec6() << 1, 30e3, 200, 300, 200, -250).finished(), a)};
  Eigen::VectorXd sigma(layout.size());
  sigma.head<6>() << 10.0, 1e-5, 1e-5, 5e-6, 5e-6, 3e-6;
  for (int k = 0; k < 3; ++k) {
    sigma.segment<6>(layout.target_offset(k)) = astro::Vec6::Constant(100.0 / a);
    sigma[layout.target_offset(k) + 1] = 2000.0 / a;
  }
  astro::TimeTT t = astro::tt_from_utc_string("2024-05-08T00:00:00Z");
  filter.initialize(t, filter.make_state(obs, roe), sigma.cwiseAbs2().asDiagonal());
  int k = 0;
  for (auto _ : state) {
    t = t.plus_seconds(60.0);
    const auto tu = filter.time_update(t);
    // Measurement from the current estimate (the update still runs in full).
    state.PauseTiming();
    sod::BearingMeasurement m;
    m.t = t;
    m.target = k;
    const auto xo = astro::cartesian_from_qns(filter.observer(), forces.gm_m3ps2());
    const auto xt = astro::cartesian_from_qns(astro::qns_from_roe(filter.observer(), filter.roe(k)),
                                              forces.gm_m3ps2());
    m.R_v_from_eci = astro::R_v_from_eci(xo, astro::Boresight::kMinusVelocity);
    m.angles = astro::bearing_from_eci(xo.r_m, xt.r_m, m.R_v_from_eci);
    m.sigma_az_rad = m.sigma_el_rad = 30.0 * astro::kArcsecToRad;
    state.ResumeTiming();
    const auto mu = filter.update_bearing(m);
    if (!tu.usable || !mu.usable) state.SkipWithError("SOD update not usable");
    k = (k + 1) % 3;
  }
}
BENCHMARK_CAPTURE(BM_SodTimeAndBearingUpdate3Targets, flight_grav10_drag_sun_moon,
                  std::string("grav10,drag,sun,moon"))
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(7)
    ->ReportAggregatesOnly(true);
BENCHMARK_CAPTURE(BM_SodTimeAndBearingUpdate3Targets, j2, std::string("j2"))
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(7)
    ->ReportAggregatesOnly(true);

}  // namespace

BENCHMARK_MAIN();
