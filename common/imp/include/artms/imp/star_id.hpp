// Star identification (paper, "Image Processing": "the Pyramid star
// identification algorithm is applied to remove Stellar Objects from the
// list of pointing vectors").
//
// Lost in space: the Pyramid technique of Mortari, Samaan, Bruccoleri and
// Junkins (2004, "The Pyramid Star Identification Technique", Navigation
// 51(3)), with the k-vector range search of Mortari and Neta (2000, "k-vector
// range searching techniques", AAS 00-128) over a table of catalog star
// pairs built once at start-up.
//
//  * Catalog: every pair of catalog stars closer than max_pair_angle_rad (the
//    field-of-view diagonal) with the cosine of its angle, sorted by cosine.
//    The k-vector: with the sorted cosines s_0 <= ... <= s_{n-1} and the line
//    z(k) = m k + q through (0, s_0 - d) and (n - 1, s_{n-1} + d) (d a few
//    ulps), K[k] = #{ i : s_i <= z(k) }. All pairs with cosine in [a, b] then
//    lie in [K[floor((a - q) / m)], K[ceil((b - q) / m)]) plus at most a
//    couple of extra entries at the ends, trimmed by comparison: a range
//    search in O(1) independent of the catalog size.
//  * Triangles of measured stars i < j < k are visited in Pyramid's order
//      for dj = 1..n-2, for dk = 1..n-dj-1, for i = 1..n-dj-dk: j = i + dj,
//      k = j + dk,
//    which cycles quickly through all stars, so that a false star (a target,
//    an uncatalogued star, a hot pixel) is left out after a few triangles.
//    Input vectors should be sorted brightest first (detect() does): only
//    the first max_stars take part in the search.
//  * For each side, the catalog pairs whose angle is within
//    match_tolerance_rad of the measured one (k-vector); catalog triangles
//    (I, J, K) with (I, J), (I, K), (J, K) all candidates. The spectral
//    (handedness) test: sign(b_i . (b_j x b_k)) must equal
//    sign(r_I . (r_J x r_K)) (a mirror image has the same side lengths);
//    near-collinear measured triangles (|triple product| < min_triple_product)
//    are skipped.
//  * The pyramid: a fourth measured star r whose three sides to i, j, k
//    match catalog pairs (I, R), (J, R), (K, R) for exactly one catalog star
//    R confirms the triangle. A measured triangle is accepted only if exactly
//    one of its catalog triangles is confirmed.
//  * With the four pairs, the attitude (Kabsch/SVD solution of Wahba's
//    problem); every input vector is then matched to the nearest catalog star
//    within accept_tolerance_rad, one centroid per catalog star, and the
//    attitude re-solved from all matches (twice). The answer stands only if
//    at least min_matches_lost_in_space stars match (the pyramid plus at
//    least one independent star); otherwise the search goes on.
//
// Tracking: identify_with_prior() projects the catalog with a previous
// attitude and matches each vector to its nearest catalog star within a
// tolerance that covers the attitude change since; then the same refinement.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>
#include <utility>
#include <vector>

namespace artms::imp {

struct CatalogStar {
  int id = 0;             // catalog number (BSC5: HR)
  Eigen::Vector3d u_eci;  // unit direction at the frame epoch, ECI (J2000)
  double vmag = 0.0;      // visual magnitude (0 when the catalog file has none)
};

class StarIdCatalog {
 public:
  // A catalog pair: indices into stars(), a < b, and cos(angle).
  struct Pair {
    double cos_angle = 0.0;
    int a = 0;
    int b = 0;
  };

  StarIdCatalog() = default;
  // Builds the pair table (all pairs within max_pair_angle_rad, usually the
  // sensor's diagonal field of view) and its k-vector. Directions are
  // normalised. Throws std::invalid_argument on an empty catalog, duplicate
  // ids or an angle outside (0, pi/2].
  static StarIdCatalog build(std::vector<CatalogStar> stars, double max_pair_angle_rad);

  [[nodiscard]] const std::vector<CatalogStar>& stars() const { return stars_; }
  [[nodiscard]] const std::vector<Pair>& pairs() const { return pairs_; }
  [[nodiscard]] double max_pair_angle_rad() const { return max_pair_angle_rad_; }
  // Index of a catalog id in stars(), -1 if absent.
  [[nodiscard]] int index_of(int id) const;

  // k-vector range search: [first, last) into pairs() of the pairs with
  // cos_lo <= cos_angle <= cos_hi.
  [[nodiscard]] std::pair<std::size_t, std::size_t> pairs_in_cos_range(double cos_lo,
                                                                       double cos_hi) const;
  // The same for angles in [angle_lo, angle_hi] (radians).
  [[nodiscard]] std::pair<std::size_t, std::size_t> pairs_in_angle_range(double angle_lo,
                                                                         double angle_hi) const;
  // Indices of the stars within half_angle_rad of dir (any length).
  [[nodiscard]] std::vector<int> in_cone(const Eigen::Vector3d& dir, double half_angle_rad) const;

 private:
  std::vector<CatalogStar> stars_;
  std::vector<Pair> pairs_;        // sorted by cos_angle
  std::vector<std::size_t> kvec_;  // k-vector, same length as pairs_
  double m_ = 0.0, q_ = 0.0;       // k-vector line z(k) = m k + q
  double max_pair_angle_rad_ = 0.0;
  std::vector<std::pair<int, int>> id_index_;  // (id, index), sorted by id
};

struct StarIdOptions {
  // Tolerance on a measured inter-star angle against the catalog's (k-vector
  // search). Several times the pair-angle noise: sqrt(2) x the single-star
  // direction error, plus calibration errors (default ~20 arcsec: the NST's
  // centroids are good to ~0.1 px = 3.4 arcsec).
  double match_tolerance_rad = 1.0e-4;
  // Tolerance of a single star against its catalog direction once the
  // attitude is known (final matching); <= 0: match_tolerance_rad.
  double accept_tolerance_rad = 0.0;
  // Brightest input vectors taking part in the triangle search.
  int max_stars = 12;
  // Give up after this many measured triangles.
  int max_triangles = 500;
  // Catalog triangles per measured triangle taken to the pyramid test; more
  // than this: the triangle is too ambiguous, skip it.
  int max_candidates_per_triangle = 20;
  // Measured triangles with |b_i . (b_j x b_k)| below this are skipped
  // (the handedness test would be unreliable).
  double min_triple_product = 1.0e-6;
  // Fewest matched stars (pyramid included) for a usable lost-in-space
  // solution. With 4, a pyramid of random directions is "confirmed" by the
  // 800,000-pair BSC5 table now and then (1 in 30 random 12-star skies at
  // 20 arcsec); one more star within accept_tolerance of a catalog star is
  // then a ~1e-4 coincidence per extra vector.
  int min_matches_lost_in_space = 5;
  // Fewest matched stars for a usable tracking solution.
  int min_matches_tracking = 3;

  // Throws std::invalid_argument naming the first bad field.
  void validate() const;
  [[nodiscard]] double accept_tolerance() const {
    return accept_tolerance_rad > 0.0 ? accept_tolerance_rad : match_tolerance_rad;
  }
};

struct StarIdResult {
  bool usable = false;
  std::string why;  // empty when usable
  // (index into the input vectors, catalog id), sorted by input index.
  std::vector<std::pair<int, int>> matches;
  // Rotates ECI components into camera components (identity when unusable).
  Eigen::Quaterniond q_cam_from_eci = Eigen::Quaterniond::Identity();
  // RMS angle between the matched vectors and the rotated catalog directions.
  double residual_rms_rad = 0.0;
  int triangles_tried = 0;
};

// Kabsch/SVD solution of Wahba's problem: the rotation R (as a quaternion)
// minimising sum w_i |b_i - R r_i|^2; equal weights if w is empty.
Eigen::Quaterniond solve_wahba_svd(const std::vector<Eigen::Vector3d>& b_cam,
                                   const std::vector<Eigen::Vector3d>& r_eci,
                                   const std::vector<double>& w = {});

// Lost-in-space identification of unit vectors in camera components (sorted
// brightest first). Throws std::invalid_argument on invalid options.
StarIdResult identify_lost_in_space(const std::vector<Eigen::Vector3d>& unit_vectors_cam,
                                    const StarIdCatalog& catalog, const StarIdOptions& options);

// Tracking mode: nearest-neighbour matching of the catalog projected with
// q_prior (q_cam_from_eci of a previous frame), within tolerance_rad, then
// refinement as above with options.accept_tolerance().
StarIdResult identify_with_prior(const std::vector<Eigen::Vector3d>& unit_vectors_cam,
                                 const StarIdCatalog& catalog, const Eigen::Quaterniond& q_prior,
                                 double tolerance_rad, const StarIdOptions& options = {});

}  // namespace artms::imp
