// SPDX-License-Identifier: BSD-3-Clause
// Object consensus (our addition, doc/OBJECTS.md): the per-point test of DESIGN §2b sees only the
// parts of a vehicle whose space becomes empty in other scans; a long vehicle moving along its
// own length keeps its sides occupied. A rigid object moves as a whole: if enough of a connected,
// vehicle-sized group of non-ground points is moving, all of it is.
#pragma once
#include <cstdint>
#include <vector>

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
  /// Points of a moving component's raised parts (joined to it only below the foot) with no
  /// moving point of their own, not turned moving.
  std::size_t still_part_points_left = 0;
};

/// Whether few moving points are noise (doc/OBJECTS.md rules 2-3): the windowed test's scattered
/// alarms are; the map's removals (DESIGN §2e), each in a voxel the sequence saw empty, are not.
struct ConsensusRules {
  /// Rule 2: a vehicle-sized object with fewer than min_moving moving points is static (as one
  /// with less than static_fraction of its points moving always is); rule 3: so is a connected
  /// group of fewer than min_moving moving points. false: only the share counts, groups stay.
  bool few_points_are_noise = true;
};

/// Groups `points[i]` with `member[i]` (in crop, not ground) into 26-connected voxel components
/// and sets `moving[i]` = 1 for every point of a component that passes the rule of `p`.
/// `near_previous[i]` (optional): point i lies within p.persist_radius of a moving point of the
/// previous scan (world frame); it lets a partly moving object stay moving (hysteresis).
/// `in_moving_object` (optional, per point): set to 1 where the point's component is a
/// vehicle-sized object that moves as a whole (turned moving, or moving in every point).
/// `could_persist` (optional, per point): set to 1 where the point's component was left as it is
/// but rule 4 would take it next to a moving object (vehicle-sized, at least min_moving and
/// static_fraction of its points moving, not all). Deterministic; O(points).
ObjectConsensusStats objectConsensus(const std::vector<PointXYZI>& points,
                                     const std::vector<uint8_t>& member,
                                     std::vector<uint8_t>& moving, const ObjectParams& p,
                                     const std::vector<uint8_t>* near_previous = nullptr,
                                     std::vector<uint8_t>* in_moving_object = nullptr,
                                     const ConsensusRules& rules = {},
                                     std::vector<uint8_t>* could_persist = nullptr);

/// Per point: a member of a vehicle-sized component (as objectConsensus groups them). Under
/// ConsensusRules{few_points_are_noise = false} no other point's decision can change, and
/// objectConsensus on these points alone decides each of them as on the whole set (same
/// components, extents and counts): DESIGN §4b keeps only these. Deterministic; O(points).
std::vector<uint8_t> inVehicleSizedObject(const std::vector<PointXYZI>& points,
                                          const std::vector<uint8_t>& member,
                                          const ObjectParams& p);

/// Rule 4's memory (doc/OBJECTS.md): the cells of side `radius` holding a point of `points`
/// (world frame; only those with `mask[i]` where a mask is given), dilated by one cell.
void persistCells(const std::vector<PointXYZI>& points, const std::vector<uint8_t>* mask,
                  double radius, CellMap<uint8_t>& cells);

/// DESIGN §2e, "Objects": the map's decision made per rigid object. The free space removes a
/// point whose voxel the sequence saw empty; a slow truck's side, occupied in every scan, keeps
/// the part that never left while its ends came and went, and a parked car seen through its
/// windows loses a few points. Scan by scan (in increasing order), the object consensus of the
/// windowed test (doc/OBJECTS.md, rules 1-4) runs on the map's points with the removed ones as
/// its moving points, counting shares only (ConsensusRules): a vehicle-sized object with at
/// least moving_fraction of its points removed goes whole (so does one with static_fraction next
/// to an object the last scan removed whole, rule 4); one with less than static_fraction keeps
/// all its points. Epochs of `epoch` scans start with no memory, as the pipeline's do (§2f).
///
/// Rule 4 both ways: the map is decided with the whole sequence, so an object with
/// static_fraction of its points removed next to an object the *next* scan removed whole goes
/// too (a slow mover whose removed share reaches moving_fraction only after some scans). With
/// record(true) decide() keeps each scan's objects that rule 4 could take and its whole objects'
/// cells; backward() then runs rule 4 from the last scan to the first over them.
class MapObjectConsensus {
 public:
  MapObjectConsensus(const ObjectParams& p, int epoch) : p_(p), epoch_(epoch) {}
  /// Keep what backward() needs from each decide() call (off by default).
  void record(bool on) { record_ = on; }
  /// `points`: a scan's map points (world frame), then from `fixed_from` on its moving points
  /// (the windowed test's: part of the objects, and they stay removed); `member[i]`: not ground;
  /// `removed[i]` on entry the free space's decision (1 for the moving points), on return the
  /// objects'. `density`: the lidar's (min_moving, §2d). Stats: points_added / points_removed
  /// count the map points the objects removed / kept against the free space.
  ObjectConsensusStats decide(int64_t scan, double density, const std::vector<PointXYZI>& points,
                              const std::vector<uint8_t>& member, std::vector<uint8_t>& removed,
                              std::size_t fixed_from);
  /// After the recorded decide() calls, in their order: per call, the indices (into its `points`,
  /// below fixed_from) of the points rule 4 backwards removes in addition to decide()'s. Stats:
  /// points_added, moving_objects, persisted (the same objects).
  std::vector<std::vector<uint32_t>> backward(ObjectConsensusStats* stats = nullptr);

 private:
  // One recorded scan: its whole objects' cells (dilated) and the points of the objects rule 4
  // could take, with their decision and index.
  struct Recorded {
    int64_t scan = 0;
    int min_moving = 1;
    std::vector<uint64_t> whole_cells;
    std::vector<PointXYZI> points;
    std::vector<uint8_t> removed;
    std::vector<uint32_t> index;
  };
  int64_t epochOf(int64_t scan) const { return epoch_ > 0 ? scan / epoch_ : 0; }
  ObjectParams p_;
  int epoch_;
  int64_t epoch_of_last_ = -1;
  CellMap<uint8_t> prev_cells_;  // the last scan's removed cells, dilated
  std::vector<uint8_t> near_, decided_, whole_, could_;
  bool record_ = false;
  std::vector<Recorded> recorded_;
};

}  // namespace cleanmap
