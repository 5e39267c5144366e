// SPDX-License-Identifier: BSD-3-Clause
#include <gtest/gtest.h>

#include <fstream>
#include <limits>

#include "cleanmap/core/error.h"
#include "cleanmap/io/files.h"
#include "test_data.h"

using namespace cleanmap;
namespace fs = std::filesystem;

namespace {

void writeRaw(const fs::path& p, const void* data, std::size_t n) {
  std::ofstream f(p, std::ios::binary);
  f.write(static_cast<const char*>(data), static_cast<std::streamsize>(n));
}

}  // namespace

TEST(KittiBin, RoundTripIsBitIdentical) {
  const auto dir = test::scratchDir("bin_roundtrip");
  std::vector<PointXYZI> pts = {{1.5f, -2.25f, 0.125f, 0.3f}, {1e-7f, 3e4f, -1.73f, 1.0f}};
  io::writeKittiBin((dir / "a.bin").string(), pts);
  const Scan s = io::readKittiBin((dir / "a.bin").string());
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(0, std::memcmp(s.points.data(), pts.data(), 2 * sizeof(PointXYZI)));
}

TEST(KittiBin, TruncatedFileIsAnError) {
  const auto dir = test::scratchDir("bin_truncated");
  const float v[5] = {1, 2, 3, 4, 5};  // 20 bytes: one point and a stray float
  writeRaw(dir / "t.bin", v, sizeof v);
  test::expectError([&] { io::readKittiBin((dir / "t.bin").string()); }, "t.bin",
                    "not a multiple of 16");
}

TEST(KittiBin, EmptyScanIsAnErrorUnlessAllowed) {
  const auto dir = test::scratchDir("bin_empty");
  writeRaw(dir / "e.bin", nullptr, 0);
  test::expectError([&] { io::readKittiBin((dir / "e.bin").string()); }, "e.bin", "empty scan");
  io::ScanReadOptions allow;
  allow.allow_empty = true;
  EXPECT_TRUE(io::readKittiBin((dir / "e.bin").string(), allow).empty());
}

TEST(KittiBin, NanPointsAreDroppedAndCounted) {
  const auto dir = test::scratchDir("bin_nan");
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float v[12] = {1, 2, 3, 0.5f, nan, 0, 0, 0, 4, 5, std::numeric_limits<float>::infinity(),
                       0};
  writeRaw(dir / "n.bin", v, sizeof v);
  const Scan s = io::readKittiBin((dir / "n.bin").string());
  EXPECT_EQ(s.size(), 1u);
  EXPECT_EQ(s.original_size, 3u);
  EXPECT_EQ(s.dropped_invalid, 2u);
  for (const auto& p : s.points) EXPECT_TRUE(std::isfinite(p.x + p.y + p.z + p.intensity));
  // Only NaNs: an empty scan, reported as such.
  const float all_nan[4] = {nan, nan, nan, nan};
  writeRaw(dir / "all.bin", all_nan, sizeof all_nan);
  test::expectError([&] { io::readKittiBin((dir / "all.bin").string()); }, "all.bin",
                    "NaN or infinite");
}

TEST(KittiBin, MissingFileIsAnError) {
  test::expectError([] { io::readKittiBin("/nonexistent/x.bin"); }, "/nonexistent/x.bin",
                    "does not exist");
}

TEST(Labels, CountMismatchNamesBothNumbers) {
  const auto dir = test::scratchDir("labels");
  io::writeLabels((dir / "l.label").string(), {9, 251, 0});
  EXPECT_EQ(io::readLabels((dir / "l.label").string(), 3u), (Labels{9, 251, 0}));
  test::expectError([&] { io::readLabels((dir / "l.label").string(), 4u); }, "l.label",
                    "has 3 labels but the scan has 4 points");
  const char odd[5] = {};
  writeRaw(dir / "odd.label", odd, sizeof odd);
  test::expectError([&] { io::readLabels((dir / "odd.label").string()); }, "odd.label",
                    "not a multiple of 4");
}

TEST(AtomicWrite, InterruptedWriteLeavesNothing) {
  const auto dir = test::scratchDir("atomic");
  const std::string target = (dir / "map.bin").string();
  io::writeFileAtomic(target, [](std::ostream& os) { os << "old"; });
  EXPECT_THROW(io::writeFileAtomic(target,
                                   [](std::ostream& os) {
                                     os << "half-written";
                                     throw std::runtime_error("interrupted");
                                   }),
               std::runtime_error);
  EXPECT_EQ(io::readTextFile(target), "old");  // the previous file is untouched
  std::size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir)) files += e.is_regular_file() ? 1 : 0;
  EXPECT_EQ(files, 1u) << "a temporary file was left behind";
}

TEST(Directories, MissingDirectoryIsAnError) {
  test::expectError([] { io::requireDirectory("/nonexistent/seq"); }, "/nonexistent/seq",
                    "directory does not exist");
}
