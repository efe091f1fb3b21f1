// Issue 3, acceptance point 2: J2-only propagation of Starling SV4 (Table 2,
// PSE) for one day against poliastro's Cowell propagation with the same GM,
// radius and J2: agreement to 1 m.
#include <cstdlib>
#include <filesystem>

#include "artms/astro/elements.hpp"
#include "artms/dynamics/ephemeris.hpp"
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

// The Earth's barycentric velocity for stellar aberration against ERFA's
// epv00: the low-precision Sun leaves out the Sun's barycentric motion and
// the Earth's about the Earth-Moon barycentre (~25 m/s together) and the
// perihelion's motion (0.33 deg a century): 91 m/s at most in 1990-2040.
TEST(OracleDynamics, EarthVelocityMatchesErfaEpv00) {
  const char* dir = std::getenv("ARTMS_ORACLE_DIR");
  const std::string path = std::string(dir ? dir : ".") + "/erfa_earth_velocity_cases.json";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "ERFA epv00 cases missing: the generator did not run";
  const nlohmann::json j = artms::testing::load_json(path);
  double worst = 0.0;
  for (const auto& c : j["cases"]) {
    const astro::TimeTT t{static_cast<std::int64_t>(std::llround(c["tt_s_since_j2000"].get<double>() * 1e9))};
    astro::Vec3 v;
    for (int k = 0; k < 3; ++k) v[k] = c["v_mps"][k].get<double>();
    worst = std::max(worst, (dynamics::earth_velocity_bcrs_mps(t) - v).norm());
  }
  std::printf("[oracle-erfa] Earth barycentric velocity vs epv00: %zu dates, max |dv| = %.1f m/s "
              "(%.3f arcsec of aberration)\n",
              j["cases"].size(), worst, worst / 299792458.0 * 206264.806);
  EXPECT_LT(worst, 100.0);
}

}  // namespace
}  // namespace artms::truth
