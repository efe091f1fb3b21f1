#include "artms/dynamics/gravity.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <random>

#include "artms/astro/constants.hpp"
#include "artms/testing/testing.hpp"

namespace artms::dynamics {
namespace {

using artms::testing::load_json;
using artms::testing::test_data_path;

const std::string kGgm01s = std::string(ARTMS_DATA_DIR) + "/gravity/GGM01S.gfc";

// Independent reference: direct summation of the potential gradient in
// spherical coordinates with unnormalised Legendre functions (long double),
// normalised with explicit factorials. Shares nothing with the V/W recursion.
Vec3 reference_acceleration(const GravityField& f, int degree, const Vec3& r_ecef) {
  using LD = long double;
  const LD x = r_ecef.x(), y = r_ecef.y(), z = r_ecef.z();
  const LD r = std::sqrt(x * x + y * y + z * z);
  const LD sphi = z / r, cphi = std::sqrt(x * x + y * y) / r;
  const LD lam = std::atan2(y, x);
  const int N = degree;
  std::vector<std::vector<LD>> P(N + 1, std::vector<LD>(N + 2, 0.0L));
  for (int m = 0; m <= N; ++m) {
    LD pmm = 1.0L;
    for (int k = 1; k <= m; ++k) pmm *= (2.0L * k - 1.0L) * cphi;  // (2m-1)!! cos^m
    P[m][m] = pmm;
    if (m + 1 <= N) P[m + 1][m] = (2.0L * m + 1.0L) * sphi * pmm;
    for (int n = m + 2; n <= N; ++n) {
      P[n][m] = ((2.0L * n - 1.0L) * sphi * P[n - 1][m] - (n + m - 1.0L) * P[n - 2][m]) / (n - m);
    }
  }
  const auto fact = [](int k) {
    LD v = 1.0L;
    for (int j = 2; j <= k; ++j) v *= j;
    return v;
  };
  const LD gm = f.gm_m3ps2(), R = f.radius_m();
  LD dU_dr = 0, dU_dphi = 0, dU_dlam = 0;
  for (int n = 0; n <= N; ++n) {
    const LD ratio = std::pow(R / r, static_cast<LD>(n));
    for (int m = 0; m <= n; ++m) {
      const LD norm = std::sqrt((m == 0 ? 1.0L : 2.0L) * (2.0L * n + 1.0L) * fact(n - m) / fact(n + m));
      const LD C = f.c(n, m) * norm, S = f.s(n, m) * norm;  // unnormalised
      const LD cm = std::cos(m * lam), sm = std::sin(m * lam);
      const LD trig = C * cm + S * sm;
      const LD pnm = P[n][m];
      const LD pn1m = n - 1 >= m ? P[n - 1][m] : 0.0L;
      const LD dP_dphi = ((n + m) * pn1m - n * sphi * pnm) / cphi;  // (1-x^2) P' identity
      dU_dr += -(n + 1.0L) * gm / (r * r) * ratio * pnm * trig;
      dU_dphi += gm / r * ratio * dP_dphi * trig;
      dU_dlam += gm / r * ratio * pnm * m * (S * cm - C * sm);
    }
  }
  const LD cl = std::cos(lam), sl = std::sin(lam);
  const LD er[3] = {cphi * cl, cphi * sl, sphi};
  const LD ephi[3] = {-sphi * cl, -sphi * sl, cphi};
  const LD elam[3] = {-sl, cl, 0.0L};
  Vec3 a;
  for (int k = 0; k < 3; ++k) {
    a[k] = static_cast<double>(dU_dr * er[k] + dU_dphi / r * ephi[k] + dU_dlam / (r * cphi) * elam[k]);
  }
  return a;
}

TEST(Gravity, LoadsGgm01sHeaderAndCoefficientLine) {
  const GravityField f = GravityField::from_gfc(kGgm01s, 10);
  EXPECT_EQ(f.max_degree(), 10);
  EXPECT_DOUBLE_EQ(f.gm_m3ps2(), 398600.4415e9);
  EXPECT_DOUBLE_EQ(f.radius_m(), 6378136.3);
  // The coefficient line, not the header's quoted tide-free value (data/README.md).
  EXPECT_DOUBLE_EQ(f.c(2, 0), -4.8416485210e-4);
  EXPECT_NEAR(-std::sqrt(5.0) * f.c(2, 0), astro::kJ2Earth, 1e-18);
}

TEST(Gravity, RejectsMalformedFiles) {
  const std::string path = ::testing::TempDir() + "/bad.gfc";
  {
    std::ofstream out(path);
    out << "modelname X\nearth_gravity_constant 3.986004415E+14\nradius 6378136.3\n"
           "max_degree 2\nend_of_head ====\ngfc 0 0 1.0 0.0\ngfc 2 0 -4.8e-4 abc\n";
  }
  try {
    (void)GravityField::from_gfc(path);
    FAIL() << "accepted a malformed coefficient";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("bad.gfc:7"), std::string::npos) << e.what();
  }
  EXPECT_THROW((void)GravityField::from_gfc(kGgm01s, 200), std::runtime_error);
  EXPECT_THROW((void)GravityField::from_gfc("/nonexistent.gfc"), std::runtime_error);
}

TEST(Gravity, TudatMatlabReferenceCases) {
  const auto j = load_json(test_data_path("sh_gravity_reference_cases.json"))["tudat_matlab"];
  const Vec3 r(j["position_m"][0], j["position_m"][1], j["position_m"][2]);
  const auto field_with = [&](const std::vector<std::pair<int, int>>& terms, bool central) {
    GravityField f(j["GM"], j["R"], 5);
    f.set(0, 0, central ? 1.0 : 0.0, 0.0);
    for (const auto& [n, m] : terms) {
      f.set(n, m, j["coefficients_C_rows_n0_to_5"][n][m], j["coefficients_S_rows_n0_to_5"][n][m]);
    }
    return f;
  };
  std::vector<std::pair<int, int>> all;
  for (int n = 2; n <= 5; ++n) {
    for (int m = 0; m <= n; ++m) all.emplace_back(n, m);
  }
  const std::vector<GravityField> fields = {field_with({{2, 0}}, false),
                                            field_with({{2, 1}}, false),
                                            field_with({{2, 2}}, false), field_with(all, true)};
  for (std::size_t k = 0; k < fields.size(); ++k) {
    const auto& c = j["cases"][k];
    const Vec3 expected(c["expected"][0], c["expected"][1], c["expected"][2]);
    const Vec3 a = SphericalHarmonicGravity(fields[k], 5, 5).acceleration_ecef(r);
    // MATLAB's own rounding: allow 1e-13 relative (the file quotes 1e-14..1e-15).
    EXPECT_LT((a - expected).norm() / expected.norm(), 1e-13) << c["terms"];
  }
}

TEST(Gravity, BraheDegree120ReferenceCases) {
  const auto j = load_json(test_data_path("sh_gravity_reference_cases.json"))["brahe_mpmath"];
  const GravityField f = GravityField::from_gfc(test_data_path("EGM2008_120.gfc"));
  for (const auto& c : j["cases"]) {
    const Vec3 r(c["position_m"][0], c["position_m"][1], c["position_m"][2]);
    const Vec3 expected(c["expected"][0], c["expected"][1], c["expected"][2]);
    const Vec3 a = SphericalHarmonicGravity(f, c["n"], c["m"]).acceleration_ecef(r);
    EXPECT_LT((a - expected).norm() / expected.norm(), 1e-13) << "n=" << c["n"] << " m=" << c["m"];
  }
}

// Acceptance (issue 3, point 3): 10x10 against the independent summation at
// 100 random points, 1e-12 relative.
TEST(Gravity, MatchesIndependentSummationAt100Points) {
  const GravityField f = GravityField::from_gfc(kGgm01s, 10);
  const SphericalHarmonicGravity g(f, 10, 10);
  std::mt19937 rng(10);
  std::uniform_real_distribution<double> rad(6.6e6, 4.2e7), ang(0, astro::kTwoPi), sl(-0.99, 0.99);
  double worst = 0.0, worst_pert = 0.0;
  for (int k = 0; k < 100; ++k) {
    const double rr = rad(rng), lon = ang(rng), s = sl(rng), c = std::sqrt(1 - s * s);
    const Vec3 r = rr * Vec3(c * std::cos(lon), c * std::sin(lon), s);
    const Vec3 ref = reference_acceleration(f, 10, r);
    const Vec3 a = g.acceleration_ecef(r);
    worst = std::max(worst, (a - ref).norm() / ref.norm());
    const Vec3 central = -f.gm_m3ps2() * r / std::pow(r.norm(), 3);
    const Vec3 pert_ref = ref - central;
    worst_pert = std::max(worst_pert, (g.perturbation_ecef(r) - pert_ref).norm() / pert_ref.norm());
  }
  std::printf("[gravity] 10x10 vs independent summation, 100 points: max relative error %.2e "
              "(total), %.2e (perturbation only)\n", worst, worst_pert);
  EXPECT_LT(worst, 1e-12);
  EXPECT_LT(worst_pert, 1e-9);
}

// The classic mistake: evaluating tesseral terms in the inertial frame. The
// ECI acceleration at a fixed inertial point must follow the Earth's rotation.
TEST(Gravity, TesseralTermsRotateWithTheEarth) {
  const GravityField f = GravityField::from_gfc(kGgm01s, 10);
  const SphericalHarmonicGravity g(f, 10, 10);
  const astro::TimeTT t0 = astro::tt_from_utc_string("2024-05-08T00:00:00Z");
  const Vec3 r_eci(6.9e6, 1.1e6, 0.7e6);
  const Mat3 R0 = astro::R_ecef_from_eci(t0);
  const Mat3 R6 = astro::R_ecef_from_eci(t0.plus_seconds(6 * 3600.0));
  const Vec3 a0 = g.acceleration_eci(r_eci, R0);
  const Vec3 a6 = g.acceleration_eci(r_eci, R6);
  // Same inertial point, Earth turned by 90 deg: the tesseral part changes.
  EXPECT_GT((a6 - a0).norm(), 1e-6);
  // Evaluating at r_eci as if it were Earth-fixed is wrong by a similar amount.
  const Vec3 wrong = g.acceleration_ecef(r_eci);
  EXPECT_GT((wrong - a0).norm(), 1e-6);
  // A point fixed on the Earth sees the same ECEF acceleration at all times.
  const Vec3 r_ecef(6.9e6, 1.1e6, 0.7e6);
  const Vec3 b0 = R0 * g.acceleration_eci(R0.transpose() * r_ecef, R0);
  const Vec3 b6 = R6 * g.acceleration_eci(R6.transpose() * r_ecef, R6);
  EXPECT_LT((b6 - b0).norm(), 1e-15 * b0.norm() * 100);
  // Zonal-only (order 0) fields are blind to the rotation about z, up to
  // precession over 6 hours (the pole of date moves ~0.014 arcsec = 7e-8 rad,
  // times the J2 acceleration ~1.5e-2 m/s^2: ~1e-9 m/s^2).
  const SphericalHarmonicGravity zonal(f, 10, 0);
  EXPECT_LT((zonal.acceleration_eci(r_eci, R6) - zonal.acceleration_eci(r_eci, R0)).norm(), 5e-9);
}

TEST(Gravity, RejectsDegreeBeyondField) {
  const GravityField f = GravityField::from_gfc(kGgm01s, 10);
  EXPECT_THROW(SphericalHarmonicGravity(f, 12, 12), std::invalid_argument);
  EXPECT_THROW(SphericalHarmonicGravity(f, 4, 5), std::invalid_argument);
}

}  // namespace
}  // namespace artms::dynamics
