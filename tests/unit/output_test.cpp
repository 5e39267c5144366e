// SPDX-License-Identifier: BSD-3-Clause
// The output folder is published as a whole (DESIGN §4): a finished run replaces an earlier one
// entirely, a failed run leaves OUTDIR as it was, a folder that is no cleanmap run is refused.
#include <gtest/gtest.h>

#include <chrono>
#include <nlohmann/json.hpp>
#include <thread>

#include "cleanmap/io/files.h"
#include "cleanmap/io/output.h"
#include "test_data.h"

using namespace cleanmap;
namespace fs = std::filesystem;

namespace {

ScanResult result(std::size_t index, std::size_t points) {
  ScanResult r;
  r.index = index;
  char stem[16];
  std::snprintf(stem, sizeof stem, "%06zu", index);
  r.stem = stem;
  r.labels.assign(points, kStatic);
  r.static_full.assign(points, PointXYZI{1, 2, 3, 0});
  r.stats.points = points;
  return r;
}

void run(const fs::path& out, std::size_t scans, const io::OutputOptions& opts = {}) {
  io::OutputWriter w(out.string(), "input", PipelineParams{}, opts);
  for (std::size_t i = 0; i < scans; ++i) w.write(result(i, 5), std::nullopt);
  w.finish(0.1);
}

std::size_t entries(const fs::path& dir) {
  std::size_t n = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++n;
  return n;
}

}  // namespace

TEST(Output, AShorterRunReplacesAnEarlierOneAsAWhole) {
  const auto dir = test::scratchDir("replace");
  run(dir / "out", 30);
  EXPECT_EQ(entries(dir / "out/labels"), 30u);
  EXPECT_TRUE(io::isCleanmapRun((dir / "out").string()));
  run(dir / "out", 5);  // no stale label files of the 30-scan run survive
  EXPECT_EQ(entries(dir / "out/labels"), 5u);
  EXPECT_EQ(entries(dir), 1u) << "a staging or old folder was left beside OUTDIR";
}

TEST(Output, AnUnfinishedRunLeavesNothingAndOutdirUnchanged) {
  const auto dir = test::scratchDir("unfinished");
  run(dir / "out", 3);
  const auto before = io::readTextFile((dir / "out/report.json").string());
  {
    io::OutputWriter w((dir / "out").string(), "input", PipelineParams{});
    EXPECT_TRUE(fs::is_directory(w.staging()));
    w.write(result(0, 1000), std::nullopt);
    w.write(result(1, 1000), std::nullopt);
  }  // an error or a signal unwinds here, before finish()
  EXPECT_EQ(entries(dir), 1u) << "the staging folder was left behind";
  EXPECT_EQ(io::readTextFile((dir / "out/report.json").string()), before);
  EXPECT_EQ(entries(dir / "out/labels"), 3u);
}

TEST(Output, RefusesAForeignFolderUnlessForced) {
  const auto dir = test::scratchDir("foreign");
  test::writeText(dir / "photos/holiday.jpg", "not a map");
  test::expectError([&] { run(dir / "photos", 2); }, "photos", "holds no cleanmap run");
  EXPECT_TRUE(fs::exists(dir / "photos/holiday.jpg"));
  test::writeText(dir / "file", "x");
  test::expectError([&] { run(dir / "file", 2); }, "file", "is not a folder");
  io::OutputOptions force;
  force.force = true;
  run(dir / "photos", 2, force);
  EXPECT_FALSE(fs::exists(dir / "photos/holiday.jpg"));
  EXPECT_EQ(entries(dir / "photos/labels"), 2u);
  fs::create_directories(dir / "empty");
  run(dir / "empty", 1);  // an empty folder is fine
  EXPECT_TRUE(io::isCleanmapRun((dir / "empty").string()));
}

TEST(Output, StagingOfAKilledRunIsRemovedByTheNext) {
  const auto dir = test::scratchDir("stale");
  // pid 2^22 + 12345 exceeds Linux's pid_max (2^22): no such process.
  fs::create_directories(dir / ".out.cleanmap-staging-4206649/labels");
  run(dir / "out", 1);
  EXPECT_EQ(entries(dir), 1u);
}

// report.json's `interval`: the wall time between two scans' results while the input still
// flows. Three results 30 ms apart, then the input ends and four come at once (the pipeline's
// last decisions): the steady rate is that of the first three (with the last four, the median
// would be near 0).
TEST(Output, TheSteadyIntervalLeavesOutTheScansDecidedAfterTheInput) {
  const auto dir = test::scratchDir("output_interval");
  {
    io::OutputWriter w((dir / "out").string(), "input", PipelineParams{});
    for (std::size_t i = 0; i < 3; ++i) {
      if (i > 0) std::this_thread::sleep_for(std::chrono::milliseconds(30));
      w.write(result(i, 5), std::nullopt);
    }
    w.inputEnded();
    for (std::size_t i = 3; i < 7; ++i) w.write(result(i, 5), std::nullopt);
    w.finish(0.1);
  }
  const auto j = nlohmann::json::parse(io::readTextFile((dir / "out/report.json").string()));
  const auto& t = j.at("timing_per_scan").at("interval");
  EXPECT_GE(t.at("median_ms").get<double>(), 30.0);
  EXPECT_GE(t.at("mean_ms").get<double>(), 30.0);
}

// DESIGN §2.1 step 4: the refused alignments counted by reason, for the app's warning line and
// report.md; a refusal after which GICP's map started again says so.
TEST(Output, RefusedAlignmentsAreCountedByReason) {
  const auto dir = test::scratchDir("output_refused");
  const char* reasons[] = {"",
                           "",
                           "degenerate scene",
                           "degenerate scene",
                           "a jump beyond max_speed / max_turn_rate",
                           "too few correspondences",
                           "",
                           "too few points"};
  io::OutputWriter w((dir / "out").string(), "input", PipelineParams{});
  for (std::size_t i = 0; i < std::size(reasons); ++i) {
    ScanResult r = result(i, 5);
    r.pose_info.source = "gicp";
    r.pose_info.reason = reasons[i];
    r.pose_info.accepted = r.pose_info.reason.empty();
    r.pose_info.status = r.pose_info.accepted ? "ok" : r.pose_info.reason + " (figures)";
    r.pose_info.map_restarts = i == 5;
    w.write(r, std::nullopt);
  }
  const std::vector<std::pair<std::string, std::size_t>> expected = {
      {"degenerate scene", 2},
      {"a jump beyond max_speed / max_turn_rate", 1},
      {"too few correspondences, the map started again", 1},
      {"too few points", 1}};
  EXPECT_EQ(w.refusedAlignments(), expected);
  w.finish(0.1);
  const std::string md = io::readTextFile((dir / "out/report.md").string());
  EXPECT_NE(md.find("3 of 8 scans aligned or first"), std::string::npos) << md;
  EXPECT_NE(md.find("| too few correspondences, the map started again | 1 |"), std::string::npos)
      << md;
}
