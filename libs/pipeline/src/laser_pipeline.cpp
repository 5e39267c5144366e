// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/pipeline/laser_pipeline.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <exception>
#include <future>
#include <limits>
#include <numeric>
#include <random>

#include "cleanmap/core/beam_index.h"
#include "cleanmap/core/cell_key.h"
#include "cleanmap/core/deskew.h"
#include "cleanmap/core/error.h"
#include "cleanmap/core/ground.h"
#include "cleanmap/core/grouped.h"
#include "cleanmap/core/median.h"
#include "cleanmap/core/mover_feet.h"
#include "cleanmap/core/object_consensus.h"
#include "cleanmap/core/object_shift.h"
#include "cleanmap/core/octree_sampling.h"
#include "cleanmap/core/parallel.h"
#include "cleanmap/core/self_returns.h"
#include "cleanmap/core/serial_worker.h"
#include "cleanmap/core/stopwatch.h"
#include "cleanmap/registration/odometry.h"
#include "cleanmap/vision/alignment.h"
#include "cleanmap/vision/image_validation.h"

namespace cleanmap {
namespace {
// Rule 4's "found moved" (doc/OBJECTS.md): m, half a car's width (a parked neighbour is 2.5 m off).
constexpr float kMovedMatch = 0.9f;
// Rule 4 backwards: a vehicle that stood is moving by the labels where it moves more than 0.5 m
// over the half window around it, static under 0.2 m, neither between (../shared/data/README.md:
// over +-5 scans). The middle of that band allows for the error of our estimate.
constexpr double kMovedDistance = 0.35;
// Rule 4 backwards: m, how far an object carried back may have moved between two scans (a car at
// 15 m/s at 10 Hz; one that waited and drove off at 10 m/s moved 1 m a scan from its start).
constexpr float kCarryMatch = 1.5f;
// Rule 4 backwards: the two scans that found an object show it at sizes within this fraction.
constexpr float kSeedSize = 0.15f;
// Rule 4's leaving and arriving tests ask at most about this many of an object's points.
constexpr std::size_t kRule4Sample = 2000;
// Rule 4's arrival at a large object's ends (doc/OBJECTS.md): m along its length from either end,
// the new space a vehicle at stop-and-go speeds (up to 2 m/s) sweeps in half a window (0.5 s).
constexpr double kArrivalEnd = 1.0;
// Rule 4's arrival, "How far it came" (doc/OBJECTS.md): m, the labels' static band (under 0.2 m
// over +-0.5 s): an object the scans before saw standing this far in from its new place came less.
constexpr double kArrivalDepth = 0.2;
// Rule 7's outline match (doc/OBJECTS.md, "Measured"): the grid, the other scans' points in
// columns of this side (m), up to this far above the object's top (m), and the least gain in
// matched cells (or 5 % of the outline's) for a shift to count.
constexpr ShiftParams kShift{};
constexpr double kShiftColumn = 2.0;
constexpr double kShiftAbove = 0.3;
constexpr std::size_t kShiftMinGain = 5;
constexpr double kShiftMinFace = 1.6;      // m of outline: a car's width, its front or rear alone
constexpr std::size_t kShiftMinSide = 20;  // cells along the shift: 3 m of a side alone
constexpr std::size_t kShiftEndGain = 2;   // a side's cells matching only shifted: its end, 0.3 m
constexpr double kShiftView = 15.0 * M_PI / 180.0;  // rad
// Rule 4 backwards, "What a scan saw of it" (doc/OBJECTS.md): m, a centroid's step that an
// object whose outline matches in place (within a cell) did not make (a cell and a half).
constexpr double kCompositionSlack = 1.5 * kShift.cell;

// Rule 7's points in vertical columns of kShiftColumn, each column's points in one run in the
// order they were added: one table, not an allocation per column (issue #16).
class ColumnTable {
 public:
  // Adds x(i) for i in [0, n), then puts them in their columns.
  template <class Point>
  void build(std::size_t n, Point&& x) {
    run_.clear();
    start_.assign(1, 0);  // first each run's count at [r + 1], then where it starts
    at_.resize(n);
    std::vector<uint32_t> of(n);
    uint64_t last_key = CellMap<uint32_t>::kEmpty;  // a ring's next return mostly shares it
    uint32_t last = 0;
    for (std::size_t i = 0; i < n; ++i) {
      at_[i] = x(i);
      const uint64_t key = keyOf(at_[i].x(), at_[i].y());
      if (key != last_key) {
        bool fresh = false;
        uint32_t& r = run_.get(key, &fresh);
        if (fresh) {
          r = static_cast<uint32_t>(start_.size() - 1);
          start_.push_back(0);
        }
        last_key = key;
        last = r;
      }
      of[i] = last;
      ++start_[last + 1];
    }
    for (std::size_t r = 1; r < start_.size(); ++r) start_[r] += start_[r - 1];
    points_.resize(n);
    std::vector<uint32_t> fill(start_.begin(), start_.end() - 1);
    for (std::size_t i = 0; i < n; ++i) points_[fill[of[i]]++] = at_[i];
  }
  static int64_t cell(float v) { return floorToCell(v, kInv); }
  // Calls f(x) for each point of column (cx, cy), in the order they were added.
  template <class F>
  void forEach(int64_t cx, int64_t cy, F&& f) const {
    if (const uint32_t* r = run_.find(cellKey(cx, cy, 0)))
      for (uint32_t k = start_[*r]; k < start_[*r + 1]; ++k) f(points_[k]);
  }

 private:
  static constexpr float kInv = static_cast<float>(1.0 / kShiftColumn);
  static uint64_t keyOf(float x, float y) { return cellKey(cell(x), cell(y), 0); }
  CellMap<uint32_t> run_;
  std::vector<uint32_t> start_;
  std::vector<Eigen::Vector3f> points_, at_;
};

// Rule 4's arrival (doc/OBJECTS.md): the object's points (idx, world frame) within kArrivalEnd
// of either end along its horizontal principal axis, in idx's order.
void arrivalEnds(const std::vector<uint32_t>& idx, const std::vector<Eigen::Vector3d>& world,
                 std::vector<uint32_t>& ends) {
  ends.clear();
  if (idx.empty()) return;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const uint32_t i : idx) mean += world[i].head<2>();
  mean /= static_cast<double>(idx.size());
  double xx = 0.0, xy = 0.0, yy = 0.0;
  for (const uint32_t i : idx) {
    const Eigen::Vector2d d = world[i].head<2>() - mean;
    xx += d.x() * d.x();
    xy += d.x() * d.y();
    yy += d.y() * d.y();
  }
  const double angle = 0.5 * std::atan2(2.0 * xy, xx - yy);  // the major axis of the 2x2 scatter
  const Eigen::Vector2d axis(std::cos(angle), std::sin(angle));
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const uint32_t i : idx) {
    const double t = axis.dot(world[i].head<2>() - mean);
    lo = std::min(lo, t);
    hi = std::max(hi, t);
  }
  for (const uint32_t i : idx) {
    const double t = axis.dot(world[i].head<2>() - mean);
    if (t < lo + kArrivalEnd || t > hi - kArrivalEnd) ends.push_back(i);
  }
}

// Positions 0..n-1 in the order of their components' roots, and where each component ends.
void orderByComponent(const std::vector<uint32_t>& root, std::vector<uint32_t>& order,
                      std::vector<uint32_t>& ends) {
  order.resize(root.size());
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(),
                   [&](uint32_t a, uint32_t b) { return root[a] < root[b]; });
  ends.clear();
  for (std::size_t k = 1; k <= order.size(); ++k)
    if (k == order.size() || root[order[k]] != root[order[k - 1]])
      ends.push_back(static_cast<uint32_t>(k));
}

// Whether `face` (its thin horizontal side within a voxel) is a face of `box`: as wide along it
// and as high, within rule 4's extent tolerance as sizedAs, whatever their depths (a side in view
// in one and not the other).
bool faceOf(const Eigen::Vector3f& face, const Eigen::Vector3f& box, double voxel,
            double tolerance) {
  int wide = 0;
  const float thin = face.head<2>().minCoeff(), along = face.head<2>().maxCoeff(&wide);
  const float f = static_cast<float>(1.0 - tolerance);
  return thin <= static_cast<float>(voxel) && box[wide] >= f * along && along >= f * box[wide] &&
         box.z() >= f * face.z() && face.z() >= f * box.z();
}
}  // namespace

struct LaserPipeline::Prepared {
  std::size_t index;
  long seq = 0;                    // its place in the pushed sequence
  bool registered_beside = false;  // its registration ran on the RegQueue's thread
  std::string stem, source;
  Scan scan;
  BeamIndex beams;
  std::vector<uint8_t> in_crop;    // DESIGN §2.2
  std::vector<uint8_t> ground;     // DESIGN §2a, within the crop and the map radius
  std::vector<uint8_t> far;        // beyond the crop, within the map radius (DESIGN §2e)
  std::vector<uint8_t> candidate;  // in the crop and not ground: what the stages decide
  std::vector<uint8_t> flat;       // kFlatSurface where on a flat top (DESIGN §2b); or empty
  // Its GrazingStretches (from, to), for the free space's insertion (computed once; or empty).
  std::vector<float> graze_from, graze_to, graze_side;
  // GrazingStretches::links (doc/OBJECTS.md rule 1, "Coarse columns"); or empty.
  std::vector<uint32_t> column_links;
  bool column_links_capped = false;  // found in a dense lidar's own columns (groupObjects)
  FreeSpaceMap::Stretches grazing() const {
    return graze_from.empty() ? FreeSpaceMap::Stretches{}
                              : FreeSpaceMap::Stretches{&graze_from, &graze_to,
                                                        graze_side.empty() ? nullptr : &graze_side};
  }
  double ground_measured = std::numeric_limits<double>::quiet_NaN();  // estimateGroundHeight
  double ground_z = 0;     // h_G below the sensor used for this scan (DESIGN §2a)
  double density = 1;      // returns per solid angle relative to the HDL-64E (DESIGN §2d)
  double ring_gap = 0;     // rad between rings, where sparse (measured or preset; 0: dense, §2b)
  double column_step = 0;  // rad between columns, where coarse (kCoarseColumnsDeg; 0: not, §2b)
  double roof_gap = 0;     // rad between rings for the roofs of rule 6: ring_gap, or dense rings'
  Eigen::Isometry3d world_to_sensor;
  PoseInfo pose_info;
  ScanStats stats;
  double prepare_ms = 0;  // prepare()'s wall: the index, crop + ground and camera view stages
  std::optional<vision::CameraView> view;  // DESIGN §3, when the frame has an image
  // DESIGN §3 "Camera poses": D, the correction of the motion from the scan buffered before this
  // one (its relative pose is T_prev^-1 T D), where the images aligned.
  std::optional<Eigen::Isometry3d> link;
  bool points_released = false;  // decided, and its points freed (releasePoints)
  // This scan as the window scan of its own points' edges (MovingTest::edgesOf, issue #15).
  WindowScan own() const {
    WindowScan o;
    o.beams = beams.empty() ? nullptr : &beams;
    o.ring_gap = ring_gap;
    o.column_step = column_step;
    return o;
  }
};

// A decided scan held for rule 4 backwards: its result and what carryBack needs of its decision.
struct LaserPipeline::Held {
  ScanResult r;
  std::vector<PointXYZI> points;              // its candidates (sensor frame) ...
  std::vector<uint32_t> original;             // ... their indices as read ...
  std::vector<uint8_t> moving, relabelled;    // ... and their decisions (Work)
  std::vector<PointXYZI> whole;               // its objects moved whole (remember()) ...
  std::vector<uint8_t> whole_measured;        // ... per point: rule 7 measured it ...
  std::optional<WholeObjects> whole_objects;  // ... grouped once it is first asked ...
  RingReach whole_reach;                      // ... with its rings' reach
  Eigen::Isometry3d world_to_sensor = Eigen::Isometry3d::Identity();
  double density = 1, ring_gap = 0;
  double ground_z = 0;      // h_G below the sensor (Prepared::ground_z)
  bool measurable = false;  // rule 7 could measure its objects (Work::measurable)
  // The candidates' components as the object consensus grouped them (grouped again if it did
  // not run): their positions in component order and where each component ends in it.
  std::vector<uint32_t> order, ends;
  std::vector<Eigen::Vector3f> lo, hi, sum;  // per component: its box and its points' sum
  // Its candidates in component order in the next held scan's sensor frame, per component on
  // first use (at_next_done): carryBack asks the same ones at each decision while it is held.
  std::vector<Eigen::Vector3f> at_next;
  std::vector<uint8_t> at_next_done;
  void summarise() {  // the components' boxes and sums, once (carryBack asks them every scan)
    lo.clear();
    hi.clear();
    sum.clear();
    std::size_t from = 0;
    for (const std::size_t to : ends) {
      Eigen::Vector3f l = Eigen::Vector3f::Constant(1e30f), u = -l, t = Eigen::Vector3f::Zero();
      for (std::size_t k = from; k < to; ++k) {
        const Eigen::Vector3f x = points[order[k]].xyz();
        l = l.cwiseMin(x);
        u = u.cwiseMax(x);
        t += x;
      }
      lo.push_back(l);
      hi.push_back(u);
      sum.push_back(t);
      from = to;
    }
  }
  // --save-overlays: the camera view, every point of the scan, its colour (collect()) and the
  // candidates' positions among them.
  std::optional<vision::CameraView> view;
  std::vector<PointXYZI> all_points;
  std::vector<uint8_t> kind;
  std::vector<uint32_t> at;
};

/// The scan being decided, computed once and passed down the stages. One instance lives as long
/// as the pipeline: clear() keeps the capacity, so steady state allocates nothing per scan here.
struct LaserPipeline::Work {
  void clear() {
    world.clear();
    duplicate.clear();
    self_index.clear();
    cand.clear();
    cand_world.clear();
    leaves.clear();
    tested_leaf.clear();
    tested_sensor.clear();
    leaf_moving.clear();
    moving.clear();
    relabelled.clear();
    whole.clear();
    held.clear();
    tested_as.clear();
    measured.clear();
    grouped = false;
    measurable = false;
  }
  std::vector<Eigen::Vector3d> world;  // candidates' world coordinates (others left zero)
  std::vector<uint8_t> duplicate;      // DESIGN §2.3
  std::vector<uint32_t> self_index;    // DESIGN §2.2: the self returns' original indices
  std::vector<uint32_t> cand;          // candidates that are not duplicates: what is tested
  std::vector<Eigen::Vector3d> cand_world;
  LeafPlan leaves;                             // DESIGN §2c, over `cand`
  std::vector<uint32_t> tested_leaf;           // the leaves with tested points
  std::vector<Eigen::Vector3f> tested_sensor;  // their first tested point, in the sensor frame
  std::vector<uint8_t> leaf_moving;            // per leaf, the decision (DESIGN §2c)
  std::vector<uint8_t> moving;                 // per scan point, the final decision
  std::vector<uint8_t> relabelled;  // per scan point: moving, relabelled static by the camera
  std::vector<uint8_t> whole;       // per scan point: in a vehicle-sized object moving as a whole
  std::vector<uint8_t> held;  // per scan point: in an object rule 4 held (the camera leaves it)
  std::vector<uint8_t> tested_as;  // per scan point: kVotes / kRun where tested moving (§2b)
  static constexpr uint8_t kVotes = 1, kRun = 2;  // by the window's votes, by an empty run alone
  std::vector<uint8_t> measured;  // per scan point: in an object rule 7 measured moving
  ObjectComponents groups;        // the candidates' components (doc/OBJECTS.md rule 1) ...
  bool grouped = false;           // ... where the object consensus ran
  bool measurable = false;        // rule 7 had the scans H before and after this one
};

LaserPipeline::LaserPipeline(const PipelineParams& params, Sink sink)
    : p_((validate(params, "parameters"), params)),
      sink_(std::move(sink)),
      test_(params.ds),
      dup_(params.filter),
      work_(std::make_unique<Work>()),
      source_(params.poses) {
  if (p_.map.clean) free_ = std::make_unique<FreeSpaceMap>(p_.map);
  if (p_.ds.window_k > 0) {
    k_ = static_cast<std::size_t>(p_.ds.window_k);
    stride_ = static_cast<std::size_t>(cleanmap::windowStride(p_.ds, p_.ds.window_k));
  }
}

// DESIGN §2b: an auto K spans window_s at the scan rate of the first kRateScans scans (a chunk
// of a steady stream gets the whole run's K). Nothing is decided before it is known: a scan is
// decided once K scans follow it, and K >= kRateScans - 1 at 3.5 Hz and above; slower, the
// first scans are decided at the kRateScans-th push, with the same windows (inWindow).
void LaserPipeline::resolveWindow() {
  const int k = windowScans(p_.ds, stamps_, &rate_hz_);
  k_ = static_cast<std::size_t>(k);
  stride_ = static_cast<std::size_t>(cleanmap::windowStride(p_.ds, k));
  stamps_.clear();
  stamps_.shrink_to_fit();
}

// DESIGN §2e: the free-space insertions of the decided scans, one at a time in scan order, on a
// thread of their own (tagged by scan index). A job reads its scan in the pipeline's buffer, which
// keeps the scan until its job is done (waitThrough).
struct LaserPipeline::FreeQueue {
  struct Job {
    const Prepared* scan = nullptr;
    std::vector<uint8_t> mask;  // its returns that are not inflated (moving, ground)
    long index = 0;
  };
  FreeQueue(FreeSpaceMap& map, std::atomic<std::size_t>& bytes)
      : worker([&map, &bytes](Job& j) {
          map.insertScan(j.scan->scan.points, j.scan->scan.pose, static_cast<int64_t>(j.index),
                         &j.mask, j.scan->grazing());
          bytes.store(map.bytes(), std::memory_order_relaxed);
        }) {}
  SerialWorker<Job> worker;
};

// Issue #16 (registerAhead): a pushed frame's registration on a thread of its own, one at a time,
// while push() decides the scans before it. Only that thread touches the registration state
// (odo_, prev_odometry_, prev_pose_) while a frame is in flight; the pipeline's thread reads it
// again only after wait().
struct LaserPipeline::RegQueue {
  explicit RegQueue(LaserPipeline& p) : worker([&p, this](int&) { p.registerScan(*slot); }) {}
  void start(Registered&& r) {
    slot = std::move(r);  // the worker is idle: the last frame was waited for
    in_flight = true;
    worker.push(0);
  }
  // Waits for the frame started last; it stays in the slot.
  const Registered& wait() {
    worker.wait();
    return *slot;
  }
  Registered take() {
    wait();
    in_flight = false;
    Registered r = std::move(*slot);
    slot.reset();
    return r;
  }

  std::optional<Registered> slot;  // the pipeline's thread leaves it alone until wait()
  bool in_flight = false;    // the pipeline's thread's own flag: a frame started, not yet taken
  SerialWorker<int> worker;  // last: its thread stops before the slot goes
};

LaserPipeline::~LaserPipeline() {
  reg_queue_.reset();   // its thread stops before the registration state it uses goes
  free_queue_.reset();  // its thread stops before the scans its jobs read are destroyed
}

std::size_t LaserPipeline::pending() const {
  return buf_.size() - next_ + (reg_queue_ && reg_queue_->in_flight ? 1 : 0) + (held_ ? 1 : 0) +
         (deskew_first_ ? 1 : 0) + held_results_.size();
}

std::unique_ptr<LaserPipeline> LaserPipeline::clone(Sink sink) const {
  auto c = std::make_unique<LaserPipeline>(p_, std::move(sink));
  // A frame registering ahead: the copy takes it as registered (the odometry copied below is the
  // one after its registration).
  if (reg_queue_ && reg_queue_->in_flight)
    c->held_ = reg_queue_->wait();
  else
    c->held_ = held_;
  c->register_ahead_ = register_ahead_;
  c->k_ = k_;
  c->stride_ = stride_;
  c->rate_hz_ = rate_hz_;
  c->stamps_ = stamps_;
  c->pushed_ = pushed_;
  c->drops_ = drops_;
  c->test_ = test_;
  c->dup_ = dup_;
  for (const auto& s : buf_) c->buf_.push_back(std::make_unique<Prepared>(*s));
  c->next_ = next_;
  c->decided_ = decided_;
  c->keep_scans_ = keep_scans_;
  c->overlays_ = overlays_;
  c->camera_ = camera_;
  c->prev_index_ = prev_index_;
  c->prev_moving_cells_ = prev_moving_cells_;
  c->prev_whole_ = prev_whole_;
  c->prev_whole_measured_ = prev_whole_measured_;
  c->prev_pose_inverse_ = prev_pose_inverse_;
  c->held_results_ = held_results_;
  c->epoch_ = epoch_;
  c->map_first_ = map_first_;
  c->map_last_ = map_last_;
  c->source_ = source_;
  if (odo_) c->odo_ = std::make_unique<reg::Odometry>(*odo_);
  c->prev_odometry_ = prev_odometry_;
  c->prev_pose_ = prev_pose_;
  c->period_stamps_ = period_stamps_;
  c->deskew_prev_ = deskew_prev_;
  c->deskew_first_ = deskew_first_;
  c->deskew_first_beside_ = deskew_first_beside_;
  joinFreeSpace();
  if (free_) c->free_ = std::make_unique<FreeSpaceMap>(*free_);
  c->free_bytes_.store(free_bytes_.load(std::memory_order_relaxed), std::memory_order_relaxed);
  return c;
}

// DESIGN §2.1: where the poses come from, resolved on the first frame (auto: given if it has one).
PoseSource LaserPipeline::resolveSource(const Frame& f) {
  if (source_ == PoseSource::kAuto)
    source_ = f.scan.has_pose ? PoseSource::kGiven : PoseSource::kGicp;
  if (source_ == PoseSource::kRefine && !f.scan.has_pose)
    throw Error(f.source.empty() ? "scan " + f.stem : f.source,
                "has no pose to refine (--poses refine)");
  return source_;
}

// A decided scan's movers leave GICP's local map (Odometry::dropPoints) before the registration of
// the scan K + 2 pushes after it: the scan K + 1 after it may be registering while it is decided
// (registerAhead), and the same lag without it keeps the poses the same.
void LaserPipeline::applyDrops(long seq) {
  const long K = static_cast<long>(k_);
  while (!drops_.empty() && drops_.front().seq <= seq - K - 2) {
    if (odo_) odo_->dropPoints(drops_.front().index, drops_.front().moving);
    drops_.pop_front();
  }
}

// DESIGN §2.1: the frame's pose estimated by GICP odometry (gicp / refine); an error is kept with
// the frame, for prepare() to rethrow.
void LaserPipeline::registerScan(Registered& r) {
  const auto t_reg = Clock::now();
  try {
    r.pose_info = registerFrame(r.frame);
  } catch (...) {
    r.error = std::current_exception();
  }
  r.ms = msSince(t_reg);
}

PoseInfo LaserPipeline::registerFrame(Frame& f) {
  PoseInfo info;
  if (!odo_) odo_ = std::make_unique<reg::Odometry>(p_.registration, p_.threads);
  // The initial guess: refine starts from every given pose; with gicp, a given first pose
  // anchors the trajectory (the maps then share the input's world frame and can be scored
  // against its labels), and input odometry moves the last estimate by its increment; otherwise
  // the odometry extrapolates at constant velocity.
  std::optional<Eigen::Isometry3d> prior;
  reg::Prior kind = reg::Prior::kGiven;
  info.guess = "constant velocity";
  if (source_ == PoseSource::kRefine || (odo_->map().empty() && f.scan.has_pose)) {
    prior = f.scan.pose;
    info.guess = "given";
  } else if (f.odometry && prev_odometry_) {
    prior = prev_pose_ * (prev_odometry_->inverse() * *f.odometry);
    kind = reg::Prior::kOdometry;
    info.guess = "odometry";
  }
  // DESIGN §2.1: the vehicle's forward axis in the lidar's frame, from its mount (a rawlog's
  // sensorPose), for the start's search.
  if (f.mount) odo_->setForwardAxis(f.mount->linear().transpose() * Eigen::Vector3d::UnitX());
  const reg::OdometryStep step =
      odo_->track(f.scan.points, f.scan.timestamp, static_cast<int64_t>(f.index), prior, kind,
                  f.scan.point_time.empty() ? nullptr : &f.scan.point_time);
  prev_odometry_ = f.odometry;
  prev_pose_ = step.pose;
  f.scan.pose = step.pose;
  f.scan.has_pose = true;
  info.source = source_ == PoseSource::kRefine ? "refine" : "gicp";
  info.status = step.status;
  info.reason = step.reason;
  info.map_restarts = step.map_restarts;
  info.start_guesses = step.start_guesses;
  info.guess_iterations = step.guess_iterations;
  info.accepted = step.accepted;
  info.iterations = step.gicp.iterations;
  info.fitness = step.gicp.fitness;
  info.rmse = step.gicp.rmse;
  info.ms_downsample = step.ms_downsample;
  info.ms_covariances = step.ms_covariances;
  info.ms_align = step.ms_align;
  info.ms_map = step.ms_map;
  return info;
}

std::unique_ptr<LaserPipeline::Prepared> LaserPipeline::prepare(Registered&& r,
                                                                bool registered_beside) {
  if (r.error) std::rethrow_exception(r.error);
  Frame& f = r.frame;
  if (!f.scan.has_pose)
    throw Error(f.source.empty() ? "scan " + f.stem : f.source,
                p_.poses == PoseSource::kGiven
                    ? "has no pose (--poses given): give a posed input, or estimate the poses "
                      "with --poses gicp"
                    : "has no pose while the first scan had one: give every scan a pose, or "
                      "estimate them all with --poses gicp");
  auto s = std::make_unique<Prepared>();
  s->pose_info = std::move(r.pose_info);
  s->stats.ms.registration = r.ms;
  s->registered_beside = registered_beside;
  s->seq = r.seq;
  s->index = f.index;
  s->stem = std::move(f.stem);
  s->source = std::move(f.source);
  s->scan = std::move(f.scan);
  s->world_to_sensor = s->scan.pose.inverse();
  auto& st = s->stats;
  st.points = s->scan.original_size ? s->scan.original_size : s->scan.size();
  st.invalid = s->scan.dropped_invalid;
  st.empty = s->scan.empty() ? 1 : 0;
  st.deskewed = r.deskew_shift >= 0 ? 1 : 0;
  st.deskew_max_shift = std::max(0.0, r.deskew_shift);

  // Issue #16: the beam index (with the grazing stretches), the crop and ground masks, and the
  // camera view depend on this scan and the ones buffered before it, never on each other; with
  // two threads or more the index is built on a thread of its own beside the other two. Each
  // writes its own fields of *s (and the index graze_), so the result is the same.
  const auto t_prepare = Clock::now();
  auto build_index = [&] {
    const auto t_index = Clock::now();
    // Every valid point is a beam (ground and far points included, DESIGN §2.4).
    // DESIGN §2b, grazing beams: each beam keeps where it grazes a flat surface of this scan.
    if (p_.ds.grazing && p_.map.flat_slope > 0) {
      const auto& pts = s->scan.points;
      std::vector<float> azimuth(pts.size());
      for (std::size_t n = 0; n < pts.size(); ++n) azimuth[n] = fast::atan2(pts[n].y, pts[n].x);
      // The clean map's grazing sides need the lidar's column step, as its free space bins it.
      // The object rules' column links need it too (rule 1, "Coarse columns").
      const bool sides = p_.map.clean && p_.map.grazing_sides;
      const bool links = p_.object.enabled && p_.object.column_links;
      const double step =
          sides || links ? freeSpaceAzimuthBin(pts, azimuth, p_.map.beam_spacing) : 0.0;
      const bool linked = links && step > 0;
      graze_.compute(pts, s->scan.pose.linear().cast<float>(), azimuth, p_.map.flat_slope,
                     p_.map.margin, p_.map.graze_reach, sides || linked ? step : 0.0,
                     sides ? p_.map.hit_inflate : 0.0, linked);
      if (linked) {
        s->column_links = graze_.links();
        s->column_links_capped = graze_.fineLinks();
      }
      s->beams = BeamIndex(pts, test_.searchRadius(), BeamIndex::Binning::kFast, &graze_);
      if (p_.map.clean) {
        s->graze_from = graze_.from();
        s->graze_to = graze_.to();
        s->graze_side = graze_.side();
      }
      s->flat.resize(pts.size());
      for (std::size_t n = 0; n < pts.size(); ++n)
        s->flat[n] = graze_.flatTop(n) ? kFlatSurface : 0;
    } else {
      s->beams = BeamIndex(s->scan.points, test_.searchRadius());
    }
    st.ms.index = msSince(t_index);
  };
  std::future<void> beside;  // joined below, or by its destructor where a stage below throws
  if (p_.threads > 1)
    beside = std::async(std::launch::async, build_index);
  else
    build_index();

  auto t0 = Clock::now();
  const auto& pts = s->scan.points;
  const float tau = static_cast<float>(p_.filter.crop_tau);
  // The ground grid covers the map radius too (inner cells do not depend on outer ones, so the
  // labels inside the crop are the same).
  const double r_map = p_.map.radius;
  // Issue #15: a tilted mount (a rawlog's sensorPose with roll or pitch) is levelled for the
  // ground stage, whose grid and heights assume z up (DESIGN §2a); yaw does not matter.
  std::vector<PointXYZI> levelled;
  if (f.mount) {
    const Eigen::Matrix3d m = f.mount->rotation();
    const Eigen::Matrix3f level =
        (Eigen::AngleAxisd(-std::atan2(m(1, 0), m(0, 0)), Eigen::Vector3d::UnitZ()) * m)
            .cast<float>();
    if (!level.isIdentity(1e-6f)) {
      levelled = pts;
      for (auto& p : levelled) {
        const Eigen::Vector3f q = level * Eigen::Vector3f(p.x, p.y, p.z);
        p.x = q.x(), p.y = q.y(), p.z = q.z();
      }
    }
  }
  const auto& gpts = levelled.empty() ? pts : levelled;
  s->ground_z = groundBelowSensor(*s, gpts);
  std::optional<AngularResolution> res;
  double rings_deg = 0;  // measured where dense too: a dense lidar's roofs (OBJECTS.md rule 6)
  if (p_.sensor.model != SensorModel::kAuto)
    res = presetResolution(p_.sensor.model);
  else
    res = measureResolution(pts, &rings_deg);
  s->roof_gap = rings_deg * M_PI / 180.0;
  if (res) {
    s->density = densityScale(*res);
    s->ring_gap = res->vertical_deg * M_PI / 180.0;
    s->roof_gap = s->ring_gap;
    if (res->azimuth_deg > kCoarseColumnsDeg) s->column_step = res->azimuth_deg * M_PI / 180.0;
  }
  s->ground = segmentGround(gpts, p_.ground, std::max(p_.filter.crop_tau, r_map), s->ground_z);
  s->in_crop.resize(pts.size());
  s->candidate.resize(pts.size());
  s->far.assign(pts.size(), 0);
  for (std::size_t i = 0; i < pts.size(); ++i) {  // DESIGN §2.2: per-axis crop, sensor frame
    s->in_crop[i] =
        std::abs(pts[i].x) <= tau && std::abs(pts[i].y) <= tau && std::abs(pts[i].z) <= tau;
    s->far[i] = !s->in_crop[i] &&
                double(pts[i].x) * pts[i].x + double(pts[i].y) * pts[i].y <= r_map * r_map;
    if (!s->in_crop[i] && !s->far[i]) s->ground[i] = kNotGround;  // keeps GroundFlag's kind
    s->candidate[i] = s->in_crop[i] && !s->ground[i];
    st.in_crop += s->in_crop[i];
    st.ground += s->ground[i] && s->in_crop[i];
    st.map_far += s->far[i];
  }
  st.ms.ground = msSince(t0);

  // DESIGN §3: the scan's camera view (image, sparse depth map, camera pose), built once and
  // used by every scan whose window holds this one.
  if (r.camera && p_.image.enabled && f.image && !f.image->bgr.empty()) {
    t0 = Clock::now();
    s->view = vision::makeCameraView(f.image->bgr, pts, s->scan.pose, *r.camera, s->index,
                                     s->source.empty() ? "scan " + s->stem : s->source,
                                     p_.image.dilation_radius);
    st.image_scans = 1;
    auto* prev = buf_.empty() || !buf_.back()->view ? nullptr : &*buf_.back()->view;
    if (p_.image.align && prev) linkToPrevious(*buf_.back(), *s, *r.camera);
    // What only the alignment reads (issue #16): this scan's full-image depth map (read as the
    // aligned view), the previous scan's pyramid (read as the reference), and this scan's own
    // pyramid when nothing will be aligned on it.
    s->view->sparse.release();
    if (prev) prev->grey.clear();
    if (!p_.image.align) s->view->grey.clear();
    st.ms.images = msSince(t0);
  }
  if (beside.valid()) beside.get();  // rethrows its error
  s->prepare_ms = msSince(t_prepare);
  return s;
}

// DESIGN §3 "Camera poses": this scan's camera aligned on the previous scan's ground returns
// (world frame, at the previous scan's pose: the road is there in every scan and never moves)
// and image. The optical-frame correction C (corrected
// optical_from_world = C optical_from_world) is the lidar pose T' = T L^-1 C^-1 L (L: optical
// from lidar), so the corrected motion from the previous scan is T_prev^-1 T D, D = L^-1 C^-1 L.
void LaserPipeline::linkToPrevious(const Prepared& prev, Prepared& s,
                                   const PinholeCamera& camera) const {
  auto& st = s.stats;
  st.image_links = 1;
  std::vector<Eigen::Vector3d> ref;
  ref.reserve(prev.scan.size());
  for (uint32_t i = 0; i < prev.scan.size(); ++i)
    if (prev.in_crop[i] && prev.ground[i])
      ref.push_back(prev.scan.pose * prev.scan.points[i].xyz().cast<double>());
  vision::AlignParams ap;
  ap.occlusion = p_.image.occlusion;
  ap.max_translation = p_.image.align_max_shift;
  ap.small_translation = p_.image.align_small_shift;
  const auto a = vision::alignView(*prev.view, *s.view, ref, ap);
  if (!a) return;
  const Eigen::Isometry3d L = camera.opticalFromLidar();
  s.link = L.inverse() * a->correction.inverse() * L;
  st.image_links_aligned = 1;
  st.image_link_shift = a->correction.translation().norm();
}

std::vector<std::optional<Eigen::Isometry3d>> LaserPipeline::posesAround(std::size_t pos) const {
  std::vector<std::optional<Eigen::Isometry3d>> out(buf_.size());
  Eigen::Isometry3d t = buf_[pos]->scan.pose;
  bool any = false;
  for (std::size_t j = pos + 1; j < buf_.size(); ++j) {  // later scans: motion from j - 1 to j
    const Eigen::Isometry3d rel = buf_[j - 1]->scan.pose.inverse() * buf_[j]->scan.pose;
    t = t * (buf_[j]->link ? rel * *buf_[j]->link : rel);
    any = any || buf_[j]->link.has_value();
    if (any) out[j] = t;
  }
  t = buf_[pos]->scan.pose;
  any = false;
  for (std::size_t j = pos; j-- > 0;) {  // earlier scans: the motion from j to j + 1, undone
    const Eigen::Isometry3d rel = buf_[j]->scan.pose.inverse() * buf_[j + 1]->scan.pose;
    t = t * (buf_[j + 1]->link ? rel * *buf_[j + 1]->link : rel).inverse();
    any = any || buf_[j + 1]->link.has_value();
    if (any) out[j] = t;
  }
  return out;
}

// DESIGN §2a / issue #15: h_G under the sensor. A configured sensor.height is the user's word;
// auto measures every scan and takes the median of this scan's and its K predecessors'
// measurements (a run cut into chunks overlapping by K scans gets the same), KITTI's 1.73 m when
// none of them could be measured.
double LaserPipeline::groundBelowSensor(Prepared& s, const std::vector<PointXYZI>& levelled) const {
  const auto measured = estimateGroundHeight(levelled);
  if (measured) s.ground_measured = *measured;
  if (p_.sensor.height > 0) return -p_.sensor.height;
  std::vector<double> m;
  if (measured) m.push_back(*measured);
  // Before an auto K is resolved, every buffered scan: fewer than kRateScans, so no more than K
  // unless K is below kRateScans - 1 (a lidar under 3.5 Hz: the first few scans only).
  const std::size_t K = k_ ? k_ : buf_.size();
  for (std::size_t i = 0; i < std::min(K, buf_.size()); ++i) {
    const double g = buf_[buf_.size() - 1 - i]->ground_measured;
    if (std::isfinite(g)) m.push_back(g);
  }
  if (m.empty()) return -kDefaultSensorHeight;
  return median(std::move(m));
}

void LaserPipeline::push(Frame&& frame) {
  if (static_cast<long>(frame.index) <= prev_index_)
    throw Error(frame.source.empty() ? "scan " + frame.stem : frame.source, "arrives out of order");
  prev_index_ = static_cast<long>(frame.index);
  const PoseSource source = resolveSource(frame);
  Registered r;
  r.frame = std::move(frame);
  r.seq = pushed_++;
  r.camera = camera_;
  if (!k_) {
    stamps_.push_back(r.frame.scan.timestamp);
    if (stamps_.size() >= static_cast<std::size_t>(kRateScans)) resolveWindow();
  }
  sweepTimes(r.frame);
  auto take_in = [&](Registered&& x, bool registered_beside) {
    admit(std::move(x), registered_beside);
  };
  if (source == PoseSource::kGiven) return take_in(std::move(r), false);
  std::optional<Registered> prev = std::move(held_);  // a frame registered ahead, not prepared
  held_.reset();
  if (reg_queue_ && reg_queue_->in_flight) prev = reg_queue_->take();
  if (!register_ahead_ || p_.threads <= 1) {
    if (prev) take_in(std::move(*prev), true);  // registerAhead was turned off: it goes first
    applyDrops(r.seq);
    registerScan(r);
    return take_in(std::move(r), false);
  }
  // Issue #16: this frame registers on its own thread while the one before it is prepared and
  // the scans before that decided (the drops its registration needs are all applied already).
  if (!reg_queue_) reg_queue_ = std::make_unique<RegQueue>(*this);
  applyDrops(r.seq);
  reg_queue_->start(std::move(r));
  if (prev) take_in(std::move(*prev), true);
}

// DESIGN §2e: every beam of a decided scan adds to the sequence's free space, the voxels near its
// static returns protected (hit_inflate). Nothing else reads or writes that map until the run's
// end, so with two threads or more the insertions are queued to a thread of their own and run
// beside the pipeline's work (the map is the same: one insertion at a time, in scan order). Their
// time is reported with the scan decided when they have finished (`free_space` is then not in
// `total`); with one thread the insertion runs here and is.
double LaserPipeline::insertFreeSpace(const Prepared& s, const Work& w) {
  const long index = static_cast<long>(s.index);
  if (!free_ || index < map_first_ || index > map_last_) return 0.0;  // §2f: another chunk's
  std::vector<uint8_t> mask(s.scan.size());
  for (std::size_t i = 0; i < mask.size(); ++i) mask[i] = w.moving[i] || s.ground[i];
  if (p_.threads > 1) {
    if (!free_queue_) free_queue_ = std::make_unique<FreeQueue>(*free_, free_bytes_);
    const double finished_ms = free_queue_->worker.takeMs();        // rethrows an insertion's error
    free_queue_->worker.push({&s, std::move(mask), index}, index);  // `s` stays buffered
    return finished_ms;
  }
  const auto t = Clock::now();
  free_->insertScan(s.scan.points, s.scan.pose, static_cast<int64_t>(s.index), &mask, s.grazing());
  free_bytes_.store(free_->bytes(), std::memory_order_relaxed);
  return msSince(t);
}

void LaserPipeline::joinFreeSpace() const {
  if (!free_queue_) return;
  free_queue_->worker.waitThrough(std::numeric_limits<long>::max());
  free_queue_->worker.takeMs();  // rethrows its error
}

// DESIGN §2.0: a scan's point times, where it is de-skewed (sensor.deskew): the input's, or
// from its azimuths at the scan period of the first timestamps (0.1 s where they give none).
void LaserPipeline::sweepTimes(Frame& f) {
  auto& times = f.scan.point_time;
  const DeskewMode mode = p_.sensor.deskew;
  if (mode == DeskewMode::kOff || (mode == DeskewMode::kAuto && times.empty())) {
    std::vector<float>().swap(times);
    return;
  }
  if (period_stamps_.size() < static_cast<std::size_t>(kRateScans))
    period_stamps_.push_back(f.scan.timestamp);
  if (times.empty()) {
    const double period = scanPeriod(period_stamps_);
    times = azimuthTimes(f.scan.points, period > 0 ? period : 0.1);
  } else if (times.size() != f.scan.size()) {
    throw Error(f.source.empty() ? "scan " + f.stem : f.source,
                "has " + std::to_string(times.size()) + " point times for " +
                    std::to_string(f.scan.size()) + " points");
  }
}

// DESIGN §2.0: a registered frame, de-skewed where it has point times, joins the buffer, and the
// scans whose windows are then complete are decided (none while K is unknown). The motion is the
// previous scan's pose to this one's; the first scan waits for the second's pose (the motion to
// it). A gap over 1 s between the two: none.
void LaserPipeline::admit(Registered&& r, bool registered_beside) {
  Scan& scan = r.frame.scan;
  if (r.error || !scan.has_pose || scan.point_time.empty()) {
    if (!r.error && scan.has_pose) deskew_prev_.emplace(scan.timestamp, scan.pose);
    return takeIn(std::move(r), registered_beside);
  }
  auto motion = [](double ta, const Eigen::Isometry3d& a, double tb, const Eigen::Isometry3d& b) {
    return tb - ta <= 1.0 ? SweepMotion::between(a, ta, b, tb) : SweepMotion{};
  };
  if (!deskew_prev_ && !deskew_first_) {
    deskew_first_ = std::move(r);
    deskew_first_beside_ = registered_beside;
    return;
  }
  if (deskew_first_) {
    Registered first = std::move(*deskew_first_);
    deskew_first_.reset();
    Scan& fs = first.frame.scan;
    first.deskew_shift = deskewPoints(fs.points, fs.point_time,
                                      motion(fs.timestamp, fs.pose, scan.timestamp, scan.pose));
    std::vector<float>().swap(fs.point_time);
    deskew_prev_.emplace(fs.timestamp, fs.pose);
    takeIn(std::move(first), deskew_first_beside_);
  }
  r.deskew_shift =
      deskewPoints(scan.points, scan.point_time,
                   motion(deskew_prev_->first, deskew_prev_->second, scan.timestamp, scan.pose));
  std::vector<float>().swap(scan.point_time);
  deskew_prev_.emplace(scan.timestamp, scan.pose);
  takeIn(std::move(r), registered_beside);
}

void LaserPipeline::takeIn(Registered&& r, bool registered_beside) {
  buf_.push_back(prepare(std::move(r), registered_beside));
  decideReady(k_ ? k_ : std::numeric_limits<std::size_t>::max());
}

void LaserPipeline::finish() {
  if (!k_) resolveWindow();
  std::optional<Registered> last = std::move(held_);
  held_.reset();
  if (reg_queue_ && reg_queue_->in_flight) last = reg_queue_->take();
  if (last) admit(std::move(*last), true);
  if (deskew_first_) {  // the only scan: no motion to undo it by
    std::vector<float>().swap(deskew_first_->frame.scan.point_time);
    admit(std::move(*deskew_first_), deskew_first_beside_);
    deskew_first_.reset();
  }
  decideReady(0);  // the windows shrink at the end
  handOn(0);
  joinFreeSpace();
  buf_.clear();
  next_ = 0;
}

// Decides every buffered scan that has at least `future` scans after it, then keeps only the K
// scans before the next one to decide.
void LaserPipeline::decideReady(std::size_t future) {
  const std::size_t K = k_;
  while (next_ < buf_.size() && buf_.size() - 1 - next_ >= future) {
    decide(next_);
    ++next_;
    releasePoints();
    while (next_ > K) {
      if (free_queue_) free_queue_->worker.waitThrough(static_cast<long>(buf_.front()->index));
      buf_.pop_front();
      --next_;
    }
  }
}

// MovingTest's EdgeBits of point i of s: its surface's edges (sparse lidars) and whether it lies
// on a flat top (grazing beams, DESIGN §2b).
uint8_t LaserPipeline::edgeBits(const Prepared& s, uint32_t i, const WindowScan& own) const {
  return static_cast<uint8_t>(test_.edgesOf(s.scan.points[i].xyz(), own) |
                              (s.flat.empty() ? 0 : s.flat[i]));
}

// Issue #16: a decided scan stays buffered as a window scan of the next K, which read only its
// beams and pose; its points and per-point masks go once its free-space insertion is done (a
// 30-scan run holds nearly every scan at once: peak RSS 13-18 MiB less, doc/BENCHMARK.md). The
// newest scan keeps its points: the next scan's camera link reads them (linkToPrevious).
void LaserPipeline::releasePoints() {
  for (std::size_t j = 0; j + 1 < buf_.size() && j < next_; ++j) {
    Prepared& s = *buf_[j];
    if (s.points_released) continue;
    if (free_queue_ && !free_queue_->worker.doneThrough(static_cast<long>(s.index))) break;
    s.points_released = true;
    for (auto* v : {&s.in_crop, &s.ground, &s.far, &s.candidate, &s.flat})
      std::vector<uint8_t>().swap(*v);
    for (auto* v : {&s.graze_from, &s.graze_to, &s.graze_side}) std::vector<float>().swap(*v);
    std::vector<uint32_t>().swap(s.column_links);
    std::vector<PointXYZI>().swap(s.scan.points);
    std::vector<uint32_t>().swap(s.scan.original_index);
  }
}

// One scan, as a list of named stages (DESIGN §2.3-2.7).
void LaserPipeline::decide(std::size_t pos) {
  Prepared& s = *buf_[pos];
  const auto t_start = Clock::now();
  const std::vector<WindowScan> window = windowAround(pos);
  s.stats.window = window.size();
  s.stats.window_k = k_;
  s.stats.window_stride = stride_;
  s.stats.scan_rate_hz = rate_hz_;
  Work& w = *work_;
  w.clear();
  startEpoch(static_cast<long>(s.index));  // §2f
  findDuplicates(s, w);                    // §2.3
  sampleLeaves(s, w);                      // §2c
  classify(window, s, w);                  // §2b
  decideLeaves(s, w);                      // §2c
  dropSelfReturns(window, s, w);           // §2.2
  objectConsensus(pos, s, w);              // doc/OBJECTS.md
  validateImages(pos, s, w);               // §3
  moverFeet(s, w);                         // doc/OBJECTS.md rule 6
  moverRoofs(s, w);                        // and the roofs' stripes
  ScanResult r = collect(s, w);            // §2.7: labels, static map, dynamic layer
  remember(r, static_cast<long>(s.index), s, w);
  if (source_ == PoseSource::kGicp || source_ == PoseSource::kRefine)  // movers leave GICP's map
    drops_.push_back({s.seq, static_cast<int64_t>(s.index), w.moving});
  r.stats.ms.free_space = insertFreeSpace(s, w);  // DESIGN §2e, beside the next scan's work
  // The stages before this call (prepare()'s wall: its index built beside counts only where it
  // finished last), and this call's. A registration ahead ran beside the pipeline's work, as the
  // free space does: not in `total`.
  r.stats.ms.total =
      msSince(t_start) + (s.registered_beside ? 0.0 : s.stats.ms.registration) + s.prepare_ms;
  ++decided_;
  if (!p_.object.enabled || p_.object.persist_radius <= 0) {
    r.decided_at = Clock::now();
    sink_(std::move(r));
    return;
  }
  // doc/OBJECTS.md rule 4 backwards: the objects the scan before this one moved whole and this one
  // too are carried back to the ceil(K / 2) held scans before them; older ones go on. A run's
  // first H + 2 scans stay held until 2 (H + 2) are decided ("Held deeper at a run's start").
  hold(std::move(r), s, w);
  handOn(p_.object.hold_start && decided_ <= 2 * holdDepth() ? decided_ : holdDepth());
  const auto t_back = Clock::now();
  carryBack();
  StageTimes& ms = held_results_.back().r.stats.ms;  // rule 4's work, in this scan's times
  const double back_ms = msSince(t_back);
  ms.objects += back_ms;
  ms.total += back_ms;
  held_results_.back().r.decided_at = Clock::now();
}

// W_k: the other buffered scans that have beams.
std::vector<WindowScan> LaserPipeline::windowAround(std::size_t pos, std::size_t from,
                                                    std::size_t before) const {
  std::vector<WindowScan> window;
  // Issue #11: estimated poses are off relative to each other by about relative_error times the
  // path between the two scans (odometry error grows with the distance travelled; our GICP
  // drifts 0.2-1.2 % on the labelled sets, doc/BENCHMARK.md). Given poses are exact.
  const bool estimated = source_ == PoseSource::kGicp || source_ == PoseSource::kRefine;
  const double e = p_.registration.relative_error;
  const auto corrected = posesAround(pos);  // DESIGN §3 "Camera poses"
  for (std::size_t j = 0; j < buf_.size(); ++j)
    if (inWindow(j, pos) && !buf_[j]->beams.empty() && (from == 0 || j >= pos + from) &&
        (before == 0 || (j < pos && pos - j <= before))) {
      double path = 0;  // summed between the two scans, so a chunk gets the same bits
      if (estimated && e > 0)
        for (std::size_t a = std::min(j, pos); a < std::max(j, pos); ++a)
          path += (buf_[a + 1]->scan.pose.translation() - buf_[a]->scan.pose.translation()).norm();
      window.push_back(
          {&buf_[j]->beams,
           corrected[j] ? Eigen::Isometry3d(corrected[j]->inverse()) : buf_[j]->world_to_sensor,
           (e * path) * (e * path), buf_[j]->ring_gap, static_cast<int>(j) - static_cast<int>(pos),
           buf_[j]->column_step});
    }
  return window;
}

std::optional<WindowScan> LaserPipeline::windowScan(std::size_t pos, std::size_t j) const {
  for (const WindowScan& s : windowAround(pos, j > pos ? j - pos : 0, j < pos ? pos - j : 0))
    if (s.beams == &buf_[j]->beams) return s;
  return std::nullopt;
}

// DESIGN §2.3: duplicates of the recent static map are static, neither tested nor inserted. The
// candidates' world coordinates are computed here, once for every later stage.
void LaserPipeline::findDuplicates(Prepared& s, Work& w) const {
  const auto t0 = Clock::now();
  const auto& pts = s.scan.points;
  const long k = static_cast<long>(s.index);
  w.world.assign(pts.size(), Eigen::Vector3d::Zero());
  w.duplicate.assign(pts.size(), 0);
  parallelFor(pts.size(), p_.threads, [&](std::size_t i) {  // read-only queries
    if (!s.candidate[i]) return;
    w.world[i] = s.scan.pose * pts[i].xyz().cast<double>();
    w.duplicate[i] = dup_.isDuplicate(w.world[i].cast<float>(), k);
  });
  for (uint32_t i = 0; i < pts.size(); ++i) {
    if (!s.candidate[i]) continue;
    if (w.duplicate[i]) {
      ++s.stats.duplicates;
      continue;
    }
    w.cand.push_back(i);
    w.cand_world.push_back(w.world[i]);
  }
  s.stats.candidates = w.cand.size();
  s.stats.ms.duplicates = msSince(t0);
}

// DESIGN §2c: octree leaves; a seeded random subset of each dense leaf is tested.
void LaserPipeline::sampleLeaves(Prepared& s, Work& w) const {
  const auto t0 = Clock::now();
  std::mt19937_64 rng(p_.seed * 0x9E3779B97F4A7C15ull + static_cast<uint64_t>(s.index));
  planLeaves(w.cand_world, p_.octree, rng, w.leaves);
  s.stats.tested = w.leaves.testedTotal();
  s.stats.ms.octree = msSince(t0);
}

// DESIGN §2b, §2c: the moving-point test of the sampled candidates against the window, leaf by
// leaf. A leaf's decision is the majority of its tested points (leafIsMoving): once the points
// tested so far settle it, the leaf's other points are not tested (issue #16; the same
// decisions, about a quarter fewer tests). Leaves are taken column by column
// (MovingTest::testOrder of their first tested point), so consecutive tests share the window's
// beams in cache. Statistics go into one accumulator per worker.
void LaserPipeline::classify(const std::vector<WindowScan>& window, Prepared& s, Work& w) const {
  const auto t0 = Clock::now();
  w.leaf_moving.assign(w.leaves.size(), 0);
  w.tested_leaf.clear();
  w.tested_sensor.clear();
  for (uint32_t l = 0; l < w.leaves.size(); ++l)
    if (!w.leaves[l].tested.empty()) {
      w.tested_leaf.push_back(l);
      w.tested_sensor.push_back(s.scan.points[w.cand[w.leaves[l].tested.front()]].xyz());
    }
  const std::vector<uint32_t> order = test_.testOrder(w.tested_sensor);
  // P's own scan, for the edges of a sparse lidar's surfaces (MovingTest::edgesOf, issue #15).
  const WindowScan own = s.own();
  const auto workers = static_cast<std::size_t>(std::max(p_.threads, 1));
  std::vector<MovingTestStats> acc(workers);
  w.tested_as.assign(s.scan.size(), 0);  // each point written by the one worker testing it
  parallelFor(
      order.size(), p_.threads,
      [&](std::size_t t, int worker) {
        const uint32_t l = w.tested_leaf[order[t]];
        auto& stats = acc[static_cast<std::size_t>(worker)];
        w.leaf_moving[l] = decideLeaf(w.leaves[l], [&](uint32_t c) {
          const uint32_t i = w.cand[c];
          bool run = false;
          const bool moving =
              test_.isMoving(w.cand_world[c], window, &stats, edgeBits(s, i, own), true, &run);
          w.tested_as[i] = moving ? (run ? Work::kRun : Work::kVotes) : 0;
          return moving;
        });
      },
      128);  // leaves differ in work: smaller chunks balance the threads
  for (const auto& a : acc) {
    s.stats.total_conflicts += a.total_conflicts;
    s.stats.no_evidence += a.no_evidence;
    s.stats.conflicting_scans += a.conflicting_scans;
    s.stats.ring_votes += a.ring_votes;
    s.stats.scans_visited += a.scans_visited;
    s.stats.beams += a.beams;
    s.stats.early_decisions += a.early;
  }
  std::size_t tests = 0;
  for (const auto& a : acc) tests += a.points;
  s.stats.settled_skips = s.stats.tested - tests;  // the leaves' points never tested
  s.stats.ms.classify = msSince(t0);
}

// DESIGN §2c: a leaf is moving iff at least half of its tested points are (classify).
void LaserPipeline::decideLeaves(const Prepared& s, Work& w) const {
  w.moving.assign(s.scan.size(), 0);
  for (std::size_t l = 0; l < w.leaves.size(); ++l)
    if (w.leaf_moving[l])
      for (uint32_t c : w.leaves[l].members) w.moving[w.cand[c]] = 1;
}

// DESIGN §2.2, "Self returns": the recording vehicle's own returns that the test flagged leave
// the crop (unclassified, in no map and no object).
void LaserPipeline::dropSelfReturns(const std::vector<WindowScan>& window, Prepared& s,
                                    Work& w) const {
  if (p_.filter.self_range <= 0) return;
  std::vector<uint8_t> self;
  const std::size_t n =
      findSelfReturns(s.scan.points, s.candidate, w.moving, s.scan.pose.translation(), window,
                      p_.filter.self_range, p_.object.voxel, self);
  if (n == 0) return;
  for (uint32_t i = 0; i < s.scan.size(); ++i)
    if (self[i]) {
      s.in_crop[i] = 0;
      s.candidate[i] = 0;
      w.moving[i] = 0;
      w.self_index.push_back(s.scan.originalIndex(i));
    }
  s.stats.in_crop -= n;
  s.stats.self_returns = n;
}

// doc/OBJECTS.md: connected objects move as a whole; duplicates take part, they belong to the
// same objects. Rule 4 (hysteresis) looks at the previous scan's moving cells.
void LaserPipeline::objectConsensus(std::size_t pos, Prepared& s, Work& w) const {
  const auto t0 = Clock::now();
  std::vector<uint8_t> near_prev;
  if (!prev_moving_cells_.empty()) {
    near_prev.assign(s.scan.size(), 0);
    const double inv = 1.0 / p_.object.persist_radius;
    for (uint32_t i = 0; i < s.scan.size(); ++i)
      if (s.candidate[i])
        near_prev[i] = prev_moving_cells_.contains(
            cellKeyOf(w.world[i].x(), w.world[i].y(), w.world[i].z(), inv));
  }
  // A sparser lidar returns fewer points from the same object (DESIGN §2d): min_moving is an
  // HDL-64E count.
  ObjectParams op = p_.object;
  op.min_moving = scaledCount(op.min_moving, s.density);
  // Rule 4 under static_fraction (doc/OBJECTS.md): the object the previous scan moved whole,
  // still moving.
  ConsensusRules rules;
  rules.reach = ringReach(op, s.ring_gap);  // a sparse lidar's rings (sensor frame; OBJECTS.md)
  // Rule 2's far exception: half a window each side (a run's ends see one side only).
  rules.far_window = std::min(pos, buf_.size() - 1 - pos) >= std::max<std::size_t>(1, k_ / 2);
  // Rule 2's foot, "What it stands on": the road's level (h_G, DESIGN §2a) and foot_height.
  rules.stand_top = static_cast<float>(s.ground_z + op.foot_height);
  // The previous scan's objects moved whole, built (or found held) on the first call.
  WholeObjects prev_own;
  const WholeObjects* prev_objects = &prev_own;
  bool prev_built = false;
  // The scans after it, the far half of them, those before it and the near half of those, built
  // on first use.
  std::optional<std::vector<WindowScan>> after, far, before, just_before;
  std::vector<Eigen::Vector3f> q_prev;     // an object's points in the previous frame
  std::vector<Eigen::Vector3f> pieces_at;  // the scan's grouped points in the previous frame
  std::vector<uint32_t> ends;              // a large object's points at its ends (arrivalEnds)
  const WindowScan own = s.own();
  w.held.assign(s.scan.size(), 0);
  w.measured.assign(s.scan.size(), 0);
  std::function<bool(const std::vector<uint32_t>&)> left_place;
  // The object the previous scan moved whole that these points are (rule 4's "the same object"):
  // half of them in its voxels (in that scan's sensor frame, where its consensus found it), as
  // they are, moved, or by its ends; `e` their extent (this scan's sensor frame), `step` a ring
  // gap at their range (sizedAs: a sparse lidar sees a height to a ring step).
  const auto previousObject = [&](const std::vector<uint32_t>& idx, Eigen::Vector3f& e,
                                  float& step) {
    if (!prev_built) {
      // Rule 4 backwards grouped them already where the previous scan is held (the same points).
      const Held* last = held_results_.empty() ? nullptr : &held_results_.back();
      if (last && last->r.index + 1 == s.index && last->whole_objects &&
          last->whole_reach == rules.reach && last->whole.size() == prev_whole_.size())
        prev_objects = &*last->whole_objects;
      else
        wholeObjectsOf(prev_whole_, std::vector<uint8_t>(prev_whole_.size(), 1), op.voxel, prev_own,
                       rules.reach);
      prev_built = true;
    }
    Eigen::Vector3f lo = Eigen::Vector3f::Constant(1e30f), hi = -lo;
    q_prev.resize(idx.size());
    for (std::size_t k = 0; k < idx.size(); ++k) {
      const uint32_t i = idx[k];
      lo = lo.cwiseMin(s.scan.points[i].xyz());
      hi = hi.cwiseMax(s.scan.points[i].xyz());
      q_prev[k] = (prev_pose_inverse_ * w.world[i]).cast<float>();
    }
    e = hi - lo;
    step = rules.reach.stepAt(lo, hi);
    // The previous scan's object in its voxels, or found moved (a car moving about a voxel a
    // scan no longer lies in its previous voxels), or by its ends (doc/OBJECTS.md rule 4: a
    // car that brakes shows a column more or less of its side, 0.4 m at 512 columns, and its
    // centroid steps by what the columns hold, not by its motion; only where the scans after
    // it can show it leave, below: the looser match is not kept on the previous scan's word).
    return matchWholeObjectOrByEnds(q_prev, *prev_objects, op.voxel, kMovedMatch);
  };
  if (!near_prev.empty()) {
    // Rule 2, "The previous scan's object": that object itself, not smaller (by its ends: no).
    rules.was_whole = [&](const std::vector<uint32_t>& idx) {
      Eigen::Vector3f e;
      float step = 0.0f;
      const std::optional<WholeMatch> match = previousObject(idx, e, step);
      return match && !match->by_ends &&
             sizedAs(e, prev_objects->extent[match->object], rules.extent_tolerance, false, step);
    };
    left_place = [&](const std::vector<uint32_t>& idx) {
      // That object, and not smaller than 1 - extent_tolerance of it (two solids do not share
      // their space; the map's rule 5).
      Eigen::Vector3f e;
      float step = 0.0f;
      const std::optional<WholeMatch> match = previousObject(idx, e, step);
      if (!match) return false;
      const WholeObjects& prev = *prev_objects;
      const float inv = static_cast<float>(1.0 / op.voxel);
      const auto voxelOf = [&](const Eigen::Vector3f& q) {
        return prev.voxel.find(
            cellKey(floorToCell(q.x(), inv), floorToCell(q.y(), inv), floorToCell(q.z(), inv)));
      };
      const bool by_ends = match->by_ends;
      const std::size_t a = match->object;
      const Eigen::Vector3f moved_by = match->shift;  // the shift that found it (zero: in place)
      const Eigen::Vector3f x = prev.extent[a];
      // Not smaller (it may have joined its other part), or a face of it: a body receding along
      // its length shows its back face alone once its side falls a column beyond (a cyclist the
      // ego overtakes, at 512 columns), as rule 4 backwards takes a face (doc/OBJECTS.md rule 4,
      // "the same object").
      const auto as_large = [&](const Eigen::Vector3f& ext, float at) {
        return sizedAs(ext, x, rules.extent_tolerance, false, at) ||
               faceOf(ringLifted(ext, x, at), x, op.voxel, rules.extent_tolerance);
      };
      // Fewer than half of the window's later scans (the sequence's last ones, a dropout) cannot
      // show it leave (below); there it must be that whole object itself, or that object in
      // rings (below).
      if (!after) {
        after = windowAround(pos, 1);
        far = windowAround(pos, std::max<std::size_t>(1, k_ / 2));
        before = windowAround(pos, 0, k_);
        just_before = windowAround(pos, 0, std::max<std::size_t>(1, k_ / 2));
      }
      const bool can_leave = 2 * after->size() >= k_ / stride_;
      if (!as_large(e, step)) {
        // Or that object in pieces (doc/OBJECTS.md rule 4): a side seen grazing has its returns
        // a column step apart (an HDL-64E's 0.18 degrees are 0.35 m along a cyclist's side 1.2 m
        // off at 11.5 m), more than the grouping's voxel, so the side falls into slices. The
        // pieces of this scan in that object's voxels (moved as this one was found) are as large
        // as it; each piece still has to show itself leaving.
        // Or in rings, where the later scans are too few to show it leave: a sparse lidar's rings
        // stand apart on a far face (1.33 degrees are 0.37 m at 16 m), the face falls into ring
        // slices, and those that the windowed test flagged, within its azimuths and a voxel of
        // that object's voxels, count to its size; at least min_moving of them show it moving
        // here (doc/OBJECTS.md rule 4, "in rings").
        if (pieces_at.empty()) {  // built on first use
          pieces_at.assign(s.scan.size(), Eigen::Vector3f::Zero());
          for (uint32_t i = 0; i < s.scan.size(); ++i)
            if (s.candidate[i]) pieces_at[i] = (prev_pose_inverse_ * w.world[i]).cast<float>();
        }
        // Its azimuths in this scan, relative to its mean direction: a slice of its side lies
        // beside them, within the test's cone (a mover that touched it lies across them).
        double sx = 0.0, sy = 0.0;
        for (const uint32_t i : idx) {
          sx += s.scan.points[i].x;
          sy += s.scan.points[i].y;
        }
        const double mean_az = std::atan2(sy, sx);
        const auto azimuth = [&](uint32_t i) {
          double d = std::atan2(s.scan.points[i].y, s.scan.points[i].x) - mean_az;
          if (d > M_PI) d -= 2.0 * M_PI;
          if (d < -M_PI) d += 2.0 * M_PI;
          return d;
        };
        double az_lo = 1e9, az_hi = -1e9;
        for (const uint32_t i : idx) {
          az_lo = std::min(az_lo, azimuth(i));
          az_hi = std::max(az_hi, azimuth(i));
        }
        const double cone = p_.ds.search_lambdas * p_.ds.lambda_theta;
        // A ring's slice is shifted level (the shift found it by a centroid without the other
        // rings) and looked for within a voxel (a ring is a thin layer at a voxel's boundary).
        const Eigen::Vector3f level(moved_by.x(), moved_by.y(), 0.0f);
        const auto nearObject = [&](const Eigen::Vector3f& q) {
          for (int dx = -1; dx <= 1; ++dx)
            for (int dy = -1; dy <= 1; ++dy)
              for (int dz = -1; dz <= 1; ++dz) {
                const uint32_t* b = voxelOf(q + Eigen::Vector3f(dx, dy, dz) * float(op.voxel));
                if (b && *b == a) return true;
              }
          return false;
        };
        Eigen::Vector3f plo = Eigen::Vector3f::Constant(1e30f), phi = -plo;
        int rings = 0;  // the flagged returns of its other rings
        for (uint32_t i = 0; i < s.scan.size(); ++i) {
          // Unflagged slices beside it where the later scans can show it leave, flagged rings
          // where they cannot.
          if (!s.candidate[i] || (w.moving[i] != 0) == can_leave) continue;
          const double az = azimuth(i);
          if (can_leave) {  // a grazing side's slice
            const uint32_t* b = voxelOf(pieces_at[i] + moved_by);
            if (!b || *b != a) continue;
            if (!((az < az_lo && az >= az_lo - cone) || (az > az_hi && az <= az_hi + cone)))
              continue;
          } else {  // a ring's slice
            if (az < az_lo - cone || az > az_hi + cone || !nearObject(pieces_at[i] + level))
              continue;
            ++rings;
          }
          plo = plo.cwiseMin(pieces_at[i]);
          phi = phi.cwiseMax(pieces_at[i]);
        }
        for (const Eigen::Vector3f& q : q_prev) {
          plo = plo.cwiseMin(q);
          phi = phi.cwiseMax(q);
        }
        if (!as_large(phi - plo, rules.reach.stepAt(plo, phi))) return false;
        if (!can_leave) return rings >= op.min_moving && !by_ends;
      }
      // It left its place: the scans after it alone see it leave, or those just before it see it
      // arrive (below; a vehicle that stopped over half a window ago shows neither). Where the
      // scans after it are too few to tell, a vehicle in stop-and-go traffic (0.5-1 m/s) moves
      // less than a voxel and the beam model's margin in half a window (0.5 s): it stays as the
      // previous scan had it. Found by its ends, only where one of the two is a face of the other,
      // which is more than a voxel deep: its side came into view, its face's end where the face
      // was (a cyclist the ego draws alongside in the run's last scan), or went out of view, its
      // face where the object's end was (a car receding at 512 columns, a column of its side
      // joined to its back in one scan and not in the next; doc/OBJECTS.md rule 4, "by its
      // ends"). A pole or a kerb's ring is no deeper than its face.
      const auto faceOfDeeper = [&](const Eigen::Vector3f& face, const Eigen::Vector3f& body) {
        return faceOf(face, body, op.voxel, rules.extent_tolerance) &&
               body.head<2>().minCoeff() > static_cast<float>(op.voxel);
      };
      if (!can_leave) return !by_ends || faceOfDeeper(x, e) || faceOfDeeper(e, x);
      // Leaving: min_moving of its moving points are moving for the later scans (its rear, the
      // gaps between its parts: a long vehicle driving on with its ends out of view), or half of
      // all its points are for the far half of them: a car pulling away at 0.8 m/s moves 0.08 m
      // a scan, the whole window may call none of its points moving (the scans before it saw its
      // back's place inside its body) and the nearer later scans still see its back within the
      // beam model's margin of where it was, but those K / 2 and more after it see it all gone.
      int left = 0;
      for (uint32_t i : idx)
        if (w.moving[i] && (left += test_.isMoving(w.world[i], *after, nullptr,
                                                   edgeBits(s, i, own))) >= op.min_moving)
          return true;
      // The two tests of all its points below ask every stride-th point of a large object, each
      // standing for stride points (a truck 2 m off holds 30,000 returns; issue #16).
      const std::size_t stride =
          std::max<std::size_t>(1, (idx.size() + kRule4Sample - 1) / kRule4Sample);
      std::size_t gone = 0, asked = 0;
      const std::size_t n = (idx.size() + stride - 1) / stride;
      for (std::size_t k = 0; k < idx.size(); k += stride) {
        const uint32_t i = idx[k];
        gone += test_.isMoving(w.world[i], *far, nullptr, edgeBits(s, i, own));
        ++asked;
        if (2 * gone >= n) return true;
        if (2 * (gone + n - asked) < n) break;  // half can no longer be reached
      }
      // Or it has just arrived: min_moving of its points are moving for the K / 2 scans before it
      // alone, or read empty from the window's far end in the scans before it (DESIGN §2b's empty
      // run): their places were empty less than half a window ago. A vehicle coming towards the
      // sensor shows only its front, which the scans after it see inside it. The K / 2 scans'
      // votes tip where it came K / 4 scans ago; the run holds a car that stopped at once from 6
      // m/s two scans ago, its leading 0.6 m alone moving by those votes (doc/OBJECTS.md rule 4,
      // "Half a window ago"). How far it came: a point does not count where the place
      // kArrivalDepth further in (towards its centroid, level) was occupied for all of the K / 2
      // scans before it. A car braking to a stand came 0.16 m in its last 0.5 s (static by the
      // labels), and the scans before saw the few returns at its leading end empty.
      Eigen::Vector2d mid = Eigen::Vector2d::Zero();
      for (const uint32_t i : idx) mid += w.world[i].head<2>();
      mid /= static_cast<double>(idx.size());
      const auto arrivedAt = [&](uint32_t i) {
        const uint8_t edges = edgeBits(s, i, own);
        if (!test_.isMoving(w.world[i], *just_before, nullptr, edges) &&
            !test_.hasEmptyRun(w.world[i], *before, nullptr, edges))
          return 0;
        const Eigen::Vector2d in = mid - w.world[i].head<2>();
        const double to_mid = in.norm();
        if (to_mid <= kArrivalDepth) return 1;  // its middle: the whole object came
        Eigen::Vector3d deeper = w.world[i];
        deeper.head<2>() += in * (kArrivalDepth / to_mid);
        // It stood there throughout where each of those scans alone (DESIGN §2b's mass of that
        // scan) saw that place occupied. Not "one saw it empty": a vehicle moving along its side
        // seen at a grazing angle hides its new place behind its old end. A sparse scan whose
        // cone holds no beam there (between two rings) saw it occupied where the rings around
        // it return at its range (MovingTest::ringsReturnAt; doc/OBJECTS.md rule 4, "Between
        // two rings").
        for (const WindowScan& by : *just_before) {
          const ds::Mass m = test_.scanMass(deeper, by, nullptr, nullptr, edges);
          if (!ds::isOccupied(m) && (m.e > m.u || !test_.ringsReturnAt(deeper, by))) return 1;
        }
        return 0;
      };
      int arrived = 0;
      for (std::size_t k = 0; k < idx.size(); k += stride)  // each asked point stands for stride
        if ((arrived += static_cast<int>(stride) * arrivedAt(idx[k])) >= op.min_moving) return true;
      if (stride == 1) return false;
      // A large object arrives at its ends: its leading end's new place is a few columns, which
      // the sample above can step over (a crawling truck's dozen arrivals among 24,000 points).
      // Its points within kArrivalEnd of either end along its length are asked, all of them or
      // every n-th, the n-th shifted by one each time so that no ring is left out.
      arrivalEnds(idx, w.world, ends);
      const std::size_t end_stride =
          std::max<std::size_t>(1, (ends.size() + kRule4Sample - 1) / kRule4Sample);
      arrived = 0;
      for (std::size_t j = 0, k = 0; k < ends.size(); ++j, k = j * end_stride + j % end_stride)
        if ((arrived += static_cast<int>(end_stride) * arrivedAt(ends[k])) >= op.min_moving)
          return true;
      return false;
    };
    rules.has_left = [&](const std::vector<uint32_t>& idx) {
      if (!left_place(idx)) return false;
      for (uint32_t i : idx) w.held[i] = 1;  // validateImages leaves it to this decision
      return true;
    };
  }
  // Rule 7 (doc/OBJECTS.md, "Measured"): the candidates of the scans half a window (H scans)
  // before and after this one, in the world frame, in columns of kShiftColumn; built on first
  // use. Both must be there (not in a run's first and last H scans).
  const std::size_t half = (k_ + 1) / 2;
  const Held* earlier = nullptr;
  for (const Held& h : held_results_)
    if (h.r.index + half == s.index) earlier = &h;
  const Prepared* later = pos + half < buf_.size() ? buf_[pos + half].get() : nullptr;
  if (later && (later->index != s.index + half || later->points_released)) later = nullptr;
  std::optional<std::array<ColumnTable, 2>> columns;
  std::vector<Eigen::Vector3f> outline, target;
  std::optional<WindowScan> seen_earlier, seen_later;  // their beams
  WindowScan seen_now = s.own();                       // and this scan's, in the world
  seen_now.world_to_sensor = s.world_to_sensor;
  const auto seenNow = [&seen_now](const WindowScan& other) {  // at the other's pose error
    WindowScan by = seen_now;
    by.pose_noise2 = other.pose_noise2;
    return by;
  };
  if (earlier && later && p_.object.measure && pos >= half &&
      buf_[pos - half]->index + half == s.index) {
    seen_earlier = windowScan(pos, pos - half);
    seen_later = windowScan(pos, pos + half);
  }
  w.measurable = seen_earlier && seen_later;
  // Rule 7's least component, an HDL-64E count as min_moving is (DESIGN §2d): car_stops_5s' car
  // 17 m ahead holds 721 of its returns, 89 of an OS1-64's at 512 columns.
  rules.measured_points =
      static_cast<std::size_t>(scaledCount(static_cast<double>(rules.measured_points), s.density));
  if (w.measurable) {
    rules.measured = [&, earlier, later](const std::vector<uint32_t>& idx) {
      if (!columns) {
        columns.emplace();
        // At the poses the test used (the cameras' corrections, DESIGN §3 "Camera poses").
        const Eigen::Isometry3f to_world_a = seen_earlier->world_to_sensor.inverse().cast<float>();
        (*columns)[0].build(earlier->points.size(), [&](std::size_t i) -> Eigen::Vector3f {
          return to_world_a * earlier->points[i].xyz();
        });
        const Eigen::Isometry3f to_world_b = seen_later->world_to_sensor.inverse().cast<float>();
        std::vector<uint32_t> cand;
        for (uint32_t i = 0; i < later->scan.size(); ++i)
          if (later->candidate[i]) cand.push_back(i);
        (*columns)[1].build(cand.size(), [&](std::size_t k) -> Eigen::Vector3f {
          return to_world_b * later->scan.points[cand[k]].xyz();
        });
      }
      // Its points above its foot (a sidewalk it touches is not its outline), seen from above.
      double z_lo = 1e30, z_hi = -1e30;
      for (const uint32_t i : idx) {
        z_lo = std::min(z_lo, w.world[i].z());
        z_hi = std::max(z_hi, w.world[i].z());
      }
      const double z_from = z_lo + op.foot_height;
      outline.clear();
      Eigen::Vector2f lo = Eigen::Vector2f::Constant(1e30f), hi = -lo;
      for (const uint32_t i : idx)
        if (w.world[i].z() >= z_from) {
          outline.push_back(w.world[i].cast<float>());
          lo = lo.cwiseMin(outline.back().head<2>());
          hi = hi.cwiseMax(outline.back().head<2>());
        }
      if (outline.size() < rules.measured_points / 2) return false;
      const float grow = static_cast<float>(kShift.reach + 2 * kShift.cell);
      Eigen::Vector3d centre = Eigen::Vector3d::Zero();
      for (const Eigen::Vector3f& q : outline) centre += q.cast<double>();
      centre /= static_cast<double>(outline.size());
      const Eigen::Vector3d here = s.world_to_sensor.inverse().translation();
      // The outline holds at least a car's width of face (kShiftMinFace) in its cells, or in its
      // columns where the lidar's lie further apart at its range than a cell (0.21 m at 17 m at
      // 512 columns): a car seen head-on shows its front and a column or two of its side, fewer
      // at coarser columns (doc/OBJECTS.md rule 7).
      const double column = (centre - here).head<2>().norm() * s.column_step;
      const auto min_cells =
          static_cast<std::size_t>(std::ceil(kShiftMinFace / std::max(kShift.cell, column)));
      const auto shiftIn = [&](const ColumnTable& cols, const WindowScan& seen) {
        // Seen from about the same side: a sensor that drove past sees other faces, and the
        // parts each view holds match best shifted (horizontal bearings within kShiftView).
        const Eigen::Vector3d there = seen.world_to_sensor.inverse().translation();
        const Eigen::Vector2d a = (centre - here).head<2>(), b = (centre - there).head<2>();
        if (a.dot(b) < std::cos(kShiftView) * a.norm() * b.norm())
          return Eigen::Vector2f(Eigen::Vector2f::Zero());
        target.clear();
        for (int64_t cy = ColumnTable::cell(lo.y() - grow); cy <= ColumnTable::cell(hi.y() + grow);
             ++cy)
          for (int64_t cx = ColumnTable::cell(lo.x() - grow);
               cx <= ColumnTable::cell(hi.x() + grow); ++cx)
            cols.forEach(cx, cy, [&](const Eigen::Vector3f& x) {
              if (x.z() >= z_from && x.z() <= z_hi + kShiftAbove) target.push_back(x);
            });
        const OutlineShift m = outlineShift(outline, target, kShift);
        // Found there (half of its outline matches, in min_cells or more), and the cells facing
        // the shift match shifted, not where they are. Not an outline that is one straight side
        // shifted along itself: its cells facing the shift are its end, where the view or the
        // lidar's columns cut it (a wall 24 m long at 512 columns, ended where they part 1.5 m
        // apart: 6 facing cells of 107); the side path below asks what such a side needs.
        const bool found = m.cells >= min_cells && 2 * m.at_shift >= m.cells;
        const bool along_side =
            !m.side.isZero() && std::abs(m.shift.dot(m.side)) >
                                    std::abs(m.shift.dot(Eigen::Vector2f(-m.side.y(), m.side.x())));
        const bool faces =
            found && !along_side && m.facing >= kShiftMinGain &&
            m.facing_at_shift >= m.facing_at_rest + std::max(kShiftMinGain, m.facing / 2);
        // Or, no face across in view, a side along the shift: all but a tenth of the outline
        // matches shifted, and more of it than in place (its ends; a side seen over another
        // stretch matches so too, and its end's place is not seen empty, below).
        const bool side = found && m.facing < kShiftMinGain && m.along >= kShiftMinSide &&
                          10 * m.at_shift >= 9 * m.cells &&
                          m.along_at_shift >= m.along_at_rest + kShiftEndGain;
        // Where it stood in one scan and not in the other, the other scan sees empty space (a
        // static object that scan did not see matches the same way, shifted onto another): a
        // third of the facing evidence, half of a side's trailing end (or of a side's end, below):
        // this scan's places seen by the other scan. Or, facing, the other scan's seen by this
        // one: a vehicle driving away from the sensor hid its new place behind its old one from
        // the earlier scan.
        const auto emptyIn = [&](const std::vector<Eigen::Vector3f>& points,
                                 const std::vector<uint32_t>& ev, const WindowScan& by) {
          std::size_t empty = 0;
          const std::size_t need = std::max(kShiftMinGain, ev.size() / (faces ? 3 : 2));
          for (std::size_t k = 0; k < ev.size() && empty < need; ++k)
            empty +=
                ds::isMoving(test_.scanMass(points[ev[k]].cast<double>(), by, nullptr, nullptr));
          return empty >= need;
        };
        const bool gone =
            (faces || side) &&
            (emptyIn(outline, faces ? m.evidence : m.end_evidence, seen) ||
             (faces && seen_now.beams && emptyIn(target, m.old_evidence, seenNow(seen))));
        if (gone) return m.shift;
        // A side's ends (doc/OBJECTS.md rule 7): no face in view, the outline one straight side.
        // Where one scan saw the side beyond the other's end and the other saw that place empty,
        // that end moved by the difference. The other scan holds both ends (a side it sees run
        // on is a piece of something longer), and a rigid side's ends move together: they agree
        // (a side whose seen length changed was cut by its view).
        if (faces || !found || m.side.isZero() || !std::isfinite(m.end_shift[0]) ||
            !std::isfinite(m.end_shift[1]) ||
            std::abs(m.end_shift[0] - m.end_shift[1]) > 2 * kShift.cell)
          return Eigen::Vector2f(Eigen::Vector2f::Zero());
        float sum = 0;
        int told = 0;
        for (int e = 0; e < 2; ++e) {
          const bool empty = !m.end_object[e].empty() ? emptyIn(outline, m.end_object[e], seen)
                             : !m.end_target[e].empty()
                                 ? seen_now.beams && emptyIn(target, m.end_target[e], seenNow(seen))
                                 : false;
          if (!empty) continue;
          sum += m.end_shift[e];
          ++told;
        }
        if (!told) return Eigen::Vector2f(Eigen::Vector2f::Zero());
        return Eigen::Vector2f(m.side * (sum / static_cast<float>(told)));
      };
      // Moving by the labels' measure (as rule 4 backwards): more than kMovedDistance between
      // half a window before and half a window after.
      const bool moved =
          (shiftIn((*columns)[1], *seen_later) - shiftIn((*columns)[0], *seen_earlier)).norm() >
          kMovedDistance;
      if (moved)
        for (const uint32_t i : idx) w.measured[i] = 1;
      return moved;
    };
  }
  // Grouped here so that a held scan keeps its components for rule 4 backwards (hold()).
  groupObjects(s.scan.points, s.candidate, op.voxel, w.groups, rules.reach,
               !s.column_links.empty() ? &s.column_links : nullptr, s.column_links_capped);
  w.grouped = true;
  const auto oc = cleanmap::objectConsensus(s.scan.points, s.candidate, w.moving, op,
                                            near_prev.empty() ? nullptr : &near_prev, &w.whole,
                                            rules, &w.groups);
  // Rule 2, "A face apart" (doc/OBJECTS.md): a component with no moving point that is a face of
  // the object the previous scan moved whole, within GrazingStretches::kMaxLink of a component
  // moving whole here, the two together that object (as they are, moved, or by its ends), is
  // its face: it goes with it.
  std::size_t faces_joined = 0, face_points = 0;
  if (!near_prev.empty() && !prev_whole_.empty()) {
    const ObjectComponents& g = w.groups;
    struct Root {
      uint32_t n = 0, moving = 0, whole = 0, near = 0;
      Eigen::Vector3f lo = Eigen::Vector3f::Constant(1e30f), hi = -lo;
      std::vector<uint32_t> idx;
    };
    std::vector<Root> roots(g.voxels.size());
    for (uint32_t i = 0; i < s.scan.size(); ++i) {
      if (g.point_voxel[i] == UINT32_MAX) continue;
      Root& r = roots[g.root_of[g.point_voxel[i]]];
      ++r.n;
      r.moving += w.moving[i] != 0;
      r.whole += w.whole[i] != 0;
      r.near += near_prev[i] != 0;
      r.lo = r.lo.cwiseMin(s.scan.points[i].xyz());
      r.hi = r.hi.cwiseMax(s.scan.points[i].xyz());
    }
    // Both near the previous scan's moving points (half of theirs), as rule 4's same object.
    std::vector<uint32_t> movers, faces;
    for (uint32_t v = 0; v < roots.size(); ++v) {
      const Root& r = roots[v];
      if (r.n == 0 || 2 * r.near < r.n) continue;
      if (2 * r.whole >= r.n)
        movers.push_back(v);
      else if (r.moving == 0)
        faces.push_back(v);
    }
    if (faces.empty()) movers.clear();
    std::vector<uint8_t> asked(roots.size(), 0);
    for (const auto* list : {&movers, &faces})
      for (const uint32_t v : *list) asked[v] = 1;
    if (!movers.empty())
      for (uint32_t i = 0; i < s.scan.size(); ++i)
        if (g.point_voxel[i] != UINT32_MAX && asked[g.root_of[g.point_voxel[i]]])
          roots[g.root_of[g.point_voxel[i]]].idx.push_back(i);
    for (const uint32_t a : movers)
      for (const uint32_t b : faces) {
        Root& rb = roots[b];
        const Root& ra = roots[a];
        if (rb.moving > 0) continue;  // joined already
        const Eigen::Vector3f gap = (rb.lo - ra.hi).cwiseMax(ra.lo - rb.hi).cwiseMax(0.0f);
        if (gap.norm() > GrazingStretches::kMaxLink) continue;
        std::vector<uint32_t> both = ra.idx;
        both.insert(both.end(), rb.idx.begin(), rb.idx.end());
        Eigen::Vector3f e;
        float step = 0.0f;
        const std::optional<WholeMatch> match = previousObject(both, e, step);
        if (!match) continue;
        const Eigen::Vector3f& x = prev_objects->extent[match->object];
        if (!sizedAs(e, x, rules.extent_tolerance, false, step) ||
            !faceOf(ringLifted(rb.hi - rb.lo, x, step), x, op.voxel, rules.extent_tolerance))
          continue;
        for (const uint32_t i : rb.idx) w.moving[i] = w.whole[i] = 1;
        rb.moving = rb.n;
        ++faces_joined;
        face_points += rb.n;
      }
  }
  s.stats.objects_persisted = oc.persisted;
  s.stats.objects_left_place = oc.left_place;
  s.stats.objects_measured = oc.measured;
  s.stats.objects_far_kept = oc.far_kept;
  s.stats.objects_moving = oc.moving_objects + faces_joined;
  s.stats.consensus_points = oc.points_added + face_points;
  s.stats.consensus_removed = oc.points_removed;
  s.stats.consensus_body_kept = oc.body_points_kept;
  s.stats.consensus_foot_left = oc.foot_points_left;
  s.stats.consensus_surface_left = oc.surface_points_left;
  s.stats.consensus_still_part_left = oc.still_part_points_left;
  s.stats.consensus_wide_left = oc.wide_objects_left;
  s.stats.ms.objects = msSince(t0);
}

// DESIGN §3: the moving points in cells of image.cell, the cells in objects (26-connected).
// A cell looks changed if it looks different in some window camera (the farthest in time first).
// An object stays moving if more than image.changed_fraction of its compared cells look changed
// (the vote below); otherwise its cells in view are relabelled static. Deciding per object keeps
// a mover whose flat side slides along itself (same look, same depth) moving by its ends and
// textured parts; cells no camera sees keep the laser label.
void LaserPipeline::validateImages(std::size_t pos, Prepared& s, Work& w) const {
  if (!s.view) return;
  const auto t0 = Clock::now();
  const ImageParams& ip = p_.image;
  // The window's cameras at the poses the laser test used (DESIGN §3 "Camera poses").
  const auto poses = posesAround(pos);
  const Eigen::Isometry3d L = camera_->opticalFromLidar();
  std::deque<vision::CameraView> moved;  // corrected copies (the images are shared)
  std::vector<std::pair<std::size_t, const vision::CameraView*>> order;
  for (std::size_t j = 0; j < buf_.size(); ++j) {
    if (!inWindow(j, pos) || !buf_[j]->view) continue;
    const vision::CameraView* v = &*buf_[j]->view;
    if (poses[j]) {  // optical_from_world L T'^-1 = (L T'^-1 T L^-1) L T^-1
      moved.push_back(
          vision::corrected(*v, L * poses[j]->inverse() * buf_[j]->scan.pose * L.inverse()));
      v = &moved.back();
    }
    order.emplace_back(j > pos ? j - pos : pos - j, v);
  }
  std::stable_sort(order.begin(), order.end(),
                   [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<const vision::CameraView*> window;
  for (const auto& o : order) window.push_back(o.second);
  // Cells of moving points: their keys in order of first point, each cell's points in flat arrays
  // (Grouped), not one vector per cell (issue #16: 4,700 allocations a highway scan).
  CellMap<std::size_t> cell_at;
  const double inv = 1.0 / ip.cell;
  std::vector<uint64_t> keys;
  std::vector<uint32_t> considered, cell_of;  // the points placed in cells, and their cells
  // An object rule 4 held is not compared (DESIGN §3, "Objects rule 4 holds"): its camera vote
  // was the previous scan's, and it stays moving on evidence the images cannot resolve. Nor is
  // an object most of whose points tested moving were found by their empty runs (DESIGN §2b): a
  // slow mover, whose images change less over the window than the colour and depth tests resolve.
  std::vector<int> run_lead;  // per component root: its points moving by runs minus by votes
  const auto root = [&](uint32_t i) {
    const uint32_t v = s.candidate[i] ? w.groups.point_voxel[i] : UINT32_MAX;
    return v == UINT32_MAX ? UINT32_MAX : w.groups.root_of[v];
  };
  if (w.grouped) {
    run_lead.assign(w.groups.root_of.size(), 0);
    for (uint32_t i = 0; i < s.scan.size(); ++i)
      if (w.tested_as[i] && w.moving[i] && root(i) != UINT32_MAX)
        run_lead[root(i)] += w.tested_as[i] == Work::kRun ? 1 : -1;
  }
  auto found_by_run = [&](uint32_t i) {
    if (!w.grouped) return w.tested_as[i] == Work::kRun;  // no objects: the point itself
    const uint32_t r = root(i);
    return r != UINT32_MAX && run_lead[r] > 0;
  };
  for (uint32_t i = 0; i < s.scan.size(); ++i) {
    if (!w.moving[i]) continue;
    if (w.held[i] || found_by_run(i)) {
      ++s.stats.image_held;
      continue;
    }
    const Eigen::Vector3d& x = w.world[i];
    const uint64_t key = cellKeyOf(x.x(), x.y(), x.z(), inv);
    bool fresh = false;
    std::size_t& at = cell_at.get(key, &fresh);
    if (fresh) at = keys.size(), keys.push_back(key);
    considered.push_back(i);
    cell_of.push_back(static_cast<uint32_t>(at));
  }
  const std::size_t n_cells = keys.size();
  Grouped cell_points;  // in point order within each cell
  cell_points.assign(cell_of, n_cells, &considered);
  // Objects: connected components of the cells.
  std::vector<int> obj_of(n_cells, -1);
  std::vector<std::vector<std::size_t>> objects;
  for (std::size_t c0 = 0; c0 < n_cells; ++c0) {
    if (obj_of[c0] >= 0) continue;
    const int id = static_cast<int>(objects.size());
    objects.push_back({c0});
    obj_of[c0] = id;
    for (std::size_t q = 0; q < objects.back().size(); ++q) {
      const uint64_t k = keys[objects.back()[q]];
      forEachNeighbour27([&](int dx, int dy, int dz) {
        const std::size_t* at = cell_at.find(cellKeyShift(k, dx, dy, dz));
        if (!at || obj_of[*at] >= 0) return;
        obj_of[*at] = id;
        objects[static_cast<std::size_t>(id)].push_back(*at);
      });
    }
  }
  // Each cell's point nearest its mean speaks for it.
  std::vector<Eigen::Vector3d> rep(n_cells);
  for (std::size_t c = 0; c < n_cells; ++c) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (uint32_t i : cell_points[c]) mean += w.world[i];
    mean /= double(cell_points[c].size());
    rep[c] = w.world[cell_points[c].front()];
    for (uint32_t i : cell_points[c])
      if ((w.world[i] - mean).squaredNorm() < (rep[c] - mean).squaredNorm()) rep[c] = w.world[i];
  }
  enum Outcome : uint8_t {
    kUnseen,
    kConfirmedColour,
    kConfirmedDepth,
    kRejectedColour,
    kRejectedDepth
  };
  // A cell's surface (DESIGN §3): the plane of the moving points within 1.5 cells of its
  // representative, for the cameras that see it grazing; zero where they do not form one.
  const double reach2 = std::pow(1.5 * ip.cell, 2);
  const auto surfaceAround = [&](std::size_t c) -> Eigen::Vector3d {
    if (ip.max_incidence_deg >= 90) return Eigen::Vector3d::Zero();
    std::vector<Eigen::Vector3d> near;
    forEachNeighbour27([&](int dx, int dy, int dz) {
      const std::size_t* at = cell_at.find(cellKeyShift(keys[c], dx, dy, dz));
      if (!at) return;
      for (uint32_t i : cell_points[*at])
        if ((w.world[i] - rep[c]).squaredNorm() <= reach2) near.push_back(w.world[i]);
    });
    return vision::surfaceNormal(near).value_or(Eigen::Vector3d::Zero());
  };
  std::vector<Outcome> outcome(objects.size(), kUnseen);
  std::vector<std::size_t> grazing(objects.size(), 0);
  std::vector<uint8_t> relabel_cell(n_cells, 0);
  parallelFor(objects.size(), p_.threads, [&](std::size_t o) {
    auto& members = objects[o];
    // Extremes first: a mover's leading and trailing ends differ most from frame to frame.
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (std::size_t c : members) centre += rep[c];
    centre /= double(members.size());
    std::stable_sort(members.begin(), members.end(), [&](std::size_t a, std::size_t b) {
      return (rep[a] - centre).squaredNorm() > (rep[b] - centre).squaredNorm();
    });
    // The vote (vision::voteObject); a static object's cells in its own camera's view are
    // relabelled static, the few that looked changed included (parallax at an edge, a pose error
    // beyond the search margin); cells out of view keep the laser label.
    const auto v =
        vision::voteObject(members.size(), ip.changed_fraction, ip.max_cells, [&](std::size_t i) {
          const std::size_t c = members[i];
          return vision::decide(*s.view, window, rep[c], ip, surfaceAround(c));
        });
    grazing[o] = v.grazing;
    if (v.outcome == vision::ObjectVote::Outcome::kUnseen) return;
    if (v.outcome == vision::ObjectVote::Outcome::kMoving) {
      outcome[o] =
          v.changed_by == vision::Verdict::kDifferentColour ? kConfirmedColour : kConfirmedDepth;
      return;
    }
    for (std::size_t c : members) relabel_cell[c] = vision::visibleIn(*s.view, rep[c], ip);
    outcome[o] = v.used_depth ? kRejectedDepth : kRejectedColour;
  });
  w.relabelled.assign(s.scan.size(), 0);
  auto& st = s.stats;
  st.image_units += objects.size();
  for (const Outcome oc : outcome) {
    st.image_unseen += oc == kUnseen;
    st.image_confirmed_colour += oc == kConfirmedColour;
    st.image_confirmed_depth += oc == kConfirmedDepth;
    st.image_rejected_colour += oc == kRejectedColour;
    st.image_rejected_depth += oc == kRejectedDepth;
  }
  for (const std::size_t g : grazing) st.image_grazing += g;
  for (std::size_t c = 0; c < n_cells; ++c)
    if (relabel_cell[c])
      for (uint32_t i : cell_points[c]) {
        w.moving[i] = 0;
        w.relabelled[i] = 1;
        ++st.image_relabelled;
      }
  st.ms.images += msSince(t0);
}

// DESIGN §2.7 and §4: labels in the original order; static points to the map (the compact map
// without duplicates), moving points to the dynamic layer, all in the world frame.
// doc/OBJECTS.md rule 6: the returns refined to ground under a moving object, raised over the
// road around them, go with it (after the camera: they follow the final decision).
void LaserPipeline::moverFeet(Prepared& s, Work& w) const {
  if (!p_.object.enabled || !p_.object.feet) return;
  const auto t0 = Clock::now();
  MoverFeetParams fp;
  fp.cell = p_.ground.cell;
  if (s.ring_gap > 0) fp.ring_gap = s.ring_gap;
  const auto& pts = s.scan.points;
  // Work::world holds the candidates (in the crop, not ground) as the feet compute them.
  for (uint32_t i :
       cleanmap::moverFeet(pts, s.scan.pose, s.ground, w.moving, s.in_crop, fp, &w.world)) {
    s.ground[i] = kNotGround;
    w.moving[i] = 1;
    w.world[i] = s.scan.pose * pts[i].xyz().cast<double>();
    ++s.stats.mover_feet;
    --s.stats.ground;  // in the crop, as every foot: counted moving now
  }
  s.stats.ms.objects += msSince(t0);
}

// doc/OBJECTS.md rule 6, roofs: the roof stripes behind a vehicle moving whole.
void LaserPipeline::moverRoofs(Prepared& s, Work& w) const {
  if (!p_.object.enabled || !p_.object.roofs || s.roof_gap <= 0 || !w.grouped) return;
  const auto t0 = Clock::now();
  MoverRoofParams rp;
  rp.ring_gap = s.roof_gap;
  rp.dense = s.ring_gap <= 0;
  rp.voxel = p_.object.voxel;
  rp.narrow = p_.object.ring_pool;
  rp.flagged = p_.object.moving_fraction;
  rp.max_length = p_.object.max_length;
  rp.max_height = p_.object.max_height;
  for (uint32_t i : cleanmap::moverRoofs(s.scan.points, s.scan.pose, w.groups, w.moving, w.whole,
                                         s.ground, rp)) {
    w.moving[i] = 1;
    ++s.stats.mover_roofs;
  }
  s.stats.ms.objects += msSince(t0);
}

ScanResult LaserPipeline::collect(Prepared& s, const Work& w) const {
  ScanResult r;
  r.index = s.index;
  r.stem = s.stem;
  r.source = s.source;
  r.timestamp = s.scan.timestamp;
  r.pose = s.scan.pose;
  r.pose_info = s.pose_info;
  r.ground_measured = s.ground_measured;
  r.ground_z = s.ground_z;
  r.density = s.density;
  r.ring_gap = s.ring_gap;
  r.labels.assign(s.stats.points, kUnclassified);
  const auto& pts = s.scan.points;
  // Where each point goes, for the count and the fill below alike.
  enum class Dest : uint8_t { kNone, kFar, kGround, kMoving, kStatic, kDuplicate };
  auto dest = [&](uint32_t i) {
    if (s.far[i]) return Dest::kFar;  // DESIGN §2e: beyond the crop, in the map, unclassified
    if (!s.in_crop[i]) return Dest::kNone;
    if (s.ground[i]) return Dest::kGround;
    if (w.moving[i]) return Dest::kMoving;
    return w.duplicate[i] ? Dest::kDuplicate : Dest::kStatic;
  };
  // The lists' sizes first: grown by push_back they would hold up to twice their points, copied
  // on each growth, for as long as the scan is held and spooled (issue #16).
  std::size_t n_full = 0, n_moving = 0, n_compact = 0;
  for (uint32_t i = 0; i < pts.size(); ++i) {
    const Dest d = dest(i);
    n_moving += d == Dest::kMoving;
    n_full += d != Dest::kNone && d != Dest::kMoving;
    n_compact += d == Dest::kStatic;
  }
  r.static_full.reserve(n_full);
  r.static_full_index.reserve(n_full);
  r.static_full_kind.reserve(n_full);
  r.moving.reserve(n_moving);
  r.moving_index.reserve(n_moving);
  r.static_compact.reserve(n_compact);
  for (uint32_t i = 0; i < pts.size(); ++i) {
    const Dest d = dest(i);
    if (d == Dest::kNone) continue;
    const uint32_t orig = s.scan.originalIndex(i);
    if (d == Dest::kFar) {  // its label stays unclassified
      const Eigen::Vector3d wd = s.scan.pose * pts[i].xyz().cast<double>();
      r.static_full.push_back({static_cast<float>(wd.x()), static_cast<float>(wd.y()),
                               static_cast<float>(wd.z()), pts[i].intensity});
      r.static_full_index.push_back(orig);
      r.static_full_kind.push_back(s.ground[i] ? kMapFarGround : kMapFar);
      continue;
    }
    // Ground points were never transformed by the stages above.
    const Eigen::Vector3d wd = d == Dest::kGround
                                   ? Eigen::Vector3d(s.scan.pose * pts[i].xyz().cast<double>())
                                   : w.world[i];
    const PointXYZI p{static_cast<float>(wd.x()), static_cast<float>(wd.y()),
                      static_cast<float>(wd.z()), pts[i].intensity};
    if (d == Dest::kGround) {
      r.labels[orig] = kGround;
      r.static_full.push_back(p);
      r.static_full_index.push_back(orig);
      r.static_full_kind.push_back(kMapGround);
    } else if (d == Dest::kMoving) {
      r.labels[orig] = kMoving;
      r.moving.push_back(p);
      r.moving_index.push_back(orig);
      ++s.stats.moving;
    } else {
      r.labels[orig] = kStatic;
      r.static_full.push_back(p);
      r.static_full_index.push_back(orig);
      r.static_full_kind.push_back(d == Dest::kDuplicate ? kMapDuplicate : kMapStatic);
      ++s.stats.static_points;
      if (d == Dest::kStatic) r.static_compact.push_back(p);
    }
  }
  if (!w.relabelled.empty())
    for (uint32_t i = 0; i < pts.size(); ++i)
      if (w.relabelled[i]) r.relabelled_index.push_back(s.scan.originalIndex(i));
  r.self_index = w.self_index;
  if (overlays_ && s.view)
    r.overlay = vision::drawOverlay(*s.view, pts, s.scan.pose, overlayKinds(s, w));
  r.stats = s.stats;
  if (keep_scans_) r.scan = s.scan;
  return r;
}

// --save-overlays: per point, 0 not drawn, 1 static (green), 2 moving (red), 3 relabelled static
// by the camera (yellow).
std::vector<uint8_t> LaserPipeline::overlayKinds(const Prepared& s, const Work& w) {
  std::vector<uint8_t> kind(s.scan.size(), 0);
  for (uint32_t i = 0; i < s.scan.size(); ++i)
    if (s.in_crop[i] && !s.ground[i])
      kind[i] = !w.relabelled.empty() && w.relabelled[i] ? 3 : w.moving[i] ? 2 : 1;
  return kind;
}

// State for the next scans: the compact static points feed the duplicate filter; this scan's
// moving points, dilated by one cell, feed the next scan's hysteresis.
// DESIGN §2f: the first scan of an epoch starts with no memory of earlier decisions, so labels
// depend on the epoch's scans and the 2K before it (windows, ground heights), never on where the
// run started.
void LaserPipeline::startEpoch(long index) {
  const long e = p_.epoch > 0 ? index / p_.epoch : 0;
  if (e == epoch_) return;
  epoch_ = e;
  dup_ = DuplicateFilter(p_.filter);
  prev_moving_cells_.clear();
  prev_whole_.clear();
  prev_whole_measured_.clear();
}

void LaserPipeline::remember(const ScanResult& r, long index, const Prepared& s, const Work& w) {
  std::vector<Eigen::Vector3f> inserted;
  inserted.reserve(r.static_compact.size());
  for (const auto& p : r.static_compact) inserted.push_back(p.xyz());
  dup_.insert(inserted, index);
  prev_moving_cells_.clear();
  prev_whole_.clear();
  prev_whole_measured_.clear();
  if (!p_.object.enabled || p_.object.persist_radius <= 0) return;
  persistCells(r.moving, nullptr, p_.object.persist_radius, prev_moving_cells_);
  // The objects moved whole (all their points, foot included), unless the camera relabelled them,
  // in the sensor frame (where the consensus found them) with the pose.
  for (std::size_t i = 0; i < w.whole.size(); ++i)
    if (w.whole[i] && (w.relabelled.empty() || !w.relabelled[i])) {
      prev_whole_.push_back(s.scan.points[i]);
      prev_whole_measured_.push_back(w.measured[i]);
    }
  prev_pose_inverse_ = s.world_to_sensor;
}

void LaserPipeline::hold(ScanResult&& r, const Prepared& s, const Work& w) {
  Held h;
  h.r = std::move(r);
  const auto n = static_cast<std::size_t>(
      std::count_if(s.candidate.begin(), s.candidate.end(), [](uint8_t c) { return c != 0; }));
  h.points.reserve(n);
  h.original.reserve(n);
  h.moving.reserve(n);
  h.relabelled.reserve(n);
  for (uint32_t i = 0; i < s.scan.size(); ++i) {
    if (!s.candidate[i]) continue;
    h.points.push_back(s.scan.points[i]);
    h.original.push_back(s.scan.originalIndex(i));
    if (overlays_ && s.view) h.at.push_back(i);
    h.moving.push_back(w.moving[i]);
    h.relabelled.push_back(w.relabelled.empty() ? 0 : w.relabelled[i]);
  }
  if (w.grouped) {  // its components as the object consensus found them
    std::vector<uint32_t> root;
    root.reserve(h.points.size());
    for (uint32_t i = 0; i < s.scan.size(); ++i)
      if (s.candidate[i]) root.push_back(w.groups.root_of[w.groups.point_voxel[i]]);
    orderByComponent(root, h.order, h.ends);
    h.summarise();
  }
  h.whole = prev_whole_;
  h.whole_measured = prev_whole_measured_;
  h.world_to_sensor = s.world_to_sensor;
  h.density = s.density;
  h.ring_gap = s.ring_gap;
  h.ground_z = s.ground_z;
  h.measurable = w.measurable;
  if (overlays_ && s.view) {
    h.view = s.view;
    h.all_points = s.scan.points;
    h.kind = overlayKinds(s, w);
  }
  held_results_.push_back(std::move(h));
}

void LaserPipeline::handOn(std::size_t keep) {
  while (held_results_.size() > keep) {
    sink_(std::move(held_results_.front().r));
    held_results_.pop_front();
  }
}

namespace {

// The positions from + k of the points q[k] (the object's frame) that lie, shifted by the match,
// in the matched object's voxels or next to them (26 neighbours).
std::vector<uint32_t> nearObject(const std::vector<Eigen::Vector3f>& q, std::size_t from,
                                 const WholeObjects& objects, const WholeMatch& m, double side) {
  const float inv = static_cast<float>(1.0 / side);
  std::vector<uint32_t> near;
  for (std::size_t k = 0; k < q.size(); ++k) {
    const Eigen::Vector3f x = q[k] + m.shift;
    const int cx = floorToCell(x.x(), inv), cy = floorToCell(x.y(), inv),
              cz = floorToCell(x.z(), inv);
    const auto inObject = [&](int dx, int dy, int dz) {
      const uint32_t* o = objects.voxel.find(cellKey(cx + dx, cy + dy, cz + dz));
      return o && *o == m.object;
    };
    bool in = inObject(0, 0, 0);  // its own voxel first: most are in it
    for (int dx = -1; dx <= 1 && !in; ++dx)
      for (int dy = -1; dy <= 1 && !in; ++dy)
        for (int dz = -1; dz <= 1 && !in; ++dz) in = inObject(dx, dy, dz);
    if (in) near.push_back(static_cast<uint32_t>(from + k));
  }
  return near;
}

// As wide (the smaller horizontal extent) and as high as x within kSeedSize, however long: the
// same face, its side in view or not ("Its side comes and goes", doc/OBJECTS.md rule 4
// backwards).
bool sameFace(const Eigen::Vector3f& e, const Eigen::Vector3f& x) {
  const float f = 1.0f - kSeedSize, ew = e.head<2>().minCoeff(), xw = x.head<2>().minCoeff();
  return ew >= f * xw && xw >= f * ew && e.z() >= f * x.z() && x.z() >= f * e.z();
}

// Rule 4 backwards: pieces pooled in a held scan are one object in the scan before (their
// voxels, boxes and centroids joined), where the grouping of `points` (the objects of `objects`,
// voxels of 1 / inv) splits them again. `pool` per point: its pool, or UINT32_MAX; `track_of`
// is then per joined object.
void joinPooled(const std::vector<PointXYZI>& points, const std::vector<uint32_t>& pool, float inv,
                WholeObjects& objects, std::vector<uint32_t>& track_of) {
  const std::size_t n_objects = track_of.size();
  std::vector<uint32_t> pool_of(n_objects, UINT32_MAX);
  bool pooled = false;
  for (std::size_t k = 0; k < points.size(); ++k)
    if (pool[k] != UINT32_MAX)
      if (const uint32_t* o =
              objects.voxel.find(cellKeyOf(points[k].x, points[k].y, points[k].z, inv))) {
        pool_of[*o] = pool[k];
        pooled = true;
      }
  if (!pooled) return;
  // Each object's joined one: the first object of its pool, numbered in order.
  std::vector<uint32_t> id(n_objects), kept;
  for (std::size_t o = 0; o < n_objects; ++o) {
    std::size_t a = 0;
    while (a < kept.size() && !(pool_of[o] != UINT32_MAX && pool_of[kept[a]] == pool_of[o])) ++a;
    id[o] = static_cast<uint32_t>(a);
    if (a == kept.size()) kept.push_back(static_cast<uint32_t>(o));
  }
  if (kept.size() == n_objects) return;
  std::vector<std::pair<uint64_t, uint32_t>> cells;
  objects.voxel.forEach([&](uint64_t key, uint32_t o) { cells.emplace_back(key, o); });
  for (const auto& [key, o] : cells) objects.voxel.get(key) = id[o];
  const std::size_t n = kept.size();
  objects.lo.assign(n, Eigen::Vector3f::Constant(std::numeric_limits<float>::max()));
  objects.hi.assign(n, Eigen::Vector3f::Constant(std::numeric_limits<float>::lowest()));
  objects.centroid.assign(n, Eigen::Vector3f::Zero());
  std::vector<std::size_t> count(n, 0);
  for (const PointXYZI& p : points) {
    const Eigen::Vector3f x = p.xyz();
    const uint32_t* o = objects.voxel.find(cellKeyOf(x.x(), x.y(), x.z(), inv));
    if (!o) continue;
    objects.lo[*o] = objects.lo[*o].cwiseMin(x);
    objects.hi[*o] = objects.hi[*o].cwiseMax(x);
    objects.centroid[*o] += x;
    ++count[*o];
  }
  objects.extent.resize(n);
  std::vector<uint32_t> tracks(n);
  for (std::size_t o = 0; o < n; ++o) {
    objects.extent[o] = objects.hi[o] - objects.lo[o];
    objects.centroid[o] /= static_cast<float>(std::max<std::size_t>(count[o], 1));
    tracks[o] = track_of[kept[o]];
  }
  track_of = std::move(tracks);
}

// Rule 2's foot (doc/OBJECTS.md, Foot) of the points order[k] of `part`: the part without it.
// The scan's other points around it show the surface it stands on (Foot::addAround): those of
// the components (order[ends[c - 1] .. ends[c]), boxes lo[c] .. hi[c]) that reach the foot band's
// heights within two voxels of the part.
std::vector<uint32_t> withoutFoot(const std::vector<uint32_t>& part,
                                  const std::vector<uint32_t>& order,
                                  const std::vector<uint32_t>& ends,
                                  const std::vector<Eigen::Vector3f>& lo,
                                  const std::vector<Eigen::Vector3f>& hi,
                                  const std::vector<PointXYZI>& points, double side, double foot,
                                  double reach, double ring_gap, float stand_top) {
  if (foot <= 0 || part.empty()) return part;
  Eigen::Vector3f p_lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
  Eigen::Vector3f p_hi = -p_lo;
  for (const uint32_t k : part) {
    p_lo = p_lo.cwiseMin(points[order[k]].xyz());
    p_hi = p_hi.cwiseMax(points[order[k]].xyz());
  }
  std::vector<uint32_t> sorted = part;
  std::sort(sorted.begin(), sorted.end());
  const float lowest = p_lo.z();
  Foot feet(side, foot, reach, ring_gap, stand_top);
  for (const uint32_t k : part) feet.add(points[order[k]].xyz(), 0, lowest);
  const float margin = 2.0f * static_cast<float>(side);  // beyond it no column is near the band
  for (std::size_t c = 0, from = 0; c < ends.size() && feet.levels(); from = ends[c++]) {
    if (lo[c].z() >= lowest + static_cast<float>(foot) || lo[c].x() > p_hi.x() + margin ||
        hi[c].x() < p_lo.x() - margin || lo[c].y() > p_hi.y() + margin ||
        hi[c].y() < p_lo.y() - margin)
      continue;
    auto next = std::lower_bound(sorted.begin(), sorted.end(), static_cast<uint32_t>(from));
    for (std::size_t k = from; k < ends[c]; ++k) {
      while (next != sorted.end() && *next < k) ++next;
      if (next == sorted.end() || *next != k)
        feet.addAround(points[order[k]].xyz());  // not its own
    }
  }
  feet.settle();
  std::vector<uint32_t> kept;
  for (const uint32_t k : part)
    if (feet.at(points[order[k]].xyz(), 0, lowest) == Foot::kBody) kept.push_back(k);
  return kept;
}

}  // namespace

// doc/OBJECTS.md rule 4 backwards, the mirror of rule 4 over the scans before a decision: the
// objects the last two decided scans both moved whole are carried back through the held scans,
// nearest first. A held scan's vehicle-sized component that is the object the next scan moved
// or turned whole (half of its points in that object's voxels, as they are or found moved, and
// not smaller than 1 - extent_tolerance of it) is moving, every part but its foot, where it was
// moving by the labels: where it was half a window before and where it is half a window after
// lie more than kMovedDistance apart. A vehicle coming towards the sensor in the run's first
// scans shows only its front, whose place only the scans before saw empty; a vehicle about to
// pull away is moving by the labels' +-0.5 s before it starts. A car whose side comes and goes
// (joined in one scan, a slice of its own in the next) is found by its ends where no centroid
// finds it (doc/OBJECTS.md rule 4 backwards). Only the results change: the memories of later
// decisions (duplicates, persistence, the free space) keep what the scans were decided with, so
// no later scan depends on it (DESIGN §2f).
void LaserPipeline::carryBack() {
  const double tolerance = ConsensusRules{}.extent_tolerance;
  const auto paramsOf = [&](const Held& h) {
    ObjectParams op = p_.object;
    op.min_moving = scaledCount(op.min_moving, h.density);
    return std::make_pair(op, ringReach(op, h.ring_gap));
  };
  const std::size_t n_held = held_results_.size();
  if (n_held < 3) return;
  const float inv = static_cast<float>(1.0 / p_.object.voxel);
  const auto objectOf = [&](const WholeObjects& o, const Eigen::Vector3f& x) {
    return o.voxel.find(cellKeyOf(x.x(), x.y(), x.z(), inv));
  };
  // An object carried back: where it was (world centroids, horizontal) at which scan (index),
  // the nearest first, and its motion per scan when first found.
  struct Track {
    std::deque<std::pair<double, Eigen::Vector2d>> at;
    Eigen::Vector2d velocity = Eigen::Vector2d::Zero();
    bool waited = false;  // it stood in a held scan: the scans before it wait too (below)
    Eigen::Vector2d where(double t) const {  // extrapolated after its last known place
      if (t >= at.back().first) return at.back().second + velocity * (t - at.back().first);
      std::size_t j = 1;
      while (j + 1 < at.size() && at[j].first < t) ++j;
      const auto& [ta, pa] = at[j - 1];
      const auto& [tb, pb] = at[j];
      return tb > ta ? Eigen::Vector2d(pa + (pb - pa) * ((t - ta) / (tb - ta))) : pb;
    }
  };
  std::vector<Track> tracks;
  const auto worldCentroid = [](const Held& h, Eigen::Vector3f c) {
    return Eigen::Vector2d((h.r.pose * c.cast<double>()).head<2>());
  };
  // The objects the scan before the newest moved whole that the newest moved whole too (the same
  // object as rule 4 finds it): one scan's mistake is not carried back.
  std::vector<PointXYZI> next_whole;
  std::vector<uint32_t> next_track;  // per point of next_whole
  std::vector<uint32_t> next_pool;   // per point of next_whole: its pooled pieces (or none)
  {
    Held& a = held_results_[n_held - 2];
    Held& b = held_results_[n_held - 1];
    const ObjectParams op = paramsOf(a).first;
    const auto wholeOf = [&](Held& x) -> const WholeObjects& {
      if (!x.whole_objects) {
        x.whole_objects.emplace();
        x.whole_reach = paramsOf(x).second;
        wholeObjectsOf(x.whole, std::vector<uint8_t>(x.whole.size(), 1), op.voxel, *x.whole_objects,
                       x.whole_reach);
      }
      return *x.whole_objects;
    };
    // A held scan's whole points (indices into x.whole) per object of `o`.
    const auto membersOf = [&](const Held& x, const WholeObjects& o) {
      std::vector<std::vector<uint32_t>> of(o.extent.size());
      for (uint32_t k = 0; k < x.whole.size(); ++k)
        if (const uint32_t* m = objectOf(o, x.whole[k].xyz())) of[*m].push_back(k);
      return of;
    };
    const WholeObjects &oa = wholeOf(a), &ob = wholeOf(b);
    if (oa.empty() || ob.empty()) return;
    // Rule 7 measured the scans before the older one only where it had their half windows: not
    // in a run's first and last H scans, which only the chain from here reaches.
    const bool before_measurable = std::all_of(held_results_.begin(), held_results_.end() - 2,
                                               [](const Held& h) { return h.measurable; });
    std::vector<std::vector<uint32_t>> members = membersOf(a, oa);
    const Eigen::Isometry3d a_to_b = b.world_to_sensor * a.r.pose;
    const double dt = static_cast<double>(b.r.index) - static_cast<double>(a.r.index);
    std::vector<Eigen::Vector3f> q;
    // A seed of two sizes whose ends moved a voxel or less between the two scans, what a box's
    // face is known to ("A slow seed", doc/OBJECTS.md rule 4 backwards): its velocity (per scan,
    // b's frame) over a longer span, from the nearest older held scan, within half a window,
    // where its ends lie more than a voxel from b's, each scan between moving it whole too;
    // nullopt where the span breaks or the newest step `ab` is not that velocity within half of
    // it (a standing object's ends come and go with its rings; a cyclist's move on).
    const auto spanVelocity = [&](std::size_t object_b,
                                  const Eigen::Vector3f& ab) -> std::optional<Eigen::Vector3f> {
      const std::size_t span = std::min<std::size_t>((k_ + 1) / 2, n_held - 1);
      std::vector<Eigen::Vector3f> qc;
      for (std::size_t j = 2; j <= span; ++j) {
        Held& c = held_results_[n_held - 1 - j];
        const std::vector<std::vector<uint32_t>> of = membersOf(c, wholeOf(c));
        const Eigen::Isometry3d c_to_b = b.world_to_sensor * c.r.pose;
        std::optional<WholeMatch> best;
        std::size_t best_n = 0;
        for (const std::vector<uint32_t>& members_c : of) {
          if (members_c.size() <= best_n) continue;
          qc.clear();
          for (const uint32_t k : members_c)
            qc.push_back((c_to_b * c.whole[k].xyz().cast<double>()).cast<float>());
          const std::optional<WholeMatch> mc =
              matchWholeObjectByEnds(qc, ob, op.voxel, kCarryMatch);
          if (mc && mc->object == object_b) {
            best = mc;
            best_n = members_c.size();
          }
        }
        if (!best) return std::nullopt;
        if (best->shift.head<2>().norm() <= op.voxel) continue;
        const Eigen::Vector3f v =
            best->shift / static_cast<float>(double(b.r.index) - double(c.r.index));
        if ((ab - v).head<2>().norm() > 0.5f * v.head<2>().norm()) return std::nullopt;
        return v;
      }
      return std::nullopt;
    };
    for (std::size_t o = 0; o < members.size(); ++o) {
      // Not an object rule 7 measured in the older scan: it measured the half windows around
      // it (the scans before were measured too, where they could be), and its component is not
      // what rule 4 takes on in the next scan (all parts: a standing car's centroid moved 0.6 m
      // with the kerb).
      std::size_t measured = 0;
      for (const uint32_t k : members[o]) measured += a.whole_measured[k];
      if (2 * measured >= members[o].size() && before_measurable) continue;
      q.clear();
      for (const uint32_t k : members[o])
        q.push_back((a_to_b * a.whole[k].xyz().cast<double>()).cast<float>());
      std::optional<WholeMatch> m = matchWholeObjectOrByEnds(q, ob, op.voxel, kCarryMatch);
      if (!m || dt <= 0) continue;
      // The same size in both (horizontal diagonal, within kSeedSize): a step of the centroids
      // between two sizes is what the two components hold, not the object's motion (a car that
      // stands, with the kerb joined in one of the two scans: a "velocity" of 0.9 m a scan).
      // Where they differ, its ends say how far it moved ("Its side comes and goes"): b's place
      // is then a's centroid shifted by them, the same composition in both. Only more than a
      // voxel, what a box's face is known to: a standing truck's side at 16 rings, its ends
      // coming and going with the rings, "moved" 0.07-0.14 m a scan. Under that, over a longer
      // span (spanVelocity): a cyclist at 2 m/s, his side in view every other scan.
      const float ea = oa.extent[o].head<2>().norm(), eb = ob.extent[m->object].head<2>().norm();
      Eigen::Vector3f at_b = ob.centroid[m->object];
      if (std::abs(ea - eb) > kSeedSize * std::max(ea, eb)) {
        if (!m->by_ends) m = matchWholeObjectByEnds(q, ob, op.voxel, kCarryMatch);
        if (!m) continue;
        Eigen::Vector3f shift = m->shift;
        if (shift.head<2>().norm() <= op.voxel) {
          const std::optional<Eigen::Vector3f> v = spanVelocity(m->object, shift);
          if (!v) continue;
          shift = *v * static_cast<float>(dt);
        }
        at_b = std::accumulate(q.begin(), q.end(), Eigen::Vector3f(Eigen::Vector3f::Zero())) /
                   static_cast<float>(q.size()) +
               shift;
      }
      Track t;
      t.at.push_back({double(a.r.index), worldCentroid(a, oa.centroid[o])});
      t.at.push_back({double(b.r.index), worldCentroid(b, at_b)});
      t.velocity = (t.at[1].second - t.at[0].second) / dt;
      for (const uint32_t k : members[o]) {
        next_whole.push_back(a.whole[k]);
        next_track.push_back(static_cast<uint32_t>(tracks.size()));
        next_pool.push_back(UINT32_MAX);
      }
      tracks.push_back(std::move(t));
    }
  }
  // The half window after a held scan, in scans (H, as long as it is held).
  const double half = static_cast<double>((k_ + 1) / 2);
  // A held scan's object that stood by the track known when it was found, or was found after
  // such a scan: its scan (position in held_results_), time, track, whether it counts as
  // carried back, and the candidates it would turn.
  struct Waiting {
    std::size_t at;
    double t;
    uint32_t track;
    bool counted;
    std::vector<uint32_t> turns;
  };
  std::vector<Waiting> waiting;
  // Per held scan, the candidates turned moving: its result is rebuilt once, at the end.
  std::vector<std::vector<uint32_t>> turned_in(n_held);
  Eigen::Isometry3d next_world_to_sensor = held_results_[n_held - 2].world_to_sensor;
  for (std::size_t at = n_held - 2; at-- > 0 && !next_whole.empty();) {
    Held& h = held_results_[at];
    const auto params = paramsOf(h);  // not a structured binding: the lambdas below capture them
    const ObjectParams& op = params.first;
    const RingReach& reach = params.second;
    if (h.ends.empty() && !h.points.empty()) {
      ObjectComponents cc;
      groupObjects(h.points, std::vector<uint8_t>(h.points.size(), 1), op.voxel, cc, reach);
      std::vector<uint32_t> root(h.points.size());
      for (uint32_t k = 0; k < h.points.size(); ++k) root[k] = cc.root_of[cc.point_voxel[k]];
      orderByComponent(root, h.order, h.ends);
      h.summarise();
    }
    WholeObjects next;
    wholeObjectsOf(next_whole, std::vector<uint8_t>(next_whole.size(), 1), op.voxel, next, reach);
    std::vector<uint32_t> track_of(next.extent.size(), UINT32_MAX);  // each object's track
    for (std::size_t k = 0; k < next_whole.size(); ++k)
      if (const uint32_t* o = objectOf(next, next_whole[k].xyz()))
        if (track_of[*o] == UINT32_MAX) track_of[*o] = next_track[k];
    joinPooled(next_whole, next_pool, inv, next, track_of);
    std::vector<uint32_t>& turned = turned_in[at];      // candidate positions turned moving
    std::vector<PointXYZI> next_points;                 // the next scan's objects (its frame)
    next_points.swap(next_whole);                       // next_whole becomes what this scan turned
    std::vector<std::vector<Eigen::Vector3f>> next_of;  // next_points per object, on first use
    next_track.clear();
    next_pool.clear();
    std::vector<Eigen::Vector3f> q;
    // The world point as the test had it (Work::world: the pose times the point), in the next
    // scan's sensor frame.
    const Eigen::Isometry3d to_next = next_world_to_sensor * h.r.pose;
    // The held components that are an object the next scan carried or moved whole.
    struct Found {
      WholeMatch m;
      std::vector<uint32_t> part;  // positions in h.order: its points, or those near the object
      std::vector<std::size_t> pieces;  // its components (more than one where they are pooled)
      Eigen::AlignedBox3f box;          // of its part's points
    };
    std::vector<Found> found;
    std::size_t from = 0;
    for (std::size_t c_at = 0; c_at < h.ends.size(); ++c_at) {
      const std::size_t to = h.ends[c_at];
      const std::size_t n = to - from;
      const Eigen::Vector3f &lo = h.lo[c_at], &hi = h.hi[c_at];
      const Eigen::Vector3f& sum = h.sum[c_at];
      // Only a component that can reach an object: its box and the object's overlap (the one
      // holding half of its points in the other's voxels, a voxel's quantisation aside), or do
      // once shifted by at most kCarryMatch; two points of overlapping boxes lie at most their
      // diagonals apart.
      const auto within_reach = [&] {
        const Eigen::Vector3f c = (to_next * (sum / float(n)).cast<double>()).cast<float>();
        const float own = (hi - lo).head<2>().norm() + static_cast<float>(2 * op.voxel);
        for (std::size_t o = 0; o < next.extent.size(); ++o)
          if ((c - next.centroid[o]).head<2>().norm() <=
              kCarryMatch + own + next.extent[o].head<2>().norm())
            return true;
        return false;
      };
      // One moving in every point (rule 7 found a car before it pulls away) turns nothing but
      // carries the object on to the scan before.
      if (static_cast<int>(n) >= op.min_moving &&
          vehicleSized(lo, hi, op.max_length, op.max_height) && within_reach()) {
        if (h.at_next_done.empty()) {
          h.at_next.resize(h.order.size());
          h.at_next_done.assign(h.ends.size(), 0);
        }
        if (!h.at_next_done[c_at]) {  // the next held scan, hence to_next, is always the same
          for (std::size_t k = from; k < to; ++k)
            h.at_next[k] = (to_next * h.points[h.order[k]].xyz().cast<double>()).cast<float>();
          h.at_next_done[c_at] = 1;
        }
        q.assign(h.at_next.begin() + static_cast<std::ptrdiff_t>(from),
                 h.at_next.begin() + static_cast<std::ptrdiff_t>(to));
        const std::optional<WholeMatch> m =
            matchWholeObjectOrByEnds(q, next, op.voxel, kCarryMatch);
        if (m && track_of[m->object] != UINT32_MAX) {
          // Its points turn whole where it is that object's size; where it is larger (it holds
          // something else too: a car that stood at a kerb, joined with the kerb's stones in one
          // scan), those in the object's voxels and next to them, once shifted, if they are.
          Found f{*m, {}, {c_at}, {}};
          if (sizedAs(hi - lo, next.extent[m->object], tolerance, true, reach.stepAt(lo, hi)))
            for (std::size_t k = from; k < to; ++k) f.part.push_back(static_cast<uint32_t>(k));
          else
            f.part = nearObject(q, from, next, *m, op.voxel);
          for (const uint32_t k : f.part) f.box.extend(h.points[h.order[k]].xyz());
          found.push_back(std::move(f));
        }
      }
      from = to;
    }
    // Its size: the object's, or as wide and as high within kSeedSize and not longer (its side
    // out of view here or in the next scan), or a face of it, or it a face of this (a cyclist's
    // back, its side in view only while farther ahead).
    // A sparse lidar sees a height to a ring step (ringLifted): a part seen one ring shorter
    // than the object is that object (`pedestrian_wall` with an HDL-32E: the walker 0.82 m high
    // in scan 6 against 1.20 m in scan 7, 16 m off, a step 0.37 m), as a face of it is.
    const auto sized = [&](const Eigen::AlignedBox3f& box, const Eigen::Vector3f& x) {
      const Eigen::Vector3f e = ringLifted(box.sizes(), x, reach.stepAt(box.min(), box.max()));
      return sizedAs(e, x, tolerance, true) ||
             (sameFace(e, x) &&
              e.head<2>().norm() * static_cast<float>(1.0 - tolerance) <= x.head<2>().norm()) ||
             faceOf(x, e, op.voxel, tolerance) || faceOf(e, x, op.voxel, tolerance);
    };
    // The object's pieces: the components that are the same object and stacked (their boxes
    // overlap horizontally) are one where together they are its size: a car's rings apart at 16
    // rings, its roof's stripe and its body two components, neither its height. Not side by
    // side: a car and the parked one the next scan joined it with (kitti_city, 956 false
    // positives in scan 0). The pool goes where its first piece is.
    std::vector<std::vector<std::size_t>> of_object(next.extent.size());
    for (std::size_t f = 0; f < found.size(); ++f)
      if (!found[f].part.empty()) of_object[found[f].m.object].push_back(f);
    for (const std::vector<std::size_t>& same : of_object) {
      if (same.size() < 2) continue;
      // A ring of it spans it: as wide as the object's narrower side, within its tolerance (not
      // a piece of the road at a truck's wheels, kitti_highway scan 21, 46 false positives).
      const float width = next.extent[found[same.front()].m.object].head<2>().minCoeff();
      std::vector<std::size_t> rings;
      for (const std::size_t f : same)
        if (found[f].box.sizes().head<2>().maxCoeff() >= (1.0 - tolerance) * width)
          rings.push_back(f);
      if (rings.size() < 2) continue;
      Found pool = found[rings.front()];
      std::vector<std::size_t> taken;  // the pieces pooled after the first
      std::size_t largest = pool.part.size();
      for (std::size_t k = 1; k < rings.size(); ++k) {
        const Found& piece = found[rings[k]];
        const Eigen::AlignedBox3f &a = pool.box, &b = piece.box;
        if ((a.min().head<2>().array() > b.max().head<2>().array()).any() ||
            (b.min().head<2>().array() > a.max().head<2>().array()).any())
          continue;
        if (piece.part.size() > largest) {  // the largest piece's match
          largest = piece.part.size();
          pool.m = piece.m;
        }
        pool.part.insert(pool.part.end(), piece.part.begin(), piece.part.end());
        pool.pieces.push_back(piece.pieces.front());
        pool.box.extend(b);
        taken.push_back(rings[k]);
      }
      // Together its size and no higher: pieces pooled over a slice (a bush's two rings under
      // the one ring a mistaken track held, kitti_residential at 16 rings, 190 false
      // positives) are not it.
      const Eigen::Vector3f x = next.extent[pool.m.object];
      if (taken.empty() || !sized(pool.box, x) ||
          pool.box.sizes().z() * static_cast<float>(1.0 - tolerance) > x.z())
        continue;
      pool.m.by_ends = false;  // its place is its own centroid: the object whole
      for (const std::size_t f : taken) found[f].part.clear();
      found[rings.front()] = std::move(pool);
    }
    for (const Found& f : found) {
      const std::vector<uint32_t>& part = f.part;
      if (part.empty()) continue;
      const WholeMatch& m = f.m;
      // And where it was moving by the labels: more than kMovedDistance between where it was
      // half a window before this scan and where it is half a window after. After its last
      // known place the object goes on at the velocity it was found with; before this scan it
      // stood, unless it moves here (from here to its next known place within half that
      // velocity of it): then it came at that velocity.
      Track& track = tracks[track_of[m.object]];
      // Found by its ends, it is where the object's centroid lies shifted back by them: the
      // composition its track knows (its side in view or not), not this one.
      Eigen::Vector3f c = Eigen::Vector3f::Zero();
      for (const uint32_t k : part) c += h.points[h.order[k]].xyz();
      const double t = static_cast<double>(h.r.index);
      Eigen::Vector2d here =
          m.by_ends ? Eigen::Vector2d((next_world_to_sensor.inverse() *
                                       (next.centroid[m.object] - m.shift).cast<double>())
                                          .head<2>())
                    : worldCentroid(h, c / static_cast<float>(part.size()));
      // What a scan saw of it moves its centroid too: a standing car shows more of itself as
      // the ego comes nearer (parked_leaves at 128 rings, scan 20: 0.26 m, and it went moving
      // 0.5 s before it starts). Where its outline, matched against the object in the next scan,
      // matches in place as well as anywhere (in 1.6 m of outline at least, half of it), it
      // stands within a cell: a centroid step over kCompositionSlack is what the scans saw, and
      // it is where the next scan had it. Not a shift otherwise: the outline's is known to a
      // cell, and its errors would add up along the chain.
      if (!m.by_ends && track.at.front().first == t + 1 &&
          (track.at.front().second - here).norm() > kCompositionSlack) {
        if (next_of.empty()) {
          next_of.resize(next.extent.size());
          for (const PointXYZI& x : next_points)
            if (const uint32_t* o = objectOf(next, x.xyz())) next_of[*o].push_back(x.xyz());
        }
        std::vector<Eigen::Vector3f> mine;
        mine.reserve(part.size());
        for (const uint32_t k : part) mine.push_back(h.at_next[k]);
        const OutlineShift os = outlineShift(mine, next_of[m.object], kShift);
        const auto min_cells = static_cast<std::size_t>(std::ceil(kShiftMinFace / kShift.cell));
        if (os.cells >= min_cells && os.at_rest == os.at_shift && 2 * os.at_rest >= os.cells)
          here = track.at.front().second;
      }
      // Its motion here: to its last known place within half of the half window after it (a
      // longer span steadies a slow walker's jittering centroid; a shorter one keeps a car
      // that starts two scans later standing here).
      std::size_t j = 0;
      while (j + 1 < track.at.size() && track.at[j + 1].first <= t + std::ceil(half / 2)) ++j;
      const auto& [t_next, p_next] = track.at[j];
      // Its velocity from here to there (m a scan), where it is known later.
      const bool ahead = t_next > t;
      const Eigen::Vector2d step =
          ahead ? Eigen::Vector2d((p_next - here) / (t_next - t)) : Eigen::Vector2d::Zero();
      const bool moves_here =
          ahead && (step - track.velocity).norm() <= 0.5 * track.velocity.norm();
      const Eigen::Vector2d before =
          moves_here ? Eigen::Vector2d(here - track.velocity * half) : here;
      const double moved = (track.where(t + half) - before).norm();
      if (!sized(f.box, next.extent[m.object])) continue;
      // Where it stood here by what is known so far, it goes on in the chain and waits, and so
      // do the scans before: whether it came to a stop is told by the whole chain (below).
      const bool stood = moved <= kMovedDistance || track.waited;
      // Deeper than the usual hold (a run's first scans), only an object that moves there goes on:
      // at its track's velocity, or faster than a voxel a scan to its next known place (a car whose
      // track was seeded after it stopped, car_stops_5s). One that stood there, or starts later, is
      // a vehicle yet to start, which the labels call moving at most H scans before it does, within
      // the usual depth; its centroid creeps as the ego drives away (its top and side grazed less),
      // and the chain takes that for a motion: `default` at 2 m/s2, a car standing 14 m behind in
      // scans 0-4 (0.08 m a scan, 4,379 false positives), and with the ego at 1.5 x, the car
      // standing in scan 0 before it drives off (1,092). And only in the first 2K decided, which no
      // chunk owns (DESIGN §2f; K 1 alone reaches past them).
      const bool steps = ahead && step.norm() > op.voxel;
      if (at + holdDepth() < n_held &&
          (!(steps || (moves_here && !stood)) || decided_ - n_held + at >= 2 * k_))
        continue;
      track.waited = stood;
      // Counted where a point of its components was not moving.
      bool all_moving = true;
      for (const std::size_t c_at : f.pieces)
        for (std::size_t k = c_at ? h.ends[c_at - 1] : 0; k < h.ends[c_at] && all_moving; ++k)
          all_moving = h.moving[h.order[k]] != 0;
      if (stood)
        waiting.push_back({at, t, track_of[m.object], !all_moving, {}});
      else
        h.r.stats.objects_carried_back += !all_moving;
      track.at.push_front({t, here});
      std::vector<uint32_t>& turning = stood ? waiting.back().turns : turned;
      // Its foot stays (rule 2): it goes on in the chain, as the objects moved whole keep
      // theirs, but does not turn. Asked only where a point can turn (issue #16: a truck
      // moving in every point is carried on through every held scan).
      bool turns = false;
      for (const uint32_t k : part) {
        const uint32_t i = h.order[k];
        turns = turns || (!h.moving[i] && !h.relabelled[i]);
      }
      const std::vector<uint32_t> body =
          turns ? withoutFoot(part, h.order, h.ends, h.lo, h.hi, h.points, op.voxel, op.foot_height,
                              op.foot_reach, h.ring_gap,
                              static_cast<float>(h.ground_z + op.foot_height))
                : std::vector<uint32_t>{};
      std::vector<uint8_t> in_body(part.size(), 0);
      for (std::size_t a = 0, b = 0; a < part.size() && b < body.size(); ++a)
        if (body[b] == part[a]) {
          in_body[a] = 1;
          ++b;
        }
      for (std::size_t a = 0; a < part.size(); ++a) {
        const uint32_t i = h.order[part[a]];
        if (h.relabelled[i]) continue;  // the camera's decision stands (DESIGN §3)
        next_whole.push_back(h.points[i]);
        next_track.push_back(track_of[m.object]);
        next_pool.push_back(f.pieces.size() > 1 ? static_cast<uint32_t>(&f - found.data())
                                                : UINT32_MAX);
        if (!h.moving[i] && in_body[a]) turning.push_back(i);
      }
    }
    next_world_to_sensor = h.world_to_sensor;
  }
  // A vehicle that came to a stop, by the labels' measure on the whole chain: where it was half
  // a window before a waiting scan (its earliest known place if later; none extrapolated) lies
  // more than kMovedDistance from where it is half a window after (`car_stops_5s`: it stops
  // 18 m ahead, rule 7 measures the scans after, and the scans in which it stood, moving by the
  // labels' +-0.5 s, broke the chain to the scans it drove in).
  for (const Waiting& w : waiting) {
    const Track& track = tracks[w.track];
    const double t_before = std::max(w.t - half, track.at.front().first);
    if ((track.where(w.t + half) - track.where(t_before)).norm() <= kMovedDistance) continue;
    held_results_[w.at].r.stats.objects_carried_back += w.counted;
    turned_in[w.at].insert(turned_in[w.at].end(), w.turns.begin(), w.turns.end());
  }
  for (std::size_t at = 0; at < n_held; ++at) turnInResult(held_results_[at], turned_in[at]);
}

// The result of a held scan as collect() makes it with the candidates `turned` moving.
void LaserPipeline::turnInResult(Held& h, const std::vector<uint32_t>& turned) {
  if (turned.empty()) return;
  ScanResult& r = h.r;
  for (const uint32_t k : turned) {
    h.moving[k] = 1;
    r.labels[h.original[k]] = kMoving;
    if (h.view) h.kind[h.at[k]] = 2;
  }
  std::size_t kept = 0, compact = 0, compact_kept = 0;
  for (std::size_t j = 0; j < r.static_full.size(); ++j) {
    const uint8_t kind = r.static_full_kind[j];
    const bool turns = (kind == kMapStatic || kind == kMapDuplicate) &&
                       r.labels[r.static_full_index[j]] == kMoving;
    if (kind == kMapStatic) {
      if (!turns) r.static_compact[compact_kept++] = r.static_compact[compact];
      ++compact;
    }
    if (turns) {
      r.moving.push_back(r.static_full[j]);
      r.moving_index.push_back(r.static_full_index[j]);
      continue;
    }
    r.static_full[kept] = r.static_full[j];
    r.static_full_index[kept] = r.static_full_index[j];
    r.static_full_kind[kept] = kind;
    ++kept;
  }
  r.static_full.resize(kept);
  r.static_full_index.resize(kept);
  r.static_full_kind.resize(kept);
  r.static_compact.resize(compact_kept);
  r.stats.moving += turned.size();
  r.stats.static_points -= turned.size();
  r.stats.carried_back_points += turned.size();
  if (h.view) r.overlay = vision::drawOverlay(*h.view, h.all_points, r.pose, h.kind);
}

}  // namespace cleanmap
