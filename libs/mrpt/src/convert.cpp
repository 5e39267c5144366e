// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/mrpt/convert.h"

#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/math/CMatrixFixed.h>
#include <mrpt/obs/CObservation3DRangeScan.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CObservationVelodyneScan.h>

#include "cleanmap/core/error.h"

namespace cleanmap::mrpt {

using ::mrpt::poses::CPose3D;

CPose3D toCPose3D(const Eigen::Isometry3d& T) {
  ::mrpt::math::CMatrixDouble44 m;
  m.asEigen() = T.matrix();
  return CPose3D(m);
}

Eigen::Isometry3d toIsometry(const CPose3D& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.matrix() = p.getHomogeneousMatrixVal<::mrpt::math::CMatrixDouble44>().asEigen();
  return T;
}

::mrpt::maps::CPointsMapXYZI::Ptr toPointsMap(const std::vector<PointXYZI>& points) {
  auto map = ::mrpt::maps::CPointsMapXYZI::Create();
  map->resize(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto& p = points[i];
    map->setPointRGB(i, p.x, p.y, p.z, p.intensity, 0, 0);
  }
  map->mark_as_modified();
  return map;
}

::mrpt::img::TCamera toTCamera(const PinholeCamera& cam, CPose3D& cameraPoseOnRobot) {
  ::mrpt::img::TCamera tc;
  tc.ncols = static_cast<uint32_t>(cam.width);
  tc.nrows = static_cast<uint32_t>(cam.height);
  tc.intrinsicParams.asEigen() = cam.K();
  tc.distortion = ::mrpt::img::DistortionModel::none;
  tc.cameraName = cam.name;
  // MRPT's camera frame is the optical frame (z forward, x right, y down), as KITTI's.
  cameraPoseOnRobot = toCPose3D(cam.opticalFromLidar().inverse());
  return tc;
}

PinholeCamera fromTCamera(const ::mrpt::img::TCamera& tc, const CPose3D& cameraPoseOnRobot,
                          const CPose3D& lidarPoseOnRobot, const std::string& source) {
  for (double d : tc.dist)
    if (d != 0.0)
      throw Error(source, "camera '" + tc.cameraName +
                              "' has lens distortion; cleanmap needs rectified images");
  PinholeCamera cam;
  cam.name = tc.cameraName;
  cam.width = static_cast<int>(tc.ncols);
  cam.height = static_cast<int>(tc.nrows);
  cam.P.setZero();
  cam.P.leftCols<3>() = tc.intrinsicParams.asEigen();
  cam.T_cam_lidar = toIsometry(cameraPoseOnRobot).inverse() * toIsometry(lidarPoseOnRobot);
  return cam;
}

namespace {

Scan fromPointsMap(const ::mrpt::maps::CPointsMap& map) {
  Scan s;
  const auto& xs = map.getPointsBufferRef_x();
  const auto& ys = map.getPointsBufferRef_y();
  const auto& zs = map.getPointsBufferRef_z();
  const auto* xyzi = dynamic_cast<const ::mrpt::maps::CPointsMapXYZI*>(&map);
  s.points.resize(xs.size());
  for (std::size_t i = 0; i < xs.size(); ++i) {
    const float in = xyzi ? xyzi->getPointIntensity_fast(i) : 0.0f;
    s.points[i] = PointXYZI{xs[i], ys[i], zs[i], in};
  }
  return s;
}

}  // namespace

std::optional<Scan> scanFromObservation(const ::mrpt::obs::CObservation& obs) {
  using namespace ::mrpt::obs;
  std::optional<Scan> out;
  if (const auto* pc = dynamic_cast<const CObservationPointCloud*>(&obs)) {
    pc->load();
    if (!pc->pointcloud) return Scan{};
    out = fromPointsMap(*pc->pointcloud);
  } else if (const auto* velo = dynamic_cast<const CObservationVelodyneScan*>(&obs)) {
    auto copy = *velo;  // generatePointCloud() is non-const
    copy.generatePointCloud();
    const auto& c = copy.point_cloud;
    Scan s;
    s.points.resize(c.size());
    for (std::size_t i = 0; i < c.size(); ++i)
      s.points[i] = PointXYZI{c.x[i], c.y[i], c.z[i], c.intensity[i] / 255.0f};
    out = std::move(s);
  } else if (const auto* rgbd = dynamic_cast<const CObservation3DRangeScan*>(&obs)) {
    auto copy = *rgbd;
    copy.load();
    ::mrpt::maps::CSimplePointsMap map;  // the XYZI map lacks the adapter unprojectInto needs
    if (copy.hasRangeImage) copy.unprojectInto(map);  // sensor frame
    out = fromPointsMap(map);
  } else {
    return std::nullopt;
  }
  out->original_size = out->points.size();
  out->timestamp = ::mrpt::Clock::toDouble(obs.timestamp);
  dropInvalidPoints(*out);
  return out;
}

}  // namespace cleanmap::mrpt
