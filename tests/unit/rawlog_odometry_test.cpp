// SPDX-License-Identifier: BSD-3-Clause
// What rawlogs say beside the scans: odometry (DESIGN §2.1, the initial guess of GICP) and the
// lidar's mounting (issue #15).
#include <gtest/gtest.h>

#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement3D.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/serialization/CArchive.h>

#include "cleanmap/mrpt/convert.h"
#include "cleanmap/mrpt/rawlog.h"
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
