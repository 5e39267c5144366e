// SPDX-License-Identifier: BSD-3-Clause
// MRPT rawlog I/O (observation-only format). Public header free of MRPT includes.
#pragma once
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>

#include "cleanmap/core/frame.h"

namespace cleanmap::mrpt {

/// Calls MRPT's class registration for every observation type we read or write (Debian links with
/// --as-needed, so registration must be reached by a call, not by link order).
void registerClasses();

struct RawlogWriteOptions {
  /// Store scans as lazy `KittiBinFile` references (absolute paths) instead of embedding points,
  /// and images as external files. Needs the source files (write()'s scan_source / image_source)
  /// and scans without dropped points.
  bool external = false;
  std::string lidar_label = "LIDAR";
  std::string camera_label = "CAMERA";
  std::string pose_label = "POSE";
  std::string odometry_label = "ODOMETRY";
};

/// Streams frames into a rawlog: per frame a CObservationRobotPose (when the scan has a pose),
/// a CObservationOdometry (when the frame has odometry: x, y and yaw, as wheel odometry gives),
/// a CObservationPointCloud (XYZI, sensorPose = identity: the robot frame is the lidar frame) and
/// a CObservationImage (with TCamera and camera pose), all with the scan's timestamp (relative
/// times from 2000-01-01, see toMrptTime). Written to a temporary file and moved into place by
/// close(): an interrupted run leaves nothing.
///
/// A path ending in `.simplemap` gets a CSimpleMap instead, as a SLAM saves its keyframes: per
/// frame a keyframe at the scan's pose (every frame needs one) whose sensory frame holds the
/// same point cloud, odometry and image. The keyframes are held in memory until close() (MRPT
/// serializes a simplemap as one object): with `external`, a few hundred bytes a keyframe.
class RawlogWriter {
 public:
  RawlogWriter(const std::string& path, const RawlogWriteOptions& opts = {});
  ~RawlogWriter();
  RawlogWriter(const RawlogWriter&) = delete;
  RawlogWriter& operator=(const RawlogWriter&) = delete;

  /// `camera` is required for frames with an image. `scan_source` / `image_source` are the files
  /// the data came from (needed with `external`). A failed write (a full disk) is a
  /// cleanmap::Error naming the rawlog.
  void write(const Frame& frame, const std::optional<PinholeCamera>& camera,
             const std::string& scan_source = {}, const std::string& image_source = {});
  void close();

  std::size_t scans() const { return scans_; }
  std::size_t images() const { return images_; }
  std::size_t poses() const { return poses_; }
  std::size_t odometries() const { return odometries_; }

 private:
  void writeObservations(const Frame& frame, const std::optional<PinholeCamera>& camera,
                         const std::string& scan_source, const std::string& image_source);

  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string path_;
  RawlogWriteOptions opts_;
  std::size_t scans_ = 0, images_ = 0, poses_ = 0, odometries_ = 0;
  bool simplemap_ = false;
};

struct RawlogReadOptions {
  bool allow_empty_scans = false;      ///< an empty scan is an error unless allowed
  double pose_time_tolerance = 0.01;   ///< s; a robot pose this close to a scan is its pose
  double image_time_tolerance = 0.05;  ///< s; an image this close to a scan goes with it
  /// One lidar and one camera per run: the observations with this sensorLabel ("" = the label of
  /// the first lidar / image observation in the file); the others are skipped and counted.
  std::string lidar_label;
  std::string camera_label;
  bool load_images = true;  ///< false: images are skipped unread (laser only)
};

/// Reads a rawlog (either MRPT format) as a stream of frames. Scans come from
/// CObservationPointCloud, CObservationVelodyneScan (point cloud generated),
/// CObservationRotatingScan (range image, VLP-16 / HDL-32E / planar) and CObservation3DRangeScan
/// (unprojected); CObservationRobotPose gives the robot pose (scan pose =
/// robot pose + sensor pose) and CObservationImage the image, each matched to the scan with the
/// nearest timestamp within tolerance. Other observations are counted and skipped, and so are
/// the scans and images of other sensors than the one lidar and camera read (by sensorLabel).
/// A .simplemap (one CSimpleMap: a SLAM's keyframes) is read the same way, keyframe by keyframe,
/// each scan at its keyframe's pose (isSimplemap).
class RawlogSource : public FrameSource {
 public:
  /// Throws cleanmap::Error if the file is missing or not a rawlog.
  explicit RawlogSource(const std::string& path, const RawlogReadOptions& opts = {});
  ~RawlogSource() override;

  std::optional<Frame> next() override;
  std::optional<PinholeCamera> camera() const override;

  std::size_t skippedObservations() const;
  /// The sensorLabel of the scans and images read ("" before the first / where there is none).
  const std::string& lidarLabel() const;
  const std::string& cameraLabel() const;
  /// Per sensorLabel, the scans / images of other lidars / cameras skipped so far.
  const std::map<std::string, std::size_t>& otherLidars() const;
  const std::map<std::string, std::size_t>& otherCameras() const;
  /// The scans read so far that are timed earlier than the scan before them (a glitch in the
  /// recording, or rawlogs joined out of order), and the first of them ("<path> entry N: t =
  /// ... s, ... s before the scan before"; "" while there is none). They are read all the same:
  /// the window counts scans in file order, and such a scan is not de-skewed (DESIGN §2.0).
  std::size_t scansTimedBack() const;
  const std::string& firstTimedBack() const;
  /// The folders (absolute) of the external files of the scans and images read so far (MRPT's
  /// external storage: cleanmap-kitti2rawlog --external, rawlog-edit --externalize), which no
  /// output may replace. The constructor reads up to the first scan, so its folders are known
  /// from the start. Relative paths are read from "<name>_Images" beside the rawlog where that
  /// folder exists (MRPT's convention; the constructor sets MRPT's process-wide lazy-load base).
  const std::set<std::string>& externalFolders() const;
  /// The file is a simplemap (one mrpt::maps::CSimpleMap: a SLAM's keyframes), read keyframe by
  /// keyframe, each scan at its keyframe's pose; messages name "keyframe N" for "entry N".
  bool isSimplemap() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// A simplemap by its file name: ".simplemap" or ".simplemap.gz" (MRPT's tools' names). The
/// writer writes a CSimpleMap to such a path, and the apps read one as keyframes.
bool isSimplemapName(const std::string& path);

/// Per-sensorLabel counts as the messages give them: 'FRONT' (3), 'LIDAR' (24).
std::string labelCounts(const std::map<std::string, std::size_t>& counts);

/// Relative external files (rawlog-edit --externalize) are read from the folder beside a rawlog or
/// simplemap that MRPT's tools use, "<name>_Images" (or _images, _IMAGES, or Images): sets MRPT's
/// process-wide lazy-load base (mrpt::io::setLazyLoadPathBase) to the first that exists, as
/// RawLogViewer and rawlog-edit do, and returns it ("" where none exists: the base is left).
std::string useExternalFilesFolderOf(const std::string& file);

/// The apps' warning about the scans timed back (scansTimedBack), without the "prog: warning: "
/// prefix; "" when there is none.
std::string timedBackWarning(const RawlogSource& rawlog);

}  // namespace cleanmap::mrpt
