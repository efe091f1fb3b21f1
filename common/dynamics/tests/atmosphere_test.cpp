#include "artms/dynamics/atmosphere.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "artms/astro/constants.hpp"
#include "artms/testing/testing.hpp"

namespace artms::dynamics {
namespace {

using artms::testing::test_data_path;
using ::testing::HasSubstr;

constexpr double kWgs84A_m = 6378137.0;
constexpr double kWgs84F = 1.0 / 298.257223563;
constexpr double kAu_m = 149597870700.0;

std::string table_path() {
  return std::string(ARTMS_DATA_DIR) + "/atmosphere/harris_priester_table.csv";
}

// Forward WGS84 transform (closed form), to test the inverse.
Vec3 ecef_from_geodetic(double lat_rad, double lon_rad, double h_m) {
  const double e2 = kWgs84F * (2.0 - kWgs84F);
  const double n = kWgs84A_m / std::sqrt(1.0 - e2 * std::sin(lat_rad) * std::sin(lat_rad));
  return {(n + h_m) * std::cos(lat_rad) * std::cos(lon_rad),
          (n + h_m) * std::cos(lat_rad) * std::sin(lon_rad),
          (n * (1.0 - e2) + h_m) * std::sin(lat_rad)};
}

TEST(Atmosphere, GeodeticHeightInvertsTheForwardTransform) {
  const double b = kWgs84A_m * (1.0 - kWgs84F);
  EXPECT_NEAR(geodetic_height_m(Vec3(kWgs84A_m + 500e3, 0, 0)), 500e3, 1e-6);
  EXPECT_NEAR(geodetic_height_m(Vec3(0, 0, -(b + 400e3))), 400e3, 1e-6);
  for (double lat_deg : {-89.9, -60.0, -23.0, 0.5, 45.0, 77.0, 90.0}) {
    for (double h : {0.0, 150e3, 550e3, 2000e3}) {
      const Vec3 r = ecef_from_geodetic(lat_deg * astro::kDegToRad, 1.1, h);
      EXPECT_NEAR(geodetic_height_m(r), h, 1e-6) << "lat " << lat_deg << " h " << h;
    }
  }
}

TEST(Atmosphere, ReproducesBraheReferenceCases) {
  // brahe (M&G's code) uses pow(cos^2(psi/2), 3) = cos^6(psi/2): n = 6,
  // the default. The header of the CSV calls it n = 3 (brahe's n_prm).
  const HarrisPriester hp = HarrisPriester::from_file(table_path());
  ASSERT_EQ(hp.options().cosine_exponent, 6.0);
  std::ifstream in(test_data_path("harris_priester_reference_cases.csv"));
  ASSERT_TRUE(in);
  std::string line;
  int cases = 0;
  double max_rel = 0.0;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#' || line[0] == 'r') continue;  // comments, header
    std::replace(line.begin(), line.end(), ',', ' ');
    std::istringstream fields(line);
    double v[7];
    for (double& x : v) ASSERT_TRUE(fields >> x) << line;
    const Vec3 r_sun(v[0], v[1], v[2]), r(v[3], v[4], v[5]);
    const double rho = hp.density_kgpm3(r, r, r_sun);
    const double rel = std::abs(rho / v[6] - 1.0);
    EXPECT_LT(rel, 1e-5) << line;
    max_rel = std::max(max_rel, rel);
    ++cases;
  }
  EXPECT_EQ(cases, 18);
  std::printf("Harris-Priester vs brahe: max relative error %.2e over %d cases\n", max_rel, cases);
}

TEST(Atmosphere, BulgeApexAndAntapexGiveTableMaxAndMin) {
  // Sun on the equator at RA = -lag: the bulge apex is the +x axis.
  const HarrisPriester hp = HarrisPriester::from_file(table_path());
  const double lag = hp.options().lag_angle_rad;
  const Vec3 sun = kAu_m * Vec3(std::cos(-lag), std::sin(-lag), 0.0);
  const Vec3 apex(kWgs84A_m + 400e3, 0, 0);
  EXPECT_NEAR(hp.density_kgpm3(apex, apex, sun), 7.492e-12, 1e-20);    // rho_max(400 km)
  EXPECT_NEAR(hp.density_kgpm3(-apex, -apex, sun), 2.249e-12, 1e-20);  // rho_min(400 km)
  // Exponential interpolation: halfway between nodes is the geometric mean.
  const Vec3 mid(kWgs84A_m + 450e3, 0, 0);
  EXPECT_NEAR(hp.density_kgpm3(mid, mid, sun), std::sqrt(4.355e-12 * 3.362e-12), 1e-22);
  // Perpendicular to the apex, cos^6(45 deg) = 1/8 of the way to the maximum.
  const Vec3 side(0, kWgs84A_m + 400e3, 0);
  EXPECT_NEAR(hp.density_kgpm3(side, side, sun), 2.249e-12 + (7.492e-12 - 2.249e-12) / 8.0, 1e-20);
  // With n = 2 it is half way.
  HarrisPriesterOptions n2;
  n2.cosine_exponent = 2.0;
  const HarrisPriester hp2 = HarrisPriester::from_file(table_path(), n2);
  EXPECT_NEAR(hp2.density_kgpm3(side, side, sun), 0.5 * (2.249e-12 + 7.492e-12), 1e-20);
}

TEST(Atmosphere, HeightComesFromTheEarthFixedVector) {
  // Same inertial geometry, different Earth-fixed vector: the height (and so
  // the density) follows r_ecef, the bulge weight follows r_eci.
  const HarrisPriester hp = HarrisPriester::from_file(table_path());
  const Vec3 sun(kAu_m, 0, 0);
  const Vec3 r_eci(kWgs84A_m + 400e3, 0, 0);
  const double rho_400 = hp.density_kgpm3(r_eci, r_eci, sun);
  const double rho_500 = hp.density_kgpm3(r_eci, Vec3(0, kWgs84A_m + 500e3, 0), sun);
  EXPECT_LT(rho_500, 0.5 * rho_400);
  EXPECT_GT(rho_500, 0.0);
}

TEST(Atmosphere, ZeroAboveTheTableAndThrowsBelowIt) {
  const HarrisPriester hp = HarrisPriester::from_file(table_path());
  const Vec3 sun(kAu_m, 0, 0);
  for (double h : {1000.001e3, 1001e3, 1500e3, 36000e3}) {
    const Vec3 r(0, kWgs84A_m + h, 0);
    EXPECT_EQ(hp.density_kgpm3(r, r, sun), 0.0) << h;
  }
  const Vec3 r_999(0, kWgs84A_m + 999e3, 0);
  EXPECT_GT(hp.density_kgpm3(r_999, r_999, sun), 0.0);
  const Vec3 r_100(0, kWgs84A_m + 100.001e3, 0);
  EXPECT_NEAR(hp.density_kgpm3(r_100, r_100, sun), 4.974e-7, 1e-3 * 4.974e-7);
  for (double h : {99.9e3, 50e3, 0.0}) {
    const Vec3 r(0, kWgs84A_m + h, 0);
    EXPECT_THROW((void)hp.density_kgpm3(r, r, sun), std::out_of_range) << h;
  }
}

void expect_load_error(const std::string& name, const std::string& where, const std::string& what) {
  const std::string path = test_data_path(name);
  try {
    (void)HarrisPriester::from_file(path);
    ADD_FAILURE() << "no error for " << name;
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr(path + ":" + where)) << e.what();
    EXPECT_THAT(e.what(), HasSubstr(what)) << e.what();
  }
}

TEST(Atmosphere, MalformedTableNamesFileAndLine) {
  expect_load_error("harris_priester_malformed_number.csv", "6:", "not a number");
  expect_load_error("harris_priester_malformed_fields.csv", "5:", "expected 3 fields");
  expect_load_error("harris_priester_malformed_order.csv", "7:", "heights must increase");
  // A file that is not a table at all fails on its header line.
  expect_load_error("harris_priester_reference_cases.csv", "3:", "expected header");
  try {
    (void)HarrisPriester::from_file("/nonexistent/hp.csv");
    ADD_FAILURE() << "no error for a missing file";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("/nonexistent/hp.csv"));
  }
}

TEST(Atmosphere, DragOpposesRelativeVelocityWithCannonballMagnitude) {
  const Vec3 r(-2100e3, 4300e3, 5000e3);
  const Vec3 v(-3000.0, -4800.0, 2900.0);
  const double rho = 3e-12, cd = 2.2, am = 0.015;
  const Vec3 a = drag_acceleration_mps2(r, v, rho, cd, am);
  const Vec3 v_rel = v - Vec3(0, 0, astro::kEarthRotation_radps).cross(r);
  EXPECT_NEAR(a.normalized().dot(-v_rel.normalized()), 1.0, 1e-14);
  EXPECT_NEAR(a.norm(), 0.5 * rho * cd * am * v_rel.squaredNorm(), 1e-14 * a.norm());
  EXPECT_EQ(drag_acceleration_mps2(r, v, 0.0, cd, am).norm(), 0.0);
}

TEST(Atmosphere, CoRotationReducesDragOnProgradeEquatorialOrbit) {
  const double radius = 6878e3;
  const double speed = std::sqrt(astro::kGmEarth_m3ps2 / radius);
  const double rho = 5e-12, cd = 2.2, am = 0.01;
  const double no_rotation = 0.5 * rho * cd * am * speed * speed;
  const Vec3 r(radius, 0, 0);
  const double prograde = drag_acceleration_mps2(r, Vec3(0, speed, 0), rho, cd, am).norm();
  const double retrograde = drag_acceleration_mps2(r, Vec3(0, -speed, 0), rho, cd, am).norm();
  EXPECT_LT(prograde, no_rotation);
  EXPECT_GT(retrograde, no_rotation);
  // v_rel = v - omega r: (1 - omega r / v)^2 of the non-rotating value (~0.87).
  const double k = 1.0 - astro::kEarthRotation_radps * radius / speed;
  EXPECT_NEAR(prograde, no_rotation * k * k, 1e-12 * no_rotation);
}

}  // namespace
}  // namespace artms::dynamics
