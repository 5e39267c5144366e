// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §4: the output folder of a run — labels per scan, binary PLY maps, poses, report — and
// how it is published: everything is written into a staging folder beside OUTDIR and moved into
// place only when the run is complete, so OUTDIR always holds one whole run (or nothing new).
#pragma once
#include <chrono>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cleanmap/core/free_space.h"
#include "cleanmap/core/metrics.h"
#include "cleanmap/core/params.h"
#include "cleanmap/core/scan_result.h"

namespace cleanmap::io {

class StagedFolder;  // files.h

class PlyStreamWriter;
class DirectFile;
class BackgroundFiles;  // background_files.h

struct OutputOptions {
  /// Replace OUTDIR even if it is a non-empty folder that holds no cleanmap run.
  bool force = false;
};

/// Refuses (cleanmap::Error naming the folder) an OUTDIR that is a file, or a non-empty folder
/// without a cleanmap report.json unless `force`. An earlier cleanmap run is fine: it is replaced.
void checkOutputFolder(const std::string& outdir, const OutputOptions& opts);

/// True if `dir` holds a finished cleanmap run (a report.json written by cleanmap).
bool isCleanmapRun(const std::string& dir);

/// One scan's share of the cleaned map, as OutputWriter::writeMaps decides it (DESIGN §2e).
struct MapScan {
  int64_t index = 0;                   ///< the scan's index in the input
  const std::string& stem;             ///< its file stem
  const Labels& map_labels;            ///< per original point: what the map did (map_labels/<stem>)
  const std::vector<PointXYZI>& kept;  ///< world frame: its points in static_map_full.ply
  const std::vector<PointXYZI>& removed;  ///< world frame: its points in map_removed.ply
};
using MapScanSink = std::function<void(const MapScan&)>;

/// Writes labels/<stem>.label, static_map.ply, static_map_full.ply, dynamic.ply, poses.txt,
/// params.ini, report.md and, last, report.json (which marks a finished run) into a staging folder
/// `.<name>.cleanmap-staging-<pid>` beside OUTDIR; finish() swaps it into place as a whole. The
/// maps are streamed, so memory does not grow with the sequence. Destroyed without finish() (an
/// error, a signal), it removes the staging folder and leaves OUTDIR as it was.
class OutputWriter {
 public:
  OutputWriter(const std::string& outdir, const std::string& input, const PipelineParams& params,
               const OutputOptions& opts = {});
  ~OutputWriter();
  OutputWriter(const OutputWriter&) = delete;
  OutputWriter& operator=(const OutputWriter&) = delete;

  /// One decided scan, with its evaluation when ground truth exists.
  void write(const ScanResult& r, const std::optional<MosCounts>& eval);
  /// The input has ended: the scans decided from now on are the last ones, decided without new
  /// scans coming in. report.json's `interval` (the run's steady rate: the wall time between two
  /// scans' decisions, ScanResult::decided_at, or their writes where unset; everything the process
  /// does per scan) leaves them out.
  void inputEnded() { input_ended_ = std::chrono::steady_clock::now(); }
  /// Wall time (ms, whole run) of another writer of the run (report.json `output_ms`).
  void addOutputTime(const std::string& name, double ms) { output_ms_[name] += ms; }
  /// Where ground truth exists: how many points the camera check relabelled static were truly
  /// static / truly moving (report.json "images").
  void addRelabelledTruth(std::size_t truly_static, std::size_t truly_moving) {
    relabelled_static_ += truly_static;
    relabelled_moving_ += truly_moving;
    has_relabel_truth_ = true;
  }
  /// A rawlog's sensors (report.json `rawlog_sensors`): the sensorLabel of the lidar and camera
  /// read, per label the scans / images of the other lidars / cameras, skipped, and the lidar's
  /// scans timed earlier than the scan before them.
  struct Sensors {
    std::string lidar, camera;
    std::map<std::string, std::size_t> other_lidars, other_cameras;
    std::size_t scans_timed_back = 0;
  };
  void setSensors(Sensors s) { sensors_ = std::move(s); }
  /// Cleans the maps with the sequence's free space (DESIGN §2e; null: no cleaning), writes
  /// static_map(_full).ply, map_removed.ply, map_labels/, poses and the report, and publishes the
  /// folder as OUTDIR. `wall_s`: whole run, seconds.
  void finish(double wall_s, const FreeSpaceMap* free_space = nullptr);
  /// The map part of finish(), for a caller that needs the map's decisions first (the MRPT
  /// outputs): decides every spooled point and streams the maps and map_labels/, handing each
  /// scan's share to `sink` in scan order. finish() then does not decide again (its free_space
  /// is ignored). Call it once.
  void writeMaps(const FreeSpaceMap* free_space, const MapScanSink& sink = {});

  const std::string& dir() const { return dir_; }  ///< OUTDIR
  const std::string& staging() const {
    return staging_;
  }  ///< where files are written until finish()
  std::size_t scans() const { return stats_.size(); }
  /// The process's age when this writer was made, just before the first scan is read: the
  /// start-up (processAgeSeconds; nullopt where unknown).
  std::optional<double> startSeconds() const { return started_s_; }
  /// report.json `process` as finish() wrote it: the whole command's wall (its age, nullopt where
  /// unknown) and the map's end after the scans (nullopt where the start is unknown).
  struct ProcessTimes {
    double cpu_s = 0;
    std::optional<double> wall_s, end_s;
  };
  const ProcessTimes& processTimes() const { return process_; }
  /// DESIGN §2a: the sensor's height above the ground measured over the run so far (the median of
  /// the scans' measurements), nullopt if no scan could be measured.
  std::optional<double> measuredSensorHeight() const;
  /// True where the input gave every pose (three scans or more) and they are planar: the same
  /// height, no roll, no pitch (within 1e-6 m / rad), as a 2D SLAM's (x, y, heading) are.
  bool givenPosesArePlanar() const;
  /// cleanmap::scanSpacing of the scans so far, at their poses.
  std::optional<ScanSpacing> scanSpacing() const;
  /// DESIGN §2.1: the scans whose estimated pose is the motion model's guess because GICP's
  /// alignment was refused, counted by reason (e.g. "degenerate scene"), most frequent first.
  std::vector<std::pair<std::string, std::size_t>> refusedAlignments() const;
  std::optional<MosCounts> evaluation() const {
    return has_eval_ ? std::optional(eval_) : std::nullopt;
  }

 private:
  void publish();

  std::string dir_, staging_, input_;
  std::unique_ptr<StagedFolder> staged_;
  std::unique_ptr<BackgroundFiles> files_;  // label files and spent spools, off this thread
  PipelineParams params_;
  void spoolScan(const ScanResult& r);
  bool maps_written_ = false;
  std::unique_ptr<PlyStreamWriter> compact_, full_, moving_, removed_;
  std::unique_ptr<DirectFile> spool_;  // the map points of every scan until writeMaps()
  std::string spool_path_;
  std::size_t map_removed_ = 0, map_far_kept_ = 0;
  std::size_t map_object_points_ = 0, map_object_kept_ = 0, map_objects_ = 0;  // §2e, "Objects"
  double map_ms_ = 0;
  double map_forward_ms_ = 0, map_backward_ms_ = 0, map_write_ms_ = 0;  // its passes (§2e)
  std::vector<Eigen::Isometry3d> poses_;
  // Each result's decision (its write where no pipeline stamped it), and the input's end.
  std::vector<std::chrono::steady_clock::time_point> decided_at_;
  std::chrono::steady_clock::time_point input_ended_ = std::chrono::steady_clock::time_point::max();
  std::vector<ScanStats> stats_;
  std::vector<std::string> stems_;
  std::vector<std::uint64_t> spool_offsets_;  // where each scan's spool starts
  std::vector<double> times_;
  std::vector<PoseInfo> pose_info_;
  std::vector<double> ground_measured_, ground_z_, density_;  // per scan (DESIGN §2a, §2d)
  std::vector<MosCounts> scan_eval_;
  std::optional<Sensors> sensors_;
  MosCounts eval_;
  bool has_eval_ = false;
  std::map<std::string, double> output_ms_;
  std::size_t relabelled_static_ = 0, relabelled_moving_ = 0;
  bool has_relabel_truth_ = false;
  std::optional<double> started_s_;  // the process's age when the writer was made (its start-up)
  ProcessTimes process_;             // set by finish()
};

/// Peak resident memory of this process, MiB.
double peakRssMiB();
/// Seconds since the kernel started this process (so the loading of its libraries counts, and a
/// launcher's exec of it): /proc/self/stat's start time against CLOCK_BOOTTIME, 10 ms steps.
/// nullopt where that cannot be read (not Linux, no /proc).
std::optional<double> processAgeSeconds();
/// User + system CPU seconds of every thread of this process so far, ended threads included.
double processCpuSeconds();

}  // namespace cleanmap::io
