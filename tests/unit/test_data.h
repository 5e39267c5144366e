// SPDX-License-Identifier: BSD-3-Clause
// Access to ../shared/data (KITTI sequences with labels) and scratch folders for tests.
#pragma once
#include <gtest/gtest.h>

#include <sys/resource.h>

#include <Eigen/Geometry>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "cleanmap/core/error.h"
#include "cleanmap/core/types.h"

namespace cleanmap::test {

/// ../shared/data, or $CLEANMAP_DATA_DIR.
inline std::string dataDir() {
  if (const char* env = std::getenv("CLEANMAP_DATA_DIR")) return env;
  return CLEANMAP_SHARED_DATA_DIR;
}

inline bool inCI() {
  const char* ci = std::getenv("CI");
  return ci && std::string(ci) == "true";
}

/// The scratch folders made by the running test.
inline std::vector<std::filesystem::path>& scratchOfThisTest() {
  static std::vector<std::filesystem::path> dirs;
  return dirs;
}

/// Removes the running test's scratch folders when it ends without failing: the tests write
/// 3.7 GB in all, and `make test` runs on machines with little disk. A failing test keeps its
/// folders to look at, as every test does with CLEANMAP_KEEP_SCRATCH=1.
class ScratchCleaner : public ::testing::EmptyTestEventListener {
  void OnTestEnd(const ::testing::TestInfo& info) override {
    auto& dirs = scratchOfThisTest();
    if (!info.result()->Failed() && !std::getenv("CLEANMAP_KEEP_SCRATCH"))
      for (const auto& d : dirs) {
        std::error_code ec;  // a folder that cannot be removed is left, not a failure
        std::filesystem::remove_all(d, ec);
      }
    dirs.clear();
  }
};
inline const bool kScratchCleanerInstalled = [] {
  ::testing::UnitTest::GetInstance()->listeners().Append(new ScratchCleaner);
  return true;
}();

/// A fresh empty directory under the build tree, removed at the start of each use and when the
/// test that made it passes (ScratchCleaner).
inline std::filesystem::path scratchDir(const std::string& name) {
  const auto p = std::filesystem::path(CLEANMAP_TEST_SCRATCH_DIR) / name;
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  scratchOfThisTest().push_back(p);
  return p;
}

/// While alive, no file of this process grows past `bytes`: writes beyond fail with EFBIG
/// (RLIMIT_FSIZE, with SIGXFSZ ignored), as they would with ENOSPC on a full disk.
class FileSizeLimit {
 public:
  explicit FileSizeLimit(std::uint64_t bytes) {
    ::getrlimit(RLIMIT_FSIZE, &old_);
    old_handler_ = std::signal(SIGXFSZ, SIG_IGN);
    rlimit r = old_;
    r.rlim_cur = bytes;
    ::setrlimit(RLIMIT_FSIZE, &r);
  }
  ~FileSizeLimit() {
    ::setrlimit(RLIMIT_FSIZE, &old_);
    std::signal(SIGXFSZ, old_handler_);
  }
  FileSizeLimit(const FileSizeLimit&) = delete;
  FileSizeLimit& operator=(const FileSizeLimit&) = delete;

 private:
  rlimit old_{};
  void (*old_handler_)(int) = SIG_DFL;
};

/// Writes `text` to `p`, creating its folder.
inline void writeText(const std::filesystem::path& p, const std::string& text) {
  std::filesystem::create_directories(p.parent_path());
  std::ofstream(p) << text;
}

/// The indices of the points of lasers offset, offset + k, ... of a KITTI HDL-64E scan, stored
/// laser after laser, each a full turn from the first azimuth: a sparser lidar of the same scene
/// (datasets/decimate_kitti_rings.py does the same to a folder).
inline std::vector<std::size_t> kittiRingsKept(const std::vector<PointXYZI>& pts, int k,
                                               int offset = 0) {
  std::vector<std::size_t> out;
  if (pts.empty()) return out;
  const double th0 = std::atan2(pts[0].y, pts[0].x);
  double prev = th0;
  int turns = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const double a = std::atan2(pts[i].y, pts[i].x);
    if (a - prev < -M_PI) ++turns;
    prev = a;
    if (static_cast<int>(std::floor((a + 2 * M_PI * turns - th0) / (2 * M_PI) + 1e-9)) % k ==
        offset)
      out.push_back(i);
  }
  return out;
}

/// The indices of the points of a KITTI HDL-64E scan whose azimuth lies in every c-th of its
/// column steps (360 / 2083 degrees): c = 2 gives columns 0.35 degrees apart, an Ouster's at
/// 1024 columns, with the HDL-64E's rings (datasets/decimate_kitti_rings.py --columns).
inline std::vector<std::size_t> kittiColumnsKept(const std::vector<PointXYZI>& pts, int c) {
  const double step = 2 * M_PI / 2083;
  std::vector<std::size_t> out;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const double a = std::atan2(pts[i].y, pts[i].x);
    if (static_cast<int>(std::floor((a + M_PI) / step)) % c == 0) out.push_back(i);
  }
  return out;
}

/// Mean translation error of the relative poses over `d` scans, as a share of the path; `poses`
/// holds (estimated, true) per scan.
inline double relativeError(
    const std::vector<std::pair<Eigen::Isometry3d, Eigen::Isometry3d>>& poses, std::size_t d) {
  double err = 0, path = 0;
  for (std::size_t k = 0; k + d < poses.size(); ++k) {
    const Eigen::Isometry3d est = poses[k].first.inverse() * poses[k + d].first;
    const Eigen::Isometry3d truth = poses[k].second.inverse() * poses[k + d].second;
    err += (est.translation() - truth.translation()).norm();
    path += truth.translation().norm();
  }
  return err / path;
}

/// Runs f and expects a cleanmap::Error whose one-line message names `file` and holds `what`.
template <class F>
void expectError(F&& f, const std::string& file, const std::string& what) {
  try {
    f();
    ADD_FAILURE() << "no error thrown; expected '" << what << "'";
  } catch (const cleanmap::Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(file), std::string::npos) << msg;
    EXPECT_NE(msg.find(what), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << "not one line: " << msg;
  }
}

}  // namespace cleanmap::test

/// Skips (outside CI) or fails (with CI=true) when the labelled data set is missing.
#define CLEANMAP_REQUIRE_DATASET(set)                                            \
  do {                                                                           \
    const std::string _d = cleanmap::test::dataDir() + "/" + (set);              \
    if (!std::filesystem::is_directory(_d)) {                                    \
      if (cleanmap::test::inCI()) FAIL() << "dataset missing in CI: " << _d;     \
      GTEST_SKIP() << "dataset not found: " << _d << " (set CLEANMAP_DATA_DIR)"; \
    }                                                                            \
  } while (0)
