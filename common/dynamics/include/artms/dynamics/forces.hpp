// The force model shared by the truth propagator (Cowell, CVODE) and the
// onboard propagator (GVE, RK4): gravity to degree/order N, Harris-Priester
// drag against a co-rotating atmosphere, Sun and Moon third-body, cannonball
// SRP with Earth shadow. ECI J2000 components, SI units.
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
  // Throws std::invalid_argument naming the bad field.
  void validate() const;
};

struct ForceModelOptions {
  int gravity_degree = 10;  // 0: point mass only
  int gravity_order = 10;
  bool drag = true;
  bool sun = true;
  bool moon = true;
  bool srp = false;
  ShadowModel shadow = ShadowModel::kConical;
  HarrisPriesterOptions atmosphere;

  // Parses the artms-propagate --force syntax (DESIGN.md section 7):
  // "two-body", "j2" (point mass + the degree-2 zonal of the shipped field),
  // or a comma list of gravN (N x N), gravN_M, drag, sun, moon, srp.
  // Throws std::invalid_argument naming the unknown item.
  static ForceModelOptions parse(std::string_view spec);
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
  // from data_dir. Throws std::runtime_error naming a missing file.
  static ForceModel load(const ForceModelOptions& options, const std::string& data_dir);
  ForceModel(const ForceModelOptions& options, const GravityField& field,
             std::optional<HarrisPriester> atmosphere);

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
  ForceModelOptions options_;
  SphericalHarmonicGravity gravity_;
  std::optional<HarrisPriester> atmosphere_;
};

}  // namespace artms::dynamics
