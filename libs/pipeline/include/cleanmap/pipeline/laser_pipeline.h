// SPDX-License-Identifier: BSD-3-Clause
// SPEC §2: the laser pipeline over a stream of posed scans, with a delay of K scans and memory
// bounded by the window (2K + 1 scans), not by the sequence.
#pragma once
#include <deque>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <unordered_set>
#include <vector>

#include "cleanmap/core/beam_index.h"
#include "cleanmap/core/duplicate_filter.h"
#include "cleanmap/core/moving_test.h"
#include "cleanmap/core/params.h"
#include "cleanmap/core/types.h"

namespace cleanmap {

/// Per-stage wall time of one scan, milliseconds.
struct StageTimes {
  double index = 0, ground = 0, duplicates = 0, octree = 0, classify = 0, objects = 0, total = 0;
  StageTimes& operator+=(const StageTimes& o);
};

struct ScanStats {
  std::size_t points = 0;         ///< original points (invalid included)
  std::size_t invalid = 0;        ///< NaN / inf, dropped on reading
  std::size_t in_crop = 0, ground = 0, duplicates = 0, candidates = 0, tested = 0;
  std::size_t moving = 0, static_points = 0;
  std::size_t window = 0;         ///< scans in the window
  std::size_t total_conflicts = 0, no_evidence = 0;
  std::size_t conflicting_scans = 0;  ///< empty scan votes made unknown (doc/SCAN_CONFLICT.md)
  std::size_t objects_moving = 0, consensus_points = 0, consensus_removed = 0;  ///< doc/OBJECTS.md
  std::size_t objects_persisted = 0;  ///< of objects_moving, kept moving by the hysteresis
  bool empty = false;
  StageTimes ms;
};

/// Everything the pipeline says about one scan, handed to the sink once the scan is decided.
struct ScanResult {
  std::size_t index = 0;
  std::string stem;
  double timestamp = 0;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  Labels labels;  ///< one per original point, original order (SPEC §4)
  std::vector<PointXYZI> static_compact;  ///< world frame: static points not already in the map
  std::vector<PointXYZI> static_full;     ///< world frame: every static point (ground included)
  std::vector<PointXYZI> moving;          ///< world frame
  ScanStats stats;
};

class LaserPipeline {
 public:
  using Sink = std::function<void(ScanResult&&)>;
  LaserPipeline(const PipelineParams& params, Sink sink);
  ~LaserPipeline();

  /// Adds the next scan (it must have a pose). Scans are decided K scans later.
  void push(Frame&& frame);
  /// Decides the remaining scans (windows shrink at the end).
  void finish();

  std::size_t decided() const { return decided_; }

 private:
  struct Prepared;
  std::unique_ptr<Prepared> prepare(Frame&& f);
  void decide(std::size_t pos);
  void decideReady(std::size_t future);
  uint64_t persistCell(const Eigen::Vector3d& w) const;

  PipelineParams p_;
  Sink sink_;
  MovingTest test_;
  DuplicateFilter dup_;
  std::deque<std::unique_ptr<Prepared>> buf_;  // scans k-K .. k+K around the next to decide
  std::size_t next_ = 0;                       // position in buf_ of the next scan to decide
  std::size_t decided_ = 0;
  long prev_index_ = -1;
  std::unordered_set<uint64_t> prev_moving_cells_;  // last decided scan's moving cells, dilated
};

}  // namespace cleanmap
