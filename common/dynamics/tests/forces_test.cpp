#include "artms/dynamics/forces.hpp"

#include <gtest/gtest.h>

#include "artms/astro/constants.hpp"
#include "artms/astro/elements.hpp"
#include "artms/testing/testing.hpp"

namespace artms::dynamics {
namespace {

TEST(ForceSpec, ParsesDesignSyntax) {
  const auto two = ForceModelOptions::parse("two-body");
  EXPECT_EQ(two.gravity_degree, 0);
  EXPECT_FALSE(two.drag);
  const auto j2 = ForceModelOptions::parse("j2");
  EXPECT_EQ(j2.gravity_degree, 2);
  EXPECT_EQ(j2.gravity_order, 0);
  const auto full = ForceModelOptions::parse("grav10,drag,sun,moon,srp");
  EXPECT_EQ(full.gravity_degree, 10);
  EXPECT_EQ(full.gravity_order, 10);
  EXPECT_TRUE(full.drag && full.sun && full.moon && full.srp);
  const auto g = ForceModelOptions::parse("grav20_4,sun");
  EXPECT_EQ(g.gravity_degree, 20);
  EXPECT_EQ(g.gravity_order, 4);
  EXPECT_FALSE(g.drag);
}

TEST(ForceSpec, RejectsUnknownItemsByName) {
  for (const char* bad : {"grav10,dragg", "gravx", "grav4_5", "", "grav10,,sun"}) {
    try {
      (void)ForceModelOptions::parse(bad);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("force model"), std::string::npos);
    }
  }
}

TEST(ForceSpec, FlightLikeTruthIsRicherThanThePaperModel) {
  const ForceModelOptions paper;
  EXPECT_EQ(paper.gravity_degree, 10);
  EXPECT_EQ(paper.atmosphere_model, AtmosphereModel::kHarrisPriester);
  EXPECT_FALSE(paper.srp);
  const ForceModelOptions f = ForceModelOptions::flight_like_truth();
  EXPECT_GT(f.gravity_degree, paper.gravity_degree);
  EXPECT_EQ(f.gravity_order, f.gravity_degree);
  EXPECT_TRUE(f.drag && f.sun && f.moon && f.srp);
  EXPECT_EQ(f.atmosphere_model, AtmosphereModel::kJacchiaScaledHarrisPriester);
  EXPECT_EQ(f.shadow, ShadowModel::kConical);
  const std::string d = f.describe();
  for (const char* part : {"gravity 20x20", "Jacchia 1971", "F10.7 170", "81-day 165", "Kp 3", "semi-annual",
                           "Sun", "Moon", "SRP (conical shadow)"}) {
    EXPECT_NE(d.find(part), std::string::npos) << part << " not in: " << d;
  }
  EXPECT_NE(paper.describe().find("Harris-Priester drag (n=6)"), std::string::npos) << paper.describe();
  // The --force syntax reaches both.
  const ForceModelOptions p = ForceModelOptions::parse("flight-like");
  EXPECT_EQ(p.describe(), d);
  const ForceModelOptions j = ForceModelOptions::parse("grav10,drag-jacchia,sun");
  EXPECT_TRUE(j.drag);
  EXPECT_EQ(j.atmosphere_model, AtmosphereModel::kJacchiaScaledHarrisPriester);
  EXPECT_EQ(ForceModelOptions::parse("grav10,drag").atmosphere_model, AtmosphereModel::kHarrisPriester);
}

TEST(Forces, JacchiaAtmosphereFollowsTheSpaceWeatherDeterministically) {
  const astro::TimeTT t = astro::tt_from_utc_string("2024-05-08T06:00:00Z");
  const astro::StateVector x = astro::cartesian_from_qns(
      {6943e3, 0.0001, 0.0016, 99.4 * astro::kDegToRad, -38.0 * astro::kDegToRad, -153.0 * astro::kDegToRad});
  ForceModelOptions o = ForceModelOptions::parse("grav10,drag-jacchia");
  const ForceModel quiet = ForceModel::load(o, ARTMS_DATA_DIR);
  o.space_weather.kp = 7.0;
  o.space_weather.f107_sfu = 240.0;
  const ForceModel storm = ForceModel::load(o, ARTMS_DATA_DIR);
  const ForceModel hp = ForceModel::load(ForceModelOptions::parse("grav10,drag"), ARTMS_DATA_DIR);
  const double rho_quiet = quiet.density_kgpm3(t, x.r_m);
  EXPECT_GT(rho_quiet, 0.0);
  EXPECT_GT(storm.density_kgpm3(t, x.r_m), 2.0 * rho_quiet);
  EXPECT_NE(hp.density_kgpm3(t, x.r_m), rho_quiet);
  EXPECT_EQ(ForceModel::load(ForceModelOptions::parse("grav10,drag-jacchia"), ARTMS_DATA_DIR).density_kgpm3(t, x.r_m),
            rho_quiet);
  const SpacecraftProperties sc;
  EXPECT_GT((storm.perturbation_eci(t, x, sc) - quiet.perturbation_eci(t, x, sc)).norm(), 0.0);
  EXPECT_EQ(ForceModel::load(ForceModelOptions::parse("grav10"), ARTMS_DATA_DIR).density_kgpm3(t, x.r_m), 0.0);
}

TEST(Forces, BadSpaceWeatherIsRefusedAtLoadNamingTheField) {
  ForceModelOptions o = ForceModelOptions::flight_like_truth();
  o.space_weather.f107_81day_sfu = -1.0;
  try {
    (void)ForceModel::load(o, ARTMS_DATA_DIR);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("f107_81day_sfu"), std::string::npos) << e.what();
  }
  o.atmosphere_model = AtmosphereModel::kHarrisPriester;  // space weather unused: no check
  EXPECT_NO_THROW((void)ForceModel::load(o, ARTMS_DATA_DIR));
}

TEST(Forces, CentralTermAndPerturbationSplit) {
  const ForceModel f = ForceModel::load(ForceModelOptions::parse("grav10,drag,sun,moon,srp"),
                                        ARTMS_DATA_DIR);
  const astro::TimeTT t = astro::tt_from_utc_string("2024-05-08T00:00:00Z");
  const astro::StateVector x{Vec3(6.9e6, 0.5e6, 0.8e6), Vec3(-800, 1200, 7400)};
  const SpacecraftProperties sc;
  const Vec3 total = f.acceleration_eci(t, x, sc);
  const Vec3 pert = f.perturbation_eci(t, x, sc);
  const Vec3 central = -f.gm_m3ps2() * x.r_m / std::pow(x.r_m.norm(), 3);
  EXPECT_LT((total - pert - central).norm(), 1e-12);
  // J2 dominates the perturbation in LEO: ~1e-2 m/s^2.
  EXPECT_GT(pert.norm(), 5e-3);
  EXPECT_LT(pert.norm(), 3e-2);
}

TEST(Forces, ManeuverIsInRtn) {
  const astro::StateVector x{Vec3(7e6, 0, 0), Vec3(0, 7500, 0)};
  const astro::StateVector y = apply_maneuver(x, Vec3(1.0, 2.0, 3.0));
  // Circular equatorial at +x: R = x, T = y, N = z.
  EXPECT_LT((y.v_mps - Vec3(1.0, 7502.0, 3.0)).norm(), 1e-12);
  EXPECT_EQ(y.r_m, x.r_m);
}

TEST(Forces, DragAreaVariesTwicePerOrbit) {
  const ForceModel f = ForceModel::load(ForceModelOptions::parse("drag"), ARTMS_DATA_DIR);
  const astro::TimeTT t = astro::tt_from_utc_string("2024-05-08T00:00:00Z");
  SpacecraftProperties fixed, varying;
  varying.drag_area_variation = 0.5;
  // Inclined circular orbit at 550 km: u = 0 at the node, 90 deg at the top.
  const double i = 97.6 * astro::kDegToRad, r = 6928e3, v = std::sqrt(astro::kGmEarth_m3ps2 / r);
  for (double u_deg : {0.0, 45.0, 90.0, 180.0}) {
    const double u = u_deg * astro::kDegToRad;
    const Vec3 e_r(std::cos(u), std::sin(u) * std::cos(i), std::sin(u) * std::sin(i));
    const Vec3 e_t(-std::sin(u), std::cos(u) * std::cos(i), std::cos(u) * std::sin(i));
    const astro::StateVector x{r * e_r, v * e_t};
    const double ratio = f.perturbation_eci(t, x, varying).norm() / f.perturbation_eci(t, x, fixed).norm();
    EXPECT_NEAR(ratio, 1.0 + 0.5 * std::cos(2.0 * u), 1e-9) << u_deg;
  }
  varying.drag_area_variation = 1.0;
  EXPECT_THROW(varying.validate(), std::invalid_argument);
}

TEST(Forces, ValidatesSpacecraftProperties) {
  SpacecraftProperties sc;
  EXPECT_NO_THROW(sc.validate());
  sc.cd = 0.0;
  try {
    sc.validate();
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("cd"), std::string::npos);
  }
}

}  // namespace
}  // namespace artms::dynamics
