// SPDX-License-Identifier: BSD-3-Clause
// Access to ../shared/data (KITTI sequences with labels) and scratch folders for tests.
#pragma once
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "cleanmap/core/error.h"

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

/// A fresh empty directory under the build tree, removed at the start of each use.
inline std::filesystem::path scratchDir(const std::string& name) {
  const auto p = std::filesystem::path(CLEANMAP_TEST_SCRATCH_DIR) / name;
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  return p;
}

/// Writes `text` to `p`, creating its folder.
inline void writeText(const std::filesystem::path& p, const std::string& text) {
  std::filesystem::create_directories(p.parent_path());
  std::ofstream(p) << text;
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
