// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §4b: the moving-objects map, an MRPT map plugin (alias `cleanmap_moving`) around the
// laser pipeline (SPEC §2, the paper's windowed Dempster-Shafer classifier). Inserting a posed
// scan (robot pose (+) sensor pose) pushes it into the window; each scan is decided K scans later
// and its static and moving points go into the map, one point per `map_voxel` (memory bounded by
// the area mapped). flush() decides the last K scans.
//
// Copies (copy constructor, clone()) are deep, the window included: a copy fed the same scans
// decides them as the original would. A serialized map holds its content as if flushed (the
// window's last K scans decided with the shorter window, as at the end of a sequence); a map read
// back starts a fresh window. MRPT 2.5.8 copies a CMultiMetricMap through serialization, so a
// copied CMultiMetricMap holds our map flushed.
#pragma once
#include <mrpt/maps/CMetricMap.h>
#include <mrpt/maps/TMetricMapInitializer.h>
#include <mrpt/poses/CPose3D.h>

#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "cleanmap/core/frame.h"
#include "cleanmap/core/object_consensus.h"
#include "cleanmap/core/params.h"
#include "cleanmap/core/scan_result.h"

namespace cleanmap {
class LaserPipeline;
class FreeSpaceMap;
}  // namespace cleanmap

namespace cleanmap_maps {

class CMovingObjectsMap : public mrpt::maps::CMetricMap {
  DEFINE_SERIALIZABLE(CMovingObjectsMap, cleanmap_maps)

 public:
  struct TrajectoryPoint {
    std::size_t index = 0;
    double timestamp = 0;
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  ///< sensor pose in the world
  };

  struct TInsertionOptions {
    /// Take each scan's pose from the CObservationRobotPose inserted just before it (same
    /// timestamp, within 10 ms) instead of the robot pose handed to insertObservation: for
    /// RawLogViewer's "Map from odometry", which inserts every observation of a posed rawlog at
    /// 2D odometry. Off in SLAM, where the pose is the SLAM estimate.
    bool use_pose_observations = false;
    /// The lidar whose observations this layer takes (sensorLabel; "" = the first lidar
    /// observation's): the windowed test compares scans of one sensor, so a second lidar's
    /// observations are not inserted (insertObservation returns false).
    std::string sensor_label;
  };

  CMovingObjectsMap();
  explicit CMovingObjectsMap(const cleanmap::PipelineParams& params, double map_voxel = 0.1);
  CMovingObjectsMap(const CMovingObjectsMap& o);
  CMovingObjectsMap& operator=(const CMovingObjectsMap& o);
  ~CMovingObjectsMap() override;

  /// The classifier's parameters (creationOpts). Changing them is allowed only while the map has
  /// no scan in its window; throws cleanmap::Error otherwise. The scans decided before keep the
  /// objects found with the parameters of their time (static_map.objects).
  const cleanmap::PipelineParams& params() const { return params_; }
  /// DESIGN §2e: the free space of every scan decided (null before the first, or with
  /// static_map.clean off). The app cleans its map files with it, and staticPoints() this layer's
  /// own points.
  const cleanmap::FreeSpaceMap* freeSpace() const;
  /// LaserPipeline::freeSpaceBytes(): without waiting, while scans are inserted (0 before).
  std::size_t freeSpaceBytes() const;
  /// freeSpaceBytes() summed over every layer alive in the process: what an app that does not
  /// hold its layers (MRPT's ICP-SLAM builds them inside its run) watches, from the thread that
  /// inserts into them.
  static std::size_t freeSpaceBytesOfAll();
  TInsertionOptions insertionOptions;
  /// The sensorLabel of the lidar observations inserted so far ("" before the first).
  const std::string& lidarLabel() const { return lidar_label_; }
  void setParams(const cleanmap::PipelineParams& params);
  double mapVoxel() const { return map_voxel_; }
  /// static_map.objects (DESIGN §4b): the layer keeps the objects of the last `n` decided scans
  /// (0: all); an older scan's objects are decided when it leaves them, with the free space seen
  /// then and rule 4 forwards, and only their voxels' decisions are kept. Bounds the memory.
  void setObjectScans(std::size_t n);
  static constexpr int kDefaultObjectScans = 100;
  std::size_t objectScans() const { return object_scans_max_; }

  /// Native insertion of a posed scan (`frame.scan.pose`, or estimated with PipelineParams::poses).
  void insertFrame(cleanmap::Frame&& frame);
  /// Decides the scans still in the window. Later insertions start a new window.
  void flush();
  /// Scans inserted but not yet decided (at most K until flush()), or decided and held with the
  /// first K / 2 (LaserPipeline::push()).
  std::size_t pending() const;
  std::size_t decided() const { return trajectory_.size(); }

  /// Every decided scan is also handed here (labels, points, stage times), in order. Not copied.
  void setScanSink(std::function<void(cleanmap::ScanResult&&)> sink) { sink_ = std::move(sink); }
  /// false: decided points are not kept in the map (the app streams them to files instead).
  void setStorePoints(bool on) { store_points_ = on; }
  /// Hand each scan's own points to the sink too (ScanResult::scan).
  void setKeepScans(bool on);
  /// DESIGN §3: the camera of the inserted frames' images (LaserPipeline::setCamera; it applies to
  /// the frames inserted after it), and whether each scan's overlay image is handed to the sink
  /// (ScanResult::overlay).
  void setCamera(std::optional<cleanmap::PinholeCamera> camera);
  void setSaveOverlays(bool on);
  /// Issue #16: GICP registers each inserted frame on a thread of its own while the frames before
  /// it are decided (LaserPipeline::registerAhead; same results, one frame later).
  void setRegisterAhead(bool on);
  const std::optional<cleanmap::PinholeCamera>& camera() const { return camera_; }

  /// One point per voxel: the static map (ground included) and the moving points, sorted by voxel.
  /// The static map is cleaned with the free space seen so far (DESIGN §2e, static_map.policy):
  /// a non-ground point whose space the scans decided so far saw empty is left out (and kept in
  /// the layer: later scans do not bring it back, a merge or an ini change may). With
  /// static_map.objects a voxel holding points of the scans' rigid objects is decided with them,
  /// as the app's maps are (DESIGN §2e "Objects", §4b): removed if every one of them is. The
  /// layer keeps each decided scan's vehicle-sized objects for it.
  std::vector<cleanmap::PointXYZI> staticPoints() const;
  /// The static points staticPoints() leaves out, sorted by voxel.
  std::vector<cleanmap::PointXYZI> removedPoints() const;
  std::vector<cleanmap::PointXYZI> movingPoints() const;
  const std::vector<TrajectoryPoint>& trajectory() const { return trajectory_; }
  /// Counts summed over the decided scans.
  const cleanmap::ScanStats& totals() const { return totals_; }
  /// Points of the decided scans' vehicle-sized objects kept for static_map.objects (12 bytes
  /// each; DESIGN §4b), at most map_object_scans scans' worth.
  std::size_t objectPoints() const;

  // CMetricMap. saveMetricMapRepresentationToFile writes <prefix>_static.ply, _moving.ply (RGB)
  // and _trajectory.txt of the map as if flushed; getVisualizationInto shows the decided scans.
  bool isEmpty() const override;
  void saveMetricMapRepresentationToFile(const std::string& prefix) const override;
  void getVisualizationInto(mrpt::opengl::CSetOfObjects& o) const override;
  std::string asString() const override;

  MAP_DEFINITION_START(CMovingObjectsMap)
  cleanmap::PipelineParams params;             ///< creationOpts: every key of the parameter table
  double map_voxel = 0.1;                      ///< creationOpts: m; 0 keeps every point
  int map_object_scans = kDefaultObjectScans;  ///< creationOpts: setObjectScans() (0: all)
  CMovingObjectsMap::TInsertionOptions insertionOpts;  ///< insertOpts
  MAP_DEFINITION_END(CMovingObjectsMap)

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

  void onDecided(cleanmap::ScanResult&& r);
  void ensurePipeline();
  void copyFrom(const CMovingObjectsMap& o);

  cleanmap::PipelineParams params_;
  double map_voxel_ = 0.1;
  std::unique_ptr<cleanmap::LaserPipeline> pipe_;
  std::function<void(cleanmap::ScanResult&&)> sink_;
  bool store_points_ = true, keep_scans_ = false, overlays_ = false, register_ahead_ = false;
  std::optional<cleanmap::PinholeCamera> camera_;
  std::optional<std::pair<double, mrpt::poses::CPose3D>> pose_obs_;  // use_pose_observations
  std::size_t next_index_ = 0;  // index given to the next observation inserted through MRPT
  std::string lidar_label_;     // the sensorLabel of the observations inserted (sensor_label)
  std::unordered_map<uint64_t, cleanmap::PointXYZI> static_, moving_;  // voxel key -> first point
  std::unordered_map<uint64_t, int64_t> static_scan_;  // non-ground static_ entries: their scan
  // DESIGN §4b, static_map.objects: per decided scan, the points of its vehicle-sized objects
  // (the only ones the map's object rules decide): its map points, then from `fixed_from` on its
  // moving points.
  struct ObjectScan {
    int64_t index = 0;
    double density = 1;
    cleanmap::RingReach reach;  // its lidar's rings (doc/OBJECTS.md rule 1)
    std::vector<Eigen::Vector3f> points;
    std::size_t fixed_from = 0;
    std::vector<uint64_t> keys;  // with map_voxel 0: the map points' static_ keys
  };
  std::deque<ObjectScan> object_scans_;
  std::size_t object_scans_max_ = kDefaultObjectScans;
  // The scans that left object_scans_: their voxels' decisions (removed if every one of their
  // objects' points was) and rule 4's memory after the last of them.
  std::unordered_map<uint64_t, uint8_t> frozen_;
  std::optional<cleanmap::MapObjectConsensus> frozen_consensus_;
  void freezeOldest();
  void decideScan(cleanmap::MapObjectConsensus& consensus, const cleanmap::FreeSpaceMap& fs,
                  const ObjectScan& os, std::vector<uint8_t>& gone) const;
  // A voxel's decision by the objects: kept (a point of them kept), removed (all of them
  // removed), or left to the free space's rule.
  static constexpr uint8_t kObjectKept = 0, kObjectGone = 1, kFreeSpace = 2;
  // Adds scan `os`'s decisions `gone` (its map points') to `by_object`: kept if one is kept.
  void addDecisions(const ObjectScan& os, const std::vector<uint8_t>& gone,
                    std::unordered_map<uint64_t, uint8_t>& by_object) const;
  bool byObjects() const;
  // The objects' decision per voxel key (null: per voxel only), computed once per state of the
  // map (version_ counts the insertions, decisions and changes).
  std::shared_ptr<const std::unordered_map<uint64_t, uint8_t>> objectDecisions() const;
  uint64_t version_ = 0;
  mutable std::mutex objects_mutex_;
  mutable std::shared_ptr<const std::unordered_map<uint64_t, uint8_t>> by_object_;
  mutable uint64_t by_object_version_ = 0;
  std::vector<cleanmap::PointXYZI> cleanedStatic(bool removed) const;
  std::vector<TrajectoryPoint> trajectory_;
  cleanmap::ScanStats totals_;
};

}  // namespace cleanmap_maps
