// SPDX-License-Identifier: BSD-3-Clause
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>

#include "cleanmap/core/error.h"
#include "cleanmap/io/background_files.h"
#include "cleanmap/io/direct_file.h"
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

// A folder written as a whole: nothing in it until publish(), an earlier folder replaced as a
// whole, and an unpublished one leaves nothing behind; errors name the folder's own paths.
TEST(StagedFolder, PublishesAsAWholeAndLeavesNothingUnpublished) {
  const auto root = test::scratchDir("staged");
  const std::string dir = (root / "out").string();
  {
    io::StagedFolder s(dir, "t");
    test::writeText(std::filesystem::path(s.path()) / "a.txt", "first");
    EXPECT_FALSE(std::filesystem::exists(dir));
    s.publish();
  }
  EXPECT_EQ(io::readTextFile(dir + "/a.txt"), "first");
  {
    io::StagedFolder s(dir + "/", "t");
    test::writeText(std::filesystem::path(s.path()) / "b.txt", "second");
    const std::string msg = s.path() + "/b.txt.tmp." + std::to_string(::getpid()) + ": failed";
    EXPECT_EQ(io::messageWithoutStaging(msg, dir + "/", "t"), dir + "/b.txt: failed");
  }  // not published: the earlier folder as it was, no staging left
  EXPECT_EQ(io::readTextFile(dir + "/a.txt"), "first");
  EXPECT_FALSE(std::filesystem::exists(dir + "/b.txt"));
  {
    io::StagedFolder s(dir, "t");
    test::writeText(std::filesystem::path(s.path()) / "b.txt", "second");
    s.publish();
  }
  EXPECT_FALSE(std::filesystem::exists(dir + "/a.txt")) << "the earlier folder was not replaced";
  EXPECT_EQ(io::readTextFile(dir + "/b.txt"), "second");
  std::size_t entries = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(root)) ++entries;
  EXPECT_EQ(entries, 1u) << "a staging folder was left";
}

// An output folder never takes its input with it, whatever option asked for the replacement: not
// the input itself, not a folder holding it (as written, through "..", through a symbolic link),
// not a non-empty folder inside it that is no earlier output (its velodyne/). A folder beside it
// whose name starts alike, an empty one or an earlier output inside it, and a missing one are fine.
TEST(RequireOutsideInput, RefusesWhatWouldDeleteTheInput) {
  const auto root = test::scratchDir("outside_input");
  const auto seq = root / "data" / "seq";
  fs::create_directories(seq / "velodyne");
  test::writeText(seq / "velodyne" / "000000.bin", "");
  test::writeText(root / "data" / "run.rawlog", "");
  fs::create_directory_symlink(root / "data", root / "link");
  const auto never = [](const std::string&) { return false; };
  const auto check = [&](const fs::path& dir, const fs::path& input) {
    io::requireOutsideInput(dir.string(), input.string(), never, "-o");
  };
  test::expectError([&] { check(seq, seq); }, seq.string(),
                    "the output folder is the input folder");
  test::expectError([&] { check(seq.string() + "/", seq); }, seq.string() + "/",
                    "the output folder is the input folder");
  test::expectError([&] { check(root / "data", seq); }, (root / "data").string(),
                    "holds the input " + seq.string());
  test::expectError([&] { check(seq / "..", seq.string() + "/"); }, (seq / "..").string(),
                    "holds the input");
  test::expectError([&] { check(root / "link", seq); }, (root / "link").string(),
                    "holds the input");
  test::expectError([&] { check(root, root / "link" / "run.rawlog"); }, root.string(),
                    "holds the input");
  test::expectError([&] { check(seq / "velodyne", seq); }, (seq / "velodyne").string(),
                    "lies inside the input folder " + seq.string());
  // Fine: beside it, a name that starts alike, a missing or empty folder inside it, an earlier
  // output inside it, and no input.
  EXPECT_NO_THROW(check(root / "data" / "seq2", seq));
  EXPECT_NO_THROW(check(root / "data" / "out", root / "data" / "run.rawlog"));
  EXPECT_NO_THROW(check(seq / "out", seq));
  fs::create_directory(seq / "out");
  EXPECT_NO_THROW(check(seq / "out", seq));
  test::writeText(seq / "out" / "report.json", "{}");
  EXPECT_NO_THROW(io::requireOutsideInput((seq / "out").string(), seq.string(),
                                          [](const std::string&) { return true; }, "-o"));
  EXPECT_THROW(check(seq / "out", seq), Error);
  EXPECT_NO_THROW(check(seq, ""));
}

TEST(Directories, MissingDirectoryIsAnError) {
  test::expectError([] { io::requireDirectory("/nonexistent/seq"); }, "/nonexistent/seq",
                    "directory does not exist");
}

// Issue #16: outputs and spools past the page cache. Whatever the chunking, the buffer size and
// whether the file system takes O_DIRECT, the file holds exactly the bytes written, a patched
// header included, and reads back the same.
TEST(DirectFile, WritesExactlyTheBytesAndReadsThemBack) {
  const auto dir = test::scratchDir("direct_file");
  std::vector<unsigned char> bytes(3 * 8192 + 1234);
  uint32_t x = 12345;
  for (auto& b : bytes) b = static_cast<unsigned char>((x = x * 1664525u + 1013904223u) >> 24);
  for (const bool direct : {true, false})
    for (const std::size_t buffer : {std::size_t(4096), std::size_t(8192), std::size_t(1) << 20}) {
      const std::string path =
          (dir / ("f" + std::to_string(buffer) + (direct ? "d" : "p"))).string();
      io::DirectFile f(path, buffer, direct);
      std::size_t at = 0, step = 1;
      while (at < bytes.size()) {  // chunks of 1, 2, 3, ... bytes: every alignment
        const std::size_t n = std::min(step++ * 97, bytes.size() - at);
        f.write(bytes.data() + at, n);
        at += n;
      }
      EXPECT_EQ(f.size(), bytes.size());
      const uint32_t count = 0xdeadbeef;  // a header's count, set at the end
      f.patchHead(100, &count, 4);
      test::expectError([&] { f.patchHead(4094, &count, 4); }, path, "outside the written header");
      f.close();
      std::vector<unsigned char> expected = bytes;
      std::memcpy(expected.data() + 100, &count, 4);
      std::ifstream in(path, std::ios::binary);
      const std::vector<unsigned char> disk((std::istreambuf_iterator<char>(in)), {});
      EXPECT_EQ(disk, expected) << path;
      io::DirectReader r(path, buffer, direct);
      std::vector<unsigned char> back(expected.size());
      r.read(back.data(), 5);
      r.read(back.data() + 5, back.size() - 5);
      EXPECT_EQ(back, expected) << path;
      unsigned char more;
      test::expectError([&] { r.read(&more, 1); }, path, "truncated");
    }
  // A header patched while still in the buffer, and a file shorter than one block.
  io::DirectFile small((dir / "small").string());
  small.write("ply\ncount 0\n", 12);
  small.patchHead(10, "7", 1);
  small.close();
  std::ifstream in(dir / "small", std::ios::binary);
  EXPECT_EQ(std::string((std::istreambuf_iterator<char>(in)), {}), "ply\ncount 7\n");
}

TEST(DirectFile, ErrorsNameTheFile) {
  const auto dir = test::scratchDir("direct_file_errors");
  const std::string missing = (dir / "no" / "such" / "dir" / "f").string();
  test::expectError([&] { io::DirectFile f(missing); }, missing, "cannot open for writing");
  test::expectError([&] { io::DirectReader r(missing); }, missing, "cannot open for reading");
  // The per-scan label files: written whole, the temporary gone, an error names the real file.
  const Labels labels{9, 251, 40, 0, 9};
  io::writeLabels((dir / "a.label").string(), labels);
  EXPECT_EQ(io::readLabels((dir / "a.label").string()), labels);
  std::size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir)) files += e.is_regular_file();
  EXPECT_EQ(files, 1u);
  const std::string under_file = (dir / "a.label" / "x.label").string();  // a file as a folder
  test::expectError([&] { io::writeLabels(under_file, labels); }, "a.label", "cannot");
}

// Issue #16: label files written on a thread of their own. Every file queued is there, whole,
// once wait() returns (or the writer is destroyed); a failed write is rethrown by the next call
// naming its file, and a queued removal removes.
TEST(BackgroundFiles, WritesEveryFileWholeAndRethrowsAFailureByName) {
  const auto dir = test::scratchDir("background_files");
  std::vector<Labels> written;
  {
    io::BackgroundFiles files(2);
    for (uint32_t k = 0; k < 12; ++k) {
      Labels l(1000 + 517 * k);
      for (std::size_t i = 0; i < l.size(); ++i) l[i] = uint32_t(i * 7 + k) % 260;
      written.push_back(l);
      files.writeLabels((dir / (std::to_string(k) + ".label")).string(), std::move(l));
    }
    files.wait();
    for (uint32_t k = 0; k < 12; ++k)
      EXPECT_EQ(io::readLabels((dir / (std::to_string(k) + ".label")).string()), written[k]);
    writeRaw(dir / "spent", "x", 1);
    files.remove((dir / "spent").string());
    files.remove((dir / "never_there").string());  // no error
    files.wait();
    EXPECT_FALSE(fs::exists(dir / "spent"));
    files.writeLabels((dir / "last.label").string(), written[3]);
  }  // destroyed with a job queued: it is done first
  EXPECT_EQ(io::readLabels((dir / "last.label").string()), written[3]);
  std::size_t files_left = 0;  // no temporaries
  for (const auto& e : fs::directory_iterator(dir)) files_left += e.is_regular_file();
  EXPECT_EQ(files_left, 13u);

  io::BackgroundFiles files(2);
  const std::string under_file = (dir / "last.label" / "x.label").string();  // a file as a folder
  files.writeLabels(under_file, written[0]);
  test::expectError([&] { files.wait(); }, "last.label", "cannot");
  // The error stays: every later call rethrows it and queues nothing (a run never ends with a
  // label file missing unseen).
  const std::string after = (dir / "after.label").string();
  test::expectError([&] { files.writeLabels(after, written[0]); }, "last.label", "cannot");
  test::expectError([&] { files.wait(); }, "last.label", "cannot");
  EXPECT_FALSE(fs::exists(after));
  io::BackgroundFiles more(2);
  test::expectError(
      [&] {
        for (int k = 0; k < 4; ++k) more.writeLabels(under_file, written[0]);
      },
      "last.label", "cannot");
  // Destroyed after a failure: the error is dropped.
}

TEST(PositionalFile, ReadsAndPatchesAtOffsets) {
  // The map's backward pass (DESIGN §2e): a spool written front to back is read at each scan's
  // offset, past the page cache where allowed (ranges that straddle 4 KiB blocks, the file's
  // last partial block), and its decisions are patched in place.
  const auto dir = test::scratchDir("positional_file");
  const std::string path = (dir / "spool").string();
  std::vector<unsigned char> bytes(3 * 4096 + 123);
  for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<unsigned char>(i * 7 + 3);
  io::DirectFile f(path);
  f.write(bytes.data(), bytes.size());
  f.close();
  io::PositionalFile r(path, false), w(path, true);
  for (const auto& [at, n] : std::vector<std::pair<std::size_t, std::size_t>>{
           {0, 10}, {4090, 20}, {5000, 7000}, {bytes.size() - 5, 5}, {100, 0}}) {
    std::vector<unsigned char> got(n), back(n);
    r.readAt(at, n ? got.data() : nullptr, n);
    w.readAt(at, n ? back.data() : nullptr, n);
    EXPECT_TRUE(std::equal(got.begin(), got.end(), bytes.begin() + long(at))) << at;
    EXPECT_EQ(back, got) << at;
  }
  unsigned char past[8];
  test::expectError([&] { r.readAt(bytes.size() - 4, past, 8); }, path, "truncated");
  const unsigned char patch[3] = {1, 2, 3};
  w.writeAt(4095, patch, 3);
  unsigned char now[3];
  io::PositionalFile again(path, false);
  again.readAt(4095, now, 3);
  EXPECT_TRUE(std::equal(now, now + 3, patch));
  test::expectError([&] { io::PositionalFile missing((dir / "none").string(), false); }, "none",
                    "cannot open");
}
