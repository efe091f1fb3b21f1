// The force model shared by the truth propagator (Cowell, CVODE) and the
// onboard propagator (GVE, RK4): gravity to degree/order N, drag against a
// co-rotating atmosphere (Harris-Priester, or Harris-Priester rescaled by
// Jacchia 1971 with space weather), Sun and Moon third-body, cannonball SRP
// with Earth shadow. ECI J2000 components, SI units.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "artms/astro/frames.hpp"
#include "artms/astro/time.hpp"
#include "artms/dynamics/atmosphere.hpp"
#include "artms/dynamics/gravity.hpp"
#include "artms/dynamics/jacchia.hpp"
#include "artms/dynamics/shadow.hpp"

namespace artms::dynamics {

using astro::StateVector;

// Physical properties of one spacecraft. Defaults: a Starling-like 6U
// CubeSat; Cd A / m = 0.015 m^2/kg is the ballistic figure ARTMS flies
// (paper, "Dynamics Model").
struct SpacecraftProperties {
  double mass_kg = 10.0;
  double drag_area_m2 = 0.068;
  double cd = 2.2;
  double srp_area_m2 = 0.068;
  double cr = 1.3;
  // Attitude-like variation of the drag area over the orbit (truth side):
  // A = drag_area_m2 (1 + f cos 2u), u the argument of latitude (largest at
  // the nodes, smallest over the poles, twice per orbit); 0 <= f < 1.
  double drag_area_variation = 0.0;
  // Throws std::invalid_argument naming the bad field.
  void validate() const;
};

// The density model behind drag.
enum class AtmosphereModel {
  kHarrisPriester,               // M&G 3.5.2, mean solar activity (the paper's onboard model)
  kJacchiaScaledHarrisPriester,  // the table rescaled by J71's T_inf (jacchia.hpp)
};

// Defaults: the paper's onboard model (10x10 GGM01S, Harris-Priester drag,
// Sun, Moon; no SRP).
struct ForceModelOptions {
  int gravity_degree = 10;  // 0: point mass only
  int gravity_order = 10;
  bool drag = true;
  bool sun = true;
  bool moon = true;
  bool srp = false;
  ShadowModel shadow = ShadowModel::kConical;
  HarrisPriesterOptions atmosphere;
  AtmosphereModel atmosphere_model = AtmosphereModel::kHarrisPriester;
  SpaceWeather space_weather;  // kJacchiaScaledHarrisPriester only
  JacchiaOptions jacchia;      // kJacchiaScaledHarrisPriester only

  // The truth side's default, a world richer than the onboard model:
  // GGM01S 20x20 (cost: docs/dynamics.md), drag with the Jacchia-scaled
  // atmosphere and the default space weather, SRP (conical shadow), Sun, Moon.
  static ForceModelOptions flight_like_truth();

  // Parses the artms-propagate --force syntax (DESIGN.md section 7):
  // "two-body", "j2" (point mass + the degree-2 zonal of the shipped field),
  // "flight-like" (flight_like_truth()), or a comma list of gravN (N x N),
  // gravN_M, drag, drag-jacchia (drag with the Jacchia-scaled atmosphere,
  // default space weather), sun, moon, srp.
  // Throws std::invalid_argument naming the unknown item.
  static ForceModelOptions parse(std::string_view spec);
  // Names every term, with the atmosphere model and its space weather.
  [[nodiscard]] std::string describe() const;
};

// Impulsive maneuver: delta-v in the RTN frame of the spacecraft at epoch t.
struct ImpulsiveManeuver {
  astro::TimeTT t;
  astro::Vec3 dv_rtn_mps = astro::Vec3::Zero();
};
// Applies a maneuver to a state (velocity change in the RTN frame of x).
StateVector apply_maneuver(const StateVector& x_eci, const astro::Vec3& dv_rtn_mps);

class ForceModel {
 public:
  // Loads the gravity field (data/gravity/GGM01S.gfc) and, if drag is on,
  // the Harris-Priester table (data/atmosphere/harris_priester_table.csv)
  // from data_dir. Throws std::runtime_error naming a missing file,
  // std::invalid_argument for bad space weather (naming the field).
  static ForceModel load(const ForceModelOptions& options, const std::string& data_dir);
  ForceModel(const ForceModelOptions& options, const GravityField& field,
             std::optional<HarrisPriester> atmosphere);

  // Drag density (kg/m^3) at t for the ECI position, from whichever
  // atmosphere the options name; 0 with drag off.
  [[nodiscard]] double density_kgpm3(astro::TimeTT t, const Vec3& r_eci_m) const;

  // Total acceleration (central term included), ECI, m/s^2.
  [[nodiscard]] Vec3 acceleration_eci(astro::TimeTT t, const StateVector& x_eci,
                                      const SpacecraftProperties& sc) const;
  // Everything but the central GM/r^2 term (the d of the GVE), ECI.
  [[nodiscard]] Vec3 perturbation_eci(astro::TimeTT t, const StateVector& x_eci,
                                      const SpacecraftProperties& sc) const;

  // Drag acceleration of a spacecraft with a ballistic coefficient Cd A/m of
  // 1 m^2/kg (ECI); zero without drag. Scaled by a ballistic coefficient, the
  // drag of any spacecraft: what SOD's differential ballistic state needs.
  [[nodiscard]] Vec3 unit_ballistic_drag_eci(astro::TimeTT t, const StateVector& x_eci) const;

  [[nodiscard]] const ForceModelOptions& options() const { return options_; }
  [[nodiscard]] double gm_m3ps2() const { return gravity_.gm_m3ps2(); }

 private:
  [[nodiscard]] Vec3 evaluate(astro::TimeTT t, const StateVector& x, const SpacecraftProperties& sc,
                              bool central) const;
  [[nodiscard]] double density(astro::TimeTT t, const Vec3& r_eci_m, const Vec3& r_ecef_m,
                               const Vec3& r_sun_eci_m) const;
  ForceModelOptions options_;
  SphericalHarmonicGravity gravity_;
  std::optional<HarrisPriester> atmosphere_;
  std::optional<JacchiaScaledHarrisPriester> jacchia_;
};

}  // namespace artms::dynamics
