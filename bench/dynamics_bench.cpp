// Issue 3, acceptance point 6: one 10x10 gravity evaluation, one GVE-RK4
// step, and 24 h of 4 spacecraft with 10x10 + drag + Sun/Moon through CVODE
// (target: under 0.5 s of CPU). Issue 17: the cost of the flight-like truth
// (gravity N x N, one force evaluation, 19 h of 3 spacecraft) against the
// paper's model, to choose its degree (docs/dynamics.md).
#include <benchmark/benchmark.h>

#include "artms/astro/elements.hpp"
#include "artms/dynamics/gve.hpp"
#include "artms/truth_propagator/cowell.hpp"

namespace {

using namespace artms;

astro::QnsElements sv4_pse() {
  using astro::kDegToRad;
  return {6943e3, 0.0001, 0.0016, 99.4 * kDegToRad, -38.0 * kDegToRad, -153.0 * kDegToRad};
}

void BM_Gravity10x10(benchmark::State& state) {
  const auto field = dynamics::GravityField::from_gfc(std::string(ARTMS_DATA_DIR) + "/gravity/GGM01S.gfc", 10);
  const dynamics::SphericalHarmonicGravity g(field, 10, 10);
  astro::Vec3 r(6.9e6, 1.2e6, 0.4e6);
  for (auto _ : state) {
    benchmark::DoNotOptimize(g.acceleration_ecef(r));
    r.x() += 1e-3;
  }
}
BENCHMARK(BM_Gravity10x10);

void BM_GravityNxN(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const auto field = dynamics::GravityField::from_gfc(std::string(ARTMS_DATA_DIR) + "/gravity/GGM01S.gfc", n);
  const dynamics::SphericalHarmonicGravity g(field, n, n);
  astro::Vec3 r(6.9e6, 1.2e6, 0.4e6);
  for (auto _ : state) {
    benchmark::DoNotOptimize(g.acceleration_ecef(r));
    r.x() += 1e-3;
  }
}
BENCHMARK(BM_GravityNxN)->Arg(10)->Arg(20)->Arg(30)->Arg(40);

// Arg 0: the paper's onboard model (10x10, Harris-Priester, Sun, Moon);
// N > 0: flight_like_truth() with gravity N x N.
dynamics::ForceModelOptions bench_options(int n) {
  if (n == 0) return dynamics::ForceModelOptions{};
  auto o = dynamics::ForceModelOptions::flight_like_truth();
  o.gravity_degree = o.gravity_order = n;
  return o;
}

void BM_ForceEvaluation(benchmark::State& state) {
  const auto forces = dynamics::ForceModel::load(bench_options(static_cast<int>(state.range(0))), ARTMS_DATA_DIR);
  astro::StateVector x = astro::cartesian_from_qns(sv4_pse());
  astro::TimeTT t = astro::tt_from_utc_string("2024-05-08T00:00:00Z");
  const dynamics::SpacecraftProperties sc;
  for (auto _ : state) {
    benchmark::DoNotOptimize(forces.acceleration_eci(t, x, sc));
    t = t.plus_seconds(1.0);
    x.r_m.x() += 1.0;
  }
}
BENCHMARK(BM_ForceEvaluation)->Arg(0)->Arg(10)->Arg(20)->Arg(30)->Arg(40);

// Truth runs as the scenarios fly them: n spacecraft ~70 km apart along
// track, states every 60 s (as the truth service publishes them) for `minutes`;
// CVODE's steps and force evaluations of the last iteration as counters.
void run_cowell(benchmark::State& state, const dynamics::ForceModel& forces, int n_spacecraft, int minutes) {
  const astro::TimeTT t0 = astro::tt_from_utc_string("2024-05-08T00:00:00Z");
  long steps = 0, evals = 0;
  for (auto _ : state) {
    std::vector<truth::CowellPropagator> props;
    for (int k = 0; k < n_spacecraft; ++k) {
      astro::QnsElements oe = sv4_pse();
      oe.u_rad += 0.01 * k;
      props.emplace_back(forces, dynamics::SpacecraftProperties{}, t0, astro::cartesian_from_qns(oe));
    }
    for (int s = 1; s <= minutes; ++s) {
      for (auto& p : props) benchmark::DoNotOptimize(p.state_at(t0.plus_seconds(60.0 * s)));
    }
    steps = evals = 0;
    for (auto& p : props) {
      steps += p.stats().steps;
      evals += p.stats().rhs_evaluations;
    }
  }
  state.counters["cvode_steps"] = static_cast<double>(steps);
  state.counters["force_evals"] = static_cast<double>(evals);
}

// 3 spacecraft, 19 h, with gravity of degree state.range(0).
void BM_Cowell3Spacecraft19h(benchmark::State& state) {
  const auto forces = dynamics::ForceModel::load(bench_options(static_cast<int>(state.range(0))), ARTMS_DATA_DIR);
  run_cowell(state, forces, 3, 19 * 60);
}
BENCHMARK(BM_Cowell3Spacecraft19h)->Arg(0)->Arg(10)->Arg(20)->Arg(30)->Arg(40)->Unit(benchmark::kMillisecond)->Iterations(3);

void BM_GveRk4Step(benchmark::State& state) {
  const auto forces = dynamics::ForceModel::load(
      dynamics::ForceModelOptions::parse("grav10,drag,sun,moon"), ARTMS_DATA_DIR);
  const dynamics::GveRk4Propagator prop(forces, dynamics::SpacecraftProperties{});
  astro::Vec6 y = sv4_pse().as_vector();
  astro::TimeTT t = astro::tt_from_utc_string("2024-05-08T00:00:00Z");
  for (auto _ : state) {
    y = prop.step(y, t, 30.0);
    t = t.plus_seconds(30.0);
  }
  benchmark::DoNotOptimize(y);
}
BENCHMARK(BM_GveRk4Step);

void BM_Cowell4Spacecraft24h(benchmark::State& state) {
  const auto forces = dynamics::ForceModel::load(
      dynamics::ForceModelOptions::parse("grav10,drag,sun,moon"), ARTMS_DATA_DIR);
  run_cowell(state, forces, 4, 1440);
}
BENCHMARK(BM_Cowell4Spacecraft24h)->Unit(benchmark::kMillisecond)->Iterations(3);

}  // namespace

BENCHMARK_MAIN();
