// Star catalog: the Yale Bright Star Catalogue (BSC5, data/stars/bsc5.dat),
// J2000 positions at epoch J2000 with proper motion.
#pragma once

#include <Eigen/Core>
#include <istream>
#include <string>
#include <vector>

#include "artms/astro/time.hpp"

namespace artms::imaging {

struct Star {
  int catalog_id = 0;   // Harvard Revised (HR) number
  double ra_rad = 0.0;  // J2000 equator and equinox, epoch J2000.0
  double dec_rad = 0.0;
  double vmag = 0.0;
  double b_minus_v = 0.65;  // Johnson B-V (BSC5 bytes 110-114; solar when blank)
  double pm_ra_cosdec_radpyr = 0.0;  // mu_alpha * cos(dec), rad per Julian year
  double pm_dec_radpyr = 0.0;        // rad per Julian year

  // Unit direction in ECI (J2000) at time t. Linear proper motion in the
  // tangent plane: u(t) = normalize(u0 + (mu_a* e_ra + mu_d e_dec) dt), dt in
  // Julian years of TT from J2000.0. For a star with zero parallax and radial
  // velocity this is the rigorous space motion (straight-line motion seen
  // from the origin), so it has no 1/cos(dec) singularity at the poles.
  [[nodiscard]] Eigen::Vector3d unit_eci_at(astro::TimeTT t) const;
  [[nodiscard]] Eigen::Vector3d unit_eci_j2000() const;
};

class StarCatalog {
 public:
  StarCatalog() = default;
  explicit StarCatalog(std::vector<Star> stars);

  // Reads BSC5 fixed-width lines (CDS V/50 byte layout, see data/README.md:
  // HR 1-4, RA J2000 76-83 "hhmmss.s", Dec J2000 84-90 "+ddmmss", Vmag
  // 103-107, pmRA 149-154 and pmDE 155-160 in arcsec/yr; pmRA is
  // mu_alpha*cos(dec)). Keeps stars with vmag <= vmag_limit. Entries with a
  // blank position (novae, non-stellar objects removed from BSC5) are
  // skipped; blank proper motions read as zero. Any other malformed field
  // throws std::runtime_error "file:line: HR n: field (bytes a-b): problem".
  static StarCatalog load_bsc5(const std::string& path, double vmag_limit);
  static StarCatalog parse_bsc5(std::istream& in, const std::string& source_name,
                                double vmag_limit);

  [[nodiscard]] const std::vector<Star>& stars() const { return stars_; }
  [[nodiscard]] std::size_t size() const { return stars_.size(); }
  // nullptr if absent.
  [[nodiscard]] const Star* find(int catalog_id) const;

  // Stars whose direction at time t lies within half_angle_rad of dir_eci
  // (any length), in catalog order. A prefilter on J2000 directions widened
  // by the largest proper-motion displacement keeps this a dot product per
  // star.
  [[nodiscard]] std::vector<const Star*> in_cone(const Eigen::Vector3d& dir_eci,
                                                 double half_angle_rad, astro::TimeTT t) const;

 private:
  std::vector<Star> stars_;
  std::vector<Eigen::Vector3d> u_j2000_;  // parallel to stars_
  double max_pm_radpyr_ = 0.0;
};

}  // namespace artms::imaging
