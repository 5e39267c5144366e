// SPDX-License-Identifier: BSD-3-Clause
// KITTI readers: odometry / SemanticKITTI folders and raw (synced) drives. Formats: doc/FORMATS.md.
#pragma once
#include <optional>
#include <string>
#include <vector>

#include "cleanmap/core/frame.h"
#include "cleanmap/io/files.h"

namespace cleanmap::io {

enum class KittiLayout { kOdometry, kRaw };

struct KittiReadOptions {
  ScanReadOptions scan;
  bool load_images = true;  ///< deliver images with frames (when the folder has them)
  bool point_times = true;  ///< a raw drive's point times from the azimuth (DESIGN §2.0)
};

/// A KITTI sequence folder, opened once (file lists, poses, times, calibration are read and
/// checked up front); scans, images and labels are loaded on demand.
class KittiSequence : public FrameSource {
 public:
  /// Detects the layout: `velodyne/` (odometry, SemanticKITTI) or `velodyne_points/data/` (raw).
  /// Throws cleanmap::Error on a missing directory, count mismatches, missing calibration keys.
  static KittiSequence open(const std::string& dir, const KittiReadOptions& opts = {});

  KittiLayout layout() const { return layout_; }
  const std::string& directory() const { return dir_; }
  std::size_t size() const { return scan_files_.size(); }
  const std::vector<std::string>& stems() const { return stems_; }
  const std::string& scanPath(std::size_t i) const { return scan_files_.at(i); }

  bool hasPoses() const { return !poses_.empty(); }
  /// Lidar pose in the world (world = first lidar frame for raw drives; KITTI's for odometry).
  const std::vector<Eigen::Isometry3d>& poses() const { return poses_; }
  /// Seconds; relative (odometry times.txt) or since the epoch (raw timestamps.txt).
  const std::vector<double>& timestamps() const { return times_; }

  bool hasImages() const { return !image_files_.empty(); }
  const std::string& imagePath(std::size_t i) const { return image_files_.at(i); }
  bool hasLabels() const { return !label_files_.empty(); }
  const std::string& labelPath(std::size_t i) const { return label_files_.at(i); }
  /// objects.json beside the scans, if present.
  std::optional<std::string> objectsPath() const;

  Scan loadScan(std::size_t i) const;
  std::optional<Image> loadImage(std::size_t i) const;
  /// Labels in the original point order, checked against the scan's point count.
  Labels loadLabels(std::size_t i, std::optional<std::size_t> expected_count = {}) const;
  Frame frame(std::size_t i) const;

  // FrameSource
  std::optional<Frame> next() override;
  std::optional<std::size_t> sizeHint() const override { return size(); }
  std::optional<PinholeCamera> camera() const override { return camera_; }

 private:
  void openOdometry();
  void openRaw();
  void listLabels();

  std::string dir_;
  KittiReadOptions opts_;
  KittiLayout layout_ = KittiLayout::kOdometry;
  std::vector<std::string> scan_files_, stems_, image_files_, label_files_;
  std::vector<Eigen::Isometry3d> poses_;
  std::vector<double> times_;
  std::vector<double> sweeps_;  // raw drives: each scan's sweep duration (s), DESIGN §2.0
  std::optional<PinholeCamera> camera_;
  std::size_t cursor_ = 0;
};

/// Files in `dir` with extension `ext` (".bin"), sorted by name; empty if the directory is absent.
std::vector<std::string> listFiles(const std::string& dir, const std::string& ext);

/// KITTI odometry poses file: one row-major 3x4 matrix per line.
std::vector<Eigen::Isometry3d> readPosesFile(const std::string& path);
/// Writes poses in the same format, atomically.
void writePosesFile(const std::string& path, const std::vector<Eigen::Isometry3d>& poses);

/// OXTS record (first six fields of a KITTI oxts/data/*.txt line) to pose, by the standard KITTI
/// conversion: Mercator with scale = cos(lat0), R = Rz(yaw) Ry(pitch) Rx(roll). Returns IMU poses
/// in the Mercator frame; callers make the first one the origin.
Eigen::Isometry3d oxtsToMercatorPose(double lat, double lon, double alt, double roll, double pitch,
                                     double yaw, double scale);

/// "2011-09-26 13:02:25.964389445" -> seconds since the epoch (UTC).
double parseKittiTimestamp(const std::string& text, const std::string& file);

}  // namespace cleanmap::io
