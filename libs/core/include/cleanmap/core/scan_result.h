// SPDX-License-Identifier: BSD-3-Clause
// What the pipeline says about one decided scan (DESIGN §4): labels, map points, counts, stage
// times. Plain data below the pipeline, so the writers in cleanmap::io need no pipeline.
#pragma once
#include <Eigen/Geometry>
#include <chrono>
#include <cstddef>
#include <limits>
#include <opencv2/core/mat.hpp>
#include <string>
#include <vector>

#include "cleanmap/core/types.h"

namespace cleanmap {

/// Per-stage wall time of one scan, milliseconds.
struct StageTimes {
  double registration = 0, index = 0, ground = 0, duplicates = 0, octree = 0, classify = 0,
         objects = 0, free_space = 0, images = 0, total = 0;
  StageTimes& operator+=(const StageTimes& o);
};

/// Counts of one scan (or, summed with +=, of a run).
struct ScanStats {
  std::size_t points = 0;   ///< original points (invalid included)
  std::size_t invalid = 0;  ///< NaN / inf, dropped on reading
  std::size_t in_crop = 0, ground = 0, duplicates = 0, candidates = 0, tested = 0;
  /// DESIGN §2.2: the recording vehicle's own returns, taken out of the crop (findSelfReturns)
  std::size_t self_returns = 0;
  std::size_t moving = 0, static_points = 0;
  std::size_t window = 0;  ///< scans in the window
  /// DESIGN §2b: the window's K and stride, and the scan rate an auto K came from (Hz, 0: none);
  /// one value per run, so sums keep the largest.
  std::size_t window_k = 0, window_stride = 0;
  double scan_rate_hz = 0;
  std::size_t map_far = 0;  ///< points beyond the crop within the map radius (DESIGN §2e)
  /// DESIGN §2.0: 1 for a de-skewed scan (summed: de-skewed scans); the largest distance one of
  /// its points moved (m; the run's largest in sums).
  std::size_t deskewed = 0;
  double deskew_max_shift = 0;
  std::size_t total_conflicts = 0, no_evidence = 0;
  /// The moving-point test's work (issue #16): (tested point, window scan) pairs looked up, beams
  /// evaluated in their cones, points decided before their last window scan.
  std::size_t scans_visited = 0, beams = 0, early_decisions = 0;
  /// Sampled points left untested because their leaf's majority was already settled (DESIGN
  /// §2c; `tested` counts them too).
  std::size_t settled_skips = 0;
  std::size_t conflicting_scans = 0;  ///< empty scan votes made unknown (doc/SCAN_CONFLICT.md)
  std::size_t ring_votes = 0;  ///< empty votes of a sparse lidar's rings around P (DESIGN §2b)
  std::size_t objects_moving = 0, consensus_points = 0, consensus_removed = 0;  ///< doc/OBJECTS.md
  std::size_t objects_persisted = 0;  ///< of objects_moving, kept moving by the hysteresis
  /// of objects_persisted, under static_fraction (leaving or arriving)
  std::size_t objects_left_place = 0;
  std::size_t objects_measured = 0;  ///< of objects_moving, those rule 7 measured moving
  std::size_t objects_far_kept = 0;  ///< far objects rule 2 kept moving, fewer than min_moving
  /// Rule 4 at the start: objects the next scan moved whole, turned moving, and their points
  /// turned moving (doc/OBJECTS.md).
  std::size_t objects_carried_back = 0, carried_back_points = 0;
  std::size_t consensus_body_kept = 0;  ///< moving points of bodies a static component kept
  std::size_t consensus_foot_left = 0;  ///< points at a moving component's foot left static
  /// of consensus_foot_left, in a raised part's columns with nothing of it over them (rule 2)
  std::size_t consensus_surface_left = 0;
  std::size_t mover_feet = 0;   ///< ground returns under a moving object taken along (rule 6)
  std::size_t mover_roofs = 0;  ///< a sparse lidar's roof stripes taken along (rule 6)
  /// points of a moving component's raised parts with no moving point of their own, left static
  std::size_t consensus_still_part_left = 0;
  /// components of vehicle extent too wide for a vehicle, not turned moving whole (rule 2)
  std::size_t consensus_wide_left = 0;
  std::size_t empty = 0;  ///< 1 for a scan without valid points (summed: empty scans)
  /// DESIGN §3, the camera check: scans that had an image; decision units (cells of moving
  /// points) tested, of which confirmed moving by the colour / depth test, relabelled static
  /// when every camera found them similar (by colour only / with the depth test), and unseen
  /// (no camera to compare with: the laser label stays); points relabelled static; (cell,
  /// camera) pairs not compared because the cell's surface was seen grazing; moving points of
  /// objects rule 4 held (doc/OBJECTS.md), not compared: they keep the laser label.
  std::size_t image_scans = 0, image_units = 0, image_confirmed_colour = 0,
              image_confirmed_depth = 0, image_rejected_colour = 0, image_rejected_depth = 0,
              image_unseen = 0, image_relabelled = 0, image_grazing = 0, image_held = 0;
  /// DESIGN §3 "Camera poses": 1 when this scan and the one before it both had an image (a link
  /// to align), 1 when that alignment corrected the relative pose; the correction's length (m).
  std::size_t image_links = 0, image_links_aligned = 0;
  double image_link_shift = 0;
  StageTimes ms;
  /// Sums every count and time (window: sum too; divide by scans for a mean).
  ScanStats& operator+=(const ScanStats& o);
};

/// How the scan's pose was obtained (DESIGN §2.1).
struct PoseInfo {
  std::string source = "given";  ///< "given", "gicp" or "refine"
  std::string status = "given";  ///< "given", "first", "ok", or why the alignment was refused
  bool accepted = true;          ///< false: the pose is the guess (the alignment was refused)
  std::string reason;            ///< a refusal's reason without its figures ("" when accepted)
  bool map_restarts = false;     ///< refused for want of overlap: GICP's map started again
  int start_guesses = 0;         ///< DESIGN §2.1 "Starting at speed": guesses tried along the axis
  int guess_iterations = 0;      ///< and their GICP iterations
  std::string guess = "none";    ///< GICP's initial guess: "constant velocity", "odometry", "given"
  int iterations = 0;
  double fitness = 0;  ///< share of aligned points with a correspondence
  double rmse = 0;     ///< m; RMS distance of the correspondences
  /// ms per step: crop + downsampling, covariances, GICP, map update
  double ms_downsample = 0, ms_covariances = 0, ms_align = 0, ms_map = 0;
};

/// What a point of the full map is (DESIGN §2e): inside the crop and decided by the windowed test,
/// or beyond it within the map radius; ground or not. Ground is never removed by the cleaning.
/// kMapStatic points are also in static_compact; kMapDuplicate ones (static, duplicates of the
/// recent map, DESIGN §2.3) are not.
enum MapKind : uint8_t {
  kMapStatic = 0,
  kMapGround = 1,
  kMapFar = 2,
  kMapFarGround = 3,
  kMapDuplicate = 4
};
inline bool isGroundKind(uint8_t k) {
  return k == kMapGround || k == kMapFarGround;
}

/// Everything the pipeline says about one scan, handed to the sink once the scan is decided.
struct ScanResult {
  std::size_t index = 0;
  std::string stem;
  std::string source;  ///< the input it came from (Frame::source)
  double timestamp = 0;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  PoseInfo pose_info;
  /// DESIGN §2a: the ground height below the sensor measured in this scan (NaN: not measurable)
  /// and the one its ground segmentation started from (-sensor.height, or the median measured).
  double ground_measured = std::numeric_limits<double>::quiet_NaN();
  double ground_z = 0;
  double density = 1;   ///< the lidar's returns per solid angle relative to the HDL-64E (§2d)
  double ring_gap = 0;  ///< rad between the lidar's rings where sparse (§2b); 0: dense
  Labels labels;        ///< one per original point, original order (DESIGN §4)
  std::vector<PointXYZI> static_compact;  ///< world frame: static points not already in the map
  std::vector<PointXYZI> static_full;     ///< world frame: every static point (ground included)
  std::vector<PointXYZI> moving;          ///< world frame
  /// Per static_full point: its index in the original scan and its kind (MapKind); per moving
  /// point, its original index. The map's cleaning and map_labels/ use them (DESIGN §2e).
  std::vector<uint32_t> static_full_index, moving_index;
  std::vector<uint8_t> static_full_kind;
  /// Original indices of the recording vehicle's own returns (DESIGN §2.2, "Self returns"):
  /// labelled 0, and removed by the map (map_labels/ 251), so no cleaned scan holds them.
  std::vector<uint32_t> self_index;
  /// Original indices of the points the camera check relabelled static (DESIGN §3).
  std::vector<uint32_t> relabelled_index;
  /// With LaserPipeline::saveOverlays: the camera image with the scan's points drawn over it.
  cv::Mat overlay;
  /// The scan as read (sensor frame, valid points, original_index), only when the pipeline keeps
  /// scans (LaserPipeline::keepScans): the cleaned and labelled rawlogs are made from it.
  Scan scan;
  ScanStats stats;
  /// When the pipeline had decided it (rule 4's carrying back included); unset (epoch) where no
  /// pipeline made it. The report's steady rate is the time between two decisions (`interval`):
  /// a result may be held for later scans' rules before it is written.
  std::chrono::steady_clock::time_point decided_at{};
};

}  // namespace cleanmap
