// SPDX-License-Identifier: BSD-3-Clause
// Object consensus (our addition, doc/OBJECTS.md): the per-point test of DESIGN §2b sees only the
// parts of a vehicle whose space becomes empty in other scans; a long vehicle moving along its
// own length keeps its sides occupied. A rigid object moves as a whole: if enough of a connected,
// vehicle-sized group of non-ground points is moving, all of it is.
#pragma once
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <vector>

#include "cleanmap/core/cell_key.h"
#include "cleanmap/core/cell_map.h"
#include "cleanmap/core/params.h"
#include "cleanmap/core/types.h"

namespace cleanmap {

struct ObjectConsensusStats {
  std::size_t objects = 0;           ///< connected groups of non-ground points
  std::size_t moving_objects = 0;    ///< groups turned moving as a whole
  std::size_t points_added = 0;      ///< points turned moving by the consensus
  std::size_t points_removed = 0;    ///< moving points turned static (a few in a static object)
  std::size_t persisted = 0;         ///< of moving_objects, those kept moving by the hysteresis
  std::size_t body_points_kept = 0;  ///< moving points of a body a static component kept
  std::size_t foot_points_left = 0;  ///< points at a moving component's foot not turned moving
  /// Of foot_points_left, those in a raised part's columns with nothing of it over them
  /// (Overhead): a surface it stands on, the sidewalk around a walker's feet.
  std::size_t surface_points_left = 0;
  /// Points of a moving component's raised parts (joined to it only below the foot) with no
  /// moving point of their own, not turned moving.
  std::size_t still_part_points_left = 0;
  /// Of persisted, objects under static_fraction kept because they left their place
  /// (ConsensusRules::has_left).
  std::size_t left_place = 0;
  std::size_t measured = 0;  ///< of moving_objects, those rule 7 measured moving
  std::size_t far_kept = 0;  ///< objects rule 2's far exception kept moving (far_points)
  /// Components of vehicle extent wider than max_width with at least min_moving and
  /// static_fraction of their points moving, not all: rules 2, 4, 5 and 7 do not move them whole.
  std::size_t wide_objects_left = 0;
};

/// Rule 5's objects of one scan (ConsensusRules::whole_objects): each voxel (ObjectParams::voxel)
/// of an object removed whole -> the object, and per object its extent (hi - lo), centroid and
/// box (lo, hi).
struct WholeObjects {
  CellMap<uint32_t> voxel;
  std::vector<Eigen::Vector3f> extent, centroid, lo, hi;
  bool empty() const { return extent.empty(); }
};

/// A sparse lidar's rings at range lie further apart than the grouping's voxel (doc/OBJECTS.md
/// rule 1): an HDL-32E's (1.33 degrees) are 0.6 m apart at 25 m, a VLP-16's 0.9 m, and a walker
/// falls apart into one slice per ring, each too small for the rules. With `pool` > 0 a slice (a
/// 26-connected component) at most `pool` across (horizontal diagonal) is also joined to those
/// of its 3 x 3 column up to `kRingReach` ring steps above it, a ring step being d x ring_gap at
/// the column's horizontal distance d from `origin` (the sensor, in the points' frame): what lies
/// closer than that, the lidar cannot tell apart. ring_gap 0 (dense lidars, whose rings lie
/// within a voxel) or pool 0 (ObjectParams::ring_pool, the default): 26-connected voxels only.
/// It also says where low surfaces stop linking (rule 1, "Low surfaces"): a structure (more than
/// `max_length` across or `max_height` high) joined only through voxels less than `foot` above
/// the lowest member of their 3 x 3 column falls apart into what stands on them (0: it does not).
struct RingReach {
  double ring_gap = 0;  ///< rad between rings (WindowScan::ring_gap, ScanResult::ring_gap)
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();
  double pool = 0;        ///< m
  double foot = 0;        ///< m (ObjectParams::foot_height)
  double max_length = 0;  ///< m (ObjectParams::max_length)
  double max_height = 0;  ///< m (ObjectParams::max_height)
  double wall_gap = 0;    ///< m (ObjectParams::wall_gap)
  bool active() const { return ring_gap > 0 && pool > 0; }
  /// A ring step (m) at `at` (the points' frame): its horizontal distance from origin x ring_gap.
  double stepAt(const Eigen::Vector2d& at) const { return ring_gap * (at - origin).norm(); }
  /// ... at the centre of the box lo .. hi, in float as the rules' extents (sizedAs, ringLifted).
  float stepAt(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi) const {
    return static_cast<float>(ring_gap) *
           ((0.5f * (lo + hi)).head<2>() - origin.cast<float>()).norm();
  }
  bool operator==(const RingReach& o) const {
    return ring_gap == o.ring_gap && origin == o.origin && pool == o.pool && foot == o.foot &&
           max_length == o.max_length && max_height == o.max_height && wall_gap == o.wall_gap;
  }
};
/// A scan's reach under `p` (its ring_pool): `ring_gap` of the scan's lidar (0: dense), `origin`
/// its sensor in the points' frame.
inline RingReach ringReach(const ObjectParams& p, double ring_gap,
                           const Eigen::Vector2d& origin = Eigen::Vector2d::Zero()) {
  return {ring_gap, origin, p.ring_pool, p.foot_height, p.max_length, p.max_height, p.wall_gap};
}
constexpr double kRingReach = 1.25;  ///< ring steps (uneven spacing and the voxel's rounding)

/// Whether few moving points are noise (doc/OBJECTS.md rules 2-3): the windowed test's scattered
/// alarms are; the map's removals (DESIGN §2e), each in a voxel the sequence saw empty, are not.
struct ConsensusRules {
  /// Rule 2: a vehicle-sized object with fewer than min_moving moving points is static (as one
  /// with less than static_fraction of its points moving always is); rule 3: so is a connected
  /// group of fewer than min_moving moving points. false: only the share counts, groups stay.
  bool few_points_are_noise = true;
  /// Rule 5 (the map's, DESIGN §2e "Objects"): the objects the adjacent scan removed whole. A
  /// vehicle-sized object with at least min_moving points and at least `overlap_fraction` of
  /// them in the voxels of one of them, as they are or moved by the difference of the two's
  /// centroids (at most `max_shift`: a car that kept its distance to the sensor moved that far
  /// and shows the same faces), its extents (horizontal diagonal, height) within
  /// `extent_tolerance` of that one's, is that object a scan earlier or later and goes whole (two
  /// solids do not share their space; the size keeps one that touched another, and was removed
  /// with it, from taking that other's place).
  const WholeObjects* whole_objects = nullptr;
  double overlap_fraction = 0.5;
  double extent_tolerance = 0.3;
  double max_shift = 3.0;  ///< m: 30 m/s between two scans at 10 Hz
  /// How the points' voxels join (a sparse lidar's rings; groupObjects); a `grouped` given to
  /// objectConsensus must have been made with the same.
  RingReach reach;
  /// Rule 4 under static_fraction (doc/OBJECTS.md): a vehicle-sized object not all moving that
  /// the rules above leave static (under static_fraction or min_moving of its points moving, or
  /// none), at least half of its points near the previous scan's moving points, moves as a whole,
  /// all of its parts, if has_left(its points' indices) says it is the object the previous scan
  /// moved whole (where it was, or moved by less than half a car's width) and the scans after it
  /// see it leave (at least min_moving of its moving points, or half of all its points for the
  /// far half of them) or are too few to see that. Empty: such an object is static.
  std::function<bool(const std::vector<uint32_t>&)> has_left;
  /// Rule 2, "The previous scan's object" (doc/OBJECTS.md): a component rule 2 turns moving, at
  /// least half of its points near the previous scan's moving points, goes with all of its parts
  /// (those above its foot with no moving point of their own too) if was_whole(its points'
  /// indices) says it is the object the previous scan moved whole (in its voxels or moved, not
  /// smaller). Empty: such parts keep their labels.
  std::function<bool(const std::vector<uint32_t>&)> was_whole;
  /// Rule 7 (doc/OBJECTS.md, "Measured"): a vehicle-sized object not all moving that the rules
  /// above leave moving in none of its points or too few, of at least `measured_points` points,
  /// moves as a whole, all of its parts, if measured(its points' indices) says its outline moved
  /// (the caller's measure). Empty: no such rule.
  std::function<bool(const std::vector<uint32_t>&)> measured;
  std::size_t measured_points = 100;
  /// Rule 2's far exception (ObjectParams::far_points; the points in the sensor frame): the
  /// scan's window reaches half of K on both sides. false: no such exception.
  bool far_window = false;
  /// Rule 2's foot, "What it stands on" (Overhead, ObjectParams::foot_reach): only points below
  /// this height (the points' frame) may be what an object stands on; the pipeline gives the
  /// road's level under the sensor plus foot_height. -infinity (the map's objects, whose frame
  /// gives no road level): none, the columns alone decide.
  float stand_top = -std::numeric_limits<float>::infinity();
};

/// Rule 2's foot, "What it stands on" (doc/OBJECTS.md): whether a point of an object's foot band
/// is what it stands on: below `stand_top` (ConsensusRules::stand_top) with no point of the object
/// kRise to gap higher within about `reach` horizontally (ObjectParams::foot_reach), gap being
/// `foot` (ObjectParams::foot_height) or 1.5 ring steps at the point's range where more
/// (`ring_gap`, rad; 0: a dense lidar). A walker's shoe and a car's lowest ring have their faces
/// over them; the sidewalk around the walker's feet and the road under a truck's chassis that
/// ground removal left do not. Points are added per object (`object`: any tag; tags 2^21 apart
/// share cells) with `base`, the object's lowest height; the frame's z is up. Inactive (reach 0,
/// or stand_top not finite): nothing is what an object stands on.
class Overhead {
 public:
  static constexpr float kRise = 0.05f;  ///< m
  static constexpr float kCell = 0.05f;  ///< m: the cells, and the slices of height
  Overhead(double reach, double foot, double ring_gap, float stand_top)
      : reach_(static_cast<int>(std::ceil(reach / kCell - 1e-6))),
        foot_(foot),
        ring_gap_(ring_gap),
        stand_top_(stand_top),
        active_(reach > 0 && std::isfinite(stand_top)) {}
  /// Keeps x only where it may lie over a point that may be what the object stands on.
  void add(const Eigen::Vector3f& x, uint32_t object, float base) {
    if (!active_ || !(base < stand_top_) || !(x.z() < base + foot_ + gapAt(x) + kCell)) return;
    const int s = static_cast<int>(std::floor((x.z() - base) / kCell));
    if (s >= 0 && s < 32) slices_.get(key(x, object, 0, 0)) |= 1u << s;
  }
  /// x, a point of the foot band of `object` (lowest at `base`), is what it stands on.
  bool standsOn(const Eigen::Vector3f& x, uint32_t object, float base) const {
    return active_ && x.z() < stand_top_ && !over(x, object, base, gapAt(x));
  }

 private:
  float gapAt(const Eigen::Vector3f& x) const {
    return ring_gap_ > 0 ? static_cast<float>(std::max(foot_, 1.5 * x.head<2>().norm() * ring_gap_))
                         : static_cast<float>(foot_);
  }
  // Whether a point of `object` lies kRise to `gap` over x in the cells some part of which lies
  // within reach of x's cell.
  bool over(const Eigen::Vector3f& x, uint32_t object, float base, float gap) const;
  static uint64_t key(const Eigen::Vector3f& x, uint32_t object, int dx, int dy) {
    return cellKey(floorToCell(x.x(), 1 / kCell) + dx, floorToCell(x.y(), 1 / kCell) + dy,
                   static_cast<int64_t>(object));
  }
  int reach_;  // cells
  double foot_, ring_gap_;
  float stand_top_;
  bool active_;
  CellMap<uint32_t> slices_;  // per (cell, object): the slices holding a point
};

/// Rule 2's foot (doc/OBJECTS.md): which points of an object's foot band, those less than `foot`
/// (ObjectParams::foot_height) over its lowest (`base`), belong to it. A band point with no raised
/// point (at or above base + foot) of its object in its 3 x 3 column of voxels of side `side` is a
/// low surface the object touches (from 0.8 m, a sidewalk 0.12 m up); so is one it stands on
/// (Overhead), and one level with the surface around it (kLevel; where Overhead applies). A
/// vehicle's wheels and sills have its body over them. Points are added per object (`object`: any
/// tag, as Overhead's), then the scan's points around the objects (addAround), then settle(),
/// every one before the first at().
class Foot {
 public:
  enum Kind : uint8_t {
    kBody = 0,     ///< not in the foot band, or in it under the object: a part of it
    kTouched = 1,  ///< in the band with no raised point in its column
    kStoodOn = 2,  ///< in the band under a raised column, but what the object stands on
    /// in the band under the object, but level with the surface the scan shows around it (the
    /// sidewalk in front of a walker's shoes, which his face reaches over; doc/OBJECTS.md rule
    /// 2, "Level with the surface around it")
    kLevel = 3,
  };
  /// m; kLevel: within this height of the surface around it (rule 6's least rise over the road,
  /// MoverFeetParams::rise)
  static constexpr float kLevelBand = 0.03f;
  static constexpr std::size_t kLevelColumns = 3;  ///< kLevel: columns showing that surface
  Foot(double side, double foot, double reach, double ring_gap, float stand_top)
      : inv_(static_cast<float>(1.0 / side)),
        foot_(foot),
        stand_top_(stand_top),
        levels_(reach > 0 && std::isfinite(stand_top)),
        overhead_(reach, foot, ring_gap, stand_top) {}
  /// Whether height z lies in the foot band of an object whose lowest is at base.
  bool low(float z, float base) const { return foot_ > 0 && z < base + foot_; }
  /// A point of `object`; a raised one marks its column only where `raises` (objectConsensus: a
  /// part the spread reaches).
  void add(const Eigen::Vector3f& x, uint32_t object, float base, bool raises = true);
  /// A point of the scan in none of the objects: a sample of the surface around them where it
  /// lies in the 3 x 3 column of an object's band point.
  void addAround(const Eigen::Vector3f& x);
  void settle();                           ///< after the last add() and addAround()
  bool levels() const { return levels_; }  ///< whether kLevel may be found (as Overhead)
  Kind at(const Eigen::Vector3f& x, uint32_t object, float base) const;

 private:
  // The tag of the columns around the objects (band_, near_band_, around_: apart from raised_).
  static constexpr uint32_t kAround = 0;
  uint64_t column(const Eigen::Vector3f& x, uint32_t object, int dx, int dy) const {
    return cellKey(floorToCell(x.x(), inv_) + dx, floorToCell(x.y(), inv_) + dy,
                   static_cast<int64_t>(object));
  }
  bool level(const Eigen::Vector3f& x, float base) const;
  float inv_;
  double foot_;
  float stand_top_;
  bool levels_;              // kLevel as Overhead: reach > 0, stand_top finite
  CellMap<uint8_t> raised_;  // (column, object) holding a raised point
  Overhead overhead_;
  CellMap<uint8_t> band_;       // columns holding a band point (tag kAround)
  CellMap<uint8_t> near_band_;  // columns in the 3 x 3 column of a band point (tag kAround)
  std::vector<std::pair<uint64_t, float>> around_;  // (column, height) of addAround's samples
};

/// The 26-connected components of a set of member points' voxels (and those a sparse lidar's rings
/// join, RingReach): objectConsensus's grouping, which depends only on the points, the members,
/// the voxel side and the reach. groupObjects() computes it
/// apart, so that a caller can group the next scan's points while this one is decided (issue
/// #16: the map's decision per object, DESIGN §2e).
struct ObjectComponents {
  double side = 0;  ///< the voxel side it was computed with
  RingReach reach;  ///< and the rings' reach
  /// per voxel: its slice may join others across rings (RingReach); empty where none may
  std::vector<uint8_t> pooled;
  CellMap<uint32_t> voxel_of;           ///< voxel key -> voxel
  std::vector<Eigen::Vector3i> voxels;  ///< per voxel: its cell
  /// per point: its voxel (or, for a body's return in a wall's voxel, the body's voxel beside
  /// it: doc/OBJECTS.md rule 1, "Beside a wall"); UINT32_MAX: not a member
  std::vector<uint32_t> point_voxel;
  std::vector<uint32_t> root_of;  ///< per voxel: its component's root, its smallest voxel
  /// per voxel: its component is a piece of a structure that low surfaces joined (RingReach),
  /// or a body parted from the wall it stands against (RingReach::wall_gap); empty where none
  /// is. Rule 2 may turn such a piece moving, not static (doc/OBJECTS.md).
  std::vector<uint8_t> piece;
  /// Coarse columns (doc/OBJECTS.md rule 1): per voxel v, the voxels after it that column links
  /// join to it, across[across_start[v] .. across_start[v + 1]); both empty where none were given.
  std::vector<uint32_t> across_start, across;
};

/// Fills `out` (its buffers reused) with the components of the points with `member[i]`, in
/// voxels of side `side`. `column_links` (optional): pairs of point indices, flat
/// (GrazingStretches::links), whose members' voxels also join (coarse columns, doc/OBJECTS.md
/// rule 1); the low surfaces' split keeps them. `cap_links`: they join no more than a vehicle's
/// size (reach.max_length, max_height), as where they were found in a dense lidar's own columns
/// (GrazingStretches::fineLinks). A structure falls apart at low surfaces (reach.foot), and a
/// body standing against a wall (or a stretch of one of a vehicle's size) is parted from it with
/// its returns in the wall's voxels (reach.wall_gap, doc/OBJECTS.md rule 1, "Beside a wall").
/// Deterministic; O(points).
void groupObjects(const std::vector<PointXYZI>& points, const std::vector<uint8_t>& member,
                  double side, ObjectComponents& out, const RingReach& reach = {},
                  const std::vector<uint32_t>* column_links = nullptr, bool cap_links = false);

/// Rule 2's width (doc/OBJECTS.md): per voxel, at its component's root (0 elsewhere), the spread
/// of the component's voxels across their main horizontal axis, as the width of a uniform strip
/// of that variance (sqrt(12 lambda_min), metres): about 2.5 m for a truck seen from any side,
/// 9 m for a hedge's corner 12 x 14 m. Only its voxels from ceil(foot / side) layers above its
/// lowest count (all where it has none there): not the sidewalk a car touches.
std::vector<float> componentWidths(const ObjectComponents& cc, double foot);

/// The most voxels above a voxel that the ring reach spans (forEachRingAbove).
constexpr int kMaxReachVoxels = 8;
/// The geometry alone: f(voxel) for each voxel of v's 3 x 3 column 2 to the reach's voxels above
/// it (cc.reach's ring step at the column's distance; at most kMaxReachVoxels), pooled or not.
/// The wall split joins a sparse lidar's groups in front of a plane with it (doc/OBJECTS.md rule
/// 1).
template <class F>
void forEachRingAbove(const ObjectComponents& cc, uint32_t v, F&& f) {
  const Eigen::Vector3i& c = cc.voxels[v];
  const Eigen::Vector2d at((c.x() + 0.5) * cc.side, (c.y() + 0.5) * cc.side);
  const double up = std::ceil(kRingReach * cc.reach.stepAt(at) / cc.side);
  const int top = static_cast<int>(std::min<double>(kMaxReachVoxels, up));
  for (int dz = 2; dz <= top; ++dz)
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        if (const uint32_t* n = cc.voxel_of.find(cellKey(c.x() + dx, c.y() + dy, c.z() + dz)))
          f(*n);
}
/// Calls f(voxel) for the voxels of `cc` that voxel v's slice joins across rings (RingReach):
/// where both are pooled, forEachRingAbove's. Visiting every voxel meets each such pair once.
template <class F>
void forEachAcrossRings(const ObjectComponents& cc, uint32_t v, F&& f) {
  if (cc.pooled.empty() || !cc.pooled[v]) return;
  forEachRingAbove(cc, v, [&](uint32_t n) {
    if (cc.pooled[n]) f(n);
  });
}

/// Calls f(voxel) for the voxels of `cc` linked to voxel v and coming after it: its forward
/// 26-neighbours (forEachNeighbour13), those forEachAcrossRings gives and those column links
/// join (`cc.across`). Visiting every voxel meets each linked pair once.
template <class F>
void forEachLinked(const ObjectComponents& cc, uint32_t v, F&& f) {
  const Eigen::Vector3i& c = cc.voxels[v];
  forEachNeighbour13([&](int dx, int dy, int dz) {
    if (const uint32_t* n = cc.voxel_of.find(cellKey(c.x() + dx, c.y() + dy, c.z() + dz))) f(*n);
  });
  forEachAcrossRings(cc, v, f);
  if (!cc.across_start.empty())
    for (uint32_t j = cc.across_start[v]; j < cc.across_start[v + 1]; ++j) f(cc.across[j]);
}

/// Groups `points[i]` with `member[i]` (in crop, not ground) into 26-connected voxel components
/// and sets `moving[i]` = 1 for every point of a component that passes the rule of `p`.
/// `grouped` (optional): groupObjects() of the same points and members with side p.voxel, which
/// is then not computed again (the same decisions); one of another size or side is an
/// std::invalid_argument.
/// `near_previous[i]` (optional): point i lies within p.persist_radius of a moving point of the
/// previous scan (world frame); it lets a partly moving object stay moving (hysteresis).
/// `in_moving_object` (optional, per point): set to 1 where the point's component is a
/// vehicle-sized object that moves as a whole (turned moving, or moving in every point).
/// Deterministic; O(points).
ObjectConsensusStats objectConsensus(const std::vector<PointXYZI>& points,
                                     const std::vector<uint8_t>& member,
                                     std::vector<uint8_t>& moving, const ObjectParams& p,
                                     const std::vector<uint8_t>* near_previous = nullptr,
                                     std::vector<uint8_t>* in_moving_object = nullptr,
                                     const ConsensusRules& rules = {},
                                     const ObjectComponents* grouped = nullptr);

/// Rule 5's objects (ConsensusRules::whole_objects): the components (groupObjects) of the points
/// with `mask[i]`, in voxels of side `side`, with their extents and centroids.
void wholeObjectsOf(const std::vector<PointXYZI>& points, const std::vector<uint8_t>& mask,
                    double side, WholeObjects& out, const RingReach& reach = {});

/// Rules 1-2 apply to an object whose points span lo..hi if its horizontal extent is at most
/// `max_length` and its height at most `max_height`; a larger one is a structure.
bool vehicleSized(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, double max_length,
                  double max_height);

/// Rule 4's "the same object" (doc/OBJECTS.md): the object of `objects` (voxels of side `side`)
/// holding at least half of `q` (an object's points in the frame of `objects`) as they are, the
/// one holding most of them; or, failing that, *found moved*: the first object whose centroid
/// lies within `max_shift` of theirs holding half of them shifted by the difference, or by its
/// horizontal part alone (a sparse lidar's rings: a stripe joined in one scan and not the other
/// moves the centroid up or down, not the vehicle). `object` is its index, `shift` the shift that
/// found it (zero as they are), `by_ends` whether matchWholeObjectByEnds found it; nullopt: none.
struct WholeMatch {
  std::size_t object = 0;
  Eigen::Vector3f shift = Eigen::Vector3f::Zero();
  bool by_ends = false;
};
std::optional<WholeMatch> matchWholeObject(const std::vector<Eigen::Vector3f>& q,
                                           const WholeObjects& objects, double side,
                                           float max_shift);
/// Rule 4 "by its ends", "Its side comes and goes" (doc/OBJECTS.md): the first object of
/// `objects` holding half of `q` shifted level so that one end of their boxes meets the object's,
/// in x and in y (lower or upper faces, four pairings), the shift within `max_shift`. A car seen
/// from behind at an angle has its side, grazing, joined in one scan and a slice of its own in
/// the next: the centroids step by half the side, the near end moves with the car. nullopt: none
/// (or the objects' boxes not given).
std::optional<WholeMatch> matchWholeObjectByEnds(const std::vector<Eigen::Vector3f>& q,
                                                 const WholeObjects& objects, double side,
                                                 float max_shift);
/// Rule 4's match both ways (forward and backwards): matchWholeObject, and where it finds none,
/// matchWholeObjectByEnds (`by_ends` set).
std::optional<WholeMatch> matchWholeObjectOrByEnds(const std::vector<Eigen::Vector3f>& q,
                                                   const WholeObjects& objects, double side,
                                                   float max_shift);

/// Rule 4's "not smaller than 1 - tolerance of it" (doc/OBJECTS.md; horizontal diagonal, height)
/// of an extent `e` against an object's extent `x`, and with `at_most`, not larger than
/// x / (1 - tolerance) across. `step`: a sparse lidar's ring gap at e's range (m; 0 for dense
/// lidars), e's height taken as ringLifted.
bool sizedAs(const Eigen::Vector3f& e, const Eigen::Vector3f& x, double tolerance, bool at_most,
             float step = 0.0f);
/// A sparse lidar sees a height to a ring step (doc/OBJECTS.md rule 4, "A ring step"): its rings
/// slide over a body from scan to scan, so a part on two rings or more (at least half a `step`
/// high) counts up to one step higher, not over x's height. A slice of one ring has no height to
/// compare (a kerb's ring and a car's are alike): as it is.
Eigen::Vector3f ringLifted(Eigen::Vector3f e, const Eigen::Vector3f& x, float step);

/// Per point: a member of a vehicle-sized component (as objectConsensus groups them). Under
/// ConsensusRules{few_points_are_noise = false} no other point's decision can change, and
/// objectConsensus on these points alone decides each of them as on the whole set (same
/// components, extents and counts): DESIGN §4b keeps only these. Deterministic; O(points).
std::vector<uint8_t> inVehicleSizedObject(const std::vector<PointXYZI>& points,
                                          const std::vector<uint8_t>& member, const ObjectParams& p,
                                          const RingReach& reach = {});

/// Rule 4's memory (doc/OBJECTS.md): the cells of side `radius` holding a point of `points`
/// (world frame; only those with `mask[i]` where a mask is given), dilated by one cell.
void persistCells(const std::vector<PointXYZI>& points, const std::vector<uint8_t>* mask,
                  double radius, CellMap<uint8_t>& cells);

/// Rule 5's share as the map applies it (static_map.object_overlap): under the `moving` policy a
/// car that stops stays where it stood when it was last removed whole, and rule 5 would take it
/// through every scan it stands in; only `transient` removes what stood, so only it applies rule 5.
inline double mapObjectOverlap(const MapParams& m) {
  return m.policy == MapPolicy::kTransient ? m.object_overlap : 0.0;
}

/// DESIGN §2e, "Objects": the map's decision per rigid object. The free space removes a point
/// whose voxel the sequence saw empty; a slow truck's side, occupied in every scan, keeps the
/// part that never left while its ends came and went, and a parked car seen through its windows
/// loses a few points. Scan by scan (in increasing order), the object consensus of the windowed
/// test (doc/OBJECTS.md, rules 1-4) runs on the map's points with the removed ones as its moving
/// points, counting shares only (ConsensusRules): a vehicle-sized object with at least
/// moving_fraction of its points removed goes whole (so does one with static_fraction next to an
/// object the last scan removed whole, rule 4, and one that stands where an object of its size
/// that the last scan removed whole stood, rule 5); one with less than static_fraction keeps all
/// its points. Epochs of `epoch` scans start with no memory, as the pipeline's do (§2f).
///
/// Both ways in time: the map is decided with the whole sequence, so rules 4 and 5 also look at
/// the *next* scan's whole objects (a slow mover whose removed share reaches moving_fraction only
/// after some scans): decideBackward() over the scans in decreasing order, after decide().
class MapObjectConsensus {
 public:
  /// `overlap`: rule 5's share (static_map.object_overlap; 0: off).
  MapObjectConsensus(const ObjectParams& p, int epoch, double overlap = 0)
      : p_(p), epoch_(epoch), overlap_(overlap) {}
  /// `points`: a scan's map points (world frame), then from `fixed_from` on its moving points
  /// (the windowed test's: part of the objects, and they stay removed); `member[i]`: not ground;
  /// `removed[i]` on entry the free space's decision (1 for the moving points), on return the
  /// objects'. `density`: the lidar's (min_moving, §2d); `reach`: its rings' (the sensor's
  /// position in the world frame). Stats: points_added / points_removed count the map points the
  /// objects removed / kept against the free space. `grouped` (optional): group() of the same
  /// points, members and reach.
  ObjectConsensusStats decide(int64_t scan, double density, const RingReach& reach,
                              const std::vector<PointXYZI>& points,
                              const std::vector<uint8_t>& member, std::vector<uint8_t>& removed,
                              std::size_t fixed_from, const ObjectComponents* grouped = nullptr) {
    return run(forward_, false, scan, density, reach, points, member, removed, fixed_from, grouped);
  }
  /// Rules 4 and 5 with the next scan's whole objects: after decide() of every scan, the same
  /// scans in decreasing order, each with the points decide() had and the `removed` it returned;
  /// adds removals, never takes one back. Stats: points_added (map points), moving_objects,
  /// persisted.
  ObjectConsensusStats decideBackward(int64_t scan, double density, const RingReach& reach,
                                      const std::vector<PointXYZI>& points,
                                      const std::vector<uint8_t>& member,
                                      std::vector<uint8_t>& removed, std::size_t fixed_from,
                                      const ObjectComponents* grouped = nullptr) {
    return run(backward_, true, scan, density, reach, points, member, removed, fixed_from, grouped);
  }
  /// The objects' grouping of a scan's points for decide() / decideBackward(): it reads only the
  /// parameters, so one thread may group the next scan while another decides this one.
  void group(const std::vector<PointXYZI>& points, const std::vector<uint8_t>& member,
             const RingReach& reach, ObjectComponents& out) const {
    if (p_.enabled) groupObjects(points, member, p_.voxel, out, reach);
  }
  /// Whether decide()'s last scan had whole objects. decideBackward() of a scan without them,
  /// while backwardMemory() is false, changes nothing: skipBackward() stands for it.
  bool hadWholeObjects() const { return has(forward_); }
  bool backwardMemory() const { return has(backward_); }
  void skipBackward(int64_t scan) { backward_.epoch = epochOf(scan); }

 private:
  // Rule 4's cells (side persist_radius, dilated) and rule 5's objects of the last scan decided
  // in one direction.
  struct Memory {
    int64_t epoch = -1;
    CellMap<uint8_t> cells;
    WholeObjects objects;
  };
  static bool has(const Memory& m) { return !m.cells.empty() || !m.objects.empty(); }
  ObjectConsensusStats run(Memory& m, bool backward, int64_t scan, double density,
                           const RingReach& reach, const std::vector<PointXYZI>& points,
                           const std::vector<uint8_t>& member, std::vector<uint8_t>& removed,
                           std::size_t fixed_from, const ObjectComponents* grouped);
  int64_t epochOf(int64_t scan) const { return epoch_ > 0 ? scan / epoch_ : 0; }
  ObjectParams p_;
  int epoch_;
  double overlap_;
  Memory forward_, backward_;
  std::vector<uint8_t> near_, decided_, whole_;
};

}  // namespace cleanmap
