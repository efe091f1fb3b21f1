// Imaging: one full NST frame (1280 x 1024, 12 bit) with ~50 stars and every
// noise term on (target: median under 15 ms on one core), and its parts.
#include <benchmark/benchmark.h>

#include <random>

#include "artms/astro/elements.hpp"
#include "artms/imaging/image.hpp"
#include "artms/imaging/renderer.hpp"

namespace {

using namespace artms;

// nst.yaml has the real-camera effects (stray light, vignetting, ...),
// nst_ideal.yaml none: a flat sky.
imaging::CameraModel nst(const std::string& file = "nst") {
  return imaging::CameraModel::load(std::string(ARTMS_CONFIG_DIR) + "/cameras/" + file + ".yaml");
}

// 50 stars at random sub-pixel positions, V uniform in [2, 7].
std::vector<imaging::PointSource> fifty_stars(const imaging::CameraModel& cam) {
  std::mt19937_64 rng(2024);
  std::uniform_real_distribution<double> ux(0.0, cam.width_px - 1.0), uy(0.0, cam.height_px - 1.0),
      uv(2.0, 7.0);
  std::vector<imaging::PointSource> out;
  for (int k = 0; k < 50; ++k) out.push_back({ux(rng), uy(rng), cam.electrons_from_vmag(uv(rng))});
  return out;
}

void BM_RenderNstFrame50StarsFullNoise(benchmark::State& state, const std::string& camera_file) {
  const imaging::ImageFormer former(nst(camera_file));
  const auto stars = fifty_stars(former.camera());
  std::uint64_t seed = 1;
  for (auto _ : state) {
    auto frame = former.render(stars, seed++);
    benchmark::DoNotOptimize(frame.data());
  }
  state.counters["Mpx_per_s"] = benchmark::Counter(
      static_cast<double>(state.iterations()) * 1280.0 * 1024.0 / 1e6, benchmark::Counter::kIsRate);
}
BENCHMARK_CAPTURE(BM_RenderNstFrame50StarsFullNoise, nst_ideal, std::string("nst_ideal"))
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(7)
    ->ReportAggregatesOnly(true);
BENCHMARK_CAPTURE(BM_RenderNstFrame50StarsFullNoise, nst, std::string("nst"))
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(7)
    ->ReportAggregatesOnly(true);

// The deterministic part alone: background, hot pixels, 50 PSFs.
void BM_ExpectedElectrons50Stars(benchmark::State& state) {
  const imaging::ImageFormer former(nst());
  const auto stars = fifty_stars(former.camera());
  for (auto _ : state) {
    auto img = former.expected_electrons(stars);
    benchmark::DoNotOptimize(img.data());
  }
}
BENCHMARK(BM_ExpectedElectrons50Stars)->Unit(benchmark::kMillisecond);

// Catalog stars in the field for one attitude (BSC5 to V 6.5, cone + projection).
void BM_StarsInFrame(benchmark::State& state) {
  const auto cam = nst();
  const auto catalog =
      imaging::StarCatalog::load_bsc5(std::string(ARTMS_DATA_DIR) + "/stars/bsc5.dat", 6.5);
  const Eigen::Quaterniond q(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()));
  const auto t = astro::tt_from_utc_string("2024-05-08T00:00:00Z");
  std::size_t n = 0;
  for (auto _ : state) {
    const auto stars = imaging::stars_in_frame(catalog, cam, q, t, 6.0);
    n = stars.size();
    benchmark::DoNotOptimize(stars.data());
  }
  state.counters["stars"] = static_cast<double>(n);
}
BENCHMARK(BM_StarsInFrame)->Unit(benchmark::kMicrosecond);

// The whole renderer as the service runs it: catalog stars, the faint-star
// sky, two targets, exclusions and the full noise model (PSE, SV4 camera).
void BM_FullRendererFrame(benchmark::State& state, const std::string& camera_file) {
  imaging::RenderOptions options;
  options.profile = imaging::TargetProfile::flight_like();
  const imaging::FrameRenderer renderer(
      nst(camera_file), imaging::StarCatalog::load_bsc5(std::string(ARTMS_DATA_DIR) + "/stars/bsc5.dat", 99.0), options);
  using astro::kDegToRad;
  const astro::QnsElements sv4{6943e3, 0.0001, 0.0016, 99.4 * kDegToRad, -38.0 * kDegToRad, -153.0 * kDegToRad};
  imaging::RenderRequest req;
  req.observer = "SV4";
  req.t = astro::tt_from_utc_string("2024-05-08T00:10:00Z");
  req.observer_eci = astro::cartesian_from_qns(sv4);
  req.q_cam_from_eci = Eigen::Quaterniond(astro::R_v_from_eci(req.observer_eci, astro::Boresight::kMinusVelocity));
  req.targets = {{"SV2", req.observer_eci.r_m - 52e3 * req.observer_eci.v_mps.normalized()},
                 {"SV3", req.observer_eci.r_m - 130e3 * req.observer_eci.v_mps.normalized()}};
  std::size_t faint = 0, stars = 0;
  for (auto _ : state) {
    ++req.frame_index;
    const auto f = renderer.render(req);
    faint = f.faint_stars;
    stars = f.stars.size();
    benchmark::DoNotOptimize(f.pixels.data());
  }
  state.counters["catalog_stars"] = static_cast<double>(stars);
  state.counters["faint_stars"] = static_cast<double>(faint);
}
// 00:10 UTC: SV4 sunlit, the Earth limb below the boresight lit (stray light on).
BENCHMARK_CAPTURE(BM_FullRendererFrame, nst, std::string("nst"))
    ->Unit(benchmark::kMillisecond)->Repetitions(5)->ReportAggregatesOnly(true);
BENCHMARK_CAPTURE(BM_FullRendererFrame, nst_ideal, std::string("nst_ideal"))
    ->Unit(benchmark::kMillisecond)->Repetitions(5)->ReportAggregatesOnly(true);

}  // namespace

BENCHMARK_MAIN();
