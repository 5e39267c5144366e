// SPDX-License-Identifier: BSD-3-Clause
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <tuple>

#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/io/CMemoryStream.h>
#include <mrpt/maps/CPointsMapXYZI.h>
#include <mrpt/maps/CSimpleMap.h>
#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationGPS.h>
#include <mrpt/obs/CObservationImage.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CObservationRotatingScan.h>
#include <mrpt/obs/CObservationVelodyneScan.h>
#include <mrpt/obs/CRawlog.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/poses/CPose3DPDFGaussian.h>
#include <mrpt/serialization/CArchive.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <unordered_map>

#include "cleanmap/core/error.h"
#include "cleanmap/io/kitti.h"
#include "cleanmap/mrpt/convert.h"
#include "cleanmap/mrpt/input.h"
#include "cleanmap/mrpt/rawlog.h"
#include "cleanmap/vision/rectify.h"
#include "test_data.h"

using namespace cleanmap;
namespace fs = std::filesystem;

namespace {

// KITTI folder -> rawlog (first `n` scans, all if 0).
void convert(const io::KittiSequence& seq, const std::string& out, bool external,
             std::size_t n = 0) {
  cleanmap::mrpt::RawlogWriteOptions opts;
  opts.external = external;
  cleanmap::mrpt::RawlogWriter w(out, opts);
  const std::size_t count = n ? std::min(n, seq.size()) : seq.size();
  for (std::size_t i = 0; i < count; ++i)
    w.write(seq.frame(i), seq.camera(), seq.scanPath(i),
            seq.hasImages() ? seq.imagePath(i) : std::string());
  w.close();
}

// Reads the rawlog back and checks it frame by frame against the KITTI folder.
void expectSameAsKitti(const io::KittiSequence& seq, const std::string& rawlog) {
  cleanmap::mrpt::RawlogSource src(rawlog);
  std::size_t i = 0;
  while (auto f = src.next()) {
    ASSERT_LT(i, seq.size());
    const Frame k = seq.frame(i);
    SCOPED_TRACE("scan " + k.stem);
    ASSERT_EQ(f->scan.size(), k.scan.size());
    EXPECT_EQ(0, std::memcmp(f->scan.points.data(), k.scan.points.data(),
                             k.scan.size() * sizeof(PointXYZI)))
        << "points differ";
    ASSERT_EQ(f->scan.has_pose, k.scan.has_pose);
    EXPECT_LT((f->scan.pose.matrix() - k.scan.pose.matrix()).cwiseAbs().maxCoeff(), 1e-9);
    // Relative KITTI times are stamped from 2000-01-01 (MRPT reads 0 as "no time").
    EXPECT_NEAR(f->scan.timestamp, k.scan.timestamp + cleanmap::mrpt::kRelativeTimeEpoch, 1e-6);
    ASSERT_EQ(f->image.has_value(), k.image.has_value());
    if (k.image) {
      ASSERT_EQ(f->image->bgr.size(), k.image->bgr.size());
      ASSERT_EQ(f->image->bgr.type(), k.image->bgr.type());
      EXPECT_EQ(cv::norm(f->image->bgr, k.image->bgr, cv::NORM_INF), 0.0) << "image differs";
    }
    ++i;
  }
  EXPECT_EQ(i, seq.size());
  ASSERT_EQ(src.camera().has_value(), seq.camera().has_value());
  if (seq.camera()) {
    // KITTI's Tr is orthonormal to ~5e-8 only and MRPT stores rigid poses, so compare what
    // matters: where points 2-50 m away land in the image (well under a thousandth of a pixel).
    const auto a = src.camera()->lidarToPixel(), b = seq.camera()->lidarToPixel();
    for (const Eigen::Vector3d& p :
         {Eigen::Vector3d(2, 0.5, -1), Eigen::Vector3d(10, -3, 0), Eigen::Vector3d(50, 8, 2)}) {
      const Eigen::Vector3d pa = a * p.homogeneous(), pb = b * p.homogeneous();
      EXPECT_LT((pa.head<2>() / pa.z() - pb.head<2>() / pb.z()).norm(), 1e-3);
    }
    EXPECT_EQ(src.camera()->width, seq.camera()->width);
    EXPECT_EQ(src.camera()->height, seq.camera()->height);
  }
}

}  // namespace

class RawlogRoundTrip : public ::testing::TestWithParam<std::string> {};

TEST_P(RawlogRoundTrip, EmbeddedIsBitIdentical) {
  CLEANMAP_REQUIRE_DATASET(GetParam());
  const auto seq = io::KittiSequence::open(test::dataDir() + "/" + GetParam());
  const auto out = test::scratchDir("rt_" + GetParam()) / "seq.rawlog";
  convert(seq, out.string(), false);
  expectSameAsKitti(seq, out.string());
}

TEST_P(RawlogRoundTrip, ExternalIsBitIdentical) {
  CLEANMAP_REQUIRE_DATASET(GetParam());
  const auto seq = io::KittiSequence::open(test::dataDir() + "/" + GetParam());
  const auto out = test::scratchDir("rt_ext_" + GetParam()) / "seq.rawlog";
  convert(seq, out.string(), true);
  EXPECT_LT(fs::file_size(out), 100000u) << "external rawlog should hold references only";
  expectSameAsKitti(seq, out.string());
}

// A .simplemap (cleanmap-kitti2rawlog OUT.simplemap): a keyframe per scan at its pose, read back
// as the folder; a frame without a pose is an error that leaves nothing.
TEST_P(RawlogRoundTrip, SimplemapIsBitIdentical) {
  CLEANMAP_REQUIRE_DATASET(GetParam());
  const auto seq = io::KittiSequence::open(test::dataDir() + "/" + GetParam());
  const auto dir = test::scratchDir("rt_sm_" + GetParam());
  convert(seq, (dir / "seq.simplemap").string(), false);
  {
    cleanmap::mrpt::RawlogSource src((dir / "seq.simplemap").string());
    EXPECT_TRUE(src.isSimplemap());
  }
  expectSameAsKitti(seq, (dir / "seq.simplemap").string());
  Frame unposed = seq.frame(0);
  unposed.scan.has_pose = false;
  test::expectError(
      [&] {
        cleanmap::mrpt::RawlogWriter w((dir / "unposed.simplemap").string());
        w.write(unposed, seq.camera());
      },
      "unposed.simplemap", "frame " + unposed.stem + " has no pose");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
}

INSTANTIATE_TEST_SUITE_P(SharedData, RawlogRoundTrip,
                         ::testing::Values("kitti_city", "kitti_highway", "kitti_residential"));

TEST(RawlogSource, ReadsMrptVelodyneScan) {
  const std::string path = std::string(CLEANMAP_MRPT_DATASETS_DIR) + "/test_velodyne_VLP16.rawlog";
  if (!fs::exists(path)) {
    if (test::inCI()) FAIL() << "mrpt-common missing: " << path;
    GTEST_SKIP() << "mrpt-common not installed: " << path;
  }
  cleanmap::mrpt::RawlogSource src(path);
  const auto f = src.next();
  ASSERT_TRUE(f.has_value());
  EXPECT_GT(f->scan.size(), 10000u);  // a VLP-16 sweep: 16 rings x ~1800 azimuths
  double max_range = 0;
  for (const auto& p : f->scan.points) max_range = std::max<double>(max_range, p.xyz().norm());
  EXPECT_LT(max_range, 130.0);  // VLP-16 spec: 100 m
  EXPECT_GT(max_range, 2.0);
  EXPECT_FALSE(f->scan.has_pose);
  // DESIGN §2.0: each point's firing time after the observation's (the first firing's): a sweep
  // of a 5-20 Hz lidar, later firings turned further clockwise (MRPT's y = -sin(azimuth)).
  ASSERT_EQ(f->scan.point_time.size(), f->scan.size());
  const auto [lo, hi] = std::minmax_element(f->scan.point_time.begin(), f->scan.point_time.end());
  EXPECT_GE(*lo, 0.0f);
  EXPECT_GT(*hi, 0.04f);
  EXPECT_LT(*hi, 0.21f);
  std::size_t turned = 0, pairs = 0;
  for (std::size_t i = 400; i < f->scan.size(); ++i) {  // 400 returns: about 25 firings apart
    const auto& a = f->scan.points[i - 400];
    const auto& b = f->scan.points[i];
    const float dt = f->scan.point_time[i] - f->scan.point_time[i - 400];
    if (dt <= 0 || dt > 0.01f) continue;
    const float cross = a.x * b.y - a.y * b.x;  // > 0: counter-clockwise from a to b
    ++pairs;
    turned += cross < 0;
  }
  EXPECT_GT(pairs, 1000u);
  EXPECT_GT(double(turned), 0.9 * double(pairs)) << "firings turn clockwise seen from above";
}

TEST(RawlogSource, ReadsMrpt3DRangeScan) {
  const std::string path = std::string(CLEANMAP_MRPT_DATASETS_DIR) + "/tests_rgbd.rawlog";
  if (!fs::exists(path)) {
    if (test::inCI()) FAIL() << "mrpt-common missing: " << path;
    GTEST_SKIP() << "mrpt-common not installed: " << path;
  }
  cleanmap::mrpt::RawlogSource src(path);
  const auto f = src.next();
  ASSERT_TRUE(f.has_value());
  EXPECT_GT(f->scan.size(), 1000u);
  for (const auto& p : f->scan.points) ASSERT_LT(p.xyz().norm(), 20.0f);  // an indoor RGB-D scene
}

TEST(RawlogSource, MissingEmptyAndGarbageFilesAreErrors) {
  test::expectError([] { cleanmap::mrpt::RawlogSource("/nonexistent/a.rawlog"); },
                    "/nonexistent/a.rawlog", "does not exist");
  const auto dir = test::scratchDir("rawlog_bad");
  std::ofstream(dir / "empty.rawlog").close();
  test::expectError([&] { cleanmap::mrpt::RawlogSource((dir / "empty.rawlog").string()); },
                    "empty.rawlog", "is empty (0 bytes)");
  // A gzip-compressed rawlog cut before its first deflate block ends decompresses to nothing.
  {
    ::mrpt::io::CFileGZOutputStream out((dir / "whole.rawlog").string());
    auto ar = ::mrpt::serialization::archiveFrom(out);
    auto pc = ::mrpt::obs::CObservationPointCloud::Create();
    ar << *pc;
  }
  fs::copy_file(dir / "whole.rawlog", dir / "cut.rawlog");
  fs::resize_file(dir / "cut.rawlog", 10);  // the gzip header alone
  test::expectError([&] { cleanmap::mrpt::RawlogSource((dir / "cut.rawlog").string()); },
                    "cut.rawlog", "holds no complete MRPT object (cut short, or not a rawlog)");
  std::ofstream(dir / "text.rawlog") << "this is not a rawlog, just some text that goes on\n";
  test::expectError([&] { cleanmap::mrpt::RawlogSource((dir / "text.rawlog").string()); },
                    "text.rawlog", "is not an MRPT rawlog");
}

TEST(RawlogSource, TruncatedRawlogIsAnError) {
  CLEANMAP_REQUIRE_DATASET("kitti_city");
  const auto seq = io::KittiSequence::open(test::dataDir() + "/kitti_city");
  const auto dir = test::scratchDir("rawlog_trunc");
  const auto full = dir / "full.rawlog";
  convert(seq, full.string(), false, 4);
  fs::copy_file(full, dir / "cut.rawlog");
  fs::resize_file(dir / "cut.rawlog", fs::file_size(full) * 5 / 8);
  test::expectError(
      [&] {
        cleanmap::mrpt::RawlogSource src((dir / "cut.rawlog").string());
        while (src.next()) {
        }
      },
      "cut.rawlog", "truncated or corrupt rawlog at entry");
}

TEST(RawlogWriter, UnfinishedWriteLeavesNothing) {
  CLEANMAP_REQUIRE_DATASET("kitti_city");
  const auto seq = io::KittiSequence::open(test::dataDir() + "/kitti_city");
  const auto dir = test::scratchDir("rawlog_unfinished");
  {
    cleanmap::mrpt::RawlogWriter w((dir / "x.rawlog").string());
    w.write(seq.frame(0), std::nullopt);
    // destroyed without close(): as if the run was interrupted by an exception
  }
  EXPECT_TRUE(fs::is_empty(dir)) << "a partial rawlog or temporary was left behind";
}

// A disk that fills up, during the writes or in close()'s last flush (cut 8 bytes short: the
// gzip trailer, which MRPT's own close() would not report): one line naming the rawlog, no file.
TEST(RawlogWriter, FullDiskIsAClearErrorAndLeavesNothing) {
  CLEANMAP_REQUIRE_DATASET("kitti_city");
  const auto seq = io::KittiSequence::open(test::dataDir() + "/kitti_city");
  const auto dir = test::scratchDir("rawlog_full");
  convert(seq, (dir / "whole.rawlog").string(), false, 4);
  const std::uint64_t whole = fs::file_size(dir / "whole.rawlog");
  fs::remove(dir / "whole.rawlog");
  for (const std::uint64_t limit : {std::uint64_t{64} << 10, whole - 8}) {
    {
      const test::FileSizeLimit disk(limit);
      test::expectError([&] { convert(seq, (dir / "x.rawlog").string(), false, 4); }, "x.rawlog",
                        "write failed (disk full?)");
    }
    EXPECT_TRUE(fs::is_empty(dir)) << "a file was left with " << limit << " bytes a file";
  }
}

TEST(RawlogSource, EmptyScanIsAnErrorUnlessAllowed) {
  const auto dir = test::scratchDir("rawlog_emptyscan");
  {
    cleanmap::mrpt::RawlogWriter w((dir / "e.rawlog").string());
    Frame f;
    f.scan.timestamp = 1.0;
    w.write(f, std::nullopt);
    w.close();
  }
  cleanmap::mrpt::RawlogSource strict((dir / "e.rawlog").string());
  test::expectError([&] { strict.next(); }, "e.rawlog", "scan 000000 is empty");
  cleanmap::mrpt::RawlogReadOptions allow;
  allow.allow_empty_scans = true;
  cleanmap::mrpt::RawlogSource lenient((dir / "e.rawlog").string(), allow);
  const auto f = lenient.next();
  ASSERT_TRUE(f.has_value());
  EXPECT_TRUE(f->scan.empty());
}

// A lidar's scans timed earlier than the scan before them (a glitch, rawlogs joined out of order)
// are read in file order and counted; a repeated time is no step back.
TEST(RawlogSource, ScansTimedBackAreTakenInFileOrderAndCounted) {
  const auto dir = test::scratchDir("rawlog_timed_back");
  const std::string path = (dir / "back.rawlog").string();
  const std::vector<double> times = {1.0, 1.1, 0.5, 0.6, 0.6, 0.45, 0.7};
  {
    cleanmap::mrpt::RawlogWriter w(path);
    for (std::size_t k = 0; k < times.size(); ++k) {
      Frame f;
      f.index = k;
      f.scan.timestamp = times[k];
      f.scan.points = {PointXYZI{float(k), 0, -1, 0}, PointXYZI{float(k), 1, -1, 0}};
      w.write(f, std::nullopt);
    }
    w.close();
  }
  cleanmap::mrpt::RawlogSource src(path);
  std::vector<float> order;
  while (auto f = src.next()) {
    order.push_back(f->scan.points.at(0).x);
    if (order.size() == 2) {
      EXPECT_EQ(src.scansTimedBack(), 0u);
    }
  }
  EXPECT_EQ(order, (std::vector<float>{0, 1, 2, 3, 4, 5, 6}));
  EXPECT_EQ(src.scansTimedBack(), 2u);  // 0.5 after 1.1 and 0.45 after 0.6
  const std::string first = src.firstTimedBack();
  EXPECT_NE(first.find("back.rawlog entry "), std::string::npos) << first;
  EXPECT_NE(first.find(", 0.600 s before the scan before"), std::string::npos) << first;
  EXPECT_EQ(cleanmap::mrpt::timedBackWarning(src).rfind(
                "2 scans are timed earlier than the scan before (the first: " + first + ")", 0),
            0u)
      << cleanmap::mrpt::timedBackWarning(src);
}

namespace {

// The VLP-16 sweep of mrpt-common, as MRPT's own packets decode it (with calibration).
::mrpt::obs::CObservationVelodyneScan::Ptr readVelodyneSweep(const std::string& path) {
  cleanmap::mrpt::registerClasses();
  ::mrpt::io::CFileGZInputStream in(path);
  auto ar = ::mrpt::serialization::archiveFrom(in);
  ::mrpt::obs::CActionCollection::Ptr acts;
  ::mrpt::obs::CSensoryFrame::Ptr sf;
  ::mrpt::obs::CObservation::Ptr obs;
  std::size_t idx = 0;
  while (::mrpt::obs::CRawlog::getActionObservationPairOrObservation(ar, acts, sf, obs, idx))
    if (auto v = std::dynamic_pointer_cast<::mrpt::obs::CObservationVelodyneScan>(obs)) return v;
  return {};
}

}  // namespace

// A CObservationRotatingScan keeps ranges per (laser, firing) without calibration: read with the
// VLP-16 ring elevations and a linear azimuth per column, it must give the points MRPT computes
// from the packets, up to the azimuth interpolation (<= 0.2 deg, 3.5 cm at 10 m).
TEST(RawlogSource, ReadsMrptRotatingScanAsThePacketsGive) {
  const std::string path = std::string(CLEANMAP_MRPT_DATASETS_DIR) + "/test_velodyne_VLP16.rawlog";
  if (!fs::exists(path)) {
    if (test::inCI()) FAIL() << "mrpt-common missing: " << path;
    GTEST_SKIP() << "mrpt-common not installed: " << path;
  }
  const auto velo = readVelodyneSweep(path);
  ASSERT_TRUE(velo);
  const auto ref = cleanmap::mrpt::scanFromObservation(*velo);
  ASSERT_TRUE(ref && ref->size() > 10000u);
  ::mrpt::obs::CObservationRotatingScan rot;
  rot.fromVelodyne(*velo);
  const auto got = cleanmap::mrpt::scanFromObservation(rot);
  ASSERT_TRUE(got.has_value());
  EXPECT_NEAR(double(got->size()), double(ref->size()), 0.05 * double(ref->size()));
  // DESIGN §2.0: the columns' times over the sweep, as the packets' firings.
  ASSERT_GT(rot.sweepDuration, 0.0);
  ASSERT_EQ(got->point_time.size(), got->size());
  const auto [lo, hi] = std::minmax_element(got->point_time.begin(), got->point_time.end());
  const auto [rlo, rhi] = std::minmax_element(ref->point_time.begin(), ref->point_time.end());
  EXPECT_NEAR(*lo, *rlo, 0.002);
  EXPECT_NEAR(*hi, *rhi, 0.002);

  // Nearest reference point of each converted point, through a 0.5 m hash grid.
  std::unordered_map<uint64_t, std::vector<Eigen::Vector3f>> grid;
  auto key = [](const Eigen::Vector3f& p, int dx, int dy, int dz) {
    const auto c = [](float v, int d) {
      return uint64_t(int64_t(std::floor(v / 0.5f)) + d + 4096);
    };
    return (c(p.x(), dx) << 26) | (c(p.y(), dy) << 13) | c(p.z(), dz);
  };
  for (const auto& p : ref->points) grid[key(p.xyz(), 0, 0, 0)].push_back(p.xyz());
  std::vector<float> err;
  std::size_t near_sensor = 0;
  for (const auto& p : got->points) {
    float best = 1e9f;
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz)
          if (auto it = grid.find(key(p.xyz(), dx, dy, dz)); it != grid.end())
            for (const auto& q : it->second) best = std::min(best, (q - p.xyz()).norm());
    err.push_back(best / std::max(1.0f, p.xyz().norm() / 10.0f));  // per 10 m of range
    near_sensor += p.xyz().norm() < 1.0f;
  }
  std::sort(err.begin(), err.end());
  EXPECT_LT(err[err.size() / 2], 0.035f) << "median distance to the packet points, per 10 m";
  EXPECT_LT(err[err.size() * 95 / 100], 0.10f) << "95th percentile, per 10 m";
  EXPECT_EQ(near_sensor, 0u);
}

TEST(RawlogSource, ReadsMrptRotatingScanRawlog) {
  const std::string path = std::string(CLEANMAP_MRPT_DATASETS_DIR) + "/rot_scan_velodyne.rawlog";
  if (!fs::exists(path)) {
    if (test::inCI()) FAIL() << "mrpt-common missing: " << path;
    GTEST_SKIP() << "mrpt-common not installed: " << path;
  }
  cleanmap::mrpt::RawlogSource src(path);
  const auto f = src.next();
  ASSERT_TRUE(f.has_value());
  EXPECT_GT(f->scan.size(), 10000u);  // 11305 returns in the range image
  for (const auto& p : f->scan.points) ASSERT_LT(p.xyz().norm(), 121.0f);  // maxRange 120 m
}

TEST(RawlogSource, RotatingScanOfUnknownModelIsAClearError) {
  ::mrpt::obs::CObservationRotatingScan rot;
  rot.sensorLabel = "LIDAR";
  rot.lidarModel = "OS1-64";
  rot.rowCount = 64;
  rot.columnCount = 4;
  rot.rangeImage.setZero(64, 4);
  rot.rangeResolution = 0.01;
  try {
    cleanmap::mrpt::scanFromObservation(rot);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("OS1-64"), std::string::npos) << e.what();
  }
}

namespace {

// A pinhole camera (no distortion) of focal lengths fx, fy and principal point cx, cy.
PinholeCamera pinhole(double fx, double fy, double cx, double cy, int width, int height) {
  PinholeCamera cam;
  cam.name = "cam";
  cam.P << fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0;
  cam.width = width;
  cam.height = height;
  return cam;
}

}  // namespace

// One lidar and one camera per run: a car logging a roof Velodyne ("LIDAR") beside a front one
// ("FRONT"), an Ouster cleanmap cannot decode, and two cameras. By default the first lidar's and
// the first camera's observations are read, the others skipped (not decoded) and counted per
// sensorLabel; a label chooses; a label the rawlog lacks is an error naming the labels it has.
TEST(RawlogSource, ReadsOneLidarAndOneCameraByLabel) {
  const auto dir = test::scratchDir("rawlog_two_lidars");
  const std::string path = (dir / "two.rawlog").string();
  const PinholeCamera cam = pinhole(500, 500, 32, 24, 64, 48);
  {
    ::mrpt::io::CFileGZOutputStream out(path);
    auto ar = ::mrpt::serialization::archiveFrom(out);
    for (int k = 0; k < 3; ++k) {
      const double t = 10.0 + 0.1 * k;
      for (const auto& [label, x] : {std::pair{"LIDAR", 5.0f}, std::pair{"FRONT", 9.0f}}) {
        auto pc = ::mrpt::obs::CObservationPointCloud::Create();
        pc->sensorLabel = label;
        pc->timestamp = cleanmap::mrpt::toMrptTime(t);
        pc->pointcloud = cleanmap::mrpt::toPointsMap(
            {PointXYZI{x, 0, -1, 0}, PointXYZI{x, 1, -1, 0}, PointXYZI{x, 2, -1, float(k)}});
        ar << *pc;
      }
      ::mrpt::obs::CObservationRotatingScan rot;  // a third lidar that cleanmap cannot decode
      rot.sensorLabel = "OUSTER";
      rot.timestamp = cleanmap::mrpt::toMrptTime(t);
      rot.lidarModel = "OS1-64";
      rot.rowCount = 64;
      rot.columnCount = 4;
      rot.rangeImage.setZero(64, 4);
      rot.rangeResolution = 0.01;
      ar << rot;
      for (const auto& [label, grey] : {std::pair{"CAM_L", 50}, std::pair{"CAM_R", 200}}) {
        auto img = ::mrpt::obs::CObservationImage::Create();
        img->sensorLabel = label;
        img->timestamp = cleanmap::mrpt::toMrptTime(t);
        img->cameraParams = cleanmap::mrpt::toTCamera(cam, img->cameraPose);
        img->image = ::mrpt::img::CImage(cv::Mat(48, 64, CV_8UC3, cv::Scalar::all(grey)),
                                         ::mrpt::img::DEEP_COPY);
        ar << *img;
      }
    }
  }
  auto read = [&](const std::string& lidar, const std::string& camera) {
    cleanmap::mrpt::RawlogReadOptions o;
    o.lidar_label = lidar;
    o.camera_label = camera;
    cleanmap::mrpt::RawlogSource src(path, o);
    std::vector<float> x;
    std::vector<int> grey;
    while (auto f = src.next()) {
      x.push_back(f->scan.points.at(0).x);
      grey.push_back(f->image ? f->image->bgr.at<cv::Vec3b>(0, 0)[0] : -1);
    }
    return std::tuple{
        x, grey, src.lidarLabel(), src.cameraLabel(), src.otherLidars(), src.otherCameras()};
  };
  {
    const auto [x, grey, lidar, camera, other_lidars, other_cameras] = read("", "");
    EXPECT_EQ(x, (std::vector<float>{5, 5, 5}));  // the roof lidar's scans, not six
    EXPECT_EQ(grey, (std::vector<int>{50, 50, 50}));
    EXPECT_EQ(lidar, "LIDAR");
    EXPECT_EQ(camera, "CAM_L");
    // Not read, so the third lidar's scans (an unknown model: an error if decoded) are no error.
    EXPECT_EQ(other_lidars, (std::map<std::string, std::size_t>{{"FRONT", 3}, {"OUSTER", 3}}));
    EXPECT_EQ(other_cameras, (std::map<std::string, std::size_t>{{"CAM_R", 3}}));
  }
  {
    const auto [x, grey, lidar, camera, other_lidars, other_cameras] = read("FRONT", "CAM_R");
    EXPECT_EQ(x, (std::vector<float>{9, 9, 9}));
    EXPECT_EQ(grey, (std::vector<int>{200, 200, 200}));
    EXPECT_EQ(other_lidars, (std::map<std::string, std::size_t>{{"LIDAR", 3}, {"OUSTER", 3}}));
  }
  test::expectError([&] { read("VELODYNE", ""); }, "two.rawlog",
                    "holds no scans of lidar 'VELODYNE'; its lidars: 'FRONT' (3), 'LIDAR' (3), "
                    "'OUSTER' (3)");
  cleanmap::mrpt::InputOptions kitti;
  kitti.lidar_label = "LIDAR";
  test::expectError([&] { cleanmap::mrpt::openInput(dir.string(), kitti); }, dir.string(),
                    "is a KITTI folder: a lidar or camera label selects the sensors of a rawlog");
}

// A camera whose calibration gives an image size no camera has (MRPT keeps any uint32; found by
// fuzzing: the rectifier asked for 128 GB) is one line naming the rawlog and the camera, with
// lens distortion or without. A distorted camera of a size cameras have, 32768 x 32768, whose
// images are 640 x 480, is refused at its first image, before the rectifier's maps are made for
// the size the calibration claims (found by fuzzing: 8200 x 16384 took 7 s and 1.9 GB before its
// 8 x 4 image was refused; 32768 x 32768 would take over 8 GB).
TEST(RawlogSource, ACameraOfNoCamerasSizeIsAClearError) {
  const auto dir = test::scratchDir("rawlog_camera_size");
  for (const bool distorted : {true, false}) {
    for (const auto& [w, h] :
         {std::pair{1u << 30, 480u}, std::pair{640u, 0u}, std::pair{1u << 15, 1u << 15}}) {
      if (w == h && !distorted) continue;  // no maps; the camera stage refuses its images
      const std::string path = (dir / "cam.rawlog").string();
      {
        ::mrpt::io::CFileGZOutputStream out(path);
        auto ar = ::mrpt::serialization::archiveFrom(out);
        auto pc = ::mrpt::obs::CObservationPointCloud::Create();
        pc->sensorLabel = "LIDAR";
        pc->timestamp = cleanmap::mrpt::toMrptTime(5.0);
        pc->pointcloud = cleanmap::mrpt::toPointsMap({PointXYZI{10, 0, 0, 0}});
        ar << *pc;
        auto im = ::mrpt::obs::CObservationImage::Create();
        im->sensorLabel = "CAMERA";
        im->timestamp = pc->timestamp;
        im->cameraParams =
            cleanmap::mrpt::toTCamera(w == h ? pinhole(30000, 30000, w / 2, h / 2, 640, 480)
                                             : pinhole(600, 590, 322, 238, 640, 480),
                                      im->cameraPose);
        if (distorted) im->cameraParams.setDistortionPlumbBob(-0.3, 0.1, 0.002, -0.001, 0);
        im->cameraParams.ncols = w;
        im->cameraParams.nrows = h;
        im->image = ::mrpt::img::CImage(cv::Mat(480, 640, CV_8UC3, cv::Scalar::all(9)),
                                        ::mrpt::img::DEEP_COPY);
        ar << *im;
      }
      const auto read = [&] {
        cleanmap::mrpt::RawlogSource src(path);
        while (src.next()) {
        }
      };
      if (w == h)
        test::expectError(read, "cam.rawlog",
                          "is 640x480 px, its camera's calibration 32768x32768");
      else
        test::expectError(read, "cam.rawlog",
                          "camera 'CAMERA': its calibration gives images of " + std::to_string(w) +
                              " x " + std::to_string(h) +
                              " pixels; a camera's are 1 to 32768 pixels a side");
    }
  }
}

// DESIGN §3 "Lens distortion": a rawlog camera with lens distortion (MRPT's plumb_bob model) is
// made pinhole: its images are rectified as they are read and the camera delivered is their
// pinhole model, so a lidar point projects onto what the camera saw there (a dot drawn where the
// distorted camera saw the point lands within half a pixel of its projection).
TEST(RawlogSource, RectifiesACameraWithLensDistortion) {
  const auto dir = test::scratchDir("rawlog_distorted_camera");
  const std::string path = (dir / "cam.rawlog").string();
  PinholeCamera cam = pinhole(600, 590, 322, 238, 640, 480);
  Eigen::Matrix3d R;  // lidar (x forward, z up) to optical (x right, y down, z forward)
  R << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  cam.T_cam_lidar.linear() = R;
  cam.T_cam_lidar.translation() = Eigen::Vector3d(0.05, -0.1, 0.2);
  const std::vector<Eigen::Vector3d> targets = {
      {10, 0, 0}, {8, 4, 1}, {9, -4.5, -2}, {6, 3.5, 2.2}, {7, -1, 2.5}};
  ::mrpt::poses::CPose3D cam_pose;
  ::mrpt::img::TCamera tc = cleanmap::mrpt::toTCamera(cam, cam_pose);
  tc.setDistortionPlumbBob(-0.3, 0.1, 0.002, -0.001, 0);
  vision::Lens lens;
  std::copy(tc.dist.begin(), tc.dist.end(), lens.k.begin());
  cv::Mat img(480, 640, CV_8UC3, cv::Scalar::all(0));
  for (const auto& p : targets) {
    const Eigen::Vector3d c = cam.T_cam_lidar * p;
    const Eigen::Vector2d d = vision::distortNormalised(lens, c.head<2>() / c.z());
    cv::circle(img,
               cv::Point(int(std::lround((600 * d.x() + 322) * 16)),
                         int(std::lround((590 * d.y() + 238) * 16))),
               40, cv::Scalar::all(255), cv::FILLED, cv::LINE_AA, 4);
  }
  {
    ::mrpt::io::CFileGZOutputStream out(path);
    auto ar = ::mrpt::serialization::archiveFrom(out);
    auto pc = ::mrpt::obs::CObservationPointCloud::Create();
    pc->sensorLabel = "LIDAR";
    pc->timestamp = cleanmap::mrpt::toMrptTime(5.0);
    std::vector<PointXYZI> pts;
    for (const auto& p : targets)
      pts.push_back(PointXYZI{float(p.x()), float(p.y()), float(p.z()), 0});
    pc->pointcloud = cleanmap::mrpt::toPointsMap(pts);
    ar << *pc;
    auto im = ::mrpt::obs::CObservationImage::Create();
    im->sensorLabel = "CAMERA";
    im->timestamp = cleanmap::mrpt::toMrptTime(5.0);
    im->cameraParams = tc;
    im->cameraPose = cam_pose;
    im->image = ::mrpt::img::CImage(img, ::mrpt::img::DEEP_COPY);
    ar << *im;
  }
  cleanmap::mrpt::RawlogSource src(path);
  const auto f = src.next();
  ASSERT_TRUE(f && f->image);
  ASSERT_TRUE(src.camera());
  const PinholeCamera got = *src.camera();
  EXPECT_EQ(got.width, 640);
  EXPECT_LT(got.focal(), 600.0);  // a barrel lens: the rectified view is wider
  cv::Mat grey;
  cv::cvtColor(f->image->bgr, grey, cv::COLOR_BGR2GRAY);
  for (const auto& p : targets) {
    const auto uv = got.project(p);
    ASSERT_TRUE(uv) << p.transpose();
    double sum = 0, su = 0, sv = 0;
    for (int dv = -6; dv <= 6; ++dv)
      for (int du = -6; du <= 6; ++du) {
        const int x = int(std::lround(uv->x())) + du, y = int(std::lround(uv->y())) + dv;
        const double g = grey.at<uint8_t>(y, x);
        sum += g, su += g * x, sv += g * y;
      }
    ASSERT_GT(sum, 1000) << "no dot where " << p.transpose() << " projects";
    EXPECT_NEAR(su / sum, uv->x(), 0.5) << p.transpose();
    EXPECT_NEAR(sv / sum, uv->y(), 0.5) << p.transpose();
  }
}

// A rawlog of a 2D laser (or of anything but a 3D lidar) is refused with one line that says what
// it holds instead.
TEST(RawlogSource, ARawlogWithoutLidarSaysWhatItHolds) {
  const auto dir = test::scratchDir("rawlog_2d");
  const std::string path = (dir / "planar.rawlog").string();
  {
    ::mrpt::io::CFileGZOutputStream out(path);
    auto ar = ::mrpt::serialization::archiveFrom(out);
    for (int k = 0; k < 3; ++k) {
      auto scan = ::mrpt::obs::CObservation2DRangeScan::Create();
      scan->sensorLabel = "LASER";
      scan->resizeScan(10);
      ar << *scan;
    }
    ar << *::mrpt::obs::CObservationGPS::Create();
  }
  test::expectError([&] { cleanmap::mrpt::RawlogSource src(path); }, "planar.rawlog",
                    "holds no point-cloud observations (CObservationPointCloud, "
                    "CObservationVelodyneScan, CObservationRotatingScan or "
                    "CObservation3DRangeScan); it holds mrpt::obs::CObservation2DRangeScan (3), "
                    "mrpt::obs::CObservationGPS (1)");
}

// A rawlog whose scans and images MRPT keeps in external files named relative to it, in
// "<name>_Images" beside it (as rawlog-edit --externalize writes them), reads as the same data
// embedded, from any working folder; its external folder is reported (no output may replace it);
// a missing external scan is one line naming the rawlog and the entry.
TEST(RawlogSource, ReadsRelativeExternalFilesFromTheRawlogsImagesFolder) {
  const auto dir = test::scratchDir("rawlog_relative_external");
  const fs::path images = dir / "ext_Images";
  fs::create_directories(images);
  const PinholeCamera cam = pinhole(500, 500, 32, 24, 64, 48);
  const std::vector<PointXYZI> pts = {{5, 0, -1, 0.25f}, {5, 1, -1, 0.5f}, {6, 2, -1, 0.75f}};
  auto write = [&](const std::string& name, bool missing_scan) {
    ::mrpt::io::CFileGZOutputStream out((dir / name).string());
    auto ar = ::mrpt::serialization::archiveFrom(out);
    for (int k = 0; k < 2; ++k) {
      const std::string bin = "pc_" + std::to_string(k) + ".bin";
      if (!missing_scan || k == 0) {
        std::ofstream f(images / bin, std::ios::binary);
        for (const auto& p : pts) {
          const float v[4] = {p.x + float(k), p.y, p.z, p.intensity};
          f.write(reinterpret_cast<const char*>(v), sizeof v);
        }
      } else {
        fs::remove(images / bin);
      }
      auto pc = ::mrpt::obs::CObservationPointCloud::Create();
      pc->sensorLabel = "LIDAR";
      pc->timestamp = cleanmap::mrpt::toMrptTime(10.0 + 0.1 * k);
      pc->setAsExternalStorage(
          bin, ::mrpt::obs::CObservationPointCloud::ExternalStorageFormat::KittiBinFile);
      ar << *pc;
      auto img = ::mrpt::obs::CObservationImage::Create();
      img->sensorLabel = "CAM";
      img->timestamp = pc->timestamp;
      img->cameraParams = cleanmap::mrpt::toTCamera(cam, img->cameraPose);
      const std::string png = "img_" + std::to_string(k) + ".png";
      ::mrpt::img::CImage(cv::Mat(48, 64, CV_8UC3, cv::Scalar::all(40 + 100 * k)),
                          ::mrpt::img::DEEP_COPY)
          .saveToFile((images / png).string());
      img->image.setExternalStorage(png);
      ar << *img;
    }
  };
  write("ext.rawlog", false);
  const fs::path cwd = fs::current_path();
  fs::current_path(fs::temp_directory_path());  // not where the rawlog is
  std::vector<Frame> frames;
  std::set<std::string> folders;
  try {
    cleanmap::mrpt::RawlogSource src((dir / "ext.rawlog").string());
    folders = src.externalFolders();
    while (auto f = src.next()) frames.push_back(std::move(*f));
  } catch (const std::exception& e) {
    ADD_FAILURE() << e.what();
  }
  fs::current_path(cwd);
  ASSERT_EQ(frames.size(), 2u);
  for (int k = 0; k < 2; ++k) {
    ASSERT_EQ(frames[k].scan.points.size(), pts.size());
    EXPECT_EQ(frames[k].scan.points[2].x, 6.0f + float(k));
    EXPECT_EQ(frames[k].scan.points[1].intensity, 0.5f);
    ASSERT_TRUE(frames[k].image.has_value());
    EXPECT_EQ(frames[k].image->bgr.at<cv::Vec3b>(10, 10)[1], 40 + 100 * k);
  }
  EXPECT_EQ(folders, (std::set<std::string>{fs::absolute(images).lexically_normal().string()}));

  write("cut.rawlog", true);
  fs::rename(images, dir / "cut_Images");
  test::expectError(
      [&] {
        cleanmap::mrpt::RawlogSource src((dir / "cut.rawlog").string());
        while (src.next()) {
        }
      },
      "cut.rawlog", "entry 2: the scan's external file");
}

// An external file name MRPT cannot resolve (2 characters or fewer: MRPT asserts, naming neither
// the rawlog nor the entry; found by fuzzing) is one line naming the rawlog, the entry and the
// name, for a scan and for an image alike.
TEST(RawlogSource, AnExternalNameMrptCannotResolveIsAClearError) {
  const auto dir = test::scratchDir("rawlog_external_name");
  auto write = [&](const std::string& name, const std::string& scan, const std::string& image) {
    ::mrpt::io::CFileGZOutputStream out((dir / name).string());
    auto ar = ::mrpt::serialization::archiveFrom(out);
    auto img = ::mrpt::obs::CObservationImage::Create();
    img->sensorLabel = "CAM";
    img->timestamp = cleanmap::mrpt::toMrptTime(10.0);
    img->image.setExternalStorage(image);
    ar << *img;
    auto pc = ::mrpt::obs::CObservationPointCloud::Create();
    pc->sensorLabel = "LIDAR";
    pc->timestamp = img->timestamp;
    pc->setAsExternalStorage(
        scan, ::mrpt::obs::CObservationPointCloud::ExternalStorageFormat::KittiBinFile);
    ar << *pc;
  };
  const auto read = [&](const std::string& name) {
    cleanmap::mrpt::RawlogSource src((dir / name).string());
    while (src.next()) {
    }
  };
  write("scan.rawlog", "ab", "image.png");
  test::expectError([&] { read("scan.rawlog"); }, "scan.rawlog",
                    "entry 1: the scan's external file name \"ab\" cannot be resolved (");
  write("image.rawlog", "scan.bin", "x");
  test::expectError([&] { read("image.rawlog"); }, "image.rawlog",
                    "entry 0: the image's external file name \"x\" cannot be resolved (");
}

// A compressed rawlog whose data check fails at its end (gzread fails, and MRPT's stream returns
// its -1 as a count) is one line naming the rawlog and what is wrong; so is one whose deflate
// data is corrupt in the middle.
TEST(RawlogSource, CorruptCompressedDataIsAClearError) {
  const auto dir = test::scratchDir("rawlog_corrupt_gz");
  {
    ::mrpt::io::CFileGZOutputStream out((dir / "ok.rawlog").string());
    auto ar = ::mrpt::serialization::archiveFrom(out);
    for (int k = 0; k < 4; ++k) {
      auto pc = ::mrpt::obs::CObservationPointCloud::Create();
      pc->sensorLabel = "LIDAR";
      pc->timestamp = cleanmap::mrpt::toMrptTime(10.0 + 0.1 * k);
      pc->pointcloud = ::mrpt::maps::CSimplePointsMap::Create();
      for (int i = 0; i < 100; ++i) pc->pointcloud->insertPoint(5 + 0.01f * float(i), float(k), -1);
      ar << *pc;
    }
  }
  std::ifstream f(dir / "ok.rawlog", std::ios::binary);
  const std::string good((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  ASSERT_GT(good.size(), 100u);
  const auto readCorrupt = [&](std::size_t at, std::size_t n) {
    std::string bad = good;
    for (std::size_t i = at; i < at + n; ++i) bad[i] = static_cast<char>(bad[i] ^ 0x5a);
    std::ofstream((dir / "bad.rawlog").string(), std::ios::binary) << bad;
    cleanmap::mrpt::RawlogSource src((dir / "bad.rawlog").string());
    while (src.next()) {
    }
  };
  // The gzip trailer: the CRC-32 of the data, then its length.
  test::expectError([&] { readCorrupt(good.size() - 8, 4); }, "bad.rawlog",
                    "corrupt compressed data (gzread failed)");
  test::expectError([&] { readCorrupt(good.size() / 2, 8); }, "bad.rawlog", "rawlog");
}

// MRPT 2.5.8 crashes reading a CSimpleMap of its first format (version 0) whose pose is missing
// (found by fuzzing). Such a simplemap, or such an entry of a rawlog, is one line; so is it for
// cleanmap-build-map's reader of a whole simplemap. Where the file reads, the peeking changes
// nothing: a version-1 simplemap loads whole.
TEST(RawlogSource, ASimplemapOfMrptsFirstFormatIsAClearError) {
  const auto dir = test::scratchDir("rawlog_simplemap_v0");
  const auto write = [&](const std::string& name, bool entry_before) {
    ::mrpt::io::CFileGZOutputStream out((dir / name).string());
    auto ar = ::mrpt::serialization::archiveFrom(out);
    if (entry_before) {
      auto pc = ::mrpt::obs::CObservationPointCloud::Create();
      pc->pointcloud = ::mrpt::maps::CSimplePointsMap::Create();
      pc->pointcloud->insertPoint(5, 0, -1);
      ar << *pc;
    }
    const std::string cls = "mrpt::maps::CSimpleMap";
    const uint8_t head[] = {static_cast<uint8_t>(0x80 | cls.size())};
    out.Write(head, 1);
    out.Write(cls.data(), cls.size());
    const uint8_t version_and_count[] = {0, 1, 0, 0, 0};  // version 0, one keyframe
    out.Write(version_and_count, sizeof version_and_count);
    ar << ::mrpt::serialization::CSerializable::Ptr();  // its 2D pose: missing
    ar << ::mrpt::obs::CSensoryFrame();
    const uint8_t end = 0x88;
    out.Write(&end, 1);
  };
  write("old.simplemap", false);
  test::expectError([&] { cleanmap::mrpt::RawlogSource src((dir / "old.simplemap").string()); },
                    "old.simplemap", "is a CSimpleMap of MRPT's first format (version 0");
  ::mrpt::maps::CSimpleMap sm;
  test::expectError([&] { cleanmap::mrpt::loadSimplemap((dir / "old.simplemap").string(), sm); },
                    "old.simplemap", "is a CSimpleMap of MRPT's first format (version 0");
  write("old.rawlog", true);
  test::expectError(
      [&] {
        cleanmap::mrpt::RawlogSource src((dir / "old.rawlog").string());
        while (src.next()) {
        }
      },
      "old.rawlog", "entry 1 is a CSimpleMap of MRPT's first format (version 0");
  test::expectError([&] { cleanmap::mrpt::loadSimplemap((dir / "none.simplemap").string(), sm); },
                    "none.simplemap", "cannot be opened as a simplemap");
  test::expectError([&] { cleanmap::mrpt::loadSimplemap((dir / "old.rawlog").string(), sm); },
                    "old.rawlog", "is not a simplemap MRPT can read");

  ::mrpt::maps::CSimpleMap v1;
  auto sf = ::mrpt::obs::CSensoryFrame::Create();
  auto pc = ::mrpt::obs::CObservationPointCloud::Create();
  pc->pointcloud = ::mrpt::maps::CSimplePointsMap::Create();
  pc->pointcloud->insertPoint(5, 1, -1);
  sf->insert(pc);
  v1.insert(::mrpt::poses::CPose3DPDFGaussian::Create(::mrpt::poses::CPose3D(1, 2, 0, 0, 0, 0)),
            sf);
  ASSERT_TRUE(v1.saveToFile((dir / "new.simplemap").string()));
  cleanmap::mrpt::loadSimplemap((dir / "new.simplemap").string(), sm);
  ASSERT_EQ(sm.size(), 1u);
  EXPECT_EQ(sm.getAsPair(0).pose->getMeanVal().x(), 1.0);
  cleanmap::mrpt::RawlogSource src((dir / "new.simplemap").string());
  const auto f = src.next();
  ASSERT_TRUE(f.has_value());
  ASSERT_EQ(f->scan.points.size(), 1u);
  EXPECT_EQ(f->scan.points[0].y, 1.0f);
}

// MRPT 2.5.8 sizes a simplemap's keyframes, a sensory frame's observations and an action
// collection's actions to the count it reads first (found by fuzzing: 2 KB claiming 2^32
// observations took 2 GB before the data ran out). A count more than the file can hold is one
// line, before MRPT reads it; so is a sensory frame of MRPT's first format (version 0), whose
// reader uses observations that may be missing.
TEST(RawlogSource, AContainerClaimingMoreThanTheFileHoldsIsAClearError) {
  const auto dir = test::scratchDir("rawlog_container_counts");
  // A rawlog of one point cloud, then a container's header, its bytes, and padding.
  const auto write = [&](const std::string& name, const std::string& cls,
                         std::vector<uint8_t> after_name) {
    ::mrpt::io::CFileGZOutputStream out((dir / name).string());
    auto ar = ::mrpt::serialization::archiveFrom(out);
    auto pc = ::mrpt::obs::CObservationPointCloud::Create();
    pc->pointcloud = ::mrpt::maps::CSimplePointsMap::Create();
    pc->pointcloud->insertPoint(5, 0, -1);
    ar << *pc;
    const uint8_t len = static_cast<uint8_t>(0x80 | cls.size());
    out.Write(&len, 1);
    out.Write(cls.data(), cls.size());
    after_name.resize(after_name.size() + 64, 0);
    out.Write(after_name.data(), after_name.size());
  };
  const auto read = [&](const std::string& name) {
    cleanmap::mrpt::RawlogSource src((dir / name).string());
    while (src.next()) {
    }
  };
  write("frame.rawlog", "mrpt::obs::CSensoryFrame", {2, 0xff, 0xff, 0xff, 0x7f});
  test::expectError([&] { read("frame.rawlog"); }, "frame.rawlog",
                    "entry 1 is a CSensoryFrame claiming 2147483647 elements, more than the file "
                    "can hold (corrupt)");
  write("frame1.rawlog", "mrpt::obs::CSensoryFrame", {1, 7, 0, 0, 0, 0, 0, 0, 0x10});
  test::expectError([&] { read("frame1.rawlog"); }, "frame1.rawlog",
                    "entry 1 is a CSensoryFrame claiming 268435456 elements");
  write("acts.rawlog", "mrpt::obs::CActionCollection", {0, 0, 0, 0, 0x01});
  test::expectError([&] { read("acts.rawlog"); }, "acts.rawlog",
                    "entry 1 is a CActionCollection claiming 16777216 elements");
  write("map.rawlog", "mrpt::maps::CSimpleMap", {1, 0, 0, 1, 0});
  test::expectError([&] { read("map.rawlog"); }, "map.rawlog",
                    "entry 1 is a CSimpleMap claiming 65536 keyframes");
  // MRPT reads a class by the name's part after its last "::" where no class has the whole name
  // (found by fuzzing: a mutated namespace passed the check by name and took over 2 GB).
  write("prefix.rawlog", "mrpt:Cmaps::CSimpleMap", {1, 0, 0, 1, 0});
  test::expectError([&] { read("prefix.rawlog"); }, "prefix.rawlog",
                    "entry 1 is a CSimpleMap claiming 65536 keyframes");
  write("nul.rawlog", std::string("mrpt::\x96mrpt::maps::CSimpleMap\0\3", 31), {1, 0, 0, 1, 0});
  test::expectError([&] { read("nul.rawlog"); }, "nul.rawlog",
                    "entry 1 is a CSimpleMap claiming 65536 keyframes");
  write("frame0.rawlog", "mrpt::obs::CSensoryFrame", {0, 0, 0, 0, 0});
  test::expectError([&] { read("frame0.rawlog"); }, "frame0.rawlog",
                    "entry 1 is a CSensoryFrame of MRPT's first format (version 0)");
  // A count the file can hold goes to MRPT, which finds the data cut short.
  write("short.rawlog", "mrpt::obs::CSensoryFrame", {2, 3, 0, 0, 0});
  test::expectError([&] { read("short.rawlog"); }, "short.rawlog",
                    "truncated or corrupt rawlog at entry 1");
}

namespace {

// A rawlog's or simplemap's bytes, uncompressed.
std::vector<char> bytesOf(const std::string& path) {
  std::vector<char> bytes;
  ::mrpt::io::CFileGZInputStream in(path);
  char buf[4096];
  for (size_t got; (got = in.Read(buf, sizeof buf)) > 0;) bytes.insert(bytes.end(), buf, buf + got);
  return bytes;
}

// Where the second object headed `header` (its name length and name) has its version byte.
std::size_t secondVersionAt(const std::vector<char>& bytes, const std::string& header) {
  auto at = std::search(bytes.begin(), bytes.end(), header.begin(), header.end());
  if (at != bytes.end()) at = std::search(at + 1, bytes.end(), header.begin(), header.end());
  EXPECT_NE(at, bytes.end()) << header;
  return at == bytes.end() ? 0 : static_cast<std::size_t>(at - bytes.begin()) + header.size();
}

}  // namespace

// The same checks inside a container: a simplemap's keyframe whose sensory frame claims more
// observations than the file holds, or is of the first format, is refused as MRPT reads it, by
// both readers, in one line naming the file; the same map unchanged reads.
TEST(RawlogSource, AContainerInsideAnotherIsCheckedToo) {
  const auto dir = test::scratchDir("rawlog_nested_counts");
  ::mrpt::maps::CSimpleMap sm;
  for (int k = 0; k < 2; ++k) {
    auto pc = ::mrpt::obs::CObservationPointCloud::Create();
    pc->pointcloud = ::mrpt::maps::CSimplePointsMap::Create();
    pc->pointcloud->insertPoint(5, k, -1);
    auto sf = ::mrpt::obs::CSensoryFrame::Create();
    sf->insert(pc);
    sm.insert(::mrpt::poses::CPose3DPDFGaussian::Create(::mrpt::poses::CPose3D(k, 0, 0, 0, 0, 0)),
              sf);
  }
  ASSERT_TRUE(sm.saveToFile((dir / "good.simplemap").string()));
  const std::vector<char> bytes = bytesOf((dir / "good.simplemap").string());
  // The second keyframe's frame: its header, then version 2 and its count (1).
  const std::string header = "\x98mrpt::obs::CSensoryFrame";
  const std::size_t version_at = secondVersionAt(bytes, header);
  ASSERT_GT(version_at, 0u);
  ASSERT_EQ(bytes[version_at], 2);
  ASSERT_EQ(bytes[version_at + 1], 1);
  const auto write = [&](const std::string& name, std::size_t offset, std::vector<char> patch) {
    std::vector<char> b = bytes;
    std::copy(patch.begin(), patch.end(), b.begin() + static_cast<std::ptrdiff_t>(offset));
    std::ofstream((dir / name).string(), std::ios::binary)
        .write(b.data(), static_cast<std::streamsize>(b.size()));
    return (dir / name).string();
  };
  const auto both = [&](const std::string& path, const std::string& what) {
    test::expectError(
        [&] {
          cleanmap::mrpt::RawlogSource src(path);
          while (src.next()) {
          }
        },
        path, what);
    ::mrpt::maps::CSimpleMap out;
    test::expectError([&] { cleanmap::mrpt::loadSimplemap(path, out); }, path, what);
  };
  both(write("count.simplemap", version_at + 1, {'\xff', '\xff', '\xff', '\x7f'}),
       "holds a CSensoryFrame claiming 2147483647 elements, more than the file can hold (corrupt)");
  {  // MRPT 1 wrote class names without their namespace
    std::vector<char> b = bytes;
    b[version_at + 4] = '\x7f';
    const std::string bare = std::string(1, '\x8d') + "CSensoryFrame";
    const auto from = b.begin() + static_cast<std::ptrdiff_t>(version_at - header.size());
    b.erase(from, from + static_cast<std::ptrdiff_t>(header.size()));
    b.insert(b.begin() + static_cast<std::ptrdiff_t>(version_at - header.size()), bare.begin(),
             bare.end());
    const std::string path = (dir / "bare.simplemap").string();
    std::ofstream(path, std::ios::binary).write(b.data(), static_cast<std::streamsize>(b.size()));
    both(path, "holds a CSensoryFrame claiming 2130706433 elements");
  }
  both(write("v0.simplemap", version_at, {0}),
       "holds a CSensoryFrame of MRPT's first format (version 0), which cleanmap does not read");
  // The second keyframe's points map claiming 2^32 - 1 points (MRPT zero-fills its arrays: 48 GB).
  const std::size_t count_at = secondVersionAt(bytes, "\x9cmrpt::maps::CSimplePointsMap") + 1;
  ASSERT_GT(count_at, 1u);
  ASSERT_EQ(bytes[count_at], 1);
  both(write("points.simplemap", count_at, {'\xff', '\xff', '\xff', '\xff'}),
       "holds a CSimplePointsMap claiming 4294967295 points, more than the file can hold");
  std::size_t scans = 0;
  cleanmap::mrpt::RawlogSource src(write("same.simplemap", version_at, {2}));
  while (src.next()) ++scans;
  EXPECT_EQ(scans, 2u);
  // The same in a rawlog's observation: its entry named.
  {
    ::mrpt::io::CFileGZOutputStream out((dir / "cloud.rawlog").string());
    auto ar = ::mrpt::serialization::archiveFrom(out);
    for (int k = 0; k < 2; ++k) {
      auto pc = ::mrpt::obs::CObservationPointCloud::Create();
      pc->pointcloud = ::mrpt::maps::CPointsMapXYZI::Create();
      pc->pointcloud->insertPoint(5, k, -1);
      ar << *pc;
    }
  }
  std::vector<char> cloud = bytesOf((dir / "cloud.rawlog").string());
  const std::size_t xyzi_version = secondVersionAt(cloud, "\x9amrpt::maps::CPointsMapXYZI");
  ASSERT_GT(xyzi_version, 0u);
  const auto n_at = cloud.begin() + static_cast<std::ptrdiff_t>(xyzi_version) + 1;
  ASSERT_EQ(*n_at, 1);
  std::fill(n_at, n_at + 4, '\x40');
  const std::string cut = (dir / "cloud_count.rawlog").string();
  std::ofstream(cut, std::ios::binary)
      .write(cloud.data(), static_cast<std::streamsize>(cloud.size()));
  test::expectError(
      [&] {
        cleanmap::mrpt::RawlogSource reader(cut);
        while (reader.next()) {
        }
      },
      cut,
      "entry 1 holds a CPointsMapXYZI claiming 1077952576 points, more than the file can hold");
}

// MRPT 2.5.8's image reader allocates the JPEG bytes or the pixels an image's header claims before
// reading them (a 3 KB rawlog took 4.2 GB), and in its first format (version 0) reads a byte
// count apart from the size it allocated into the image: more overflowed the heap (a 2 x 2 image
// given 200,000 bytes aborted a run in malloc). Each is one line naming the entry (a simplemap's
// keyframe: both readers), before MRPT reads it; images MRPT wrote, colour and grey, and a
// first-format image that fits, read.
TEST(RawlogSource, AnImageClaimingMoreThanTheFileHoldsIsAClearError) {
  const auto dir = test::scratchDir("rawlog_image_sizes");
  // Bytes written by MRPT, to `name` in dir; where `body` is given, with the image's bytes from
  // its version byte on (an external image's: version 9, true, a 12-character name) replaced.
  const auto patched = [&](std::string b, const std::string& body, const std::string& name) {
    const std::string header = "\x91mrpt::img::CImage";
    const std::size_t at = b.find(header) + header.size();
    if (!body.empty()) {
      EXPECT_EQ(b.substr(std::min(at, b.size()), 6), std::string("\x09\x01\x0c\0\0\0", 6));
      b = b.substr(0, at) + body + b.substr(std::min(b.size(), at + 6 + 12));
    }
    const std::string path = (dir / name).string();
    std::ofstream(path, std::ios::binary).write(b.data(), static_cast<std::streamsize>(b.size()));
    return path;
  };
  // A rawlog of a point cloud and a camera's image.
  const auto write = [&](const std::string& name, const ::mrpt::img::CImage& image,
                         const std::string& body) {
    ::mrpt::io::CMemoryStream mem;
    auto ar = ::mrpt::serialization::archiveFrom(mem);
    auto pc = ::mrpt::obs::CObservationPointCloud::Create();
    pc->pointcloud = ::mrpt::maps::CSimplePointsMap::Create();
    pc->pointcloud->insertPoint(5, 0, -1);
    ar << *pc;
    auto im = ::mrpt::obs::CObservationImage::Create();
    im->image = image;
    ar << *im;
    std::string b(static_cast<const char*>(mem.getRawBufferData()), mem.getTotalBytesCount());
    return patched(b, body, name);
  };
  const auto le32 = [](int64_t v) {
    std::string s(4, '\0');
    for (int i = 0; i < 4; ++i)
      s[i] = static_cast<char>((static_cast<uint64_t>(v) >> (8 * i)) & 0xff);
    return s;
  };
  const auto read = [](const std::string& path) {
    cleanmap::mrpt::RawlogSource src(path);
    std::size_t images = 0;
    while (const auto f = src.next()) images += f->image.has_value();
    return images;
  };
  ::mrpt::img::CImage external;
  external.setExternalStorage("abcdefgh.png");
  const auto refused = [&](const std::string& name, const std::string& body,
                           const std::string& what) {
    const std::string path = write(name, external, body);
    test::expectError([&] { read(path); }, path, "entry 1 holds " + what);
  };
  // Version 0: width, height, channels, origin, then the byte count read into the image.
  const std::string v0 = std::string(1, '\0') + le32(2) + le32(2) + le32(1) + '\1';
  refused("v0_overflow.rawlog", v0 + le32(4096) + std::string(4096, 'A'),
          "a CImage of 2 x 2 pixels of 1 byte claiming 4096 bytes of them (corrupt: MRPT would "
          "write past the image)");
  refused("v0_channels.rawlog",
          std::string(1, '\0') + le32(2) + le32(2) + le32(513) + '\1' + le32(4) + "AAAA",
          "a CImage of 513 channels (corrupt)");
  EXPECT_EQ(read(write("v0.rawlog", external, v0 + le32(4) + "AAAA")), 1u);
  // A JPEG's byte count: version 1; version 9 in colour at a positive size.
  refused("v1_jpeg.rawlog", std::string(1, '\1') + le32(-1) + "AAAA",
          "a CImage claiming 4294967295 bytes of JPEG data, more than the file can hold (corrupt)");
  const std::string v9 = std::string("\x09\0", 2);
  refused("v9_jpeg.rawlog", v9 + '\1' + le32(640) + le32(480) + le32(0x7fffffff) + "AAAA",
          "a CImage claiming 2147483647 bytes of JPEG data");
  // Raw pixels: colour (a negative size), grey of 8-byte pixels (depth 6: double).
  refused("v9_rgb.rawlog", v9 + '\1' + le32(-4096) + le32(-4096) + "AAAA",
          "a CImage claiming 4096 x 4096 pixels of 3 bytes, more than the file can hold (corrupt)");
  refused("v9_grey.rawlog",
          v9 + '\0' + le32(4096) + le32(4096) + le32(0) + le32(134217728) + le32(6) + "AAAA",
          "a CImage claiming 4096 x 4096 pixels of 8 bytes");
  // As MRPT writes them: raw colour and grey (8 and 16 bits).
  EXPECT_EQ(read(write("rgb.rawlog",
                       ::mrpt::img::CImage(cv::Mat(48, 64, CV_8UC3, cv::Scalar(10, 20, 30)),
                                           ::mrpt::img::DEEP_COPY),
                       "")),
            1u);
  for (const int type : {CV_8UC1, CV_16UC1}) {
    const std::string path = write(
        "grey.rawlog",
        ::mrpt::img::CImage(cv::Mat(48, 64, type, cv::Scalar(9)), ::mrpt::img::DEEP_COPY), "");
    EXPECT_NO_THROW(read(path)) << type;
  }
  // A keyframe's image in a simplemap: both readers.
  {
    auto pc = ::mrpt::obs::CObservationPointCloud::Create();
    pc->pointcloud = ::mrpt::maps::CSimplePointsMap::Create();
    pc->pointcloud->insertPoint(5, 0, -1);
    auto im = ::mrpt::obs::CObservationImage::Create();
    im->image = external;
    auto sf = ::mrpt::obs::CSensoryFrame::Create();
    sf->insert(pc);
    sf->insert(im);
    ::mrpt::maps::CSimpleMap sm;
    sm.insert(::mrpt::poses::CPose3DPDFGaussian::Create(::mrpt::poses::CPose3D()), sf);
    ASSERT_TRUE(sm.saveToFile((dir / "image.simplemap").string()));
  }
  const std::vector<char> b = bytesOf((dir / "image.simplemap").string());
  const std::string path = patched(std::string(b.begin(), b.end()),
                                   v0 + le32(4096) + std::string(4096, 'A'), "v0.simplemap");
  const std::string what = "holds a CImage of 2 x 2 pixels of 1 byte claiming 4096 bytes of them";
  test::expectError([&] { read(path); }, path, what);
  ::mrpt::maps::CSimpleMap out;
  test::expectError([&] { cleanmap::mrpt::loadSimplemap(path, out); }, path, what);
}

// A simplemap (a SLAM's output: keyframes of a pose and a sensory frame) reads as its scans, each
// at its keyframe's pose: the points bit for bit, the poses within 1e-9. The pose and the image go
// by the keyframe, not by time, so keyframes without times (older simplemaps) keep their own.
TEST(RawlogSource, ReadsASimplemapKeyframeByKeyframe) {
  CLEANMAP_REQUIRE_DATASET("kitti_city");
  const auto seq = io::KittiSequence::open(test::dataDir() + "/kitti_city");
  const auto dir = test::scratchDir("rawlog_simplemap");
  for (const bool timed : {true, false}) {
    SCOPED_TRACE(timed ? "timed" : "no times");
    const std::string path = (dir / (timed ? "timed.simplemap" : "untimed.simplemap")).string();
    {
      ::mrpt::maps::CSimpleMap sm;
      for (std::size_t i = 0; i < 4; ++i) {
        const Frame k = seq.frame(i);
        auto pc = ::mrpt::obs::CObservationPointCloud::Create();
        pc->sensorLabel = "LIDAR";
        pc->timestamp =
            timed ? cleanmap::mrpt::toMrptTime(k.scan.timestamp) : ::mrpt::Clock::time_point();
        pc->pointcloud = cleanmap::mrpt::toPointsMap(k.scan.points);
        auto img = ::mrpt::obs::CObservationImage::Create();  // after the scan in its keyframe
        img->sensorLabel = "CAM";
        img->timestamp = pc->timestamp;
        img->cameraParams =
            cleanmap::mrpt::toTCamera(pinhole(500, 500, 32, 24, 64, 48), img->cameraPose);
        img->image = ::mrpt::img::CImage(cv::Mat(48, 64, CV_8UC3, cv::Scalar::all(10 + 50 * i)),
                                         ::mrpt::img::DEEP_COPY);
        auto sf = ::mrpt::obs::CSensoryFrame::Create();
        sf->insert(pc);
        sf->insert(img);
        sm.insert(::mrpt::poses::CPose3DPDFGaussian::Create(cleanmap::mrpt::toCPose3D(k.scan.pose)),
                  sf);
      }
      ASSERT_TRUE(sm.saveToFile(path));
    }
    cleanmap::mrpt::RawlogSource src(path);
    EXPECT_TRUE(src.isSimplemap());
    std::size_t i = 0;
    while (auto f = src.next()) {
      ASSERT_LT(i, 4u);
      const Frame k = seq.frame(i);
      ASSERT_EQ(f->scan.size(), k.scan.size());
      EXPECT_EQ(0, std::memcmp(f->scan.points.data(), k.scan.points.data(),
                               k.scan.size() * sizeof(PointXYZI)));
      ASSERT_TRUE(f->scan.has_pose);
      EXPECT_LT((f->scan.pose.matrix() - k.scan.pose.matrix()).cwiseAbs().maxCoeff(), 1e-9) << i;
      EXPECT_EQ(f->source, path + " keyframe " + std::to_string(i));
      ASSERT_TRUE(f->image.has_value());
      EXPECT_EQ(f->image->bgr.at<cv::Vec3b>(5, 5)[0], 10 + 50 * i) << "the image of keyframe " << i;
      ++i;
    }
    EXPECT_EQ(i, 4u);
  }
  {
    ASSERT_TRUE(::mrpt::maps::CSimpleMap().saveToFile((dir / "empty.simplemap").string()));
    test::expectError([&] { cleanmap::mrpt::RawlogSource((dir / "empty.simplemap").string()); },
                      "empty.simplemap", "is a simplemap with no keyframes");
    // One object: a file cut short fails as a whole, said as a simplemap's failure.
    fs::copy_file(dir / "timed.simplemap", dir / "cut.simplemap");
    fs::resize_file(dir / "cut.simplemap", fs::file_size(dir / "timed.simplemap") / 2);
    test::expectError([&] { cleanmap::mrpt::RawlogSource((dir / "cut.simplemap").string()); },
                      "cut.simplemap", "is not a simplemap MRPT can read");
  }
}
