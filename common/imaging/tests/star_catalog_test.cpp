// Star catalog: BSC5 parsing, proper motion against skyfield, cone queries.
#include "artms/imaging/star_catalog.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <random>
#include <sstream>
#include <stdexcept>

#include "artms/astro/constants.hpp"
#include "artms/testing/testing.hpp"

namespace artms::imaging {
namespace {

using astro::kArcsecToRad;
using astro::kDegToRad;

const std::string kBsc5Path = std::string(ARTMS_DATA_DIR) + "/stars/bsc5.dat";

Eigen::Vector3d unit_from_radec_deg(double ra_deg, double dec_deg) {
  const double ra = ra_deg * kDegToRad, dec = dec_deg * kDegToRad;
  return {std::cos(dec) * std::cos(ra), std::cos(dec) * std::sin(ra), std::sin(dec)};
}

double angle_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

astro::TimeTT tt_from_jd(double jd_tt) {
  return {std::llround((jd_tt - 2451545.0) * 86400.0 * 1e9)};
}

// Real BSC5 lines (HR 1 and HR 3) to build malformed variants from.
const std::string kHr1 =
    "   1          BD+44 4550      3 36042          46           "
    "000001.1+444022000509.9+451345114.44-16.88 6.70  +0.07 +0.08         A1Vn"
    "               -0.012-0.018      -018      195  4.2  21.6AC   3";
const std::string kHr3 =
    "   3 33    PscBD-06 6357     281285721002I         Var?     "
    "000013.0-061601000520.1-054227 93.75-65.93 4.61  +1.04 +0.89 +0.54   K0IIIbCN-0.5"
    "       -0.009+0.089 +.014-006SB1O < 17  2.5   0.0     3*";

std::string with_bytes(std::string line, std::size_t first, const std::string& text) {
  line.replace(first - 1, text.size(), text);
  return line;
}

std::string parse_error(const std::string& text) {
  std::istringstream in(text);
  try {
    StarCatalog::parse_bsc5(in, "cat.dat", 99.0);
  } catch (const std::runtime_error& ex) {
    return ex.what();
  }
  return "";
}

TEST(StarCatalog, LoadsShippedBsc5) {
  const StarCatalog all = StarCatalog::load_bsc5(kBsc5Path, 99.0);
  EXPECT_EQ(all.size(), 9096u);  // this copy omits the 14 blank-position entries
  const StarCatalog bright = StarCatalog::load_bsc5(kBsc5Path, 6.0);
  EXPECT_EQ(bright.size(), 5080u);
  for (const Star& s : bright.stars()) EXPECT_LE(s.vmag, 6.0);

  const Star* sirius = all.find(2491);
  ASSERT_NE(sirius, nullptr);
  EXPECT_DOUBLE_EQ(sirius->vmag, -1.46);
  // RA 06 45 08.9, Dec -16 42 58 (J2000); pm -0.553 "/yr (x cos dec), -1.205 "/yr.
  EXPECT_NEAR(sirius->ra_rad / kDegToRad, (6 + 45 / 60.0 + 8.9 / 3600.0) * 15.0, 1e-12);
  EXPECT_NEAR(sirius->dec_rad / kDegToRad, -(16 + 42 / 60.0 + 58 / 3600.0), 1e-12);
  EXPECT_NEAR(sirius->pm_ra_cosdec_radpyr, -0.553 * kArcsecToRad, 1e-18);
  EXPECT_NEAR(sirius->pm_dec_radpyr, -1.205 * kArcsecToRad, 1e-18);
  EXPECT_EQ(all.find(92), nullptr);
}

TEST(StarCatalog, ProperMotionMatchesSkyfieldWithin10mas) {
  const StarCatalog cat = StarCatalog::load_bsc5(kBsc5Path, 99.0);
  const auto ref = testing::load_json(testing::test_data_path("skyfield_bsc5_star_positions.json"));
  double max_err_mas = 0.0;
  int checked = 0;
  for (const auto& js : ref["stars"]) {
    const int hr = js["HR"].get<int>();
    const Star* s = cat.find(hr);
    ASSERT_NE(s, nullptr) << "HR " << hr;
    EXPECT_DOUBLE_EQ(s->vmag, js["Vmag"].get<double>()) << "HR " << hr;
    EXPECT_NEAR(s->ra_rad / kDegToRad, js["ra_j2000_deg"].get<double>(), 1e-9) << "HR " << hr;
    EXPECT_NEAR(s->dec_rad / kDegToRad, js["dec_j2000_deg"].get<double>(), 1e-9) << "HR " << hr;
    EXPECT_NEAR(s->pm_ra_cosdec_radpyr / kArcsecToRad,
                js["pmra_cosdec_arcsec_per_yr"].get<double>(), 1e-12);
    EXPECT_NEAR(s->pm_dec_radpyr / kArcsecToRad, js["pmdec_arcsec_per_yr"].get<double>(), 1e-12);
    for (const auto& p : js["positions"]) {
      const Eigen::Vector3d expected =
          unit_from_radec_deg(p["ra_deg"].get<double>(), p["dec_deg"].get<double>());
      const Eigen::Vector3d got = s->unit_eci_at(tt_from_jd(p["jd_tt"].get<double>()));
      const double err_mas = angle_between(got, expected) / kArcsecToRad * 1e3;
      EXPECT_LT(err_mas, 10.0) << "HR " << hr << " at " << p["epoch"].get<std::string>();
      max_err_mas = std::max(max_err_mas, err_mas);
      ++checked;
    }
  }
  EXPECT_EQ(checked, 60);
  std::cout << "[ skyfield ] " << checked << " star directions, max error " << max_err_mas
            << " mas\n";
}

TEST(StarCatalog, ProperMotionMovesStarsLinearlyInTheTangentPlane) {
  const StarCatalog cat = StarCatalog::load_bsc5(kBsc5Path, 99.0);
  const Star* arcturus = cat.find(5340);
  ASSERT_NE(arcturus, nullptr);
  const double mu = std::hypot(arcturus->pm_ra_cosdec_radpyr, arcturus->pm_dec_radpyr);
  const astro::TimeTT t{static_cast<std::int64_t>(50.0 * 365.25 * 86400.0 * 1e9)};
  EXPECT_NEAR(angle_between(arcturus->unit_eci_at(t), arcturus->unit_eci_j2000()),
              std::atan(mu * 50.0), 1e-14);
  EXPECT_NEAR(arcturus->unit_eci_at(t).norm(), 1.0, 1e-15);
}

TEST(StarCatalog, SkipsBlankPositionsAndReadsBlankProperMotionAsZero) {
  const std::string removed = with_bytes(kHr3, 76, std::string(15, ' '));
  const std::string no_pm = with_bytes(kHr1, 149, std::string(12, ' '));
  std::istringstream in(no_pm + "\n" + removed + "\n\n");
  const StarCatalog cat = StarCatalog::parse_bsc5(in, "cat.dat", 99.0);
  ASSERT_EQ(cat.size(), 1u);
  EXPECT_EQ(cat.stars()[0].catalog_id, 1);
  EXPECT_EQ(cat.stars()[0].pm_ra_cosdec_radpyr, 0.0);
  EXPECT_EQ(cat.stars()[0].pm_dec_radpyr, 0.0);
  // The same lines, parsed in full, give the catalog values.
  std::istringstream in2(kHr1 + "\r\n" + kHr3 + "\n");
  const StarCatalog two = StarCatalog::parse_bsc5(in2, "cat.dat", 99.0);
  ASSERT_EQ(two.size(), 2u);
  EXPECT_DOUBLE_EQ(two.stars()[1].vmag, 4.61);
  EXPECT_NEAR(two.stars()[1].dec_rad / kDegToRad, -(5 + 42 / 60.0 + 27 / 3600.0), 1e-12);
  EXPECT_NEAR(two.stars()[0].pm_ra_cosdec_radpyr / kArcsecToRad, -0.012, 1e-12);
}

TEST(StarCatalog, MalformedLinesNameFileLineAndField) {
  const std::string bad_vmag = parse_error(kHr1 + "\n" + with_bytes(kHr3, 103, " 4.x1"));
  EXPECT_NE(bad_vmag.find("cat.dat:2: HR 3: Vmag (bytes 103-107): not a number: '4.x1'"),
            std::string::npos)
      << bad_vmag;
  const std::string bad_sign = parse_error(with_bytes(kHr1, 84, "*"));
  EXPECT_NE(bad_sign.find("cat.dat:1: HR 1: DE- (bytes 84-84)"), std::string::npos) << bad_sign;
  const std::string bad_minutes =
      parse_error(kHr3 + "\n" + kHr3 + "\n" + with_bytes(kHr1, 78, "61"));
  EXPECT_NE(bad_minutes.find("cat.dat:3: HR 1: RAm (bytes 78-79): out of range"), std::string::npos)
      << bad_minutes;
  const std::string bad_hr = parse_error(with_bytes(kHr1, 1, "  x1"));
  EXPECT_NE(bad_hr.find("cat.dat:1: HR (bytes 1-4)"), std::string::npos) << bad_hr;
  const std::string bad_pm = parse_error(with_bytes(kHr1, 155, "-0.0?8"));
  EXPECT_NE(bad_pm.find("pmDE (bytes 155-160)"), std::string::npos) << bad_pm;
  const std::string truncated = parse_error(kHr1.substr(0, 100));
  EXPECT_NE(truncated.find("Vmag (bytes 103-107): blank"), std::string::npos) << truncated;
  EXPECT_THROW(StarCatalog::load_bsc5(kBsc5Path + ".missing", 6.0), std::runtime_error);
}

TEST(StarCatalog, ConeQueryMatchesBruteForce) {
  const StarCatalog cat = StarCatalog::load_bsc5(kBsc5Path, 6.5);
  const astro::TimeTT t = astro::tt_from_utc_string("2024-05-08T00:00:00Z");
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n01;
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Vector3d dir(n01(rng), n01(rng), n01(rng));
    const double half = (2.0 + trial) * kDegToRad;
    const auto got = cat.in_cone(dir * 3.0, half, t);
    std::size_t expected = 0;
    for (const Star& s : cat.stars()) {
      if (angle_between(s.unit_eci_at(t), dir) <= half) ++expected;
    }
    EXPECT_EQ(got.size(), expected) << "trial " << trial;
    for (const Star* s : got) EXPECT_LE(angle_between(s->unit_eci_at(t), dir), half + 1e-12);
  }
  // Proper motion is applied: a 30 arcsec cone on Arcturus' position in 2100
  // holds it, the same cone on its J2000 position does not.
  const StarCatalog all = StarCatalog::load_bsc5(kBsc5Path, 99.0);
  const Star* arcturus = all.find(5340);
  const astro::TimeTT t2100{static_cast<std::int64_t>(100.0 * 365.25 * 86400.0 * 1e9)};
  const auto near_2100 = all.in_cone(arcturus->unit_eci_at(t2100), 30.0 * kArcsecToRad, t2100);
  ASSERT_EQ(near_2100.size(), 1u);
  EXPECT_EQ(near_2100[0]->catalog_id, 5340);
  EXPECT_TRUE(all.in_cone(arcturus->unit_eci_j2000(), 30.0 * kArcsecToRad, t2100).empty());
}

}  // namespace
}  // namespace artms::imaging
