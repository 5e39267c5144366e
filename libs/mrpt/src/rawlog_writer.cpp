// SPDX-License-Identifier: BSD-3-Clause
#include <unistd.h>

#include <cstdio>
#include <filesystem>

#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/maps/CSimpleMap.h>
#include <mrpt/obs/CObservationImage.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CObservationRobotPose.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/poses/CPose3DPDFGaussian.h>
#include <mrpt/serialization/CArchive.h>

#include "cleanmap/core/error.h"
#include "cleanmap/mrpt/convert.h"
#include "cleanmap/mrpt/rawlog.h"
#include "gz_file.h"

namespace fs = std::filesystem;

namespace cleanmap::mrpt {

struct RawlogWriter::Impl {
  std::string tmp;
  ::mrpt::io::CFileGZOutputStream out;
  bool open = false;
  ::mrpt::maps::CSimpleMap keyframes;  // a .simplemap's, serialized by close()
};

RawlogWriter::RawlogWriter(const std::string& path, const RawlogWriteOptions& opts)
    : impl_(std::make_unique<Impl>()), path_(path), opts_(opts) {
  registerClasses();
  const fs::path target(path);
  if (target.has_parent_path()) {
    std::error_code ec;
    fs::create_directories(target.parent_path(), ec);
    if (ec) throw Error(target.parent_path().string(), "cannot create directory: " + ec.message());
  }
  simplemap_ = isSimplemapName(path);
  impl_->tmp = path + ".tmp." + std::to_string(::getpid());
  if (!impl_->out.open(impl_->tmp)) throw Error(path, "cannot open for writing");
  impl_->open = true;
  // Images are stored raw (bit-exact), not JPEG-compressed.
  ::mrpt::img::CImage::DISABLE_JPEG_COMPRESSION(true);
}

RawlogWriter::~RawlogWriter() {
  if (impl_ && impl_->open) {  // not closed: an error happened, leave nothing behind
    impl_->out.close();
    std::remove(impl_->tmp.c_str());
  }
}

void RawlogWriter::write(const Frame& frame, const std::optional<PinholeCamera>& camera,
                         const std::string& scan_source, const std::string& image_source) {
  try {
    writeObservations(frame, camera, scan_source, image_source);
  } catch (const Error&) {
    throw;
  } catch (const std::exception&) {  // MRPT's archive: "Cannot write bytes to stream!" + a trace
    throw Error(path_, "write failed (disk full?)");
  }
}

void RawlogWriter::writeObservations(const Frame& frame, const std::optional<PinholeCamera>& camera,
                                     const std::string& scan_source,
                                     const std::string& image_source) {
  using namespace ::mrpt::obs;
  auto arch = ::mrpt::serialization::archiveFrom(impl_->out);
  const auto stamp = toMrptTime(frame.scan.timestamp);
  // A simplemap's keyframe: the frame's pose, and its observations in one sensory frame.
  CSensoryFrame::Ptr keyframe;
  if (simplemap_) {
    if (!frame.scan.has_pose)
      throw Error(path_, "frame " + frame.stem +
                             " has no pose: a simplemap's keyframes need poses (write a .rawlog)");
    keyframe = CSensoryFrame::Create();
  }
  const auto put = [&](const CObservation::Ptr& obs) {
    if (keyframe)
      keyframe->insert(obs);
    else
      arch << *obs;
  };

  if (simplemap_) {
    ++poses_;
  } else if (frame.scan.has_pose) {
    auto obs = CObservationRobotPose::Create();
    obs->sensorLabel = opts_.pose_label;
    obs->timestamp = stamp;
    obs->pose.mean = toCPose3D(frame.scan.pose);
    obs->pose.cov.setZero();
    put(obs);
    ++poses_;
  }

  if (frame.odometry) {  // planar, as a wheel odometry reports it
    const Eigen::Isometry3d& T = *frame.odometry;
    if (!T.matrix().allFinite())
      throw Error(path_, "frame " + frame.stem + ": odometry not finite");
    auto od = CObservationOdometry::Create();
    od->sensorLabel = opts_.odometry_label;
    od->timestamp = stamp;
    od->odometry = ::mrpt::poses::CPose2D(T.translation().x(), T.translation().y(),
                                          std::atan2(T.linear()(1, 0), T.linear()(0, 0)));
    put(od);
    ++odometries_;
  }

  auto pc = CObservationPointCloud::Create();
  pc->sensorLabel = opts_.lidar_label;
  pc->timestamp = stamp;
  pc->sensorPose = ::mrpt::poses::CPose3D();  // robot frame == lidar frame
  if (opts_.external) {
    if (scan_source.empty())
      throw Error(path_, "external storage needs the source .bin of scan " + frame.stem);
    if (frame.scan.dropped_invalid > 0)
      throw Error(scan_source, "has NaN/inf points; cannot be referenced externally, embed it");
    pc->setAsExternalStorage(fs::absolute(scan_source).string(),
                             CObservationPointCloud::ExternalStorageFormat::KittiBinFile);
  } else {
    pc->pointcloud = toPointsMap(frame.scan.points);
  }
  put(pc);
  ++scans_;

  if (frame.image) {
    if (!camera) throw Error(path_, "frame " + frame.stem + " has an image but no camera");
    auto img = CObservationImage::Create();
    img->sensorLabel = opts_.camera_label;
    img->timestamp = toMrptTime(frame.image->timestamp);
    img->cameraParams = toTCamera(*camera, img->cameraPose);
    if (opts_.external && !image_source.empty())
      img->image.setExternalStorage(fs::absolute(image_source).string());
    else
      img->image = ::mrpt::img::CImage(frame.image->bgr, ::mrpt::img::DEEP_COPY);
    put(img);
    ++images_;
  }
  if (keyframe)
    impl_->keyframes.insert(::mrpt::poses::CPose3DPDFGaussian::Create(toCPose3D(frame.scan.pose)),
                            keyframe);
}

void RawlogWriter::close() {
  if (!impl_->open) return;
  if (simplemap_) {
    try {
      ::mrpt::serialization::archiveFrom(impl_->out) << impl_->keyframes;
    } catch (const std::exception&) {
      throw Error(path_, "write failed (disk full?)");
    }
    impl_->keyframes.clear();
  }
  closeGzChecked(impl_->out, impl_->tmp, path_);  // on error the destructor removes the temporary
  std::error_code ec;
  fs::rename(impl_->tmp, path_, ec);
  if (ec)
    throw Error(path_, std::string("cannot move the finished ") +
                           (simplemap_ ? "simplemap" : "rawlog") + " into place: " + ec.message());
  impl_->open = false;
}

}  // namespace cleanmap::mrpt
