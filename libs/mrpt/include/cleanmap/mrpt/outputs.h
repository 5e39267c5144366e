// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §4a: the outputs for MRPT users, written beside the PLY/PCD maps of a run —
// static_map.3Dscene (SceneViewer3D), static_map.simplemap, cleaned.rawlog, labelled.rawlog.
// Public header free of MRPT includes.
#pragma once
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "cleanmap/core/scan_result.h"

namespace cleanmap::mrpt {

struct MrptOutputOptions {
  /// cleaned.rawlog, labelled.rawlog and static_map.simplemap (every scan's points).
  bool rawlogs = true;
  /// static_map.3Dscene: the static map, the moving points and the trajectory.
  bool scene = true;
  /// m. The scene shows one static (and one moving) point per voxel of this side, so a long drive
  /// stays viewable; every file other than the scene keeps every point.
  double viewer_voxel = 0.10;
  /// Of the rawlogs and the simplemap: 0 writes them plain (MRPT reads both), 1 (fastest) .. 9
  /// (best) gzip them: level 1 took 81 ms per 64-ring scan against 18 ms plain (DESIGN §4a).
  int gzip_level = 0;
  /// Write on a thread of its own (one scan queued at most besides the one being written), so the
  /// work overlaps the pipeline's single-threaded stages. Output bytes do not depend on it.
  bool background = true;
  /// The caller hands the cleaned map's decision of every scan (writeMapScan, in the order the
  /// scans were written; the app does it from io::OutputWriter::writeMaps): cleaned.rawlog, the
  /// simplemap and the scene's static map then hold what static_map_full.ply holds, and the
  /// cleaned scans wait in a spool in `folder` until then. Off: they hold every point the
  /// windowed labels do not call moving, written as the scans come.
  bool map_decisions = false;
};

/// Colour of a label in labelled.rawlog (RGB in [0, 1]); exact binary fractions, so a reader
/// recovers the label from the colour (labelFromColour).
std::array<float, 3> labelColour(uint32_t label);
/// The label of a labelled.rawlog colour; kOutlier (1) for a colour of no label.
uint32_t labelFromColour(float r, float g, float b);

/// Writes the MRPT outputs of a run into `folder` (the run's staging folder), scan by scan.
/// Each scan, as decided (ScanResult with its scan kept), adds to
///  - cleaned.rawlog: CObservationRobotPose "POSE" + CObservationPointCloud "LIDAR" (XYZI, sensor
///    frame, sensorPose identity) holding every point but the moving ones (with map_decisions:
///    but those the map's decision calls moving, written when writeMapScan decides the scan);
///  - labelled.rawlog: the same pose + a CObservationPointCloud "LIDAR_LABELLED" of every valid
///    point, a CColouredPointsMap coloured by label (labelColour);
///  - static_map.simplemap: (CPose3DPDFGaussian, sensory frame of the cleaned point cloud);
///  - the in-memory voxel-decimated scene, saved as static_map.3Dscene by finish().
/// Files are complete only after finish(); destroyed without it, nothing half-written remains
/// (temporaries are removed).
class MrptOutputWriter {
 public:
  MrptOutputWriter(const std::string& folder, const MrptOutputOptions& opts = {});
  ~MrptOutputWriter();
  MrptOutputWriter(const MrptOutputWriter&) = delete;
  MrptOutputWriter& operator=(const MrptOutputWriter&) = delete;

  /// Takes the scan (queued with `background`). Throws cleanmap::Error if the scan's points were
  /// not kept (with rawlogs on), or an error of an earlier scan's writing.
  void write(ScanResult&& r);
  /// With map_decisions: the map's decision of the next scan written (its index checked):
  /// `map_labels` per original point (kMoving: not in the cleaned scan), `kept` / `removed` its
  /// points in the map / removed from it (world frame, for the scene). Queued like write().
  void writeMapScan(int64_t index, const Labels& map_labels, const std::vector<PointXYZI>& kept,
                    const std::vector<PointXYZI>& removed);
  /// Writes the rest and closes every file; rethrows an error of the worker. With map_decisions,
  /// a scan the map did not decide is an error.
  void finish();

  double writeMs() const { return ms_; }  ///< time spent writing (on the worker), after finish()
  std::size_t scenePoints() const;        ///< static + moving points shown in the scene

 private:
  struct Job;
  void writeNow(const ScanResult& r);
  void writeMapNow(const Job& j);
  void run(const Job& j);
  void enqueue(Job&& j);

  struct Impl;
  std::unique_ptr<Impl> impl_;
  MrptOutputOptions opts_;
  double ms_ = 0;
};

}  // namespace cleanmap::mrpt
