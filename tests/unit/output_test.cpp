// SPDX-License-Identifier: BSD-3-Clause
// The output folder is published as a whole (DESIGN §4): a finished run replaces an earlier one
// entirely, a failed run leaves OUTDIR as it was, a folder that is no cleanmap run is refused.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <ctime>
#include <nlohmann/json.hpp>
#include <random>
#include <thread>

#include "cleanmap/core/error.h"
#include "cleanmap/core/free_space.h"
#include "cleanmap/io/files.h"
#include "cleanmap/io/grouping_spool.h"
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

// The steady rate is that of the decisions, not of the writes: rule 4 backwards holds each result
// for later scans, so results decided 30 ms apart while scans came in may all be written after the
// input ended. Written at once, they keep their decisions' 30 ms; decided after the end, left out.
TEST(Output, TheSteadyIntervalIsTheTimeBetweenDecisions) {
  const auto dir = test::scratchDir("output_interval_decided");
  {
    io::OutputWriter w((dir / "out").string(), "input", PipelineParams{});
    const auto now = std::chrono::steady_clock::now();
    std::vector<ScanResult> held;
    for (std::size_t i = 0; i < 4; ++i) {
      held.push_back(result(i, 5));
      held.back().decided_at = now - std::chrono::milliseconds(30 * (3 - i));
    }
    w.inputEnded();
    for (const auto& r : held) w.write(r, std::nullopt);
    for (std::size_t i = 4; i < 8; ++i) {
      ScanResult r = result(i, 5);
      r.decided_at = std::chrono::steady_clock::now();  // after the input's end
      w.write(r, std::nullopt);
    }
    w.finish(0.1);
  }
  const auto j = nlohmann::json::parse(io::readTextFile((dir / "out/report.json").string()));
  const auto& t = j.at("timing_per_scan").at("interval");
  EXPECT_NEAR(t.at("median_ms").get<double>(), 30.0, 1e-6);
  EXPECT_NEAR(t.at("mean_ms").get<double>(), 30.0, 1e-6);
}

// The process's clocks (report.json `process`): its age runs with the wall clock and began before
// this test program's code was loaded; its CPU counts the work of its threads.
const auto kLoaded = std::chrono::steady_clock::now();

TEST(Output, TheProcessClocksRunFromTheProcesssStart) {
  const auto age0 = io::processAgeSeconds();
  ASSERT_TRUE(age0.has_value()) << "/proc/self/stat is unreadable";
  const double since_loaded =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - kLoaded).count();
  EXPECT_GE(*age0, since_loaded - 0.011);  // the start time is in 10 ms ticks
  EXPECT_LT(*age0, 3600.0);
  const double cpu0 = io::processCpuSeconds();
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  const auto age1 = io::processAgeSeconds();
  ASSERT_TRUE(age1.has_value());
  EXPECT_GE(*age1 - *age0, 0.099);
  EXPECT_LT(*age1 - *age0, 5.0);
  // Another thread computes until its own CPU clock has run 50 ms (however busy the machine):
  // the process's CPU, ended threads included, has grown by at least that.
  std::thread busy([] {
    const auto cpu = [] {
      timespec t{};
      clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
      return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
    };
    const double until = cpu() + 0.05;
    volatile double x = 0;
    while (cpu() < until) x = x + 1;
  });
  busy.join();
  EXPECT_GE(io::processCpuSeconds() - cpu0, 0.049);
}

// report.json `process`: the command's whole time, of which `wall_s` (the scans) is a part. A
// writer made, 60 ms of other work, then the scans said to take 10 ms: 50 ms and more are left to
// the end (in the app, the map's final decision and files).
TEST(Output, TheReportSaysTheWholeProcessAndItsParts) {
  const auto dir = test::scratchDir("output_process");
  {
    io::OutputWriter w((dir / "out").string(), "input", PipelineParams{});
    ASSERT_TRUE(w.startSeconds().has_value());
    std::this_thread::sleep_for(std::chrono::milliseconds(60));
    for (std::size_t i = 0; i < 4; ++i) w.write(result(i, 5), std::nullopt);
    w.finish(0.01);
  }
  const auto j = nlohmann::json::parse(io::readTextFile((dir / "out/report.json").string()));
  const auto& p = j.at("process");
  const double all = p.at("wall_s").get<double>(), start = p.at("start_s").get<double>();
  EXPECT_GE(start, 0.0);
  EXPECT_GE(all, start + 0.01 + 0.05);
  EXPECT_GE(p.at("end_s").get<double>(), 0.05);
  EXPECT_NEAR(p.at("end_s").get<double>(), all - start - 0.01, 1e-9);
  EXPECT_NEAR(p.at("wall_per_scan_ms").get<double>(), 1000 * all / 4, 1e-9);
  EXPECT_GT(p.at("cpu_s").get<double>(), 0.0);
  EXPECT_NEAR(p.at("cpu_per_scan_ms").get<double>(), 1000 * p.at("cpu_s").get<double>() / 4, 1e-9);
  EXPECT_NE(io::readTextFile((dir / "out/report.md").string()).find(" s in all"),
            std::string::npos);
}

// report.json `map.clean_passes_ms`: the map's decision pass by pass (DESIGN §2e, "Objects"). With
// the objects decided both ways the three passes run, each a part of `clean_ms`; one way (the
// objects off), the writing pass is the whole decision.
TEST(Output, TheMapsPassesArePartsOfItsDecision) {
  const auto dir = test::scratchDir("output_passes");
  for (const bool objects : {true, false}) {
    PipelineParams params;
    params.map.objects = objects;
    const auto out = dir / (objects ? "both" : "one");
    {
      io::OutputWriter w(out.string(), "input", params);
      for (std::size_t i = 0; i < 6; ++i) w.write(result(i, 50), std::nullopt);
      const FreeSpaceMap free_space(params.map);
      w.finish(0.1, &free_space);
    }
    const auto j = nlohmann::json::parse(io::readTextFile((out / "report.json").string()));
    const auto& m = j.at("map");
    const auto& p = m.at("clean_passes_ms");
    const double f = p.at("forward"), b = p.at("backward"), wr = p.at("write");
    EXPECT_GE(b, 0.0);
    EXPECT_GT(wr, 0.0);
    EXPECT_LE(f + b + wr, m.at("clean_ms").get<double>()) << p.dump();
    if (objects)
      EXPECT_GT(f, 0.0) << p.dump();
    else
      EXPECT_EQ(f + b, 0.0) << p.dump();
  }
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

TEST(MapSpool, AGroupingReadBackIsTheGroupingWrittenAndDecidesTheSame) {
  // The map's forward pass spools each scan's grouping for the backward pass (DESIGN §2e,
  // "Objects"). A street in the world frame, jittered with a seed: a sidewalk joining two walls
  // and a walker (pieces of a structure), a sparse lidar's rings on a walker 25 m from the sensor
  // (pooled slices), ground points outside the objects.
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> jitter(-0.03f, 0.03f);
  std::vector<PointXYZI> pts;
  std::vector<uint8_t> member;
  const auto add = [&](float x, float y, float z, bool m) {
    pts.push_back({x + jitter(rng), y + jitter(rng), z + jitter(rng), 0});
    member.push_back(m);
  };
  for (float x = 0; x <= 40; x += 0.2f) {
    for (float y = -10; y < -6.1f; y += 0.2f) add(x, y, 0.12f, true);  // sidewalk
    for (float y = -6; y < 6; y += 0.5f) add(x, y, 0.0f, false);       // the road: ground
    if (x > 20 && x < 22) continue;
    for (float z = 0.12f; z <= 2.5f; z += 0.2f) add(x, -10.1f, z, true);  // two walls
  }
  for (float x = 10; x <= 10.5f; x += 0.1f)
    for (float z = 0.2f; z <= 1.8f; z += 0.1f) add(x, -9.6f, z, true);  // the walker
  for (const float z : {-1.28f, -0.70f, -0.12f})                        // rings at 25 m
    for (int j = 0; j < 7; ++j) add(-25.0f, 3.0f + 0.08f * float(j), z, true);
  ObjectParams p;
  p.ring_pool = 2.5;
  const RingReach reach = ringReach(p, 1.33 * M_PI / 180.0);
  ObjectComponents own, back;
  groupObjects(pts, member, p.voxel, own, reach);
  ASSERT_FALSE(own.piece.empty());
  ASSERT_FALSE(own.pooled.empty());
  std::vector<unsigned char> bytes{1, 2, 3};  // appended after what is there
  io::appendGrouping(own, bytes);
  io::readGrouping(bytes.data() + 3, bytes.size() - 3, pts.size(), reach, "spool", back);
  EXPECT_EQ(back.side, own.side);
  EXPECT_TRUE(back.reach == own.reach);
  EXPECT_EQ(back.voxels, own.voxels);
  EXPECT_EQ(back.point_voxel, own.point_voxel);
  EXPECT_EQ(back.root_of, own.root_of);
  EXPECT_EQ(back.pooled, own.pooled);
  EXPECT_EQ(back.piece, own.piece);
  ASSERT_EQ(back.voxel_of.size(), own.voxel_of.size());
  for (uint32_t v = 0; v < own.voxels.size(); ++v) {
    const Eigen::Vector3i& c = own.voxels[v];
    const uint32_t* found = back.voxel_of.find(cellKey(c.x(), c.y(), c.z()));
    ASSERT_NE(found, nullptr);
    EXPECT_EQ(*found, v);
    EXPECT_EQ(back.voxel_of.find(cellKey(c.x(), c.y(), c.z() + 100)), nullptr);
  }
  // The same decision from either grouping: a third of the walker's and the rings' points moving.
  std::vector<uint8_t> moving(pts.size(), 0);
  for (std::size_t i = 0; i < pts.size(); ++i)
    moving[i] = member[i] && (pts[i].x < -20 || (pts[i].y > -9.7f && pts[i].y < -9.5f)) && i % 3;
  ConsensusRules rules;
  rules.reach = reach;
  auto by_own = moving, by_back = moving;
  objectConsensus(pts, member, by_own, p, nullptr, nullptr, rules, &own);
  objectConsensus(pts, member, by_back, p, nullptr, nullptr, rules, &back);
  EXPECT_NE(by_own, moving);  // the rules changed something
  EXPECT_EQ(by_back, by_own);
  // No members: an empty grouping round-trips too.
  std::vector<uint8_t> none(pts.size(), 0);
  groupObjects(pts, none, p.voxel, own, reach);
  bytes.clear();
  io::appendGrouping(own, bytes);
  io::readGrouping(bytes.data(), bytes.size(), pts.size(), reach, "spool", back);
  EXPECT_TRUE(back.voxels.empty());
  EXPECT_EQ(back.point_voxel, std::vector<uint32_t>(pts.size(), UINT32_MAX));
}

TEST(MapSpool, AGroupingOfOtherSizesIsAClearError) {
  std::vector<PointXYZI> pts;
  for (int i = 0; i < 50; ++i) pts.push_back({0.1f * float(i), 0, 1, 0});
  const std::vector<uint8_t> member(pts.size(), 1);
  ObjectComponents cc, back;
  groupObjects(pts, member, 0.3, cc);
  std::vector<unsigned char> bytes;
  io::appendGrouping(cc, bytes);
  const auto fails = [&](std::size_t n, std::size_t points, const std::string& what) {
    try {
      io::readGrouping(bytes.data(), n, points, {}, "/tmp/run/.map_groupings", back);
      ADD_FAILURE() << "no error for " << what;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("/tmp/run/.map_groupings: "), std::string::npos)
          << e.what();
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  fails(bytes.size() - 1, pts.size(), "bytes where its counts need");
  fails(10, pts.size(), "(short)");
  fails(bytes.size(), pts.size() + 1, "for a scan of 51");
  // A point's voxel past the voxels (a spool overwritten) is refused, not followed.
  auto* first_point = reinterpret_cast<uint32_t*>(bytes.data() + 32);
  ASSERT_EQ(*first_point, 0u);
  *first_point = 1000;
  fails(bytes.size(), pts.size(), "past its voxels");
}
