// SPDX-License-Identifier: BSD-3-Clause
// What rawlogs say beside the scans: odometry (DESIGN §2.1, the initial guess of GICP) and the
// lidar's mounting (issue #15).
#include <gtest/gtest.h>

#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement3D.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CObservationRobotPose.h>
#include <mrpt/obs/CObservationVelodyneScan.h>
#include <mrpt/obs/CRawlog.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/serialization/CArchive.h>

#include "cleanmap/mrpt/convert.h"
#include "cleanmap/mrpt/rawlog.h"
#include "cleanmap/pipeline/laser_pipeline.h"
#include "test_data.h"

// Odometry in a sensory-frame rawlog (actions before each frame) becomes Frame::odometry: the
// increments summed, composed with the lidar's pose on the robot (GICP's initial guess).
TEST(RawlogSource, OdometryActionsAreSummedAndSensorPoseIsTheMount) {
  using namespace ::mrpt::obs;
  using ::mrpt::poses::CPose3D;
  cleanmap::mrpt::registerClasses();
  const auto dir = cleanmap::test::scratchDir("rawlog_odometry");
  const std::string path = (dir / "odo.rawlog").string();
  const CPose3D sensor(0.5, 0, 1.7, 0.02, -0.17, 0.07);  // x y z yaw pitch roll: tilted
  const CPose3D step(1.0, 0.1, 0, 0.05, 0, 0);           // x y z yaw pitch roll per frame
  {
    ::mrpt::io::CFileGZOutputStream f(path);
    auto ar = ::mrpt::serialization::archiveFrom(f);
    for (int k = 0; k < 3; ++k) {
      CActionCollection acts;
      CActionRobotMovement3D mv;
      mv.poseChange.mean = step;
      acts.insert(mv);
      ar << acts;
      CSensoryFrame sf;
      auto pc = CObservationPointCloud::Create();
      pc->pointcloud = ::mrpt::maps::CSimplePointsMap::Create();
      for (int i = 0; i < 100; ++i) pc->pointcloud->insertPoint(float(i % 10), float(i / 10), 0.f);
      pc->sensorPose = sensor;
      pc->timestamp = ::mrpt::Clock::fromDouble(1000.0 + 0.1 * k);
      sf.insert(pc);
      ar << sf;
    }
  }
  cleanmap::mrpt::RawlogSource src(path);
  CPose3D odo;
  // The observation's sensorPose is the frame's mount (its roll and pitch level the scan).
  for (int k = 0; k < 3; ++k) {
    const auto f = src.next();
    ASSERT_TRUE(f);
    ASSERT_TRUE(f->odometry) << "frame " << k;
    odo = odo + step;
    const Eigen::Isometry3d want = cleanmap::mrpt::toIsometry(odo + sensor);
    EXPECT_LE((f->odometry->matrix() - want.matrix()).norm(), 1e-9) << "frame " << k;
    ASSERT_TRUE(f->mount) << "frame " << k;
    EXPECT_LE((f->mount->matrix() - cleanmap::mrpt::toIsometry(sensor).matrix()).norm(), 1e-12);
  }
}

// A frame's odometry written by RawlogWriter (a CObservationOdometry: x, y, yaw, as wheel odometry
// gives; cleanmap-sim's `[ego] odometry`) reads back as the same planar pose, with the scan's own
// pose beside it.
TEST(RawlogWriter, OdometryRoundTrips) {
  const auto dir = cleanmap::test::scratchDir("rawlog_odometry_write");
  const std::string path = (dir / "odo.rawlog").string();
  auto planar = [](double x, double y, double yaw) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    T.translation() = Eigen::Vector3d(x, y, 0);
    return T;
  };
  std::vector<Eigen::Isometry3d> odo;
  {
    cleanmap::mrpt::RawlogWriter w(path);
    for (int k = 0; k < 3; ++k) {
      cleanmap::Frame f;
      f.stem = std::to_string(k);
      for (int i = 0; i < 100; ++i)
        f.scan.points.push_back({float(i % 10), float(i / 10), 0.f, 0.5f});
      f.scan.timestamp = 0.1 * k;
      f.scan.pose = planar(2.0 * k, 0.1 * k, 0.0);
      f.scan.has_pose = true;
      odo.push_back(planar(100 + 1.9 * k, -3 + 0.2 * k, 0.3 + 0.05 * k));
      f.odometry = odo.back();
      w.write(f, std::nullopt);
    }
    EXPECT_EQ(w.odometries(), 3u);
    w.close();
  }
  cleanmap::mrpt::RawlogSource src(path);
  for (int k = 0; k < 3; ++k) {
    const auto f = src.next();
    ASSERT_TRUE(f);
    ASSERT_TRUE(f->odometry) << "frame " << k;
    EXPECT_LE((f->odometry->matrix() - odo[k].matrix()).norm(), 1e-9) << "frame " << k;
    EXPECT_LE((f->scan.pose.matrix() - planar(2.0 * k, 0.1 * k, 0.0).matrix()).norm(), 1e-9);
  }
  EXPECT_FALSE(src.next());
}

// DESIGN §2.0, end to end: a rawlog of Velodyne packets (mrpt-common's VLP-16 sweep, logged three
// times 0.1 s apart with the car's pose 1 m further each time: 10 m/s) reads as scans whose points
// carry their firing times, and the pipeline (sensor.deskew auto) de-skews every one of them, the
// first sweep's last firings by about 10 m/s x 0.1 s.
TEST(RawlogSource, VelodynePacketsAreDeskewed) {
  using namespace ::mrpt::obs;
  const std::string src_path =
      std::string(CLEANMAP_MRPT_DATASETS_DIR) + "/test_velodyne_VLP16.rawlog";
  if (!std::filesystem::exists(src_path)) {
    if (cleanmap::test::inCI()) FAIL() << "mrpt-common missing: " << src_path;
    GTEST_SKIP() << "mrpt-common not installed: " << src_path;
  }
  cleanmap::mrpt::registerClasses();
  CObservationVelodyneScan::Ptr velo;
  {
    ::mrpt::io::CFileGZInputStream in(src_path);
    auto ar = ::mrpt::serialization::archiveFrom(in);
    CActionCollection::Ptr acts;
    CSensoryFrame::Ptr sf;
    CObservation::Ptr obs;
    std::size_t idx = 0;
    while (!velo && CRawlog::getActionObservationPairOrObservation(ar, acts, sf, obs, idx))
      velo = std::dynamic_pointer_cast<CObservationVelodyneScan>(obs);
  }
  ASSERT_TRUE(velo);
  const auto dir = cleanmap::test::scratchDir("rawlog_velodyne_deskew");
  const std::string path = (dir / "velo.rawlog").string();
  const auto t0 = velo->timestamp;
  {
    ::mrpt::io::CFileGZOutputStream f(path);
    auto ar = ::mrpt::serialization::archiveFrom(f);
    for (int k = 0; k < 3; ++k) {
      CObservationRobotPose pose;
      pose.pose.mean = ::mrpt::poses::CPose3D(1.0 * k, 0, 0, 0, 0, 0);
      pose.timestamp = t0 + std::chrono::milliseconds(100 * k);
      ar << pose;
      CObservationVelodyneScan v = *velo;
      v.timestamp = pose.timestamp;
      ar << v;
    }
  }
  cleanmap::mrpt::RawlogSource src(path);
  std::vector<cleanmap::ScanStats> stats;
  cleanmap::LaserPipeline pipe({}, [&](cleanmap::ScanResult&& r) { stats.push_back(r.stats); });
  while (auto f = src.next()) {
    ASSERT_TRUE(f->scan.has_pose);
    ASSERT_EQ(f->scan.point_time.size(), f->scan.size());
    pipe.push(std::move(*f));
  }
  pipe.finish();
  ASSERT_EQ(stats.size(), 3u);
  for (const auto& st : stats) {
    EXPECT_EQ(st.deskewed, 1u);
    EXPECT_GT(st.deskew_max_shift, 0.7);
    EXPECT_LT(st.deskew_max_shift, 1.2);
  }
}
