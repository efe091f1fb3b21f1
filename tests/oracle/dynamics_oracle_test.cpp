// Issue 3, acceptance point 2: J2-only propagation of Starling SV4 (Table 2,
// PSE) for one day against poliastro's Cowell propagation with the same GM,
// radius and J2: agreement to 1 m.
#include <cstdlib>
#include <filesystem>

#include "artms/astro/elements.hpp"
#include "artms/testing/testing.hpp"
#include "artms/truth_propagator/cowell.hpp"

namespace artms::truth {
namespace {

constexpr double kPosTol_m = 1.0;
constexpr double kVelTol_mps = 1e-3;

TEST(OracleDynamics, Sv4J2OneDayMatchesPoliastro) {
  const char* dir = std::getenv("ARTMS_ORACLE_DIR");
  const std::string path = std::string(dir ? dir : ".") + "/sv4_j2_poliastro.json";
  if (!std::filesystem::exists(path)) {
    GTEST_SKIP() << "oracle cases missing: the poliastro generator did not run (see "
                    "oracle.dynamics.generate)";
  }
  const auto j = artms::testing::load_json(path);
  using astro::kDegToRad;
  const astro::QnsElements sv4{6943e3, 0.0001, 0.0016, 99.4 * kDegToRad, -38.0 * kDegToRad,
                               -153.0 * kDegToRad};
  const StateVector x0 = astro::cartesian_from_qns(sv4);
  // Same element conventions on both sides: the initial states agree.
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(x0.r_m[k], j["initial_r_km"][k].get<double>() * 1e3, 1e-6);
    EXPECT_NEAR(x0.v_mps[k], j["initial_v_kms"][k].get<double>() * 1e3, 1e-9);
  }
  const ForceModel forces =
      ForceModel::load(dynamics::ForceModelOptions::parse("j2"), ARTMS_DATA_DIR);
  const TimeTT t0 = astro::tt_from_utc_string(j["epoch_utc"].get<std::string>());
  CowellPropagator prop(forces, {}, t0, x0);
  double worst_r = 0.0, worst_v = 0.0;
  for (const auto& c : j["cases"]) {
    const StateVector x = prop.state_at(t0.plus_seconds(c["t_s"].get<double>()));
    astro::Vec3 r, v;
    for (int k = 0; k < 3; ++k) {
      r[k] = c["r_km"][k].get<double>() * 1e3;
      v[k] = c["v_kms"][k].get<double>() * 1e3;
    }
    worst_r = std::max(worst_r, (x.r_m - r).norm());
    worst_v = std::max(worst_v, (x.v_mps - v).norm());
  }
  std::printf("[oracle-j2] SV4 J2 1 day vs poliastro Cowell: max |dr| = %.4f m, max |dv| = %.3e m/s\n",
              worst_r, worst_v);
  EXPECT_LT(worst_r, kPosTol_m);
  EXPECT_LT(worst_v, kVelTol_mps);
}

}  // namespace
}  // namespace artms::truth
