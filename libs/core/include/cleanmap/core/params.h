// SPDX-License-Identifier: BSD-3-Clause
// Every parameter of the laser pipeline (DESIGN §2), with its default and unit. The one source of
// truth: ini files and CLI flags are parsed into these structs at the boundary.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cleanmap/core/sensor.h"

namespace cleanmap {

/// DESIGN §2.2-2.3: range crop and duplicate filter.
struct FilterParams {
  double crop_tau = 30.0;      ///< m; a point is a candidate iff |x|,|y|,|z| <= tau (sensor frame)
  int dup_window = 10;         ///< W: scans whose static points the duplicate test looks at
  double dup_distance = 0.10;  ///< m; d_dup
  /// m; DESIGN §2.2 "Self returns": flagged returns within this horizontal range that stay put in
  /// the sensor frame while it drives are the recording vehicle's own, left unclassified
  /// (findSelfReturns). 0 = off.
  double self_range = 3.0;
};

/// m; the height assumed when sensor.height is auto and a scan's ground cannot be measured
/// (KITTI's HDL-64E).
constexpr double kDefaultSensorHeight = 1.73;

/// DESIGN §2b: K where ds.window_k is auto and the timestamps give no scan rate (the paper's, at
/// KITTI's 10 Hz), and the largest K (the window's 2K + 1 scans are held in memory).
constexpr int kDefaultWindowK = 10;
constexpr int kMaxWindowK = 50;
/// Scans whose timestamps measure the scan rate for an auto K (4 intervals: one dropped scan or a
/// repeated stamp does not move their median).
constexpr int kRateScans = 5;

/// DESIGN §2.0: when a scan's points are moved into the frame of its timestamp.
enum class DeskewMode { kAuto = 0, kOff = 1, kOn = 2 };

/// DESIGN §2a: the lidar and its mounting (issue #15).
struct SensorParams {
  /// m; the sensor origin's height above the ground under the vehicle: h_G = -height starts the
  /// ground propagation (§2a). 0 = auto: measured in every scan (estimateGroundHeight), the median
  /// of the scan's and its K predecessors' measurements.
  double height = 0.0;
  /// The lidar (cleanmap/core/sensor.h presets): its angular resolution scales the point counts
  /// tuned on the HDL-64E (object.min_moving, DESIGN §2d). kAuto: measured in every scan where
  /// its rings stand apart (sparse sensors), else the HDL-64E's.
  SensorModel model = SensorModel::kAuto;
  /// DESIGN §2.0: undo the motion during each sweep (registration and every later stage see the
  /// de-skewed points). kAuto: where the input gives per-point times (a rawlog's Velodyne packets
  /// or rotating scans), not where it gives none (KITTI's scans come de-skewed). kOn: also
  /// there, the times from the azimuth (a sweep clockwise from the rear, as KITTI's HDL-64E).
  DeskewMode deskew = DeskewMode::kAuto;
};

/// DESIGN §2a: ground removal by height propagation.
struct GroundParams {
  double cell = 0.4;   ///< m; grid cell side
  double step = 0.09;  ///< m; s, the largest rise within / between cells (22 % slope)
  /// In non-ground cells, also label ground the points below h_G + s (our addition, the paper is
  /// cell-level only; see doc/SWEEP.md for its effect).
  bool point_refine = true;
  /// Across k empty cells the allowed rise is s * min(1 + k, max_gap_cells) (our addition; 1 =
  /// the paper's rule). 10 cells = 4 m, the HDL-64E blind zone on a 22 % slope.
  int max_gap_cells = 10;
};
/// The ground grid is dense, (2 n + 1)^2 cells for n = half extent / cell: at most this n
/// (5001^2 cells, about 0.5 GB of scratch), so that a small cell over a wide crop is a clear error
/// rather than an overflow.
constexpr double kMaxGroundHalfCells = 2500;
/// "" where a ground grid over +-extent in cells of `cell` keeps within kMaxGroundHalfCells, else
/// what the errors say: "N cells each side, at most 2500".
std::string groundGridExcess(double extent, double cell);

/// DESIGN §2b: Dempster-Shafer beam model and window.
struct DsParams {
  double sigma_m = 0.05;         ///< m; range measurement noise
  double sigma_r = 0.15;         ///< m; registration noise
  double lambda_theta = 0.0035;  ///< rad; angular spread of a beam (default from doc/SWEEP.md)
  double search_lambdas = 3.0;   ///< beams within search_lambdas * lambda_theta are considered
  double r_sup = 0.8;            ///< discretised belief near the sensor
  double r_inf = 0.6;            ///< discretised belief at the farthest range
  /// K: scans before and after. 0 = auto: the scans of window_s at the input's scan rate,
  /// measured from the first scans' timestamps (LaserPipeline::windowK; 10 where they give none).
  int window_k = 0;
  /// s; with window_k auto, the time the window spans on each side: the paper's K = 10 at
  /// KITTI's 10 Hz, so a 20 Hz lidar compares over the same second, not half of it (DESIGN §2b).
  double window_s = 1.0;
  /// The test compares with every window_stride-th scan of the window (offsets that are
  /// multiples of it). 0 = auto: K / 10 (integer, at least 1), so a lidar faster than 20 Hz
  /// compares with 10-19 scans each side, 0.1 s apart, as at KITTI's 10 Hz, not twice as many
  /// near-copies (DESIGN §2b).
  int window_stride = 0;
  /// Our addition (doc/SCAN_CONFLICT.md): a scan votes empty only if its own beams agree. When
  /// its most-empty and most-occupied beams conflict by K = e_max * o_max >= scan_conflict
  /// (foliage, fences, thin poles: some beams pass P, some return at P), the scan's empty vote
  /// becomes unknown; so does one where no beam passes P by more than sigma_m (a return at P's
  /// range: e' and o' near 0.5, decided by the noise). 1 = off (the paper's rule alone).
  double scan_conflict = 0.3;
  /// Our addition (issue #15, DESIGN §2b "Sparse lidars"): where a sparse lidar's scan has no beam
  /// in P's cone, the rings just above and below P vote empty if both pass well beyond P and no
  /// return of the scan lies near P (MovingTest::ringVote). false = such scans stay unknown.
  bool ring_vote = true;
  /// Our addition (DESIGN §2b, "Grazing beams"): a window scan's beam that passes P where it runs
  /// within static_map.margin of a flat surface of its own scan (static_map.flat_slope,
  /// graze_reach: the stretches the clean map's free space skips, §2e) votes nothing, at a point
  /// on a flat top of its own scan (the evidence slow movers drawing away had on their roofs is
  /// replaced by rule 4's far-half leaving test, doc/OBJECTS.md). false = such beams vote.
  bool grazing = true;
  /// Our addition (DESIGN §2b, "Empty runs"): where the votes say static, P is still moving if
  /// one side of its window, read from its far end towards P's own scan, votes empty in at least
  /// this share of the scans of the longer side before any scan votes occupied (unknown votes are
  /// passed over). A slow mover has left its place, or not yet reached it, for an unbroken
  /// stretch of time; a static point's empty votes (noise, foliage, a wall seen from afar at a
  /// grazing angle) are broken by occupied ones. 0 = off (the paper's votes alone).
  double empty_run = 0.7;
};

/// DESIGN §2c: octree leaf sampling.
struct OctreeParams {
  double leaf = 0.3;            ///< m; leaf size (OctoMap key resolution)
  int tau_np = 6;               ///< leaves with fewer points test all of them
  double fraction = 1.0 / 6.0;  ///< share of a dense leaf that is tested
};

/// Object consensus (our addition to the paper, doc/OBJECTS.md): non-ground points are grouped
/// into connected objects; a rigid object whose points are partly moving is moving as a whole.
struct ObjectParams {
  bool enabled = true;
  double voxel = 0.3;            ///< m; connectivity cell (26-neighbours)
  double moving_fraction = 0.2;  ///< an object with at least this share of moving points moves
  int min_moving = 20;           ///< ... and at least this many moving points
  /// Rule 2's far exception (doc/OBJECTS.md, "Far and few"): a vehicle-sized object 10 m or more
  /// from the sensor, wider than 0.3 m, with at least this many returns (at any lidar), nine in
  /// ten of them moving, keeps its moving points though they are fewer than min_moving, where
  /// the window reaches half of K on both sides (an HDL-64E returns fewer than 20 points from a
  /// walker past about 28 m). 0 = off.
  int far_points = 12;
  double static_fraction = 0.1;  ///< an object with a smaller share of moving points is static
  double max_length = 25.0;      ///< m; larger horizontal extents are structures, left alone
  double max_height = 5.0;       ///< m; taller objects are structures, left alone
  /// m; a component of vehicle extent that is wider than this (componentWidths: about 2.5 m for
  /// a truck, 9 m for a hedge's corner) is no vehicle: it is never turned moving as a whole
  /// (rules 2, 4, 5 and 7), only static where few of its points are moving (doc/OBJECTS.md).
  double max_width = 6.0;
  /// Hysteresis over time: a vehicle-sized object with a share of moving points between
  /// static_fraction and moving_fraction stays moving if most of its points lie within
  /// `persist_radius` of the previous scan's moving points (0 = off).
  double persist_radius = 1.5;  ///< m
  /// m; a component turned moving takes along its points below this height above its lowest
  /// point only where some of its points stand at or above it in their column (a car's wheels
  /// under its body, not the sidewalk it touches; doc/OBJECTS.md rule 2). 0 = all of them.
  double foot_height = 0.3;
  /// m; and only where some of its points lie over them, from 0.05 m to foot_height higher (or
  /// 1.5 ring steps of a sparse lidar) within this distance horizontally: its faces continue down
  /// to what it stands on, a sidewalk around a walker does not (Overhead; doc/OBJECTS.md rule 2,
  /// "What it stands on"). 0 = the columns alone.
  double foot_reach = 0.15;
  /// Rule 6: a moving object's returns refined to ground under it, raised over the road around
  /// them (its lowest face, tyres, shoes), go with it (MoverFeetParams; doc/OBJECTS.md).
  bool feet = true;
  /// Rule 6, roofs: a one-ring stripe on a moving vehicle's roof, beyond its near face, goes with
  /// it; at a sparse lidar its faces' lowest ring and stacked slices too (MoverRoofParams;
  /// doc/OBJECTS.md).
  bool roofs = true;
  /// m; rule 1 for sparse lidars (RingReach, doc/OBJECTS.md): a ring's slice of an object at
  /// most this wide (its returns' horizontal diagonal: a walker's) joins the slices of its column
  /// up to 1.25 ring steps above and below it. 0 = off (every lidar's objects are 26-connected
  /// voxels).
  double ring_pool = 1.0;
  /// m; rule 1, "Beside a wall" (doc/OBJECTS.md): where a structure's returns lie on one upright
  /// plane, what stands on its floor more than this in front of the plane (on the sensor's side)
  /// and is of a vehicle's size is an object of its own (a walker against a wall). 0 = off.
  double wall_gap = 0.15;
  /// Rule 1 for coarse columns (doc/OBJECTS.md, "Coarse columns"): returns of one upright surface
  /// in the lidar's neighbouring columns join (GrazingStretches::links: four in a row on parallel
  /// lines, or a line's last return before nothing or a farther one), however far apart a grazing
  /// angle puts them (at 512 columns, or a dense lidar's side met at 10 degrees; at a dense lidar
  /// into no more than a vehicle's size, max_length and max_height). false = off.
  bool column_links = true;
  /// Rule 7 (doc/OBJECTS.md, "Measured"): a vehicle-sized object the rules above leave static
  /// moves as a whole where its outline moved more than 0.35 m between the scans half a window
  /// before and after it (ConsensusRules::measured; the pipeline's measure).
  bool measure = true;
  /// Rule 4 backwards held deeper at a run's start (doc/OBJECTS.md, "Held deeper at a run's
  /// start"): the run's first H + 2 scans stay held until 2 (H + 2) are decided, so a vehicle
  /// falling behind the ego that the scans first show moving later is carried back to them.
  /// H + 2 more results held at the start: peak memory +43 MiB at kitti_highway. false = off.
  bool hold_start = true;
};

/// DESIGN §2.1: GICP scan-to-map odometry (used with --poses gicp / refine, or when the input has
/// no poses).
struct RegistrationParams {
  double min_range = 2.0;       ///< m; nearer returns (the car itself) are not aligned
  double max_range = 80.0;      ///< m
  double voxel = 0.5;           ///< m; the scan is downsampled to this for covariances and the map
  double align_voxel = 1.0;     ///< m; the subset aligned (one point per voxel of this size)
  int knn = 10;                 ///< neighbours of a covariance (within 2 voxel)
  double plane_epsilon = 1e-3;  ///< GICP plane regularisation: eigenvalues (eps, 1, 1)
  double max_correspondence = 1.0;  ///< m; also the map voxel
  double kernel = 0.3;              ///< m; Geman-McClure scale
  int max_iterations = 30;
  int map_points_per_voxel = 20;
  double map_radius = 100.0;   ///< m; the local map forgets what lies farther
  double max_speed = 50.0;     ///< m/s; a faster step is a failed alignment (a jump)
  double max_turn_rate = 1.5;  ///< rad/s; likewise
  /// GICP aligns each scan against the local map without the entries of the last `map_lag`
  /// accepted scans (until map_lag + 1 are accepted: the first scan's only). Traffic moving with
  /// the sensor sits where its newest entries are and drags the pose back to them; 1 cuts that
  /// drag on a 16-ring lidar in stop-and-go traffic, but can lose the pose in scenes with little
  /// static hold (DESIGN §2.1, "Traffic that moves with the sensor"). 0 = every entry.
  int map_lag = 0;
  /// Where the input has odometry (its increment is GICP's initial guess), an alignment that
  /// moves the pose farther than odometry_tolerance + odometry_drift * (odometry path since the
  /// last accepted scan) from that guess is refused, and the odometry kept: traffic that moves
  /// with the sensor, or a corridor, can hold GICP where the wheels say otherwise (DESIGN §2.1
  /// step 4). 0 = no such check.
  double odometry_tolerance = 0.2;  ///< m per scan: a 10 Hz odometry's error is centimetres
  double odometry_drift = 0.05;     ///< fraction of the path odometry alone has covered
  /// Scans: the same bound holds between the scan and each of this many scans before it (the
  /// odometry's path between them added to the drift's): a GICP that errs a few centimetres a
  /// scan the same way, under the tolerance each step, strays from the odometry over the window
  /// the laser test compares scans in (DESIGN §2.1 step 4). 1 = the previous scan only.
  int odometry_window = 10;
  /// Undo the motion during the sweep of the aligned points only (constant velocity; a point's time
  /// from its azimuth over 0.1 s, the sweep running clockwise from the rear as on KITTI's
  /// HDL-64E). 0 = off. SensorParams::deskew de-skews the points for every stage (DESIGN §2.0).
  bool deskew = false;
  /// With gicp / refine poses, the pose error between two scans is taken as relative_error times
  /// the path between them (odometry error grows with the distance travelled; #11's drift bar
  /// is 1 %). A window scan that has a return at P's range within that error of P does not vote
  /// empty (the scan-conflict rule over a cone widened by it, WindowScan::pose_noise2; issue #11,
  /// doc/SCAN_CONFLICT.md). The masses keep the beam cone. Given poses are exact. 0: off.
  double relative_error = 0.01;
};

/// What the map keeps (DESIGN §2e).
enum class MapPolicy {
  /// The benchmark's convention: remove what was moving when scanned: a point whose space was
  /// seen empty both before and after its scan (something came and went).
  kMoving,
  /// Also remove what stood still and then left (a parked car that drives away): a point whose
  /// space was seen empty at any time.
  kTransient,
};

/// DESIGN §2e: the map's coverage and its long-horizon cleaning.
struct MapParams {
  /// m; the map holds every point within this horizontal distance of its sensor (the DynamicMap
  /// benchmark's 50 m), classified for the map beyond the per-point crop.
  double radius = 50.0;
  bool clean =
      true;  ///< remove the points whose space is seen empty (false: the windowed test only)
  MapPolicy policy = MapPolicy::kTransient;
  double voxel = 0.2;      ///< m; free-space voxel side
  int min_free_scans = 2;  ///< scans that must see a voxel empty before its points go
  /// ... and by at least free_ratio times as many scans as returned from it (0 = off): see-through
  /// foliage and grazing beams past a surface are seen empty less often than they are hit.
  double free_ratio = 0.5;
  /// ... unless every scan for at least this many scans after its last return saw it empty
  /// (0 = off): what stood there has left (a slow truck, a queue), whereas see-through space is
  /// hit again now and then (DESIGN §2e).
  int vacated_scans = 5;
  /// ... or at least this many scans saw it empty before its first return (0 = off; policy
  /// transient only): something came and stood (the space a slow truck's front pushes into, a
  /// queue car that arrives); a static surface is not seen through before it is first seen,
  /// but for its top seen from afar: not over a voxel returned from with a shorter lead
  /// (arrivalStands, DESIGN §2e).
  int arrived_scans = 5;
  /// ... or a run of at least this many scans saw it empty between two of its returns (0 = off):
  /// the gap between two cars of a queue passing a standing sensor. A gap of g metres at v m/s is
  /// seen empty for about (g - 2 hit_inflate - voxel) rate / v scans (hit_inflate and margin keep
  /// each car's neighbourhood): 1.9 m at 3 m/s, 3.5 scans; foliage, hit in most scans and
  /// inflated by its neighbours' returns, is not seen empty that long (DESIGN §2e).
  int between_scans = 3;
  /// Spread the removals over rigid objects, scan by scan (the object consensus of
  /// doc/OBJECTS.md with the [object] parameters; DESIGN §2e, "Objects"): a slow truck's side
  /// that never left goes with its ends that came and went.
  bool objects = true;
  /// Rule 5 of the objects (DESIGN §2e, "Objects"; 0 = off; policy transient only): a
  /// vehicle-sized object with at least this share of its points in the voxels of an object of
  /// its size that the previous or the next scan removed whole (as they are, or moved by the
  /// centroids' difference) is that object: a crawling truck whose removed share is still small,
  /// a car following the sensor (two solids do not share their space).
  double object_overlap = 0.5;
  /// m; a scan does not see empty the voxels within this distance (per axis) of its own static,
  /// non-ground returns (0: only the voxel of each return): a beam that passes a surface's edge
  /// crosses the edge's voxel beside that surface's returns. 2 sigma of the beam model, as margin.
  double hit_inflate = 0.32;
  /// m; a beam marks space empty up to this distance short of its return, beyond the voxel's
  /// half diagonal: 2 sigma of the beam model (sqrt(sigma_m^2 + sigma_r^2) = 0.16 m).
  double margin = 0.32;
  /// Grazing beams (DESIGN §2e; 0 = off): a return whose rise to its lower neighbour in its
  /// azimuth column is at most this slope (17 degrees) lies on a flat surface (a road, a
  /// sidewalk, a roof). A beam that meets a flat surface at a grazing angle, or passes over one,
  /// runs within `margin` of it (measured across it) for margin / (its slope against the
  /// surface's) of horizontal distance, through the voxels that hold the surface: it marks none
  /// of them empty there, instead of stopping `margin` along itself short of its return.
  double flat_slope = 0.3;
  /// m; how far beyond its last return a flat surface a beam passes over is taken to go on (the
  /// depth of a car's roof seen from afar): the beam marks nothing within `margin` of it that far.
  double graze_reach = 2.5;
  /// Grazing sides (DESIGN §2e): a beam ending on an upright surface (a wall, a car's side) met at
  /// horizontal incidence alpha, where the scan's returns lie more than 2 hit_inflate apart along
  /// it (rho column step / sin alpha: coarse columns, far or grazing sides), marks nothing within
  /// margin / sin alpha of its end, where it runs through that surface's voxels between returns.
  bool grazing_sides = true;
  double min_range = 1.0;  ///< m; the first metre of every beam is not marked (the car itself)
  /// rad; azimuth step between the beams of a ring (HDL-64E: 0.0031; 0 = cast every beam whole).
  /// Near the sensor only every 2^L-th beam is cast, as far out as those alone are less than a
  /// voxel apart (free_space.cpp).
  double beam_spacing = 0.003;
};

/// DESIGN §3 (paper §III): the camera check of moving candidates, where a sequence has images and
/// calibration. Sizes are metres at the point's distance, turned into pixels by f / d.
struct ImageParams {
  bool enabled = true;         ///< validate with the images when they exist (--images on|off)
  double patch_height = 0.15;  ///< m; h, the patch side b = h f / d pixels
  int min_patch = 5;           ///< px; smallest patch side (farther points get this)
  int max_patch = 24;          ///< px; larger patches are compared downsampled to this side
  /// m; the patch in the other image is searched within this distance around its projection:
  /// the registration noise sigma_r (DESIGN §2b), so a static point still finds itself.
  double search_margin = 0.15;
  double uniform_std = 0.02;   ///< intensity std (in [0, 1]) above which a patch is textured
  double ncc_threshold = 0.1;  ///< similar iff E_c = 1 - max NCC_c < this for every channel
  /// Depth test: mean squared difference of the two patches' depths relative to the point's own
  /// depth (each patch minus the point's expected depth in its camera, over d): similar below.
  double depth_threshold = 0.001;
  int dilation_radius = 4;  ///< px; disk that closes the gaps of the lidar depth map
  double occlusion = 0.5;   ///< m; a lidar return this much nearer at the pixel hides the point
  double cell = 0.3;        ///< m; cells of moving points: one tested point each
  int min_views = 1;        ///< window cameras that must see the point to relabel it
  /// An object stays moving iff at least this fraction of its seen cells look different in some
  /// window camera (a tie keeps the laser's label; DESIGN §3); 0: any one cell keeps it moving.
  double changed_fraction = 0.5;
  /// Cells of an object compared at most (spread from its extremes to its centre); the vote
  /// stops earlier once the cells left cannot change it.
  int max_cells = 15;
  /// Degrees; a cell whose surface (the plane of the moving points around it) is seen farther
  /// than this from its normal in either camera is not compared there: foreshortened beyond
  /// 1 / cos (2:1 at 60) and its texture below the pixel, its look changes with the viewpoint
  /// (DESIGN §3). 90 (the default since the eighteenth session): every camera compares; with
  /// the camera poses it changed nothing on the simulated streets and cost kitti_highway movers.
  double max_incidence_deg = 90.0;
  /// DESIGN §3 "Camera poses": each scan's pose relative to the one before is corrected by
  /// aligning its image on the previous scan's ground returns (photometric, 6 degrees of
  /// freedom), and the laser test and the camera check compare the scans of a window at the
  /// corrected relative poses. 0: the poses as given.
  bool align = true;
  /// m; a larger correction of one scan's pose relative to the previous is refused: no pose
  /// source errs that much between two scans (a drift of 10 % of the path at 15 m/s: 4 sigma is
  /// 0.6 m), the alignment found a wrong minimum.
  double align_max_shift = 0.5;
  /// m; a correction up to this is kept if it lowers the images' robust error by 30 %, a larger
  /// one only if by 70 % (the error a true misalignment leaves grows with it; a wrong minimum
  /// explains only the images' noise). At or above align_max_shift: larger ones are all refused.
  double align_small_shift = 0.15;
};

/// Where scan poses come from (DESIGN §2.1): `kAuto` is `kGiven` when the first scan has a pose
/// and `kGicp` otherwise; `kRefine` starts GICP from the given poses.
enum class PoseSource { kAuto, kGiven, kGicp, kRefine };

struct PipelineParams {
  SensorParams sensor;
  FilterParams filter;
  GroundParams ground;
  DsParams ds;
  OctreeParams octree;
  ObjectParams object;
  RegistrationParams registration;
  MapParams map;
  ImageParams image;
  PoseSource poses = PoseSource::kAuto;  ///< a run option (--poses), not an ini key
  uint64_t seed = 42;                    ///< octree sampling; a run is reproducible bit for bit
  int threads = 2;                       ///< worker threads for the moving-point test (1 = serial)
  /// Scans. At every multiple of this scan index the memories of earlier decisions (the
  /// duplicate filter, the object persistence) are dropped, so a scan's labels depend only on
  /// its epoch and the 2K scans before it: a chunk of a long drive reproduces the whole run's
  /// labels from the first epoch that starts 2K scans after the chunk does (DESIGN §2f). 0: one
  /// epoch, the whole run.
  int epoch = 100;
};

/// Checks physical sense (positive sizes, r_inf <= r_sup < 1, K >= 1, ...); throws
/// cleanmap::Error(name, "<section.key> must ...") naming the offending key.
void validate(const PipelineParams& params, const std::string& name);

/// The median interval (s) between consecutive timestamps among those in (1 ms, 1 s] (a lidar of
/// 1 to 1000 Hz; repeats and gaps left out); 0 where there is none.
double scanPeriod(const std::vector<double>& stamps);
/// DESIGN §2b: the window's K. ds.window_k where it is set; auto: round(window_s x rate), the
/// rate from the median interval between consecutive `stamps` (seconds; those of the run's first
/// kRateScans scans) among those in (1 ms, 1 s], clamped to [1, kMaxWindowK]; kDefaultWindowK
/// where no interval is usable (no timestamps, one scan). `rate_hz` gets the rate (0: none).
int windowScans(const DsParams& ds, const std::vector<double>& stamps, double* rate_hz = nullptr);
/// The stride of a window of K scans: ds.window_stride, or auto max(1, K / kDefaultWindowK).
int windowStride(const DsParams& ds, int k);
/// The median time (s) and distance (m) between consecutive scans, over the pairs whose times
/// grow by more than 1 ms; `positions` (one per time, or none: metres 0) are where the scans
/// were taken. nullopt where there is no such pair (one scan, no times).
struct ScanSpacing {
  double seconds = 0, metres = 0;
};
std::optional<ScanSpacing> scanSpacing(const std::vector<double>& times,
                                       const std::vector<Eigen::Vector3d>& positions);
/// DESIGN §2b: the window compares neighbouring sweeps. Scans whose median interval is over
/// 0.25 s (a lidar sweeps at 5-20 Hz: a selection, as a SLAM's keyframes are) and whose median
/// distance apart is over 1 m flag more static points. What the apps say of it, from "the scans
/// are ..." on; "" where the scans are not so sparse.
std::string sparseScansWarning(double median_seconds, double median_metres);

}  // namespace cleanmap
