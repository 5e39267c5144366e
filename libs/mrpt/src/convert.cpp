// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/mrpt/convert.h"

#include <algorithm>
#include <cmath>
#include <mutex>
#include <shared_mutex>
#include <sstream>
#include <stdexcept>
#include <string>

#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/math/CMatrixFixed.h>
#include <mrpt/obs/CObservation3DRangeScan.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CObservationRotatingScan.h>
#include <mrpt/obs/CObservationVelodyneScan.h>
#include <mrpt/opengl/CPointCloudColoured.h>
#include <mrpt/system/datetime.h>

#include "cleanmap/core/error.h"

namespace cleanmap::mrpt {

using ::mrpt::poses::CPose3D;

namespace {

// Bytes of a corrupt file end up in MRPT's messages (class names read from the stream): keep
// printable ASCII only, and not too much of it.
std::string printable(const std::string& s) {
  std::string out;
  for (const char c : s)
    if (c >= 32 && c < 127) out += c;
  return out.size() > 120 ? out.substr(0, 120) + "..." : out;
}

}  // namespace

std::string briefMessage(const std::exception& e) {
  std::istringstream in(e.what());
  std::string line, last;
  while (std::getline(in, line)) {
    if (line.find_first_not_of(" \t=") == std::string::npos) continue;
    if (line.find("MRPT exception") != std::string::npos) continue;
    if (line.rfind("Message:", 0) == 0) {  // its text, without the spaces before it
      const std::size_t at = line.find_first_not_of(' ', 8);
      if (at != std::string::npos) return printable(line.substr(at));
      continue;
    }
    if (last.empty()) last = line;
  }
  return last.empty() ? std::string("unknown error") : printable(last);
}

::mrpt::Clock::time_point toMrptTime(double t) {
  return ::mrpt::Clock::fromDouble(t < 1e8 ? t + kRelativeTimeEpoch : t);
}

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
    map->setPointFast(i, p.x, p.y, p.z);  // no k-d tree lock per point; marked modified below
    map->setPointColor_fast(i, p.intensity, 0, 0);
  }
  map->mark_as_modified();
  return map;
}

void setColouredCloud(::mrpt::opengl::CPointCloudColoured& cloud,
                      const std::vector<PointXYZI>& points,
                      const std::vector<std::array<uint8_t, 3>>& rgb) {
  using ::mrpt::f2u8;
  if (rgb.size() != points.size())
    throw std::invalid_argument("setColouredCloud: " + std::to_string(rgb.size()) +
                                " colours for " + std::to_string(points.size()) + " points");
  cloud.resize(points.size());  // marks the octree outdated once
  // MRPT's raw access to the cloud's buffers (its members are mutable; the cloud is not const).
  auto& xyz =
      const_cast<std::vector<::mrpt::math::TPoint3Df>&>(cloud.shaderPointsVertexPointBuffer());
  auto& col = const_cast<std::vector<::mrpt::img::TColor>&>(cloud.shaderPointsVertexColorBuffer());
  std::unique_lock<std::shared_mutex> lock(cloud.shaderPointsBuffersMutex().data);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto& p = points[i];
    const auto& c = rgb[i];
    xyz[i] = ::mrpt::math::TPoint3Df(p.x, p.y, p.z);
    col[i] = ::mrpt::img::TColor(f2u8(c[0] / 255.0f), f2u8(c[1] / 255.0f), f2u8(c[2] / 255.0f),
                                 f2u8(1.0f));
  }
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

// Elevation (degrees) of ring `row` of a CObservationRotatingScan. MRPT 2.5.8 stores no
// per-ring calibration in it: rows are the lidar's laser ids (fromVelodyne keeps the firing
// order), so the elevations come from the model's data sheet. Unknown models are refused.
double ringElevationDeg(const ::mrpt::obs::CObservationRotatingScan& o, int row) {
  if (o.rowCount == 1) return 0.0;                   // a planar scanner (fromScan2D)
  if (o.lidarModel == "VLP-16" && o.rowCount == 16)  // ids interleave -15, +1, -13, +3, ...
    return (row % 2) ? row : row - 15;
  if (o.lidarModel == "HDL-32E" && o.rowCount == 32)  // -30.67, -9.33, -29.33, -8.00, ...
    return (row % 2) ? -9.33 + 1.333 * ((row - 1) / 2) : -30.67 + 1.333 * (row / 2);
  throw Error("CObservationRotatingScan '" + o.sensorLabel + "'",
              "lidar model '" + o.lidarModel + "' with " + std::to_string(o.rowCount) +
                  " rings has no known ring elevations (VLP-16, HDL-32E and 1-ring scanners "
                  "are read); convert it to CObservationPointCloud");
}

// A range image: column c fires at startAzimuth + azimuthSpan * c / columns; MRPT's Velodyne
// conversion counts the azimuth as the sensor turns (clockwise seen from above), hence y = -sin.
Scan fromRotatingScan(const ::mrpt::obs::CObservationRotatingScan& o) {
  Scan s;
  if (o.rangeImage.rows() != o.rowCount || o.rangeImage.cols() != o.columnCount)
    throw Error("CObservationRotatingScan '" + o.sensorLabel + "'",
                "range image is " + std::to_string(o.rangeImage.rows()) + "x" +
                    std::to_string(o.rangeImage.cols()) + ", expected rowCount x columnCount");
  const bool has_i =
      o.intensityImage.rows() == o.rowCount && o.intensityImage.cols() == o.columnCount;
  const bool velodyne = o.rowCount > 1;
  std::vector<double> cos_el(o.rowCount), sin_el(o.rowCount);
  for (int r = 0; r < o.rowCount; ++r) {
    const double el = ringElevationDeg(o, r) * M_PI / 180.0;
    cos_el[r] = std::cos(el);
    sin_el[r] = std::sin(el);
  }
  // MRPT 2.5.8's fromVelodyne allocates rowCount times more columns than there are firings and
  // fills only the first columnCount / rowCount: the azimuth span covers those.
  int used = o.columnCount;
  if (velodyne && o.columnCount % o.rowCount == 0) {
    const int firings = o.columnCount / o.rowCount;
    bool beyond = false;
    for (int c = firings; c < o.columnCount && !beyond; ++c)
      for (int r = 0; r < o.rowCount && !beyond; ++r) beyond = o.rangeImage(r, c) != 0;
    if (!beyond) used = firings;
  }
  const double cols = std::max(1, velodyne ? used : used - 1);
  // DESIGN §2.0: firings at a fixed rate over sweepDuration from the first (the timestamp's).
  const bool timed = o.sweepDuration > 0 && std::isfinite(o.sweepDuration);
  for (int c = 0; c < used; ++c) {
    const double az = o.startAzimuth + o.azimuthSpan * c / cols;
    const auto t = static_cast<float>(o.sweepDuration * c / cols);
    const double ca = std::cos(az), sa = velodyne ? -std::sin(az) : std::sin(az);
    for (int r = 0; r < o.rowCount; ++r) {
      const uint16_t raw = o.rangeImage(r, c);
      if (raw == 0) continue;
      const double d = raw * o.rangeResolution;
      const double x = d * cos_el[r] * ca, y = d * cos_el[r] * sa, z = d * sin_el[r];
      s.points.push_back(PointXYZI{static_cast<float>(x), static_cast<float>(y),
                                   static_cast<float>(z),
                                   has_i ? o.intensityImage(r, c) / 255.0f : 0.0f});
      if (timed) s.point_time.push_back(t);
    }
  }
  return s;
}

}  // namespace

bool isLidarObservation(const ::mrpt::obs::CObservation& obs) {
  using namespace ::mrpt::obs;
  return dynamic_cast<const CObservationPointCloud*>(&obs) ||
         dynamic_cast<const CObservationVelodyneScan*>(&obs) ||
         dynamic_cast<const CObservationRotatingScan*>(&obs) ||
         dynamic_cast<const CObservation3DRangeScan*>(&obs);
}

std::optional<Scan> scanFromObservation(const ::mrpt::obs::CObservation& obs) {
  using namespace ::mrpt::obs;
  std::optional<Scan> out;
  if (const auto* pc = dynamic_cast<const CObservationPointCloud*>(&obs)) {
    pc->load();
    if (!pc->pointcloud) return Scan{};
    out = fromPointsMap(*pc->pointcloud);
  } else if (const auto* velo = dynamic_cast<const CObservationVelodyneScan*>(&obs)) {
    auto copy = *velo;  // generatePointCloud() is non-const
    ::mrpt::obs::CObservationVelodyneScan::TGeneratePointCloudParameters gen;
    gen.generatePerPointTimestamp = true;  // DESIGN §2.0: each firing's time, for the de-skew
    copy.generatePointCloud(gen);
    const auto& c = copy.point_cloud;
    Scan s;
    s.points.resize(c.size());
    for (std::size_t i = 0; i < c.size(); ++i)
      s.points[i] = PointXYZI{c.x[i], c.y[i], c.z[i], c.intensity[i] / 255.0f};
    if (c.timestamp.size() == c.size() && velo->timestamp != ::mrpt::Clock::time_point()) {
      s.point_time.resize(c.size());
      for (std::size_t i = 0; i < c.size(); ++i)
        s.point_time[i] =
            static_cast<float>(::mrpt::system::timeDifference(velo->timestamp, c.timestamp[i]));
    }
    out = std::move(s);
  } else if (const auto* rot = dynamic_cast<const CObservationRotatingScan*>(&obs)) {
    out = fromRotatingScan(*rot);
  } else if (const auto* rgbd = dynamic_cast<const CObservation3DRangeScan*>(&obs)) {
    auto copy = *rgbd;
    copy.load();
    ::mrpt::maps::CSimplePointsMap map;  // the XYZI map lacks the adapter unprojectInto needs
    if (copy.hasRangeImage) {
      copy.unprojectInto(map);      // sensor frame
    } else if (copy.hasPoints3D) {  // points only (cleanmap-icp-slam's lidar scans): sensor frame
      const std::size_t n =
          std::min({copy.points3D_x.size(), copy.points3D_y.size(), copy.points3D_z.size()});
      map.reserve(n);
      for (std::size_t i = 0; i < n; ++i)
        map.insertPointFast(copy.points3D_x[i], copy.points3D_y[i], copy.points3D_z[i]);
      map.mark_as_modified();
    }
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
