// SPDX-License-Identifier: BSD-3-Clause
// Conversions between cleanmap core types and MRPT types (the only place both meet).
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <mrpt/core/Clock.h>
#include <mrpt/img/TCamera.h>
#include <mrpt/maps/CPointsMapXYZI.h>
#include <mrpt/obs/CObservation.h>
#include <mrpt/poses/CPose3D.h>

#include "cleanmap/core/error.h"
#include "cleanmap/core/types.h"

namespace mrpt::opengl {
class CPointCloudColoured;
}
namespace mrpt::maps {
class CSimpleMap;
}

namespace cleanmap::mrpt {

/// MRPT reads a timestamp of 0 as "none" (and 1970 dates as nonsense). Times below 1e8 s are
/// sequence-relative (KITTI odometry `times.txt` starts at 0): they are stamped from the epoch
/// kRelativeTimeEpoch, 2000-01-01T00:00:00Z; real epoch times (KITTI raw) are kept as they are.
constexpr double kRelativeTimeEpoch = 946684800.0;

/// MRPT exception texts span several lines (with call stacks): the most telling one, printable.
std::string briefMessage(const std::exception& e);

::mrpt::Clock::time_point toMrptTime(double t);

::mrpt::poses::CPose3D toCPose3D(const Eigen::Isometry3d& T);
Eigen::Isometry3d toIsometry(const ::mrpt::poses::CPose3D& p);

/// Points (sensor frame) into an XYZI points map.
::mrpt::maps::CPointsMapXYZI::Ptr toPointsMap(const std::vector<PointXYZI>& points);

/// Sets `cloud` to the points (their x, y, z) with colours rgb (0-255; as many as points): the
/// cloud push_back(x, y, z, r / 255, g / 255, b / 255) would make, point by point, but under one
/// lock (push_back takes the cloud's write lock and marks its octree outdated per point).
void setColouredCloud(::mrpt::opengl::CPointCloudColoured& cloud,
                      const std::vector<PointXYZI>& points,
                      const std::vector<std::array<uint8_t, 3>>& rgb);

/// TCamera (intrinsics K, no distortion) of a rectified camera; `cameraPoseOnRobot` receives the
/// pose of the camera's optical frame relative to the lidar (robot frame = lidar frame).
::mrpt::img::TCamera toTCamera(const PinholeCamera& cam, ::mrpt::poses::CPose3D& cameraPoseOnRobot);
/// Inverse of toTCamera given the lidar's pose on the robot. Throws cleanmap::Error (naming
/// `source`) if the camera has lens distortion, which our pinhole model cannot represent.
PinholeCamera fromTCamera(const ::mrpt::img::TCamera& cam,
                          const ::mrpt::poses::CPose3D& cameraPoseOnRobot,
                          const ::mrpt::poses::CPose3D& lidarPoseOnRobot,
                          const std::string& source);

/// Scan from a point-cloud-like observation (CObservationPointCloud, CObservationVelodyneScan,
/// CObservationRotatingScan, CObservation3DRangeScan), in the sensor frame, invalid points dropped.
/// nullopt for other types. Throws cleanmap::Error for a rotating scan of an unknown lidar model.
/// Loads lazy (externally stored) data first.
std::optional<Scan> scanFromObservation(const ::mrpt::obs::CObservation& obs);
/// True for the observation types scanFromObservation reads (without decoding them).
bool isLidarObservation(const ::mrpt::obs::CObservation& obs);

/// A file an observation keeps outside its rawlog or simplemap (MRPT's external storage), as an
/// absolute path (a relative one through MRPT's lazy-load base), and what it holds: "scan",
/// "range image" or "image". A stored name MRPT cannot resolve is an Error naming file_of (the
/// rawlog or simplemap) and where ("entry N", "keyframe N").
struct ExternalFile {
  std::string path;
  std::string what;
};
std::vector<ExternalFile> externalFiles(const ::mrpt::obs::CObservation& obs,
                                        const std::string& file_of, const std::string& where);

/// A simplemap read whole (cleanmap-build-map), as CSimpleMap::loadFromFile reads it, but an error
/// is one line naming the file, and a simplemap of MRPT's first format (version 0), whose MRPT
/// reader crashes on a missing pose, is refused before it is read.
void loadSimplemap(const std::string& path, ::mrpt::maps::CSimpleMap& out);

/// A scan's external file that does not exist, in one line: "<file_of>: <where>: the scan's
/// external file ... does not exist (relative paths are read from ...)". MRPT's own message is
/// a failed assertion's, naming neither.
Error missingExternalFile(const std::string& file_of, const std::string& where,
                          const ExternalFile& f);

}  // namespace cleanmap::mrpt
