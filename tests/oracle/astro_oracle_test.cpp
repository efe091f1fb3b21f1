// Issue 2, acceptance point 2: Keplerian -> Cartesian against poliastro for
// 1000 random elliptical orbits (1 mm, 1 mm/s), round trips to 1e-9; and the
// Earth-rotation chain against ERFA (pmat76, gmst82).
#include <cstdlib>
#include <filesystem>
#include <string>

#include "artms/astro/aberration.hpp"
#include "artms/astro/elements.hpp"
#include "artms/astro/frames.hpp"
#include "artms/astro/time.hpp"
#include "artms/testing/testing.hpp"

namespace artms::astro {
namespace {

constexpr double kPosTol_m = 1e-3;
constexpr double kVelTol_mps = 1e-3;
constexpr double kRoundTripRelTol = 1e-9;

// Loads a generated oracle file or skips with the reason.
bool load_cases(const std::string& name, nlohmann::json& out) {
  const char* dir = std::getenv("ARTMS_ORACLE_DIR");
  const std::string path = std::string(dir ? dir : ".") + "/" + name;
  if (!std::filesystem::exists(path)) return false;
  out = artms::testing::load_json(path);
  return true;
}

TEST(OracleKepler, CartesianMatchesPoliastroAndRoundTrips) {
  nlohmann::json j;
  if (!load_cases("kepler_poliastro_cases.json", j)) {
    GTEST_SKIP() << "oracle cases missing: the poliastro generator did not run (see "
                    "oracle.astro.generate)";
  }
  const auto& cases = j["cases"];
  ASSERT_EQ(cases.size(), 1000u);
  double max_dr = 0, max_dv = 0, max_rt = 0;
  int circular = 0, equatorial = 0;
  for (const auto& c : cases) {
    KeplerElements oe;
    oe.a_m = c["a_km"].get<double>() * 1e3;
    oe.e = c["e"];
    oe.i_rad = c["i_rad"];
    oe.raan_rad = c["raan_rad"];
    oe.argp_rad = c["argp_rad"];
    oe.M_rad = mean_from_true_anomaly(c["nu_rad"].get<double>(), oe.e);
    circular += oe.e == 0.0;
    equatorial += std::sin(oe.i_rad) < 1e-12;
    const StateVector x = cartesian_from_kepler(oe);
    Vec3 r_ref, v_ref;
    for (int k = 0; k < 3; ++k) {
      r_ref[k] = c["r_km"][k].get<double>() * 1e3;
      v_ref[k] = c["v_kms"][k].get<double>() * 1e3;
    }
    const double dr = (x.r_m - r_ref).norm(), dv = (x.v_mps - v_ref).norm();
    max_dr = std::max(max_dr, dr);
    max_dv = std::max(max_dv, dv);
    EXPECT_LT(dr, kPosTol_m) << "a=" << oe.a_m << " e=" << oe.e << " i=" << oe.i_rad;
    EXPECT_LT(dv, kVelTol_mps);
    // Round trips through Keplerian and quasi-nonsingular elements.
    for (const StateVector& y :
         {cartesian_from_kepler(kepler_from_cartesian(x)), cartesian_from_qns(qns_from_cartesian(x))}) {
      const double rt = std::max((y.r_m - x.r_m).norm() / x.r_m.norm(),
                                 (y.v_mps - x.v_mps).norm() / x.v_mps.norm());
      max_rt = std::max(max_rt, rt);
      EXPECT_LT(rt, kRoundTripRelTol);
    }
  }
  EXPECT_GE(circular, 100);
  EXPECT_GE(equatorial, 100);
  std::printf("[oracle-kepler] %zu orbits (%d circular, %d equatorial): max |dr| = %.3e m, "
              "max |dv| = %.3e m/s, max round-trip relative error = %.3e\n",
              cases.size(), circular, equatorial, max_dr, max_dv, max_rt);
}

TEST(OracleEarthRotation, PrecessionMatchesErfaPmat76) {
  nlohmann::json j;
  if (!load_cases("erfa_earth_rotation_cases.json", j)) GTEST_SKIP() << "ERFA cases missing";
  double max_err = 0;
  for (const auto& c : j["cases"]) {
    const double days = c["jd_tt"].get<double>() - 2451545.0;
    const TimeTT t{static_cast<std::int64_t>(std::llround(days * 86400.0 * 1e9))};
    const Mat3 R = R_mod_from_eci(t);
    for (int r = 0; r < 3; ++r) {
      for (int k = 0; k < 3; ++k) {
        max_err = std::max(max_err, std::abs(R(r, k) - c["pmat76"][r][k].get<double>()));
      }
    }
  }
  EXPECT_LT(max_err, 1e-12);
  std::printf("[oracle-erfa] pmat76: max element difference %.3e\n", max_err);
}

TEST(OracleEarthRotation, GmstMatchesErfaGmst82) {
  nlohmann::json j;
  if (!load_cases("erfa_earth_rotation_cases.json", j)) GTEST_SKIP() << "ERFA cases missing";
  double max_err = 0;
  for (const auto& c : j["gmst_cases"]) {
    const TimeTT t = tt_from_utc_string(c["utc"].get<std::string>());
    const double err = std::abs(wrap_pi(gmst_rad(t, 0.0) - c["gmst82_rad"].get<double>()));
    max_err = std::max(max_err, err);
  }
  EXPECT_LT(max_err, 5e-9);  // 1 mas: double rounding of the UT1 Julian date
  std::printf("[oracle-erfa] gmst82: %zu cases, max difference %.3e rad\n", j["gmst_cases"].size(),
              max_err);
}

// Stellar aberration against ERFA's ab (first order in v/c plus the
// second-order terms; ERFA's 1e-8 relative light-deflection factor is the
// only term it has and ours has not): 0.001" is 1/20000 of the largest shift.
TEST(OracleAberration, ApparentDirectionMatchesErfaAb) {
  nlohmann::json j;
  if (!load_cases("erfa_aberration_cases.json", j)) GTEST_SKIP() << "ERFA aberration cases missing";
  double max_err = 0, max_shift = 0;
  for (const auto& c : j["cases"]) {
    Vec3 u, v, ref;
    for (int k = 0; k < 3; ++k) {
      u[k] = c["u"][k].get<double>();
      v[k] = c["v_mps"][k].get<double>();
      ref[k] = c["apparent"][k].get<double>();
    }
    const Vec3 app = aberrated_direction(u, v);
    max_err = std::max(max_err, std::atan2(app.cross(ref).norm(), app.dot(ref)));
    max_shift = std::max(max_shift, std::atan2(app.cross(u).norm(), app.dot(u)));
  }
  EXPECT_LT(max_err, 0.001 * kArcsecToRad);
  EXPECT_GT(max_shift, 30.0 * kArcsecToRad);  // the cases do reach large shifts
  std::printf("[oracle-erfa] ab: %zu cases, shifts up to %.2f arcsec, max difference %.2e arcsec\n",
              j["cases"].size(), max_shift / kArcsecToRad, max_err / kArcsecToRad);
}

}  // namespace
}  // namespace artms::astro
