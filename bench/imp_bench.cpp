// IMP per frame on a full NST frame (1280 x 1024, 12 bit) rendered with every
// noise term, hot pixels and the faint uncatalogued sky: detection and
// centroiding, Pyramid lost-in-space identification, tracking, and the
// whole chain (targets: full IMP per frame <= 20 ms, lost in space <= 10 ms
// median, on one core).
#include <benchmark/benchmark.h>

#include <random>

#include "artms/astro/time.hpp"
#include "artms/imaging/renderer.hpp"
#include "artms/imp/detection.hpp"
#include "artms/imp/star_id.hpp"

namespace {

using namespace artms;

imaging::CameraModel nst() {
  return imaging::CameraModel::load(std::string(ARTMS_CONFIG_DIR) + "/cameras/nst.yaml");
}

imp::Intrinsics intrinsics(const imaging::CameraModel& c) {
  return {c.width_px, c.height_px, c.fx_px, c.fy_px, c.cx_px, c.cy_px, c.k1, c.k2};
}

const imaging::StarCatalog& bsc5() {
  static const imaging::StarCatalog cat =
      imaging::StarCatalog::load_bsc5(std::string(ARTMS_DATA_DIR) + "/stars/bsc5.dat", 99.0);
  return cat;
}

astro::TimeTT epoch() {
  return astro::tt_from_utc_string("2024-05-08T00:00:00Z");
}

// Eight frames at random attitudes clear of the exclusion zones.
const std::vector<imaging::RenderedFrame>& frames() {
  static const std::vector<imaging::RenderedFrame> out = [] {
    const imaging::FrameRenderer renderer(nst(), bsc5(), imaging::RenderOptions{});
    std::mt19937_64 rng(99);
    std::normal_distribution<double> n01;
    std::vector<imaging::RenderedFrame> v;
    imaging::RenderRequest req;
    req.observer = "SV4";
    req.t = epoch();
    req.observer_eci.r_m = astro::Vec3(4000e3, -5000e3, 2500e3);
    req.observer_eci.v_mps = astro::Vec3(5.0e3, 4.0e3, 0.5e3).normalized() * 7.5e3;
    while (v.size() < 8) {
      req.q_cam_from_eci = Eigen::Quaterniond(n01(rng), n01(rng), n01(rng), n01(rng)).normalized();
      ++req.frame_index;
      auto f = renderer.render(req);
      if (!f.exclusion.excluded && !f.dropped) v.push_back(std::move(f));
    }
    return v;
  }();
  return out;
}

const imp::StarIdCatalog& catalog() {
  static const imp::StarIdCatalog cat = [] {
    std::vector<imp::CatalogStar> stars;
    for (const auto& s : bsc5().stars()) {
      if (s.vmag <= 6.5) stars.push_back({s.catalog_id, s.unit_eci_at(epoch())});
    }
    return imp::StarIdCatalog::build(std::move(stars), 2.0 * nst().half_diagonal_fov_rad());
  }();
  return cat;
}

std::vector<Eigen::Vector3d> unit_vectors(const imp::DetectionResult& d, const imp::Intrinsics& k) {
  std::vector<Eigen::Vector3d> b;
  for (const auto& c : d.centroids) b.push_back(k.unproject(imp::Vec2(c.x_px, c.y_px)));
  return b;
}

void BM_Detect(benchmark::State& state) {
  const auto& fs = frames();
  imp::DetectionOptions o;
  if (state.range(0) == 1) o.centroid_method = imp::CentroidMethod::kGaussianFit;
  std::size_t i = 0, n = 0;
  for (auto _ : state) {
    const auto& f = fs[i++ % fs.size()];
    const auto r = imp::detect(f.pixels, f.width, f.height, o);
    n = r.centroids.size();
    benchmark::DoNotOptimize(r.centroids.data());
  }
  state.counters["centroids"] = static_cast<double>(n);
}
BENCHMARK(BM_Detect)
    ->Arg(0)
    ->Arg(1)
    ->ArgName("gaussian_fit")
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(5)
    ->ReportAggregatesOnly(true);

void BM_LostInSpace(benchmark::State& state) {
  const auto k = intrinsics(nst());
  std::vector<std::vector<Eigen::Vector3d>> bs;
  for (const auto& f : frames())
    bs.push_back(unit_vectors(imp::detect(f.pixels, f.width, f.height, {}), k));
  const auto& cat = catalog();
  std::size_t i = 0;
  int matched = 0;
  for (auto _ : state) {
    const auto r = imp::identify_lost_in_space(bs[i++ % bs.size()], cat, imp::StarIdOptions{});
    matched = static_cast<int>(r.matches.size());
    benchmark::DoNotOptimize(r.q_cam_from_eci.coeffs().data());
  }
  state.counters["matched"] = matched;
}
BENCHMARK(BM_LostInSpace)
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(5)
    ->ReportAggregatesOnly(true);

void BM_TrackingWithPrior(benchmark::State& state) {
  const auto k = intrinsics(nst());
  std::vector<std::vector<Eigen::Vector3d>> bs;
  std::vector<Eigen::Quaterniond> qs;
  const auto& cat = catalog();
  for (const auto& f : frames()) {
    bs.push_back(unit_vectors(imp::detect(f.pixels, f.width, f.height, {}), k));
    qs.push_back(imp::identify_lost_in_space(bs.back(), cat, imp::StarIdOptions{}).q_cam_from_eci);
  }
  const Eigen::Quaterniond nudge(Eigen::AngleAxisd(1e-3, Eigen::Vector3d(1, 2, 3).normalized()));
  std::size_t i = 0;
  for (auto _ : state) {
    const std::size_t j = i++ % bs.size();
    const auto r = imp::identify_with_prior(bs[j], cat, nudge * qs[j], 5e-3);
    benchmark::DoNotOptimize(r.q_cam_from_eci.coeffs().data());
  }
}
BENCHMARK(BM_TrackingWithPrior)
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(5)
    ->ReportAggregatesOnly(true);

// Detection + unit vectors + lost in space: the IMP star pipeline per frame.
void BM_ImpFrameLostInSpace(benchmark::State& state) {
  const auto k = intrinsics(nst());
  const auto& cat = catalog();
  const auto& fs = frames();
  std::size_t i = 0;
  for (auto _ : state) {
    const auto& f = fs[i++ % fs.size()];
    const auto d = imp::detect(f.pixels, f.width, f.height, {});
    const auto r = imp::identify_lost_in_space(unit_vectors(d, k), cat, imp::StarIdOptions{});
    benchmark::DoNotOptimize(r.q_cam_from_eci.coeffs().data());
  }
}
BENCHMARK(BM_ImpFrameLostInSpace)
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(5)
    ->ReportAggregatesOnly(true);

// Start-up: the pair table and k-vector of BSC5 to V 6.5 over the NST diagonal.
void BM_BuildStarIdCatalog(benchmark::State& state) {
  std::vector<imp::CatalogStar> stars;
  for (const auto& s : bsc5().stars()) {
    if (s.vmag <= 6.5) stars.push_back({s.catalog_id, s.unit_eci_at(epoch())});
  }
  const double fov = 2.0 * nst().half_diagonal_fov_rad();
  std::size_t pairs = 0;
  for (auto _ : state) {
    const auto cat = imp::StarIdCatalog::build(stars, fov);
    pairs = cat.pairs().size();
  }
  state.counters["pairs"] = static_cast<double>(pairs);
}
BENCHMARK(BM_BuildStarIdCatalog)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
