#include "artms/dynamics/forces.hpp"

#include <cmath>
#include <filesystem>
#include <sstream>
#include <stdexcept>

#include "artms/dynamics/ephemeris.hpp"

namespace artms::dynamics {

namespace {
// Gravity of flight_like_truth(): docs/dynamics.md, "Truth default and its cost".
constexpr int kFlightLikeGravityDegree = 20;
}  // namespace

void SpacecraftProperties::validate() const {
  const auto positive = [](double v, const char* name) {
    if (!(v > 0.0) || !std::isfinite(v)) {
      throw std::invalid_argument(std::string("spacecraft property ") + name +
                                  " must be a positive number, got " + std::to_string(v));
    }
  };
  positive(mass_kg, "mass_kg");
  positive(drag_area_m2, "drag_area_m2");
  positive(cd, "cd");
  positive(srp_area_m2, "srp_area_m2");
  positive(cr, "cr");
  if (!(drag_area_variation >= 0.0 && drag_area_variation < 1.0)) {
    throw std::invalid_argument("spacecraft property drag_area_variation must lie in [0, 1), got " +
                                std::to_string(drag_area_variation));
  }
}

namespace {

// cos 2u of the argument of latitude u of (r, v): c = n.r, s = (n x r).h with
// n the ascending node and h the orbit normal (units), cos 2u = (c^2 - s^2)/(c^2 + s^2).
double cos_twice_argument_of_latitude(const Vec3& r, const Vec3& v) {
  const Vec3 h = r.cross(v).normalized();
  Vec3 n(-h.y(), h.x(), 0.0);
  const double nn = n.norm();
  n = nn > 1e-12 ? Vec3(n / nn) : Vec3::UnitX();  // equatorial: u from the x axis
  const double c = n.dot(r), s = n.cross(r).dot(h);
  return (c * c - s * s) / (c * c + s * s);
}

}  // namespace

ForceModelOptions ForceModelOptions::flight_like_truth() {
  ForceModelOptions o;
  o.gravity_degree = o.gravity_order = kFlightLikeGravityDegree;
  o.drag = o.sun = o.moon = o.srp = true;
  o.shadow = ShadowModel::kConical;
  o.atmosphere_model = AtmosphereModel::kJacchiaScaledHarrisPriester;
  return o;
}

ForceModelOptions ForceModelOptions::parse(std::string_view spec) {
  if (spec == "flight-like") return flight_like_truth();
  ForceModelOptions o;
  o.drag = o.sun = o.moon = o.srp = false;
  if (spec == "two-body") {
    o.gravity_degree = o.gravity_order = 0;
    return o;
  }
  if (spec == "j2") {
    o.gravity_degree = 2;
    o.gravity_order = 0;
    return o;
  }
  o.gravity_degree = o.gravity_order = 0;
  std::string item;
  std::stringstream ss{std::string(spec)};
  bool any = false;
  while (std::getline(ss, item, ',')) {
    any = true;
    if (item == "drag") {
      o.drag = true;
    } else if (item == "drag-jacchia") {
      o.drag = true;
      o.atmosphere_model = AtmosphereModel::kJacchiaScaledHarrisPriester;
    } else if (item == "sun") {
      o.sun = true;
    } else if (item == "moon") {
      o.moon = true;
    } else if (item == "srp") {
      o.srp = true;
    } else if (item.rfind("grav", 0) == 0 && item.size() > 4) {
      int n = -1, m = -1;
      char sep = 0;
      std::istringstream in(item.substr(4));
      in >> n;
      if (in >> sep) {
        if (sep != '_' || !(in >> m)) n = -1;
      } else {
        m = n;
      }
      if (n < 0 || m < 0 || m > n || !in.eof()) {
        throw std::invalid_argument("force model: '" + item +
                                    "' is not gravN or gravN_M with 0 <= M <= N");
      }
      o.gravity_degree = n;
      o.gravity_order = m;
    } else {
      throw std::invalid_argument("force model: unknown item '" + item +
                                  "' (expected two-body, j2, flight-like, or a comma list of gravN, "
                                  "gravN_M, drag, drag-jacchia, sun, moon, srp)");
    }
  }
  if (!any) throw std::invalid_argument("force model: empty specification");
  return o;
}

std::string ForceModelOptions::describe() const {
  std::ostringstream s;
  s << "gravity " << gravity_degree << "x" << gravity_order;
  if (drag && atmosphere_model == AtmosphereModel::kHarrisPriester) {
    s << ", Harris-Priester drag (n=" << atmosphere.cosine_exponent << ")";
  } else if (drag) {
    const SpaceWeather& w = space_weather;
    s << ", drag with Harris-Priester scaled by Jacchia 1971 (F10.7 " << w.f107_sfu << ", 81-day "
      << w.f107_81day_sfu << ", Kp " << w.kp;
    if (!w.daily.empty()) s << ", " << w.daily.size() << " daily values";
    if (w.f107_daily_sigma_sfu > 0.0 || w.kp_daily_sigma > 0.0) {
      s << ", day-to-day sigma F10.7 " << w.f107_daily_sigma_sfu << " Kp " << w.kp_daily_sigma;
    }
    if (w.density_error_sigma > 0.0) {
      s << ", density model error sigma " << w.density_error_sigma << " over " << w.density_error_time_s << " s";
    }
    if (jacchia.semiannual) s << ", semi-annual";
    s << ", T_ref " << jacchia.reference_temperature_K << " K)";
  }
  if (sun) s << ", Sun";
  if (moon) s << ", Moon";
  if (srp) s << ", SRP (" << (shadow == ShadowModel::kConical ? "conical" : "cylindrical") << " shadow)";
  return s.str();
}

StateVector apply_maneuver(const StateVector& x, const astro::Vec3& dv_rtn) {
  StateVector out = x;
  out.v_mps += astro::R_rtn_from_eci(x).transpose() * dv_rtn;
  return out;
}

ForceModel ForceModel::load(const ForceModelOptions& options, const std::string& data_dir) {
  const std::string gfc = data_dir + "/gravity/GGM01S.gfc";
  const GravityField field = GravityField::from_gfc(gfc, std::max(options.gravity_degree, 2));
  std::optional<HarrisPriester> hp;
  if (options.drag) {
    hp = HarrisPriester::from_file(data_dir + "/atmosphere/harris_priester_table.csv",
                                   options.atmosphere);
  }
  return ForceModel(options, field, std::move(hp));
}

ForceModel::ForceModel(const ForceModelOptions& options, const GravityField& field,
                       std::optional<HarrisPriester> atmosphere)
    : options_(options),
      gravity_(field, options.gravity_degree, options.gravity_order),
      atmosphere_(std::move(atmosphere)) {
  if (options_.drag && !atmosphere_) {
    throw std::invalid_argument("ForceModel: drag enabled but no atmosphere model given");
  }
  if (options_.drag && options_.atmosphere_model == AtmosphereModel::kJacchiaScaledHarrisPriester) {
    jacchia_.emplace(*atmosphere_, options_.space_weather, options_.jacchia);
  }
}

double ForceModel::density(astro::TimeTT t, const Vec3& r_eci, const Vec3& r_ecef, const Vec3& r_sun) const {
  if (jacchia_) return jacchia_->density_kgpm3(t, r_eci, r_ecef, r_sun);
  return atmosphere_->density_kgpm3(r_eci, r_ecef, r_sun);
}

double ForceModel::density_kgpm3(astro::TimeTT t, const Vec3& r_eci_m) const {
  if (!options_.drag) return 0.0;
  return density(t, r_eci_m, astro::R_ecef_from_eci(t) * r_eci_m, sun_position_eci_m(t));
}

Vec3 ForceModel::evaluate(astro::TimeTT t, const StateVector& x, const SpacecraftProperties& sc,
                          bool central) const {
  Vec3 a = Vec3::Zero();
  const bool need_ecef = options_.gravity_degree > 0 || options_.drag;
  Mat3 R_ecef_from_eci = Mat3::Identity();
  Vec3 r_ecef = x.r_m;
  if (need_ecef) {
    R_ecef_from_eci = astro::R_ecef_from_eci(t);
    r_ecef = R_ecef_from_eci * x.r_m;
  }
  // Gravity in the Earth-fixed frame (tesseral terms rotate with the Earth).
  if (options_.gravity_degree > 0) {
    a += R_ecef_from_eci.transpose() *
         (central ? gravity_.acceleration_ecef(r_ecef) : gravity_.perturbation_ecef(r_ecef));
  } else if (central) {
    a += -gravity_.gm_m3ps2() * x.r_m / std::pow(x.r_m.norm(), 3);
  }
  Vec3 r_sun = Vec3::Zero();
  if (options_.sun || options_.srp || options_.drag) r_sun = sun_position_eci_m(t);
  if (options_.sun) a += third_body_acceleration_mps2(x.r_m, r_sun, kGmSun_m3ps2);
  if (options_.moon) a += third_body_acceleration_mps2(x.r_m, moon_position_eci_m(t), kGmMoon_m3ps2);
  if (options_.drag) {
    const double rho = density(t, x.r_m, r_ecef, r_sun);
    double area_m2 = sc.drag_area_m2;
    if (sc.drag_area_variation != 0.0) {
      area_m2 *= 1.0 + sc.drag_area_variation * cos_twice_argument_of_latitude(x.r_m, x.v_mps);
    }
    a += drag_acceleration_mps2(x.r_m, x.v_mps, rho, sc.cd, area_m2 / sc.mass_kg);
  }
  if (options_.srp) {
    a += srp_acceleration_mps2(x.r_m, r_sun, sc.cr, sc.srp_area_m2 / sc.mass_kg, options_.shadow);
  }
  return a;
}

Vec3 ForceModel::acceleration_eci(astro::TimeTT t, const StateVector& x,
                                  const SpacecraftProperties& sc) const {
  return evaluate(t, x, sc, true);
}

Vec3 ForceModel::perturbation_eci(astro::TimeTT t, const StateVector& x,
                                  const SpacecraftProperties& sc) const {
  return evaluate(t, x, sc, false);
}

Vec3 ForceModel::unit_ballistic_drag_eci(astro::TimeTT t, const StateVector& x) const {
  if (!options_.drag) return Vec3::Zero();
  const Vec3 r_ecef = astro::R_ecef_from_eci(t) * x.r_m;
  const double rho = atmosphere_->density_kgpm3(x.r_m, r_ecef, sun_position_eci_m(t));
  return drag_acceleration_mps2(x.r_m, x.v_mps, rho, 1.0, 1.0);
}

}  // namespace artms::dynamics
