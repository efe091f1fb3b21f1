// Harris-Priester atmosphere (Montenbruck & Gill 2000, section 3.5.2) from
// the table in data/atmosphere/harris_priester_table.csv, and cannonball drag
// against an atmosphere co-rotating with the Earth.
#pragma once

#include <string>
#include <vector>

#include "artms/astro/frames.hpp"

namespace artms::dynamics {

using astro::Vec3;

struct HarrisPriesterOptions {
  // Cosine exponent n of the diurnal bulge, rho_m + (rho_M - rho_m)
  // cos^n(psi/2) (M&G section 3.5.2): 2 for low-inclination, 6 for polar orbits.
  // M&G's code (and brahe) raise cos^2(psi/2) to n_prm = 3, i.e. n = 6; the
  // brahe reference cases need n = 6. Starling flies at 97-99 deg.
  double cosine_exponent = 6.0;
  double lag_angle_rad = 0.523599;  // 30 deg: bulge apex lags the Sun in RA
};

class HarrisPriester {
 public:
  // Loads the table (height_km, rho_min, rho_max in g/km^3; '#' lines are
  // comments; header row height_km,rho_min_g_per_km3,rho_max_g_per_km3).
  // Throws std::runtime_error naming the file and line on malformed input
  // (non-numbers, wrong field count, heights not increasing, densities not
  // decreasing with height or rho_min > rho_max), std::invalid_argument for a
  // non-positive cosine exponent.
  static HarrisPriester from_file(const std::string& csv_path,
                                  const HarrisPriesterOptions& options = {});

  // Density (kg/m^3) at the satellite position. r_eci_m and r_sun_eci_m give
  // the bulge geometry; the height is the WGS84 geodetic height of r_ecef_m
  // (same vector for both is what M&G and brahe do when no ECEF is at hand).
  // Returns 0 above the table's top (1000 km); below its bottom (100 km),
  // throws std::out_of_range (the orbit has decayed).
  [[nodiscard]] double density_kgpm3(const Vec3& r_eci_m, const Vec3& r_ecef_m,
                                     const Vec3& r_sun_eci_m) const;

  // The table's night minimum and day maximum (kg/m^3) at a WGS84 height,
  // exponentially interpolated; {0, 0} above the top, std::out_of_range
  // below the bottom.
  struct Densities {
    double min_kgpm3 = 0.0;
    double max_kgpm3 = 0.0;
  };
  [[nodiscard]] Densities table_densities(double height_m) const;

  [[nodiscard]] const HarrisPriesterOptions& options() const { return options_; }

 private:
  HarrisPriesterOptions options_;
  std::vector<double> height_m_, rho_min_, rho_max_;
};

// WGS84 geodetic height (m) of an Earth-fixed position (Bowring/iterative).
double geodetic_height_m(const Vec3& r_ecef_m);

// Cannonball drag: a = -0.5 rho Cd (A/m) |v_rel| v_rel with
// v_rel = v_eci - omega_earth x r_eci (co-rotating atmosphere), ECI.
Vec3 drag_acceleration_mps2(const Vec3& r_eci_m, const Vec3& v_eci_mps, double density_kgpm3,
                            double cd, double area_to_mass_m2pkg);

}  // namespace artms::dynamics
