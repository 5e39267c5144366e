// SPDX-License-Identifier: BSD-3-Clause
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include <opencv2/imgcodecs.hpp>

#include "cleanmap/core/error.h"
#include "cleanmap/io/calib.h"
#include "cleanmap/io/kitti.h"
#include "test_data.h"

using namespace cleanmap;
namespace fs = std::filesystem;

namespace {

// A 3-scan odometry folder made of links to kitti_city's scans, with the given poses/calib text.
fs::path miniOdometry(const std::string& name, const std::string& poses, const std::string& calib) {
  const auto dir = test::scratchDir(name);
  fs::create_directories(dir / "velodyne");
  for (const char* s : {"000000", "000001", "000002"})
    fs::create_symlink(
        fs::path(test::dataDir()) / "kitti_city/velodyne" / (std::string(s) + ".bin"),
        dir / "velodyne" / (std::string(s) + ".bin"));
  if (!poses.empty()) test::writeText(dir / "poses.txt", poses);
  if (!calib.empty()) test::writeText(dir / "calib.txt", calib);
  return dir;
}

const char* kIdentityPose = "1 0 0 0 0 1 0 0 0 0 1 0\n";

}  // namespace

TEST(KittiOdometry, OpensEachSharedSet) {
  struct Expect {
    const char* set;
    std::size_t scans;
    bool images;
  };
  for (const Expect& e : {Expect{"kitti_city", 22, false}, Expect{"kitti_highway", 30, true},
                          Expect{"kitti_residential", 30, false}}) {
    CLEANMAP_REQUIRE_DATASET(e.set);
    const auto seq = io::KittiSequence::open(test::dataDir() + "/" + e.set);
    EXPECT_EQ(seq.layout(), io::KittiLayout::kOdometry);
    EXPECT_EQ(seq.size(), e.scans) << e.set;
    ASSERT_TRUE(seq.hasPoses());
    EXPECT_EQ(seq.poses().size(), e.scans);
    EXPECT_TRUE(seq.hasLabels());
    EXPECT_EQ(seq.hasImages(), e.images);
    EXPECT_NEAR(seq.timestamps()[1] - seq.timestamps()[0], 0.1, 1e-9);
    // First scan: ~120k points, labels line up one to one.
    const Scan s = seq.loadScan(0);
    EXPECT_GT(s.size(), 100000u);
    EXPECT_LT(s.size(), 140000u);
    EXPECT_EQ(seq.loadLabels(0, s.original_size).size(), s.original_size);
    EXPECT_TRUE(s.point_time.empty()) << "odometry folders come de-skewed (DESIGN §2.0)";
  }
}

TEST(KittiOdometry, PosesAreLidarPosesInTheWorld) {
  CLEANMAP_REQUIRE_DATASET("kitti_highway");
  // poses.txt is in the camera-0 frame (z forward); converted with Tr, the car drives along the
  // lidar's +x (forward), ~2 m/s at the start, on a level road.
  const auto seq = io::KittiSequence::open(test::dataDir() + "/kitti_highway");
  const Eigen::Isometry3d rel = seq.poses()[0].inverse() * seq.poses()[10];
  const Eigen::Vector3d t = rel.translation();
  EXPECT_GT(t.x(), 1.0);
  EXPECT_LT(t.x(), 4.0);
  EXPECT_LT(std::abs(t.y()), 0.3 * t.x());
  EXPECT_LT(std::abs(t.z()), 0.2);
  // Each pose is a rigid transform.
  for (const auto& T : seq.poses())
    EXPECT_LT((T.linear() * T.linear().transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-6);
}

TEST(KittiOdometry, CameraSeesWhatIsAhead) {
  CLEANMAP_REQUIRE_DATASET("kitti_highway");
  const auto seq = io::KittiSequence::open(test::dataDir() + "/kitti_highway");
  const auto cam = seq.camera();
  ASSERT_TRUE(cam.has_value());
  EXPECT_EQ(cam->width, 1242);
  EXPECT_EQ(cam->height, 375);
  const auto img = seq.loadImage(0);
  ASSERT_TRUE(img.has_value());
  EXPECT_EQ(img->bgr.cols, 1242);
  EXPECT_EQ(img->bgr.type(), CV_8UC3);
  // Points 5-30 m ahead within +-20 deg land in the image; points behind never do.
  const Scan s = seq.loadScan(0);
  std::size_t ahead = 0, ahead_in = 0, behind_in = 0;
  for (const auto& p : s.points) {
    const Eigen::Vector3d q(p.x, p.y, p.z);
    if (p.x > 5 && p.x < 30 && std::abs(p.y) < 0.35 * p.x && p.z > -1.5 && p.z < 1.0) {
      ++ahead;
      ahead_in += cam->project(q).has_value();
    }
    if (p.x < -2) behind_in += cam->project(q).has_value();
  }
  ASSERT_GT(ahead, 1000u);
  EXPECT_GT(static_cast<double>(ahead_in) / ahead, 0.99);
  EXPECT_EQ(behind_in, 0u);
}

TEST(KittiOdometry, PoseScanCountMismatchIsAnError) {
  CLEANMAP_REQUIRE_DATASET("kitti_city");
  const auto dir = miniOdometry("mismatch", std::string(kIdentityPose) + kIdentityPose,
                                "Tr: 1 0 0 0 0 1 0 0 0 0 1 0\n");
  test::expectError([&] { io::KittiSequence::open(dir.string()); }, "poses.txt",
                    "has 2 poses but the sequence has 3 scans");
}

TEST(KittiOdometry, MissingCalibrationKeyIsAnError) {
  CLEANMAP_REQUIRE_DATASET("kitti_city");
  const std::string poses = std::string(kIdentityPose) + kIdentityPose + kIdentityPose;
  const auto dir = miniOdometry("nokey", poses, "P0: 1 0 0 0 0 1 0 0 0 0 1 0\n");
  test::expectError([&] { io::KittiSequence::open(dir.string()); }, "calib.txt",
                    "missing calibration key 'Tr'");
  const auto dir2 = miniOdometry("nocalib", poses, "");
  test::expectError([&] { io::KittiSequence::open(dir2.string()); }, "calib.txt", "does not exist");
  const auto dir3 = miniOdometry("shortkey", poses, "Tr: 1 0 0 0 0 1\n");
  test::expectError([&] { io::KittiSequence::open(dir3.string()); }, "calib.txt",
                    "has 6 numbers, expected 12");
}

TEST(KittiOdometry, TimesCountMismatchIsAnError) {
  CLEANMAP_REQUIRE_DATASET("kitti_city");
  const auto dir = miniOdometry("times", "", "");
  test::writeText(dir / "times.txt", "0.0\n0.1\n");
  test::expectError([&] { io::KittiSequence::open(dir.string()); }, "times.txt",
                    "has 2 timestamps but the sequence has 3 scans");
}

// Times may repeat (placeholders) but never go back: the window in seconds and the sweeps' motion
// read their differences.
TEST(KittiOdometry, TimesThatGoBackAreAnError) {
  CLEANMAP_REQUIRE_DATASET("kitti_city");
  const auto dir = miniOdometry("times_back", "", "");
  test::writeText(dir / "times.txt", "0.0\n0.0\n0.1\n");
  EXPECT_EQ(io::KittiSequence::open(dir.string()).timestamps()[2], 0.1);
  test::writeText(dir / "times.txt", "0.0\n0.2\n0.1\n");
  test::expectError([&] { io::KittiSequence::open(dir.string()); }, "times.txt",
                    "the time of scan 000002 (0.1) is earlier than that of the scan before (0.2)");
}

TEST(KittiOdometry, MissingOrWrongDirectoryIsAnError) {
  test::expectError([] { io::KittiSequence::open("/nonexistent/seq"); }, "/nonexistent/seq",
                    "directory does not exist");
  const auto dir = test::scratchDir("notkitti");
  test::expectError([&] { io::KittiSequence::open(dir.string()); }, dir.string(),
                    "not a KITTI folder");
}

TEST(KittiOdometry, TruncatedOrCorruptImageIsOneLineError) {
  // An image cut short (an interrupted copy) or corrupt is named in one error line, with nothing
  // from libpng before it; a PNG with bytes after its end, and a JPEG named .png, still load.
  CLEANMAP_REQUIRE_DATASET("kitti_city");
  const std::string poses = std::string(kIdentityPose) + kIdentityPose + kIdentityPose;
  const auto dir = miniOdometry("cutimage", poses,
                                "P2: 100 0 32 0 0 100 24 0 0 0 1 0\nTr: 1 0 0 0 0 1 0 0 0 0 1 0\n");
  fs::create_directories(dir / "image_2");
  cv::Mat img(48, 64, CV_8UC3);
  cv::randu(img, 0, 255);  // noise: a PNG of some kilobytes
  for (const char* s : {"000000", "000001", "000002"})
    ASSERT_TRUE(cv::imwrite((dir / "image_2" / (std::string(s) + ".png")).string(), img));
  const auto second = dir / "image_2/000001.png";
  const auto third = dir / "image_2/000002.png";
  fs::resize_file(second, fs::file_size(second) / 2);
  { std::ofstream(third, std::ios::binary | std::ios::app) << std::string(300, 'x'); }
  auto seq = io::KittiSequence::open(dir.string());
  ASSERT_TRUE(seq.hasImages());
  EXPECT_EQ(seq.loadImage(0)->bgr.cols, 64);
  testing::internal::CaptureStderr();
  test::expectError([&] { seq.loadImage(1); }, "000001.png",
                    "truncated PNG image (no IEND chunk at its end)");
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
  EXPECT_EQ(seq.loadImage(2)->bgr.rows, 48);  // bytes after IEND are ignored
  // A byte changed inside the image data (a bad disk, a copy gone wrong): libpng would print
  // "bad adaptive filter value" or decode garbage; the chunk's CRC tells it.
  ASSERT_TRUE(cv::imwrite(second.string(), img));
  {
    std::fstream f(second, std::ios::binary | std::ios::in | std::ios::out);
    const auto middle = static_cast<std::streamoff>(fs::file_size(second) / 2);
    f.seekg(middle);
    const char c = static_cast<char>(f.get());
    f.seekp(middle);
    f.put(static_cast<char>(~c));
  }
  testing::internal::CaptureStderr();
  test::expectError([&] { seq.loadImage(1); }, "000001.png",
                    "corrupt PNG image (its IDAT chunk at byte");
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
  ASSERT_TRUE(cv::imwrite(second.string(), img));
  fs::resize_file(second, 40);  // inside the second chunk's header: cut short too
  test::expectError([&] { seq.loadImage(1); }, "000001.png", "truncated PNG image");
  ASSERT_TRUE(cv::imwrite((dir / "image_2/000001.jpg").string(), img));
  fs::rename(dir / "image_2/000001.jpg", second);
  EXPECT_EQ(seq.loadImage(1)->bgr.cols, 64);  // a JPEG named .png: OpenCV reads it by content
}

// ---- KITTI raw: a synthetic drive with known motion ----

namespace {

constexpr double kEarthRadius = 6378137.0;
constexpr double kLat0 = 49.0, kLon0 = 8.4;

// Writes a raw drive (date folder with calibration, drive folder with 3 scans, OXTS, timestamps,
// images) in which the IMU moves `step` metres per frame along its heading `yaw` (0 = east).
fs::path rawDrive(const std::string& name, double yaw, double step) {
  const auto date = test::scratchDir(name);
  const auto drive = date / "2011_09_26_drive_0001_sync";
  test::writeText(date / "calib_imu_to_velo.txt",
                  "calib_time: 25-May-2012 16:47:16\n"
                  "R: 0.99875 -0.04998 0 0.04998 0.99875 0 0 0 1\n"  // Rz(0.05)
                  "T: -0.81 0.32 -0.80\n");
  test::writeText(date / "calib_velo_to_cam.txt",
                  "calib_time: 15-Mar-2012 11:37:16\n"
                  "R: 0 -1 0 0 0 -1 1 0 0\nT: 0 -0.08 -0.27\n");
  test::writeText(date / "calib_cam_to_cam.txt",
                  "calib_time: 09-Jan-2012 13:57:47\n"
                  "R_rect_00: 1 0 0 0 1 0 0 0 1\n"
                  "P_rect_02: 721.5 0 609.6 44.86 0 721.5 172.9 0.2164 0 0 1 0.0027\n"
                  "S_rect_02: 1242 375\n");
  std::string stamps;
  const double scale = std::cos(kLat0 * M_PI / 180.0);
  for (int i = 0; i < 3; ++i) {
    char stem[16];
    std::snprintf(stem, sizeof stem, "%010d", i);
    const float pts[8] = {10, 0, 0, 0.5f, 5, 1, -1.7f, 0.2f};
    fs::create_directories(drive / "velodyne_points/data");
    std::ofstream(drive / "velodyne_points/data" / (std::string(stem) + ".bin"), std::ios::binary)
        .write(reinterpret_cast<const char*>(pts), sizeof pts);
    const double east = i * step * std::cos(yaw), north = i * step * std::sin(yaw);
    const double lon = kLon0 + east * 180.0 / (scale * M_PI * kEarthRadius);
    const double lat = kLat0 + north * 180.0 / (M_PI * kEarthRadius);
    char line[256];
    std::snprintf(line, sizeof line, "%.14f %.14f 110.0 0 0 %.14f", lat, lon, yaw);
    std::string rec = line;
    for (int k = 6; k < 30; ++k) rec += " 0";
    test::writeText(drive / "oxts/data" / (std::string(stem) + ".txt"), rec + "\n");
    char ts[64];
    std::snprintf(ts, sizeof ts, "2011-09-26 13:02:25.%09d\n", 64389445 + i * 100000000);
    stamps += ts;
    fs::create_directories(drive / "image_02/data");
    cv::imwrite((drive / "image_02/data" / (std::string(stem) + ".png")).string(),
                cv::Mat(375, 1242, CV_8UC3, cv::Scalar(10 * i, 20, 30)));
  }
  test::writeText(drive / "velodyne_points/timestamps.txt", stamps);
  return drive;
}

}  // namespace

TEST(KittiRaw, OxtsPosesFollowTheDrivenPath) {
  // Heading north, 1 m per frame: in the first lidar frame the car moves along the IMU's forward
  // axis, which the lidar sees rotated by the calib_imu_to_velo rotation Rz(0.05).
  const auto drive = rawDrive("raw_north", M_PI / 2, 1.0);
  const auto seq = io::KittiSequence::open(drive.string());
  EXPECT_EQ(seq.layout(), io::KittiLayout::kRaw);
  ASSERT_EQ(seq.size(), 3u);
  ASSERT_TRUE(seq.hasPoses());
  EXPECT_LT((seq.poses()[0].matrix() - Eigen::Matrix4d::Identity()).cwiseAbs().maxCoeff(), 1e-8);
  for (int i = 1; i < 3; ++i) {
    const Eigen::Vector3d t = seq.poses()[static_cast<std::size_t>(i)].translation();
    EXPECT_NEAR(t.x(), i * std::cos(0.05), 2e-3);
    EXPECT_NEAR(t.y(), i * std::sin(0.05), 2e-3);
    EXPECT_NEAR(t.z(), 0.0, 1e-6);
    EXPECT_LT(
        (seq.poses()[static_cast<std::size_t>(i)].linear() - Eigen::Matrix3d::Identity()).norm(),
        1e-6);
  }
  EXPECT_NEAR(seq.timestamps()[0], 1317042145.064389445, 1e-5);  // 2011-09-26 13:02:25.06 UTC
  EXPECT_NEAR(seq.timestamps()[2] - seq.timestamps()[0], 0.2, 1e-6);
  const auto cam = seq.camera();
  ASSERT_TRUE(cam.has_value());
  EXPECT_EQ(cam->width, 1242);
  EXPECT_EQ(cam->height, 375);
  EXPECT_TRUE(cam->project({20, 0, 0}).has_value());
  EXPECT_EQ(seq.loadScan(1).size(), 2u);
}

TEST(KittiRaw, TimestampsThatGoBackAreAnError) {
  const auto drive = rawDrive("raw_back", 0, 1.0);
  test::writeText(drive / "velodyne_points/timestamps.txt",
                  "2011-09-26 13:02:25.1\n2011-09-26 13:02:25.3\n2011-09-26 13:02:25.2\n");
  test::expectError([&] { io::KittiSequence::open(drive.string()); }, "timestamps.txt",
                    "the time of scan 0000000002");
}

// DESIGN §2.0: a raw drive's scans are not de-skewed (KITTI's readme), so each point carries its
// time in the sweep from its azimuth: facing forward (the timestamp) 0, the sweep clockwise from
// the rear over timestamps_end - timestamps_start, else the scan period. Odometry folders' scans,
// de-skewed by KITTI, carry none.
TEST(KittiRaw, ScansCarryTheirTimesInTheSweep) {
  const auto drive = rawDrive("raw_sweep", 0, 1.0);
  const double az = std::atan2(1.0, 5.0);  // the second point, (5, 1, -1.7)
  {
    const auto scan = io::KittiSequence::open(drive.string()).loadScan(1);
    ASSERT_EQ(scan.point_time.size(), 2u);
    EXPECT_NEAR(scan.point_time[0], 0.0, 1e-7);
    EXPECT_NEAR(scan.point_time[1], -az / (2 * M_PI) * 0.1, 1e-6);
    io::KittiReadOptions no_times;  // sensor.deskew = 0: not computed
    no_times.point_times = false;
    const auto plain = io::KittiSequence::open(drive.string(), no_times).loadScan(1);
    EXPECT_TRUE(plain.point_time.empty());
    ASSERT_EQ(plain.size(), 2u);
    EXPECT_EQ(plain.points[1].xyz(), scan.points[1].xyz());
  }
  std::string start, end;
  for (int i = 0; i < 3; ++i) {
    char a[64], b[64];
    std::snprintf(a, sizeof a, "2011-09-26 13:02:25.%09d\n", 12389445 + i * 100000000);
    std::snprintf(b, sizeof b, "2011-09-26 13:02:25.%09d\n", 116389445 + i * 100000000);
    start += a;
    end += b;
  }
  test::writeText(drive / "velodyne_points/timestamps_start.txt", start);
  test::writeText(drive / "velodyne_points/timestamps_end.txt", end);
  const auto scan = io::KittiSequence::open(drive.string()).loadScan(1);
  ASSERT_EQ(scan.point_time.size(), 2u);
  EXPECT_NEAR(scan.point_time[1], -az / (2 * M_PI) * 0.104, 1e-6);
  test::writeText(drive / "velodyne_points/timestamps_end.txt", end.substr(0, end.find('\n') + 1));
  test::expectError([&] { io::KittiSequence::open(drive.string()); }, "timestamps_end.txt",
                    "has 1 timestamps but the sequence has 3 scans");
}

TEST(KittiRaw, MercatorConversionMatchesTheDevkit) {
  // Reference numbers from the KITTI devkit formula (convertOxtsToPose.m) at lat 49, lon 8.4.
  const double scale = std::cos(kLat0 * M_PI / 180.0);
  const Eigen::Isometry3d T = io::oxtsToMercatorPose(kLat0, kLon0, 110, 0.01, -0.02, 0.3, scale);
  EXPECT_NEAR(T.translation().x(), scale * kLon0 * M_PI * kEarthRadius / 180.0, 1e-6);
  EXPECT_NEAR(T.translation().y(),
              scale * kEarthRadius * std::log(std::tan((90.0 + kLat0) * M_PI / 360.0)), 1e-6);
  EXPECT_NEAR(T.translation().z(), 110.0, 1e-12);
  const Eigen::Vector3d ypr = T.linear().eulerAngles(2, 1, 0);
  EXPECT_NEAR(ypr[0], 0.3, 1e-12);
  EXPECT_NEAR(ypr[1], -0.02, 1e-12);
  EXPECT_NEAR(ypr[2], 0.01, 1e-12);
}

TEST(KittiRaw, MissingCalibrationIsAnError) {
  const auto drive = rawDrive("raw_nocalib", 0.0, 1.0);
  fs::remove(drive.parent_path() / "calib_imu_to_velo.txt");
  test::expectError([&] { io::KittiSequence::open(drive.string()); }, "calib_imu_to_velo.txt",
                    "does not exist");
}

TEST(KittiRaw, OxtsCountMismatchIsAnError) {
  const auto drive = rawDrive("raw_oxts", 0.0, 1.0);
  fs::remove(drive / "oxts/data/0000000002.txt");
  test::expectError([&] { io::KittiSequence::open(drive.string()); }, "oxts/data",
                    "has 2 OXTS records but the sequence has 3 scans");
}
