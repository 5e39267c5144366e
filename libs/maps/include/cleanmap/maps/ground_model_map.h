// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §4b: the ground model as an MRPT map plugin (alias `cleanmap_ground`). A 2D grid over the
// world of the ground heights the paper's propagation accepted (§II-B, Eq. 1): inserting a posed
// scan segments its ground (SPEC §2a, cleanmap::segmentGround in the sensor frame) and adds its
// ground points to their world cells. Cells hold sums (sum z, count), so maps of chunks merge
// by addition.
//
// Namespace cleanmap_maps, not cleanmap::maps: MRPT's class macros name `mrpt::` unqualified,
// which inside namespace cleanmap would resolve to our adapter namespace cleanmap::mrpt.
#pragma once
#include <mrpt/maps/CMetricMap.h>
#include <mrpt/maps/TMetricMapInitializer.h>
#include <mrpt/poses/CPose3D.h>

#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <unordered_map>
#include <utility>
#include <vector>

#include "cleanmap/core/params.h"
#include "cleanmap/core/types.h"

namespace cleanmap_maps {

class CGroundModelMap : public mrpt::maps::CMetricMap {
  DEFINE_SERIALIZABLE(CGroundModelMap, cleanmap_maps)

 public:
  /// One world cell: the sums of the ground points that fell in it.
  struct Cell {
    double sum_z = 0;
    uint64_t count = 0;
    double height() const { return sum_z / static_cast<double>(count); }
  };

  struct TInsertionOptions {
    /// Segmentation of each inserted scan (SPEC §2a); `cell` is the map's (creationOpts).
    double step = 0.09;  ///< m; s
    /// m; the sensor origin's height above the ground (h_G = -height); 0 = auto: measured in
    /// each scan, the median of the last 11 measurements (DESIGN §2a)
    double height = 0.0;
    bool point_refine = true;
    int max_gap_cells = 10;
    double extent = 30.0;  ///< m; half side of the square around the sensor that is segmented
    /// Poses from the rawlog's CObservationRobotPose (see CMovingObjectsMap::TInsertionOptions).
    bool use_pose_observations = false;
  };

  CGroundModelMap() = default;
  explicit CGroundModelMap(double cell);

  double cellSize() const { return cell_; }
  std::size_t cellCount() const { return cells_.size(); }
  std::size_t scansInserted() const { return scans_; }
  /// Mean ground height of the cell holding (x, y), if any ground point fell there.
  std::optional<double> height(double x, double y) const;
  /// The cells, sorted by (ix, iy): ((ix, iy), cell).
  std::vector<std::pair<std::pair<int32_t, int32_t>, Cell>> sortedCells() const;
  /// Ground flags (1 = ground) of the last inserted scan, one per point of it (sensor order).
  const std::vector<uint8_t>& lastGroundFlags() const { return last_flags_; }

  /// Native insertion: segments `scan` (sensor frame, `scan.pose` its world pose) and adds its
  /// ground points. Returns the ground flags.
  const std::vector<uint8_t>& insertScan(const cleanmap::Scan& scan);
  /// Adds the points of `scan` flagged in `ground` (e.g. a pipeline's ground labels) without
  /// segmenting again.
  void insertGround(const cleanmap::Scan& scan, const std::vector<uint8_t>& ground);
  /// Adds every cell of `other` (same cell size): the sums commute, so chunked runs merge.
  void merge(const CGroundModelMap& other);

  cleanmap::GroundParams groundParams() const;

  TInsertionOptions insertionOptions;

  // CMetricMap
  bool isEmpty() const override { return cells_.empty(); }
  void saveMetricMapRepresentationToFile(const std::string& prefix) const override;
  void getVisualizationInto(mrpt::opengl::CSetOfObjects& o) const override;
  std::string asString() const override;

  MAP_DEFINITION_START(CGroundModelMap)
  double cell = 0.4;  ///< m; the world grid's cell side, also the segmentation's (SPEC §2a)
  CGroundModelMap::TInsertionOptions insertionOpts;
  MAP_DEFINITION_END(CGroundModelMap)

 private:
  void internal_clear() override;
  bool internal_insertObservation(
      const mrpt::obs::CObservation& obs,
      const std::optional<const mrpt::poses::CPose3D>& robotPose = std::nullopt) override;
  double internal_computeObservationLikelihood(const mrpt::obs::CObservation&,
                                               const mrpt::poses::CPose3D&) const override {
    return 0.0;
  }
  bool internal_canComputeObservationLikelihood(const mrpt::obs::CObservation&) const override {
    return false;
  }

  double cell_ = 0.4;
  std::unordered_map<uint64_t, Cell> cells_;  // key: (ix, iy) packed
  std::size_t scans_ = 0;
  std::vector<uint8_t> last_flags_;
  std::deque<double> recent_ground_;  // the last scans' measured ground heights (height = auto)
  double groundBelowSensor(const cleanmap::Scan& scan);
  std::optional<std::pair<double, mrpt::poses::CPose3D>> pose_obs_;  // use_pose_observations
};

}  // namespace cleanmap_maps
