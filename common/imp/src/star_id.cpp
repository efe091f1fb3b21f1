#include "artms/imp/star_id.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <iterator>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace artms::imp {

using Vec3 = Eigen::Vector3d;

// ---------------------------------------------------------------------------
// Catalog and k-vector
// ---------------------------------------------------------------------------

StarIdCatalog StarIdCatalog::build(std::vector<CatalogStar> stars, double max_pair_angle_rad) {
  if (stars.empty()) throw std::invalid_argument("StarIdCatalog::build: empty catalog");
  if (!(max_pair_angle_rad > 0.0) || max_pair_angle_rad > std::numbers::pi / 2) {
    throw std::invalid_argument("StarIdCatalog::build: max_pair_angle_rad must be in (0, pi/2]");
  }
  StarIdCatalog c;
  c.max_pair_angle_rad_ = max_pair_angle_rad;
  for (auto& s : stars) {
    const double n = s.u_eci.norm();
    if (!(n > 0.0) || !std::isfinite(n)) {
      throw std::invalid_argument("StarIdCatalog::build: star " + std::to_string(s.id) +
                                  " has no direction");
    }
    s.u_eci /= n;
  }
  c.stars_ = std::move(stars);
  const int n_stars = static_cast<int>(c.stars_.size());
  c.id_index_.reserve(c.stars_.size());
  for (int i = 0; i < n_stars; ++i)
    c.id_index_.emplace_back(c.stars_[static_cast<std::size_t>(i)].id, i);
  std::sort(c.id_index_.begin(), c.id_index_.end());
  for (std::size_t k = 1; k < c.id_index_.size(); ++k) {
    if (c.id_index_[k].first == c.id_index_[k - 1].first) {
      throw std::invalid_argument("StarIdCatalog::build: duplicate id " +
                                  std::to_string(c.id_index_[k].first));
    }
  }

  // All pairs within the angle: sweep in z, since the chord 2 sin(angle / 2)
  // bounds |z_a - z_b|.
  std::vector<int> order(c.stars_.size());
  for (int i = 0; i < n_stars; ++i) order[static_cast<std::size_t>(i)] = i;
  auto z = [&](int i) { return c.stars_[static_cast<std::size_t>(i)].u_eci.z(); };
  std::sort(order.begin(), order.end(), [&](int a, int b) { return z(a) < z(b); });
  const double chord = 2.0 * std::sin(max_pair_angle_rad / 2.0);
  const double cos_min = std::cos(max_pair_angle_rad);
  for (std::size_t p = 0; p < order.size(); ++p) {
    const int a = order[p];
    const Vec3& ua = c.stars_[static_cast<std::size_t>(a)].u_eci;
    for (std::size_t q = p + 1; q < order.size(); ++q) {
      const int b = order[q];
      if (z(b) - ua.z() > chord) break;
      const double cs = ua.dot(c.stars_[static_cast<std::size_t>(b)].u_eci);
      if (cs >= cos_min) c.pairs_.push_back({cs, std::min(a, b), std::max(a, b)});
    }
  }
  std::sort(c.pairs_.begin(), c.pairs_.end(), [](const Pair& x, const Pair& y) {
    return x.cos_angle < y.cos_angle ||
           (x.cos_angle == y.cos_angle && (x.a < y.a || (x.a == y.a && x.b < y.b)));
  });

  // k-vector (Mortari and Neta 2000), 0-based.
  const std::size_t n = c.pairs_.size();
  if (n > 0) {
    const double ymin = c.pairs_.front().cos_angle, ymax = c.pairs_.back().cos_angle;
    const double d =
        4.0 * std::numeric_limits<double>::epsilon() * std::max(std::abs(ymin), std::abs(ymax));
    c.m_ = n > 1 ? (ymax - ymin + 2.0 * d) / static_cast<double>(n - 1) : 1.0;
    if (!(c.m_ > 0.0)) c.m_ = 1.0;
    c.q_ = ymin - d;
    c.kvec_.resize(n);
    std::size_t i = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const double zk = c.m_ * static_cast<double>(k) + c.q_;
      while (i < n && c.pairs_[i].cos_angle <= zk) ++i;
      c.kvec_[k] = i;
    }
    c.kvec_[n - 1] = n;
  }
  return c;
}

int StarIdCatalog::index_of(int id) const {
  const auto it = std::lower_bound(id_index_.begin(), id_index_.end(),
                                   std::make_pair(id, std::numeric_limits<int>::min()));
  return (it != id_index_.end() && it->first == id) ? it->second : -1;
}

std::pair<std::size_t, std::size_t> StarIdCatalog::pairs_in_cos_range(double a, double b) const {
  const std::size_t n = pairs_.size();
  if (n == 0 || !(a <= b) || b < pairs_.front().cos_angle) return {0, 0};
  if (a > pairs_.back().cos_angle) return {n, n};
  const double last_k = static_cast<double>(n - 1);
  const auto jb = static_cast<std::size_t>(std::clamp(std::floor((a - q_) / m_), 0.0, last_k));
  const auto jt = static_cast<std::size_t>(std::clamp(std::ceil((b - q_) / m_), 0.0, last_k));
  std::size_t first = kvec_[jb];
  while (first > 0 && pairs_[first - 1].cos_angle >= a) --first;
  while (first < n && pairs_[first].cos_angle < a) ++first;
  std::size_t last = std::max(first, kvec_[jt]);
  while (last < n && pairs_[last].cos_angle <= b) ++last;
  while (last > first && pairs_[last - 1].cos_angle > b) --last;
  return {first, last};
}

std::pair<std::size_t, std::size_t> StarIdCatalog::pairs_in_angle_range(double lo,
                                                                        double hi) const {
  lo = std::max(lo, 0.0);
  hi = std::min(hi, std::numbers::pi);
  if (!(lo <= hi)) return {0, 0};
  return pairs_in_cos_range(std::cos(hi), std::cos(lo));
}

std::vector<int> StarIdCatalog::in_cone(const Vec3& dir, double half_angle_rad) const {
  std::vector<int> out;
  const Vec3 d = dir.normalized();
  const double c = std::cos(std::min(half_angle_rad, std::numbers::pi));
  for (std::size_t i = 0; i < stars_.size(); ++i) {
    if (stars_[i].u_eci.dot(d) >= c) out.push_back(static_cast<int>(i));
  }
  return out;
}

// ---------------------------------------------------------------------------
// Options, Wahba
// ---------------------------------------------------------------------------

void StarIdOptions::validate() const {
  auto bad = [](const std::string& what) { throw std::invalid_argument("StarIdOptions: " + what); };
  if (!(match_tolerance_rad > 0.0) || !std::isfinite(match_tolerance_rad)) {
    bad("match_tolerance_rad must be positive");
  }
  if (!std::isfinite(accept_tolerance_rad)) bad("accept_tolerance_rad must be finite");
  if (max_stars < 3) bad("max_stars must be at least 3");
  if (max_triangles < 1) bad("max_triangles must be at least 1");
  if (max_candidates_per_triangle < 1) bad("max_candidates_per_triangle must be at least 1");
  if (!(min_triple_product >= 0.0)) bad("min_triple_product must be >= 0");
  if (min_matches_lost_in_space < 4) bad("min_matches_lost_in_space must be at least 4");
  if (min_matches_tracking < 2) bad("min_matches_tracking must be at least 2");
}

Eigen::Quaterniond solve_wahba_svd(const std::vector<Vec3>& b, const std::vector<Vec3>& r,
                                   const std::vector<double>& w) {
  if (b.size() != r.size() || (!w.empty() && w.size() != b.size())) {
    throw std::invalid_argument("solve_wahba_svd: vector counts differ");
  }
  Eigen::Matrix3d B = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < b.size(); ++i)
    B += (w.empty() ? 1.0 : w[i]) * b[i] * r[i].transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(B, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const double d = svd.matrixU().determinant() * svd.matrixV().determinant();
  const Eigen::Matrix3d R = svd.matrixU() *
                            Eigen::Vector3d(1.0, 1.0, d < 0.0 ? -1.0 : 1.0).asDiagonal() *
                            svd.matrixV().transpose();
  return Eigen::Quaterniond(R).normalized();
}

// ---------------------------------------------------------------------------
// Identification
// ---------------------------------------------------------------------------

namespace {

double angle_between(const Vec3& a, const Vec3& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

struct Slice {
  std::size_t first = 0, last = 0;
  [[nodiscard]] bool empty() const { return first >= last; }
};

// Matches every input vector to the nearest catalog star within tol for the
// attitude R (cam from eci); one vector per star, closest first.
std::vector<std::pair<int, int>> match_all(const std::vector<Vec3>& b, const StarIdCatalog& cat,
                                           const Eigen::Matrix3d& R, double tol) {
  double reach = 0.0;
  for (const auto& v : b) reach = std::max(reach, angle_between(v, Vec3::UnitZ()));
  const Vec3 boresight = R.transpose() * Vec3::UnitZ();
  const std::vector<int> cone = cat.in_cone(boresight, reach + tol + 1e-6);
  struct Cand {
    double angle;
    int vec, star;
  };
  std::vector<Cand> cands;
  const double cos_tol = std::cos(tol);
  for (std::size_t i = 0; i < b.size(); ++i) {
    const Vec3 r_pred = R.transpose() * b[i];
    double best = -2.0;
    int best_star = -1;
    for (const int s : cone) {
      const double c = cat.stars()[static_cast<std::size_t>(s)].u_eci.dot(r_pred);
      if (c > best) {
        best = c;
        best_star = s;
      }
    }
    if (best_star >= 0 && best >= cos_tol) {
      cands.push_back(
          {angle_between(cat.stars()[static_cast<std::size_t>(best_star)].u_eci, r_pred),
           static_cast<int>(i), best_star});
    }
  }
  std::sort(cands.begin(), cands.end(),
            [](const Cand& x, const Cand& y) { return x.angle < y.angle; });
  std::vector<std::pair<int, int>> out;  // (vector index, star index)
  std::vector<int> used;
  for (const auto& c : cands) {
    if (std::find(used.begin(), used.end(), c.star) != used.end()) continue;
    used.push_back(c.star);
    out.emplace_back(c.vec, c.star);
  }
  std::sort(out.begin(), out.end());
  return out;
}

Eigen::Quaterniond solve_from(const std::vector<Vec3>& b, const StarIdCatalog& cat,
                              const std::vector<std::pair<int, int>>& m) {
  std::vector<Vec3> bb, rr;
  for (const auto& [v, s] : m) {
    bb.push_back(b[static_cast<std::size_t>(v)]);
    rr.push_back(cat.stars()[static_cast<std::size_t>(s)].u_eci);
  }
  return solve_wahba_svd(bb, rr);
}

// Refines the attitude from a seed: match, solve, match, solve, match.
StarIdResult refine(const std::vector<Vec3>& b, const StarIdCatalog& cat, Eigen::Quaterniond q,
                    double tol, std::size_t min_matches) {
  StarIdResult res;
  std::vector<std::pair<int, int>> m;
  for (int pass = 0; pass < 3; ++pass) {
    m = match_all(b, cat, q.toRotationMatrix(), tol);
    if (m.size() < min_matches) break;
    if (pass < 2) q = solve_from(b, cat, m);
  }
  if (m.size() < min_matches) {
    res.why = "only " + std::to_string(m.size()) + " stars match the attitude within tolerance";
    return res;
  }
  const Eigen::Matrix3d R = q.toRotationMatrix();
  double ss = 0.0;
  for (const auto& [v, s] : m) {
    const double a = angle_between(b[static_cast<std::size_t>(v)],
                                   R * cat.stars()[static_cast<std::size_t>(s)].u_eci);
    ss += a * a;
  }
  res.residual_rms_rad = std::sqrt(ss / static_cast<double>(m.size()));
  res.q_cam_from_eci = q;
  for (const auto& [v, s] : m)
    res.matches.emplace_back(v, cat.stars()[static_cast<std::size_t>(s)].id);
  res.usable = true;
  return res;
}

// Partners of catalog star `s` among the pairs of a slice, sorted.
void partners(const StarIdCatalog& cat, Slice sl, int s, std::vector<int>* out) {
  out->clear();
  const auto& P = cat.pairs();
  for (std::size_t k = sl.first; k < sl.last; ++k) {
    if (P[k].a == s)
      out->push_back(P[k].b);
    else if (P[k].b == s)
      out->push_back(P[k].a);
  }
  std::sort(out->begin(), out->end());
}

double triple(const Vec3& a, const Vec3& b, const Vec3& c) {
  return a.dot(b.cross(c));
}

}  // namespace

StarIdResult identify_lost_in_space(const std::vector<Vec3>& b_in, const StarIdCatalog& cat,
                                    const StarIdOptions& o) {
  o.validate();
  StarIdResult res;
  std::vector<Vec3> b(b_in.size());
  for (std::size_t i = 0; i < b.size(); ++i) b[i] = b_in[i].normalized();
  const int n = std::min(static_cast<int>(b.size()), o.max_stars);
  if (static_cast<int>(b.size()) < o.min_matches_lost_in_space) {
    res.why = "too few point sources (" + std::to_string(b.size()) + ", need " +
              std::to_string(o.min_matches_lost_in_space) + ")";
    return res;
  }
  if (cat.pairs().empty()) {
    res.why = "catalog has no star pairs";
    return res;
  }
  const double tol = o.match_tolerance_rad;
  // Candidate catalog pairs for every measured side (a contiguous slice of
  // the sorted pair table).
  const auto nu = static_cast<std::size_t>(n);
  std::vector<Slice> sides(nu * nu);
  for (int i = 0; i < n; ++i) {
    for (int j = i + 1; j < n; ++j) {
      const double th =
          angle_between(b[static_cast<std::size_t>(i)], b[static_cast<std::size_t>(j)]);
      Slice s;
      if (th <= cat.max_pair_angle_rad() + tol) {
        const auto [f, l] = cat.pairs_in_angle_range(th - tol, th + tol);
        s = {f, l};
      }
      sides[static_cast<std::size_t>(i) * nu + static_cast<std::size_t>(j)] = s;
      sides[static_cast<std::size_t>(j) * nu + static_cast<std::size_t>(i)] = s;
    }
  }
  auto side = [&](int i, int j) {
    return sides[static_cast<std::size_t>(i) * nu + static_cast<std::size_t>(j)];
  };
  const auto& P = cat.pairs();
  auto r = [&](int s) -> const Vec3& { return cat.stars()[static_cast<std::size_t>(s)].u_eci; };

  std::vector<std::pair<int, int>> ik_adj;
  std::vector<std::pair<int, int>> jk_set;
  std::vector<std::array<int, 3>> cands;
  std::vector<int> pi, pj, pk, tmp, common;
  for (int dj = 1; dj <= n - 2; ++dj) {
    for (int dk = 1; dk <= n - dj - 1; ++dk) {
      for (int i = 0; i < n - dj - dk; ++i) {
        const int j = i + dj, k = j + dk;
        if (res.triangles_tried >= o.max_triangles) {
          res.why = "no pyramid confirmed within " + std::to_string(o.max_triangles) + " triangles";
          return res;
        }
        ++res.triangles_tried;
        const Slice sij = side(i, j), sik = side(i, k), sjk = side(j, k);
        if (sij.empty() || sik.empty() || sjk.empty()) continue;
        const auto iu = static_cast<std::size_t>(i), ju = static_cast<std::size_t>(j),
                   ku = static_cast<std::size_t>(k);
        const double tb = triple(b[iu], b[ju], b[ku]);
        if (std::abs(tb) < o.min_triple_product) continue;

        // Catalog triangles (I, J, K).
        ik_adj.clear();
        for (std::size_t p = sik.first; p < sik.last; ++p) {
          ik_adj.emplace_back(P[p].a, P[p].b);
          ik_adj.emplace_back(P[p].b, P[p].a);
        }
        std::sort(ik_adj.begin(), ik_adj.end());
        jk_set.clear();
        for (std::size_t p = sjk.first; p < sjk.last; ++p) jk_set.emplace_back(P[p].a, P[p].b);
        std::sort(jk_set.begin(), jk_set.end());
        cands.clear();
        bool too_many = false;
        for (std::size_t p = sij.first; p < sij.last && !too_many; ++p) {
          for (int orient = 0; orient < 2 && !too_many; ++orient) {
            const int I = orient == 0 ? P[p].a : P[p].b;
            const int J = orient == 0 ? P[p].b : P[p].a;
            auto lo = std::lower_bound(ik_adj.begin(), ik_adj.end(),
                                       std::make_pair(I, std::numeric_limits<int>::min()));
            for (auto it = lo; it != ik_adj.end() && it->first == I; ++it) {
              const int K = it->second;
              if (K == J) continue;
              if (!std::binary_search(jk_set.begin(), jk_set.end(),
                                      std::make_pair(std::min(J, K), std::max(J, K)))) {
                continue;
              }
              // Spectral (handedness) test.
              if ((triple(r(I), r(J), r(K)) > 0.0) != (tb > 0.0)) continue;
              cands.push_back({I, J, K});
              if (static_cast<int>(cands.size()) > o.max_candidates_per_triangle) {
                too_many = true;
                break;
              }
            }
          }
        }
        if (cands.empty() || too_many) continue;

        // The pyramid: a fourth star confirming exactly one catalog triangle.
        int confirmed = 0;
        std::array<int, 4> meas{}, cat_idx{};
        for (const auto& c : cands) {
          bool this_confirmed = false;
          for (int rr = 0; rr < n && !this_confirmed; ++rr) {
            if (rr == i || rr == j || rr == k) continue;
            const Slice sir = side(i, rr), sjr = side(j, rr), skr = side(k, rr);
            if (sir.empty() || sjr.empty() || skr.empty()) continue;
            partners(cat, sir, c[0], &pi);
            if (pi.empty()) continue;
            partners(cat, sjr, c[1], &pj);
            if (pj.empty()) continue;
            partners(cat, skr, c[2], &pk);
            if (pk.empty()) continue;
            tmp.clear();
            std::set_intersection(pi.begin(), pi.end(), pj.begin(), pj.end(),
                                  std::back_inserter(tmp));
            common.clear();
            std::set_intersection(tmp.begin(), tmp.end(), pk.begin(), pk.end(),
                                  std::back_inserter(common));
            std::erase_if(common, [&](int R) { return R == c[0] || R == c[1] || R == c[2]; });
            // Handedness of (i, j, r) as a second spectral test.
            const auto ru = static_cast<std::size_t>(rr);
            const double t4 = triple(b[iu], b[ju], b[ru]);
            if (std::abs(t4) >= o.min_triple_product) {
              std::erase_if(common, [&](int R) {
                return (triple(r(c[0]), r(c[1]), r(R)) > 0.0) != (t4 > 0.0);
              });
            }
            if (common.size() == 1) {
              this_confirmed = true;
              ++confirmed;
              meas = {i, j, k, rr};
              cat_idx = {c[0], c[1], c[2], common[0]};
            }
          }
        }
        if (confirmed != 1) continue;

        // Attitude from the pyramid, then every vector.
        std::vector<std::pair<int, int>> m4;
        for (int q = 0; q < 4; ++q)
          m4.emplace_back(meas[static_cast<std::size_t>(q)], cat_idx[static_cast<std::size_t>(q)]);
        const Eigen::Quaterniond q4 = solve_from(b, cat, m4);
        // The pyramid itself must fit the rigid rotation.
        const Eigen::Matrix3d R4 = q4.toRotationMatrix();
        bool fits = true;
        for (const auto& [v, s] : m4) {
          fits = fits && angle_between(b[static_cast<std::size_t>(v)], R4 * r(s)) <=
                             o.accept_tolerance() + tol;
        }
        if (!fits) continue;
        StarIdResult out = refine(b, cat, q4, o.accept_tolerance(),
                                  static_cast<std::size_t>(o.min_matches_lost_in_space));
        out.triangles_tried = res.triangles_tried;
        if (!out.usable) continue;
        return out;
      }
    }
  }
  res.why = "no pyramid confirmed (" + std::to_string(res.triangles_tried) + " triangles tried)";
  return res;
}

StarIdResult identify_with_prior(const std::vector<Vec3>& b_in, const StarIdCatalog& cat,
                                 const Eigen::Quaterniond& q_prior, double tolerance_rad,
                                 const StarIdOptions& o) {
  o.validate();
  if (!(tolerance_rad > 0.0))
    throw std::invalid_argument("identify_with_prior: tolerance_rad must be positive");
  std::vector<Vec3> b(b_in.size());
  for (std::size_t i = 0; i < b.size(); ++i) b[i] = b_in[i].normalized();
  StarIdResult res;
  const auto min_m = static_cast<std::size_t>(o.min_matches_tracking);
  const auto m = match_all(b, cat, q_prior.normalized().toRotationMatrix(), tolerance_rad);
  if (m.size() < min_m) {
    res.why = "only " + std::to_string(m.size()) + " stars within " +
              std::to_string(tolerance_rad) + " rad of the prior attitude's catalog";
    return res;
  }
  Eigen::Quaterniond q = solve_from(b, cat, m);
  // With a wide tolerance, a wrong neighbour may have joined: tighten in
  // steps down to the acceptance tolerance.
  double tol = tolerance_rad;
  while (tol > 4.0 * o.accept_tolerance()) {
    tol = std::max(tol / 4.0, o.accept_tolerance());
    const auto mm = match_all(b, cat, q.toRotationMatrix(), tol);
    if (mm.size() < min_m) break;
    q = solve_from(b, cat, mm);
  }
  return refine(b, cat, q, o.accept_tolerance(), min_m);
}

}  // namespace artms::imp
