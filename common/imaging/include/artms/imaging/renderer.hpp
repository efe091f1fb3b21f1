// One star-tracker frame from the truth geometry: catalog stars, a fixed
// population of faint uncatalogued stars, targets with their photometry and
// visibility, Sun/Moon/Earth-limb exclusion, the noise model, drop-outs and
// time-tag faults. Used by the camera renderer service and artms-render.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "artms/astro/frames.hpp"
#include "artms/astro/time.hpp"
#include "artms/imaging/camera.hpp"
#include "artms/imaging/image.hpp"
#include "artms/imaging/photometry.hpp"
#include "artms/imaging/star_catalog.hpp"
#include "artms/imaging/visibility.hpp"

namespace artms::imaging {

struct RenderOptions {
  NoiseOptions noise;                      // NoiseOptions::noise_free() for geometry checks
  TargetProfile profile = TargetProfile::nominal();  // or flight_like()
  TargetOptics optics;
  double limiting_vmag = kNstLikeLimitingVmag;  // "too faint" in the frame truth
  // Faint stars not in the catalog (IMP must reject them): a fixed sky
  // population, the same stars at the same places in every frame.
  bool faint_stars = true;
  double faint_star_min_vmag = 6.6;
  double faint_star_max_vmag = 9.0;
  double faint_stars_per_deg2 = 2.7;  // V 6.5-9 star counts: ~110,000 over the sky
  std::uint64_t sky_seed = 20240508;
  // Stars (catalogued and faint) as the moving observer sees them, shifted
  // by up to ~26" towards its velocity relative to the solar-system
  // barycentre (the Earth's, dynamics::earth_velocity_bcrs_mps, plus its own
  // orbital velocity): stellar aberration, astro/aberration.hpp. Targets
  // are drawn at their geometric directions: their light time cancels all
  // but the two velocities' difference, 0.04-0.11" for spacecraft 50-150 km
  // apart on one orbit, not drawn. Off here for geometry tests; scenarios
  // turn it on (observers[].camera.stellar_aberration).
  bool stellar_aberration = false;
  FrameFaults faults;
  astro::TimeTT fault_epoch;  // time-tag drift counts from here
  std::uint64_t noise_seed = 1;
};

struct TargetInput {
  std::string id;
  astro::Vec3 r_eci_m;
};

struct RenderRequest {
  std::string observer;
  std::uint64_t frame_index = 0;
  astro::TimeTT t;
  astro::StateVector observer_eci;
  Eigen::Quaterniond q_cam_from_eci;
  std::vector<TargetInput> targets;
};

// ra_deg/dec_deg: direction at the frame epoch (J2000 frame, proper motion
// applied, and aberration when RenderOptions::stellar_aberration: as imaged).
struct StarTruth {
  int catalog_id = 0;
  double ra_deg = 0.0, dec_deg = 0.0, vmag = 0.0, x_px = 0.0, y_px = 0.0;
};
struct TargetTruth {
  std::string id;
  double x_px = 0.0, y_px = 0.0;  // NaN when behind the camera
  double vmag = 0.0;               // +inf when unlit
  double range_m = 0.0;
  bool visible = false;
  std::string reason;  // kReason* of visibility.hpp, or an exclusion
};

struct RenderedFrame {
  bool dropped = false;          // drop-out: no pixels, no frame published
  astro::TimeTT t_true;
  astro::TimeTT time_tag;        // with the injected offset and drift
  ExclusionResult exclusion;     // excluded frames are washed out / flagged
  int width = 0, height = 0;
  std::vector<std::uint16_t> pixels;
  std::vector<StarTruth> stars;  // catalog stars imaged on the sensor
  std::vector<TargetTruth> targets;
  std::size_t faint_stars = 0;
};

class FrameRenderer {
 public:
  FrameRenderer(CameraModel camera, StarCatalog catalog, RenderOptions options);
  [[nodiscard]] RenderedFrame render(const RenderRequest& request) const;
  [[nodiscard]] const CameraModel& camera() const { return former_.camera(); }
  [[nodiscard]] const RenderOptions& options() const { return options_; }

 private:
  // v_obs_mps: the observer's barycentric velocity (aberration), or nullptr.
  [[nodiscard]] std::vector<PointSource> faint_star_sources(const Eigen::Quaterniond& q_cam_from_eci,
                                                            const astro::Vec3* v_obs_mps, std::size_t* count) const;
  ImageFormer former_;
  StarCatalog catalog_;
  RenderOptions options_;
};

// Seed of one frame's noise: independent of the order frames are rendered in.
std::uint64_t frame_seed(std::uint64_t base, const std::string& observer, std::uint64_t frame_index);

}  // namespace artms::imaging
