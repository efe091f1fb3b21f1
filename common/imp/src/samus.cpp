// SAMUS multi-hypothesis tracking; see samus.hpp and docs/imp_samus.md.
#include "artms/imp/samus.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include "artms/astro/frames.hpp"
#include "artms/imp/dbscan.hpp"

namespace artms::imp {

void SamusOptions::validate() const {
  auto bad = [](const char* f) { throw std::invalid_argument(std::string("SamusOptions.") + f + " out of range"); };
  if (!(max_rate_radps > 0.0)) bad("max_rate_radps");
  if (!(max_speed_ratio > 1.0)) bad("max_speed_ratio");
  if (!(significance_sigma > 0.0)) bad("significance_sigma");
  if (!(min_turn_sine >= 0.0 && min_turn_sine < 1.0)) bad("min_turn_sine");
  if (!(gate_sigma > 0.0)) bad("gate_sigma");
  if (!(model_floor_rad >= 0.0)) bad("model_floor_rad");
  if (!(harmonic_prior_rad > 0.0)) bad("harmonic_prior_rad");
  if (fit_window < 3) bad("fit_window");
  if (max_branches < 1) bad("max_branches");
  if (n_scan < 0) bad("n_scan");
  if (!(miss_cost >= 0.0)) bad("miss_cost");
  if (dbscan_min_points < 2) bad("dbscan_min_points");
  if (!(dbscan_radius_rad > 0.0)) bad("dbscan_radius_rad");
  if (dbscan_frames < 2) bad("dbscan_frames");
  if (!(init_max_chi2 > 0.0)) bad("init_max_chi2");
  if (confirm_measurements < dbscan_min_points) bad("confirm_measurements");
  if (!(lost_after_s > 0.0)) bad("lost_after_s");
  if (!(join_max_gap_s >= 0.0)) bad("join_max_gap_s");
  if (!(join_max_chi2 > 0.0)) bad("join_max_chi2");
  if (join_window < 1) bad("join_window");
  if (!(aided_gate_chi2 > 0.0)) bad("aided_gate_chi2");
}

namespace {

// Eq. (9) regressor: (r_o / a_o) [1, cos u_o, sin u_o].
Eigen::Vector3d regressor(double ra, double u) { return ra * Eigen::Vector3d(1.0, std::cos(u), std::sin(u)); }

double cross2(const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); }

struct Geometry {
  Eigen::Matrix3d R_rtn_from_eci;
  double ra = 1.0, u = 0.0;
};

Geometry geometry_of(const astro::StateVector& x) {
  Geometry g;
  g.R_rtn_from_eci = astro::R_rtn_from_eci(x);
  const astro::QnsElements oe = astro::qns_from_cartesian(x);
  g.ra = x.r_m.norm() / oe.a_m;
  g.u = oe.u_rad;
  return g;
}

}  // namespace

Eq9Fit fit_eq9(std::span<const Samus::Meas> meas, double harmonic_prior_rad) {
  Eq9Fit f;
  if (meas.empty()) return f;
  // Normal equations with the prior on c1, c2 (per axis, same matrix).
  Eigen::Matrix3d N = Eigen::Matrix3d::Zero();
  N(1, 1) = N(2, 2) = 1.0 / (harmonic_prior_rad * harmonic_prior_rad);
  Eigen::Vector3d bx = Eigen::Vector3d::Zero(), by = Eigen::Vector3d::Zero();
  for (const auto& m : meas) {
    const Eigen::Vector3d h = regressor(m.ra, m.u);
    const double w = 1.0 / (m.sigma * m.sigma);
    N += w * h * h.transpose();
    bx += w * h * m.p.x();
    by += w * h * m.p.y();
  }
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(N);
  if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-14)) return f;
  f.c_x = ldlt.solve(bx);
  f.c_y = ldlt.solve(by);
  f.N_inv = ldlt.solve(Eigen::Matrix3d::Identity());
  double chi2 = 0.0, ss = 0.0;
  for (const auto& m : meas) {
    const Eigen::Vector3d h = regressor(m.ra, m.u);
    const Eigen::Vector2d r(m.p.x() - h.dot(f.c_x), m.p.y() - h.dot(f.c_y));
    chi2 += r.squaredNorm() / (m.sigma * m.sigma);
    ss += r.squaredNorm();
  }
  const double n2 = 2.0 * static_cast<double>(meas.size());
  f.chi2_per_dof = chi2 / std::max(1.0, n2 - 6.0);
  f.rms_rad = std::sqrt(ss / n2);
  f.usable = std::isfinite(f.chi2_per_dof);
  return f;
}

namespace {

std::span<const Samus::Meas> window(const std::vector<Samus::Meas>& v, int n) {
  const std::size_t k = std::min<std::size_t>(v.size(), static_cast<std::size_t>(n));
  return {v.data() + (v.size() - k), k};
}

}  // namespace

namespace {

// The kinematic rules for appending m to a track whose measurements are
// `track` (time order, not empty): 1) rate below max_rate_radps; 2) speed
// ratio of the last two displacements below max_speed_ratio; 3) no reversal
// of more than 90 degrees; 4) (with `turning`) no change of turning
// direction. Rules 2-4 apply only to displacements above significance_sigma
// measurement sigmas. Also returns the speed and direction cost terms.
bool kinematic_rules_pass(std::span<const Samus::Meas> track, const Samus::Meas& m, const SamusOptions& opt,
                          bool turning, double& speed_term, double& dir_term) {
  speed_term = dir_term = 0.0;
  const Samus::Meas& last = track.back();
  const double dt = m.t_s - last.t_s;
  if (!(dt > 0.0)) return false;
  const Eigen::Vector2d d_new = m.p - last.p;
  const double noise = opt.significance_sigma * std::sqrt(2.0) * m.sigma;
  if (d_new.norm() > opt.max_rate_radps * dt + noise) return false;  // rule 1
  if (track.size() < 2) return true;
  const Samus::Meas& prev = track[track.size() - 2];
  const Eigen::Vector2d d_prev = last.p - prev.p;
  const double dt_prev = last.t_s - prev.t_s;
  if (!(d_new.norm() > noise && d_prev.norm() > noise && dt_prev > 0.0)) return true;
  const double v_new = d_new.norm() / dt, v_prev = d_prev.norm() / dt_prev;
  if (std::max(v_new, v_prev) > opt.max_speed_ratio * std::min(v_new, v_prev)) return false;  // rule 2
  const double cosang = d_new.dot(d_prev) / (d_new.norm() * d_prev.norm());
  if (cosang < 0.0) return false;  // rule 3
  speed_term = std::abs(std::log(v_new / v_prev));
  dir_term = 1.0 - cosang;
  if (turning && track.size() >= 3) {  // rule 4
    const Eigen::Vector2d d_pp = prev.p - track[track.size() - 3].p;
    if (d_pp.norm() > noise) {
      const double s1 = cross2(d_pp, d_prev) / (d_pp.norm() * d_prev.norm());
      const double s2 = cross2(d_prev, d_new) / (d_prev.norm() * d_new.norm());
      if (std::abs(s1) > opt.min_turn_sine && std::abs(s2) > opt.min_turn_sine && s1 * s2 < 0.0) return false;
    }
  }
  return true;
}

}  // namespace

Samus::Samus(SamusOptions options) : opt_(std::move(options)) { opt_.validate(); }

bool Samus::plane_coordinates(const Eigen::Vector3d& u_eci, const astro::StateVector& observer_eci,
                              Eigen::Vector2d& p) const {
  if (!plane_set_) return false;
  const Eigen::Vector3d v = astro::R_rtn_from_eci(observer_eci) * u_eci;
  const double z = v.dot(d_rtn_);
  if (!(z > 0.1)) return false;
  p = Eigen::Vector2d(v.dot(e1_rtn_), v.dot(e2_rtn_)) / z;
  return true;
}

bool Samus::predict(int track_id, const astro::StateVector& observer_eci, Eigen::Vector2d& p,
                    Eigen::Matrix2d& cov) const {
  for (const auto& f : families_) {
    if (f.id != track_id || f.branches.empty()) continue;
    const auto fit = fit_eq9(window(f.branches[0].meas, opt_.fit_window), opt_.harmonic_prior_rad);
    if (!fit.usable) return false;
    const Geometry g = geometry_of(observer_eci);
    const Eigen::Vector3d h = regressor(g.ra, g.u);
    p = Eigen::Vector2d(h.dot(fit.c_x), h.dot(fit.c_y));
    cov = Eigen::Matrix2d::Identity() * h.dot(fit.N_inv * h);
    return true;
  }
  return false;
}

bool Samus::unscented_prediction(int track_id, const Eigen::VectorXd& mean, const Eigen::MatrixXd& cov,
                                 const std::function<Eigen::Vector3d(const Eigen::VectorXd&)>& los_eci,
                                 const astro::StateVector& observer_eci, TargetPrediction& out) const {
  const Eigen::Index n = mean.size();
  if (n == 0 || cov.rows() != n || cov.cols() != n) return false;
  const Eigen::LLT<Eigen::MatrixXd> llt(cov * static_cast<double>(n));
  if (llt.info() != Eigen::Success) return false;
  const Eigen::MatrixXd L = llt.matrixL();
  std::vector<Eigen::Vector2d> pts;
  for (Eigen::Index i = 0; i < n; ++i) {
    for (const double s : {1.0, -1.0}) {
      Eigen::Vector2d p;
      if (!plane_coordinates(los_eci(mean + s * L.col(i)).normalized(), observer_eci, p)) return false;
      pts.push_back(p);
    }
  }
  Eigen::Vector2d m = Eigen::Vector2d::Zero();
  for (const auto& p : pts) m += p;
  m /= static_cast<double>(pts.size());
  Eigen::Matrix2d P = Eigen::Matrix2d::Zero();
  for (const auto& p : pts) P += (p - m) * (p - m).transpose();
  P /= static_cast<double>(pts.size());
  out.track_id = track_id;
  out.p = m;
  out.cov = P;
  return true;
}

void Samus::release(Family& f, std::int64_t upto_seq, std::vector<TrackedMeasurement>& out) const {
  if (!f.confirmed || f.branches.empty()) return;
  const auto& meas = f.branches[0].meas;
  while (f.released < meas.size() && meas[f.released].seq <= upto_seq) {
    const Meas& m = meas[f.released++];
    out.push_back({m.frame, m.t, f.id, m.candidate, m.c, f.segments});
  }
}

SamusFrameSummary Samus::process(const TrackerInput& in, std::span<const TargetPrediction> aided) {
  SamusFrameSummary s;
  s.candidates = static_cast<int>(in.candidates.size());
  ++seq_;
  const Geometry g = geometry_of(in.observer_eci);
  if (!plane_set_) {
    d_rtn_ = (g.R_rtn_from_eci * in.boresight_eci).normalized();
    Eigen::Vector3d e1 = Eigen::Vector3d::UnitX() - d_rtn_.x() * d_rtn_;
    if (e1.norm() < 0.1) e1 = Eigen::Vector3d::UnitZ() - d_rtn_.z() * d_rtn_;
    e1_rtn_ = e1.normalized();
    e2_rtn_ = d_rtn_.cross(e1_rtn_);
    plane_set_ = true;
  }
  // Candidates in the tracking plane.
  std::vector<Meas> cands;
  std::vector<int> cand_of;  // index into in.candidates
  for (std::size_t i = 0; i < in.candidates.size(); ++i) {
    const auto& c = in.candidates[i];
    const Eigen::Vector3d v = g.R_rtn_from_eci * c.u_eci;
    const double z = v.dot(d_rtn_);
    if (!(z > 0.1) || !std::isfinite(c.sigma_rad)) continue;
    Meas m;
    m.seq = seq_;
    m.frame = in.frame;
    m.t = in.t;
    m.t_s = in.t.seconds_since_j2000();
    m.candidate = static_cast<int>(i);
    m.p = Eigen::Vector2d(v.dot(e1_rtn_), v.dot(e2_rtn_)) / z;
    m.sigma = std::hypot(c.sigma_rad, opt_.model_floor_rad);
    m.ra = g.ra;
    m.u = g.u;
    m.c = c;
    cands.push_back(m);
    cand_of.push_back(static_cast<int>(i));
  }
  const Eigen::Vector3d h_now = regressor(g.ra, g.u);

  // 1. Children of every hypothesis of every active track.
  struct Child {
    std::size_t branch;
    int cand;  // index into cands, -1: miss
    double inc;
  };
  std::vector<std::vector<Child>> children(families_.size());
  for (std::size_t fi = 0; fi < families_.size(); ++fi) {
    Family& f = families_[fi];
    if (f.lost) continue;
    const TargetPrediction* aid = nullptr;
    for (const auto& a : aided) {
      if (a.track_id == f.id) aid = &a;
    }
    for (std::size_t bi = 0; bi < f.branches.size(); ++bi) {
      const Branch& b = f.branches[bi];
      children[fi].push_back({bi, -1, opt_.miss_cost});
      const auto& L = b.meas;
      const Meas& last = L.back();
      const auto fit = fit_eq9(window(L, opt_.fit_window), opt_.harmonic_prior_rad);
      if (!fit.usable) continue;
      const Eigen::Vector2d pred(h_now.dot(fit.c_x), h_now.dot(fit.c_y));
      const double var_pred = h_now.dot(fit.N_inv * h_now);
      // Median brightness of the last five measurements.
      std::vector<double> fl;
      for (std::size_t k = L.size() > 5 ? L.size() - 5 : 0; k < L.size(); ++k) fl.push_back(L[k].c.flux_dn);
      std::nth_element(fl.begin(), fl.begin() + static_cast<long>(fl.size() / 2), fl.end());
      const double flux_ref = fl[fl.size() / 2];
      for (std::size_t ci = 0; ci < cands.size(); ++ci) {
        const Meas& m = cands[ci];
        const double dt = m.t_s - last.t_s;
        if (!(dt > 0.0)) continue;
        double inc = 0.0;
        if (aid) {
          // SOD-aided: Mahalanobis gate and score on SOD's prediction.
          const Eigen::Matrix2d S = aid->cov + m.sigma * m.sigma * Eigen::Matrix2d::Identity();
          const Eigen::Vector2d r = m.p - aid->p;
          const double d2 = r.dot(S.ldlt().solve(r));
          if (!(d2 <= opt_.aided_gate_chi2)) continue;
          inc = d2;
        } else {
          double speed_term = 0.0, dir_term = 0.0;
          if (!kinematic_rules_pass(L, m, opt_, true, speed_term, dir_term)) continue;
          // Rule 5: close to the eq. (9) prediction.
          const double d2 = (m.p - pred).squaredNorm() / (var_pred + m.sigma * m.sigma);
          if (!(d2 <= opt_.gate_sigma * opt_.gate_sigma)) continue;
          inc = opt_.w_prediction * d2 + opt_.w_speed * speed_term + opt_.w_direction * dir_term;
        }
        // Fit residual with the new measurement, brightness consistency.
        std::vector<Meas> w(window(L, opt_.fit_window - 1).begin(), window(L, opt_.fit_window - 1).end());
        w.push_back(m);
        const auto fit2 = fit_eq9(w, opt_.harmonic_prior_rad);
        inc += opt_.w_fit * (fit2.usable ? fit2.chi2_per_dof : 10.0);
        if (flux_ref > 0.0 && m.c.flux_dn > 0.0) inc += opt_.w_brightness * std::abs(std::log(m.c.flux_dn / flux_ref));
        children[fi].push_back({bi, static_cast<int>(ci), inc});
      }
    }
  }
  // 2. One candidate per track: tracks claim candidates in priority order
  // (confirmed first, then the cheapest best child); lower-priority tracks
  // lose every hypothesis that uses a claimed candidate.
  std::vector<std::size_t> order;
  for (std::size_t fi = 0; fi < families_.size(); ++fi) {
    if (!families_[fi].lost) order.push_back(fi);
  }
  auto best_inc = [&](std::size_t fi) {
    double b = 1e300;
    for (const auto& c : children[fi]) {
      if (c.cand >= 0) b = std::min(b, families_[fi].branches[c.branch].cost + c.inc);
    }
    return b;
  };
  std::vector<double> prio(families_.size(), 0.0);
  for (auto fi : order) prio[fi] = best_inc(fi);
  std::stable_sort(order.begin(), order.end(), [&](auto a, auto b) {
    if (families_[a].confirmed != families_[b].confirmed) return families_[a].confirmed;
    return prio[a] < prio[b];
  });
  std::vector<bool> claimed(cands.size(), false);
  for (auto fi : order) {
    auto& ch = children[fi];
    ch.erase(std::remove_if(ch.begin(), ch.end(), [&](const Child& c) { return c.cand >= 0 && claimed[static_cast<std::size_t>(c.cand)]; }),
             ch.end());
    for (const auto& c : ch) {
      if (c.cand >= 0) claimed[static_cast<std::size_t>(c.cand)] = true;
    }
  }
  // 3. New hypotheses: the cheapest max_branches children; N-scan pruning.
  const std::int64_t decided = seq_ - opt_.n_scan;
  for (auto fi : order) {
    Family& f = families_[fi];
    auto& ch = children[fi];
    std::stable_sort(ch.begin(), ch.end(), [&](const Child& a, const Child& b) {
      return f.branches[a.branch].cost + a.inc < f.branches[b.branch].cost + b.inc;
    });
    std::vector<Branch> next;
    for (const auto& c : ch) {
      if (static_cast<int>(next.size()) >= opt_.max_branches) break;
      Branch nb = f.branches[c.branch];
      nb.cost += c.inc;
      if (c.cand >= 0) nb.meas.push_back(cands[static_cast<std::size_t>(c.cand)]);
      next.push_back(std::move(nb));
    }
    // Costs relative to the best hypothesis (keeps numbers small).
    const double c0 = next.front().cost;
    for (auto& b : next) b.cost -= c0;
    auto decided_tail = [&](const Branch& b) {
      std::size_t n = 0;
      std::int64_t last_seq = -1;
      int last_cand = -1;
      for (const auto& m : b.meas) {
        if (m.seq > decided) break;
        ++n;
        last_seq = m.seq;
        last_cand = m.candidate;
      }
      return std::tuple(n, last_seq, last_cand);
    };
    const auto ref = decided_tail(next.front());
    f.branches.clear();
    for (auto& b : next) {
      if (f.branches.empty() || decided_tail(b) == ref) f.branches.push_back(std::move(b));
    }
  }
  // 4. Lost tracks; tentative ones that never confirmed are dropped.
  for (auto& f : families_) {
    if (f.lost) continue;
    if (in.t.seconds_since_j2000() - f.branches[0].meas.back().t_s > opt_.lost_after_s) {
      f.lost = true;
      f.branches.resize(1);
      if (f.confirmed) release(f, seq_, s.released);
    }
  }
  const auto before = families_.size();
  std::size_t retired = 0;
  std::erase_if(families_, [&](const Family& f) {
    if (!f.lost) return false;
    if (!f.confirmed) return true;
    // Beyond the joining window a lost track is final.
    if (in.t.seconds_since_j2000() - f.branches[0].meas.back().t_s > opt_.join_max_gap_s) {
      retired_.push_back(info_of(f));
      ++retired;
      return true;
    }
    return false;
  });
  s.tracks_dropped = static_cast<int>(before - families_.size() - retired);
  // 5. Confirmation, with eclipse joining first.
  try_joins(s);
  for (auto& f : families_) {
    if (!f.lost && !f.confirmed && static_cast<int>(f.branches[0].meas.size()) >= opt_.confirm_measurements) {
      f.confirmed = true;
    }
  }
  // 6. Release decided measurements.
  for (auto& f : families_) {
    if (!f.lost) release(f, decided, s.released);
  }
  // 7. Initiation pool: candidates no hypothesis took.
  std::vector<bool> used(cands.size(), false);
  for (const auto& f : families_) {
    if (f.lost) continue;
    for (const auto& b : f.branches) {
      if (!b.meas.empty() && b.meas.back().seq == seq_) used[static_cast<std::size_t>(std::find_if(cands.begin(), cands.end(), [&](const Meas& m) { return m.candidate == b.meas.back().candidate; }) - cands.begin())] = true;
    }
  }
  for (std::size_t ci = 0; ci < cands.size(); ++ci) {
    if (used[ci]) {
      ++s.assigned;
      s.taken.push_back(cands[ci].candidate);
    } else {
      unassigned_.push_back({seq_, cands[ci]});
    }
  }
  std::erase_if(unassigned_, [&](const Pending& p) { return p.seq <= seq_ - opt_.dbscan_frames; });
  // 8. DBSCAN initiation.
  if (static_cast<int>(unassigned_.size()) >= opt_.dbscan_min_points) {
    std::vector<Eigen::Vector2d> pts;
    for (const auto& p : unassigned_) pts.push_back(p.m.p);
    DbscanOptions dopt;
    dopt.eps = opt_.dbscan_radius_rad;
    dopt.min_points = opt_.dbscan_min_points;
    const DbscanResult db = dbscan(std::span<const Eigen::Vector2d>(pts), dopt);
    std::vector<bool> take(unassigned_.size(), false);
    for (int c = 0; c < db.clusters; ++c) {
      const auto members = db.members(c);
      std::map<std::int64_t, std::vector<int>> by_seq;
      for (int k : members) by_seq[unassigned_[static_cast<std::size_t>(k)].seq].push_back(k);
      if (static_cast<int>(by_seq.size()) < opt_.dbscan_min_points) continue;
      // Chain one member per frame, each nearest to the previous pick (the
      // first: nearest to the cluster mean).
      Eigen::Vector2d mean = Eigen::Vector2d::Zero();
      for (int k : members) mean += pts[static_cast<std::size_t>(k)];
      mean /= static_cast<double>(members.size());
      std::vector<int> chain;
      Eigen::Vector2d ref = mean;
      for (const auto& [sq, ks] : by_seq) {
        int best = ks.front();
        for (int k : ks) {
          if ((pts[static_cast<std::size_t>(k)] - ref).norm() < (pts[static_cast<std::size_t>(best)] - ref).norm()) best = k;
        }
        chain.push_back(best);
        ref = pts[static_cast<std::size_t>(best)];
      }
      // Rules 1-3 along the chain, then the eq. (9) fit.
      std::vector<Meas> ms;
      for (int k : chain) ms.push_back(unassigned_[static_cast<std::size_t>(k)].m);
      bool ok = true;
      for (std::size_t k = 1; k < ms.size() && ok; ++k) {
        double unused_speed = 0.0, unused_dir = 0.0;
        ok = kinematic_rules_pass(std::span<const Meas>(ms.data(), k), ms[k], opt_, false, unused_speed, unused_dir);
      }
      if (!ok) continue;
      const auto fit = fit_eq9(ms, opt_.harmonic_prior_rad);
      if (!fit.usable || fit.chi2_per_dof > opt_.init_max_chi2) continue;
      Family f;
      f.id = next_id_++;
      f.created_seq = seq_;
      f.branches.push_back({ms, 0.0});
      families_.push_back(std::move(f));
      ++s.tracks_started;
      for (int k : chain) take[static_cast<std::size_t>(k)] = true;
    }
    std::vector<Pending> keep;
    for (std::size_t k = 0; k < unassigned_.size(); ++k) {
      if (!take[k]) keep.push_back(unassigned_[k]);
    }
    unassigned_ = std::move(keep);
  }
  std::stable_sort(s.released.begin(), s.released.end(),
                   [](const auto& a, const auto& b) { return std::tie(a.t, a.track_id) < std::tie(b.t, b.track_id); });
  return s;
}

void Samus::try_joins(SamusFrameSummary& s) {
  // Tentative tracks reaching confirmation, paired with lost confirmed tracks.
  struct Pair {
    double chi2;
    std::size_t young, old;
  };
  std::vector<Pair> pairs;
  for (std::size_t y = 0; y < families_.size(); ++y) {
    const Family& fy = families_[y];
    if (fy.lost || fy.confirmed || static_cast<int>(fy.branches[0].meas.size()) < opt_.confirm_measurements) continue;
    for (std::size_t o = 0; o < families_.size(); ++o) {
      const Family& fo = families_[o];
      if (!fo.lost || !fo.confirmed) continue;
      const double gap = fy.branches[0].meas.front().t_s - fo.branches[0].meas.back().t_s;
      if (!(gap > 0.0 && gap <= opt_.join_max_gap_s)) continue;
      auto w = window(fo.branches[0].meas, opt_.join_window);
      std::vector<Meas> u(w.begin(), w.end());
      u.insert(u.end(), fy.branches[0].meas.begin(), fy.branches[0].meas.end());
      const auto fit = fit_eq9(u, opt_.harmonic_prior_rad);
      if (fit.usable && fit.chi2_per_dof <= opt_.join_max_chi2) pairs.push_back({fit.chi2_per_dof, y, o});
    }
  }
  std::stable_sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) { return a.chi2 < b.chi2; });
  std::vector<bool> used_y(families_.size(), false), used_o(families_.size(), false);
  std::vector<bool> remove(families_.size(), false);
  for (const auto& p : pairs) {
    if (used_y[p.young] || used_o[p.old]) continue;
    used_y[p.young] = used_o[p.old] = true;
    Family& fy = families_[p.young];
    Family& fo = families_[p.old];
    const auto& old_meas = fo.branches[0].meas;
    for (auto& b : fy.branches) b.meas.insert(b.meas.begin(), old_meas.begin(), old_meas.end());
    fy.id = fo.id;
    fy.segments = fo.segments + 1;
    fy.released = fo.released;
    fy.confirmed = true;
    remove[p.old] = true;
    ++s.tracks_joined;
  }
  std::vector<Family> keep;
  for (std::size_t k = 0; k < families_.size(); ++k) {
    if (!remove[k]) keep.push_back(std::move(families_[k]));
  }
  families_ = std::move(keep);
}

std::vector<TrackedMeasurement> Samus::flush() {
  std::vector<TrackedMeasurement> out;
  for (auto& f : families_) release(f, seq_, out);
  std::stable_sort(out.begin(), out.end(),
                   [](const auto& a, const auto& b) { return std::tie(a.t, a.track_id) < std::tie(b.t, b.track_id); });
  return out;
}

TrackInfo Samus::info_of(const Family& f) const {
    const auto& m = f.branches[0].meas;
    TrackInfo t;
    t.track_id = f.id;
    t.first_frame = m.front().frame;
    t.last_frame = m.back().frame;
    t.measurements = static_cast<int>(m.size());
    t.segments = f.segments;
    t.confirmed = f.confirmed;
    t.lost = f.lost;
    t.fit_rms_rad = fit_eq9(window(m, opt_.fit_window), opt_.harmonic_prior_rad).rms_rad;
    return t;
}

std::optional<astro::TimeTT> Samus::oldest_undecided() const {
  std::optional<astro::TimeTT> oldest;
  const auto take = [&](const astro::TimeTT& t) {
    if (!oldest || t < *oldest) oldest = t;
  };
  for (const auto& f : families_) {
    if (f.lost) continue;
    for (const auto& b : f.branches) {
      if (f.released < b.meas.size()) take(b.meas[f.released].t);
    }
  }
  for (const auto& p : unassigned_) take(p.m.t);
  return oldest;
}

std::vector<TrackInfo> Samus::tracks() const {
  std::vector<TrackInfo> out = retired_;
  for (const auto& f : families_) {
    if (f.confirmed) out.push_back(info_of(f));
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.track_id < b.track_id; });
  return out;
}

}  // namespace artms::imp
