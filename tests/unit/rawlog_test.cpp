// SPDX-License-Identifier: BSD-3-Clause
#include <gtest/gtest.h>

#include <cstring>
#include <fstream>

#include <opencv2/core.hpp>

#include "cleanmap/io/kitti.h"
#include "cleanmap/mrpt/rawlog.h"
#include "test_data.h"

using namespace cleanmap;
namespace fs = std::filesystem;

namespace {

// KITTI folder -> rawlog (first `n` scans, all if 0).
void convert(const io::KittiSequence& seq, const std::string& out, bool external,
             std::size_t n = 0) {
  mrpt::RawlogWriteOptions opts;
  opts.external = external;
  mrpt::RawlogWriter w(out, opts);
  const std::size_t count = n ? std::min(n, seq.size()) : seq.size();
  for (std::size_t i = 0; i < count; ++i)
    w.write(seq.frame(i), seq.camera(), seq.scanPath(i),
            seq.hasImages() ? seq.imagePath(i) : std::string());
  w.close();
}

// Reads the rawlog back and checks it frame by frame against the KITTI folder.
void expectSameAsKitti(const io::KittiSequence& seq, const std::string& rawlog) {
  mrpt::RawlogSource src(rawlog);
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
    EXPECT_NEAR(f->scan.timestamp, k.scan.timestamp, 1e-6);
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

INSTANTIATE_TEST_SUITE_P(SharedData, RawlogRoundTrip,
                         ::testing::Values("kitti_city", "kitti_highway", "kitti_residential"));

TEST(RawlogSource, ReadsMrptVelodyneScan) {
  const std::string path = std::string(CLEANMAP_MRPT_DATASETS_DIR) + "/test_velodyne_VLP16.rawlog";
  if (!fs::exists(path)) {
    if (test::inCI()) FAIL() << "mrpt-common missing: " << path;
    GTEST_SKIP() << "mrpt-common not installed: " << path;
  }
  mrpt::RawlogSource src(path);
  const auto f = src.next();
  ASSERT_TRUE(f.has_value());
  EXPECT_GT(f->scan.size(), 10000u);  // a VLP-16 sweep: 16 rings x ~1800 azimuths
  double max_range = 0;
  for (const auto& p : f->scan.points) max_range = std::max<double>(max_range, p.xyz().norm());
  EXPECT_LT(max_range, 130.0);  // VLP-16 spec: 100 m
  EXPECT_GT(max_range, 2.0);
  EXPECT_FALSE(f->scan.has_pose);
}

TEST(RawlogSource, ReadsMrpt3DRangeScan) {
  const std::string path = std::string(CLEANMAP_MRPT_DATASETS_DIR) + "/tests_rgbd.rawlog";
  if (!fs::exists(path)) {
    if (test::inCI()) FAIL() << "mrpt-common missing: " << path;
    GTEST_SKIP() << "mrpt-common not installed: " << path;
  }
  mrpt::RawlogSource src(path);
  const auto f = src.next();
  ASSERT_TRUE(f.has_value());
  EXPECT_GT(f->scan.size(), 1000u);
  for (const auto& p : f->scan.points) ASSERT_LT(p.xyz().norm(), 20.0f);  // an indoor RGB-D scene
}

TEST(RawlogSource, MissingEmptyAndGarbageFilesAreErrors) {
  test::expectError([] { mrpt::RawlogSource("/nonexistent/a.rawlog"); }, "/nonexistent/a.rawlog",
                    "does not exist");
  const auto dir = test::scratchDir("rawlog_bad");
  std::ofstream(dir / "empty.rawlog").close();
  test::expectError([&] { mrpt::RawlogSource((dir / "empty.rawlog").string()); }, "empty.rawlog",
                    "holds no point-cloud observations");
  std::ofstream(dir / "text.rawlog") << "this is not a rawlog, just some text that goes on\n";
  test::expectError([&] { mrpt::RawlogSource((dir / "text.rawlog").string()); }, "text.rawlog",
                    "is not an MRPT rawlog");
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
        mrpt::RawlogSource src((dir / "cut.rawlog").string());
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
    mrpt::RawlogWriter w((dir / "x.rawlog").string());
    w.write(seq.frame(0), std::nullopt);
    // destroyed without close(): as if the run was interrupted by an exception
  }
  EXPECT_TRUE(fs::is_empty(dir)) << "a partial rawlog or temporary was left behind";
}

TEST(RawlogSource, EmptyScanIsAnErrorUnlessAllowed) {
  const auto dir = test::scratchDir("rawlog_emptyscan");
  {
    mrpt::RawlogWriter w((dir / "e.rawlog").string());
    Frame f;
    f.scan.timestamp = 1.0;
    w.write(f, std::nullopt);
    w.close();
  }
  mrpt::RawlogSource strict((dir / "e.rawlog").string());
  test::expectError([&] { strict.next(); }, "e.rawlog", "scan 000000 is empty");
  mrpt::RawlogReadOptions allow;
  allow.allow_empty_scans = true;
  mrpt::RawlogSource lenient((dir / "e.rawlog").string(), allow);
  const auto f = lenient.next();
  ASSERT_TRUE(f.has_value());
  EXPECT_TRUE(f->scan.empty());
}
