// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/params.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "cleanmap/core/error.h"
#include "cleanmap/core/median.h"

namespace cleanmap {

void validate(const PipelineParams& p, const std::string& name) {
  auto require = [&](bool ok, const std::string& what) {
    if (!ok) throw Error(name, what);
  };
  // Lengths that size a grid have physical bounds: a cell far below a lidar's noise, or a range
  // far beyond its reach, is a typo, and would overflow a grid or its 21-bit cell keys
  // (cell_key.h) rather than fail clearly.
  require(p.filter.crop_tau > 0 && p.filter.crop_tau <= 1000,
          "filter.crop_tau must be in (0, 1000] m");
  require(p.filter.self_range >= 0 && p.filter.self_range <= 10,
          "filter.self_range must be in [0, 10] m (0 = off)");
  require(p.filter.dup_window >= 0, "filter.dup_window must be >= 0");
  require(p.filter.dup_distance >= 0.01 && p.filter.dup_distance <= 5,
          "filter.dup_distance must be in [0.01, 5] m");
  require(p.sensor.height == 0 || (p.sensor.height >= 0.1 && p.sensor.height <= 10),
          "sensor.height must be auto or in [0.1, 10] m above the ground");
  require(p.ground.cell >= 0.05 && p.ground.cell <= 10, "ground.cell must be in [0.05, 10] m");
  require(p.ground.step > 0, "ground.step must be > 0");
  require(p.ds.sigma_m >= 0 && p.ds.sigma_r >= 0 && p.ds.sigma_m + p.ds.sigma_r > 0,
          "ds.sigma_m and ds.sigma_r must be >= 0, not both 0");
  require(p.ds.lambda_theta > 0 && p.ds.lambda_theta < 0.5,
          "ds.lambda_theta must be in (0, 0.5) rad");
  require(p.ds.search_lambdas > 0, "ds.search_lambdas must be > 0");
  require(0 <= p.ds.r_inf && p.ds.r_inf <= p.ds.r_sup && p.ds.r_sup < 1,
          "need 0 <= ds.r_inf <= ds.r_sup < 1");
  require(p.ds.window_k >= 0 && p.ds.window_k <= kMaxWindowK,
          "ds.window_k must be auto or in [1, " + std::to_string(kMaxWindowK) + "] scans");
  require(p.ds.window_s > 0 && p.ds.window_s <= 10, "ds.window_s must be in (0, 10] s");
  require(p.ds.window_stride >= 0 && p.ds.window_stride <= kMaxWindowK,
          "ds.window_stride must be auto or in [1, " + std::to_string(kMaxWindowK) + "] scans");
  require(p.ds.scan_conflict > 0 && p.ds.scan_conflict <= 1,
          "ds.scan_conflict must be in (0, 1] (1 = off)");
  require(p.ds.empty_run >= 0 && p.ds.empty_run <= 1, "ds.empty_run must be in [0, 1] (0 = off)");
  require(p.octree.leaf >= 0.02 && p.octree.leaf <= 10, "octree.leaf must be in [0.02, 10] m");
  require(p.octree.tau_np >= 1, "octree.tau_np must be >= 1");
  require(p.octree.fraction > 0 && p.octree.fraction <= 1, "octree.fraction must be in (0, 1]");
  require(p.object.voxel >= 0.02 && p.object.voxel <= 10, "object.voxel must be in [0.02, 10] m");
  require(0 <= p.object.static_fraction && p.object.static_fraction <= p.object.moving_fraction &&
              p.object.moving_fraction <= 1,
          "need 0 <= object.static_fraction <= object.moving_fraction <= 1");
  require(p.object.min_moving >= 1, "object.min_moving must be >= 1");
  require(p.object.far_points >= 0, "object.far_points must be >= 0 (0 = off)");
  require(p.object.max_length > 0 && p.object.max_height > 0 && p.object.max_width > 0,
          "object.max_length, max_height and max_width must be > 0");
  require(p.object.ring_pool >= 0 && p.object.ring_pool <= p.object.max_length,
          "object.ring_pool must be in [0, object.max_length] m (0 = off)");
  require(p.object.wall_gap >= 0 && p.object.wall_gap <= 1,
          "object.wall_gap must be in [0, 1] m (0 = off)");
  require(p.object.persist_radius >= 0 && p.object.persist_radius <= 10,
          "object.persist_radius must be in [0, 10] m (0 = off)");
  require(p.object.foot_height >= 0 && p.object.foot_height <= 2,
          "object.foot_height must be in [0, 2] m (0 = off)");
  require(p.object.foot_reach >= 0 && p.object.foot_reach <= 1,
          "object.foot_reach must be in [0, 1] m (0 = off)");
  const auto& r = p.registration;
  require(0 <= r.min_range && r.min_range < r.max_range,
          "need 0 <= registration.min_range < max_range");
  require(r.voxel >= 0.02 && r.voxel <= r.align_voxel && r.align_voxel <= 20,
          "need 0.02 <= registration.voxel <= align_voxel <= 20 m");
  require(r.knn >= 5, "registration.knn must be >= 5");
  require(r.relative_error >= 0 && r.relative_error <= 1,
          "registration.relative_error must be in [0, 1] (a fraction of the path)");
  require(r.plane_epsilon > 0 && r.plane_epsilon < 1,
          "registration.plane_epsilon must be in (0, 1)");
  require(r.max_correspondence >= 0.05 && r.max_correspondence <= 20,
          "registration.max_correspondence must be in [0.05, 20] m (it is also the map's voxel)");
  require(r.kernel > 0, "registration.kernel must be > 0");
  require(r.max_iterations >= 1 && r.map_points_per_voxel >= 1,
          "registration.max_iterations and map_points_per_voxel must be >= 1");
  require(r.map_radius > r.max_correspondence,
          "registration.map_radius must exceed max_correspondence");
  require(r.map_lag >= 0 && r.map_lag <= 50,
          "registration.map_lag must be in [0, 50] scans (0: align against every entry)");
  require(r.odometry_tolerance >= 0 && r.odometry_drift >= 0 && r.odometry_drift <= 1,
          "registration.odometry_tolerance must be >= 0 m (0: no check) and odometry_drift in "
          "[0, 1]");
  require(r.odometry_window >= 1 && r.odometry_window <= 1000,
          "registration.odometry_window must be in [1, 1000] scans");
  require(r.max_speed > 0 && r.max_turn_rate > 0,
          "registration.max_speed and max_turn_rate must be > 0");
  require(p.threads >= 1, "run.threads must be >= 1");
  require(p.epoch >= 0, "run.epoch must be >= 0 (0: the whole run is one epoch)");
  const auto& m = p.map;
  require(m.radius >= 0 && m.radius <= 1000,
          "static_map.radius must be in [0, 1000] m (0: the map holds the crop only)");
  const double extent = std::max(p.filter.crop_tau, p.map.radius);  // what the ground grid spans
  const std::string excess = groundGridExcess(extent, p.ground.cell);
  require(excess.empty(),
          "ground.cell is too small for the ground grid: max(filter.crop_tau, static_map.radius) / "
          "ground.cell = " +
              excess);
  require(m.voxel >= 0.02 && m.voxel <= 5, "static_map.voxel must be in [0.02, 5] m");
  require(m.min_free_scans >= 1, "static_map.min_free_scans must be >= 1");
  require(m.vacated_scans >= 0 && m.vacated_scans <= 255,
          "static_map.vacated_scans must be in [0, 255] (0: off)");
  require(m.arrived_scans >= 0 && m.arrived_scans <= 255,
          "static_map.arrived_scans must be in [0, 255] (0: off)");
  require(m.between_scans >= 0 && m.between_scans <= 255,
          "static_map.between_scans must be in [0, 255] (0: off)");
  require(m.hit_inflate >= 0 && m.hit_inflate <= 1, "static_map.hit_inflate must be in [0, 1] m");
  require(m.object_overlap >= 0 && m.object_overlap <= 1,
          "static_map.object_overlap must be in [0, 1] (0: off)");
  require(m.flat_slope >= 0 && m.flat_slope <= 1,
          "static_map.flat_slope must be in [0, 1] (0: off)");
  require(m.graze_reach >= 0 && m.graze_reach <= 20, "static_map.graze_reach must be in [0, 20] m");
  require(m.margin >= 0 && m.min_range >= 0 && m.beam_spacing >= 0,
          "static_map.margin, static_map.min_range and static_map.beam_spacing must be >= 0");
  require(m.policy == MapPolicy::kMoving || m.policy == MapPolicy::kTransient,
          "static_map.policy must be moving or transient");
  const auto& im = p.image;
  require(im.patch_height > 0, "image.patch_height must be > 0");
  require(im.min_patch >= 3 && im.max_patch >= im.min_patch && im.max_patch <= 256,
          "need 3 <= image.min_patch <= image.max_patch <= 256");
  require(im.search_margin >= 0, "image.search_margin must be >= 0");
  require(im.uniform_std >= 0 && im.uniform_std < 0.5, "image.uniform_std must be in [0, 0.5)");
  require(im.ncc_threshold > 0 && im.ncc_threshold <= 2, "image.ncc_threshold must be in (0, 2]");
  require(im.depth_threshold > 0, "image.depth_threshold must be > 0");
  require(im.dilation_radius >= 0 && im.dilation_radius <= 20,
          "image.dilation_radius must be in [0, 20] px");
  require(im.occlusion > 0, "image.occlusion must be > 0");
  require(im.cell >= 0.02 && im.cell <= 10, "image.cell must be in [0.02, 10] m");
  require(im.min_views >= 1, "image.min_views must be >= 1");
  require(im.changed_fraction >= 0 && im.changed_fraction < 1,
          "image.changed_fraction must be in [0, 1)");
  require(im.max_cells >= 1 && im.max_cells <= 1000000, "image.max_cells must be in [1, 1e6]");
  require(im.max_incidence_deg > 0 && im.max_incidence_deg <= 90,
          "image.max_incidence_deg must be in (0, 90]");
  require(im.align_max_shift > 0 && im.align_max_shift <= 5,
          "image.align_max_shift must be in (0, 5] m");
  require(im.align_small_shift > 0 && im.align_small_shift <= 5,
          "image.align_small_shift must be in (0, 5] m");
}

std::string groundGridExcess(double extent, double cell) {
  if (extent / cell <= kMaxGroundHalfCells) return {};
  return std::to_string(static_cast<long long>(extent / cell)) + " cells each side, at most " +
         std::to_string(static_cast<int>(kMaxGroundHalfCells));
}

std::optional<ScanSpacing> scanSpacing(const std::vector<double>& times,
                                       const std::vector<Eigen::Vector3d>& positions) {
  std::vector<double> dt, dx;
  for (std::size_t i = 1; i < times.size(); ++i)
    if (times[i] - times[i - 1] > 1e-3) {
      dt.push_back(times[i] - times[i - 1]);
      if (positions.size() == times.size()) dx.push_back((positions[i] - positions[i - 1]).norm());
    }
  if (dt.empty()) return std::nullopt;
  return ScanSpacing{median(std::move(dt)), dx.empty() ? 0.0 : median(std::move(dx))};
}

std::string sparseScansWarning(double median_seconds, double median_metres) {
  // kitti_residential, every third scan (0.3 s, 2.5 m apart): precision 0.82 -> 0.03;
  // kitti_highway's (0.67 m apart) 0.94 as every sweep (doc/BENCHMARK.md, seventy-fourth session).
  if (!(median_seconds > 0.25 && median_metres > 1.0)) return {};
  char text[320];
  std::snprintf(text, sizeof text,
                "the scans are %.2f s and %.1f m apart (median), sparser than a lidar's sweeps "
                "(5-20 Hz), as a SLAM's keyframes may be: the moving test compares neighbouring "
                "sweeps and flags more static points so far apart; clean every sweep "
                "(doc/MRPT.md step d)",
                median_seconds, median_metres);
  return text;
}

double scanPeriod(const std::vector<double>& stamps) {
  std::vector<double> dt;
  for (std::size_t i = 1; i < stamps.size(); ++i) {
    const double d = stamps[i] - stamps[i - 1];
    if (d > 1e-3 && d <= 1.0) dt.push_back(d);  // a lidar of 1 to 1000 Hz; repeats, gaps out
  }
  if (dt.empty()) return 0.0;
  std::sort(dt.begin(), dt.end());
  const std::size_t n = dt.size();
  return n % 2 ? dt[n / 2] : 0.5 * (dt[n / 2 - 1] + dt[n / 2]);
}

int windowScans(const DsParams& ds, const std::vector<double>& stamps, double* rate_hz) {
  if (rate_hz) *rate_hz = 0;
  if (ds.window_k > 0) return ds.window_k;
  const double period = scanPeriod(stamps);
  if (!(period > 0)) return kDefaultWindowK;
  if (rate_hz) *rate_hz = 1.0 / period;
  const double k = std::round(ds.window_s / period);
  return static_cast<int>(std::clamp(k, 1.0, double(kMaxWindowK)));
}

int windowStride(const DsParams& ds, int k) {
  if (ds.window_stride > 0) return ds.window_stride;
  return std::max(1, k / kDefaultWindowK);
}

}  // namespace cleanmap
