// SPDX-License-Identifier: BSD-3-Clause
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <condition_variable>
#include <mutex>
#include <numeric>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <unordered_map>
#include <vector>

#include <sys/syscall.h>
#include <unistd.h>

#include <cmath>
#include <limits>

#include "cleanmap/core/cell_key.h"
#include "cleanmap/core/cell_map.h"
#include "cleanmap/core/parallel.h"
#include "cleanmap/core/serial_worker.h"
#include "cleanmap/core/types.h"

using namespace cleanmap;

TEST(Scan, DropInvalidKeepsOriginalOrder) {
  Scan s;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  s.points = {{1, 2, 3, 0.5f}, {nan, 0, 0, 0}, {4, 5, 6, 0.1f}, {0, inf, 0, 0}, {7, 8, 9, nan}};
  EXPECT_EQ(dropInvalidPoints(s), 3u);
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(s.original_size, 5u);
  EXPECT_EQ(s.dropped_invalid, 3u);
  EXPECT_EQ(s.originalIndex(0), 0u);
  EXPECT_EQ(s.originalIndex(1), 2u);
  EXPECT_FLOAT_EQ(s.points[1].z, 6.0f);
  // A second pass keeps the mapping to the input, not to the first pass.
  s.points[0].x = nan;
  EXPECT_EQ(dropInvalidPoints(s), 1u);
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s.originalIndex(0), 2u);
  EXPECT_EQ(s.dropped_invalid, 4u);
}

TEST(Scan, AllValidLeavesIdentityMapping) {
  Scan s;
  s.points = {{1, 2, 3, 0}, {4, 5, 6, 0}};
  EXPECT_EQ(dropInvalidPoints(s), 0u);
  EXPECT_TRUE(s.original_index.empty());
  EXPECT_EQ(s.originalIndex(1), 1u);
}

TEST(Labels, SemanticKittiClasses) {
  EXPECT_EQ(gtClass(0), GtClass::kIgnore);
  EXPECT_EQ(gtClass(1), GtClass::kIgnore);
  EXPECT_EQ(gtClass(9), GtClass::kStatic);
  EXPECT_EQ(gtClass(40), GtClass::kStatic);
  EXPECT_EQ(gtClass(250), GtClass::kStatic);
  EXPECT_EQ(gtClass(251), GtClass::kMoving);
  EXPECT_EQ(gtClass(259), GtClass::kMoving);
  EXPECT_EQ(gtClass(260), GtClass::kStatic);
  // Instance ids live in the upper 16 bits and do not change the class.
  EXPECT_EQ(gtClass((7u << 16) | 252u), GtClass::kMoving);
  EXPECT_EQ(gtClass((7u << 16) | 0u), GtClass::kIgnore);
}

// KITTI-like camera: lidar x forward, camera z forward.
PinholeCamera kittiLikeCamera() {
  PinholeCamera c;
  c.width = 1242;
  c.height = 375;
  c.P << 721.5, 0, 609.6, 44.86, 0, 721.5, 172.9, 0.2164, 0, 0, 1, 0.0027;
  Eigen::Matrix3d R;
  R << 0, -1, 0, 0, 0, -1, 1, 0,
      0;  // lidar (x fwd, y left, z up) -> camera (x right, y down, z fwd)
  c.T_cam_lidar.linear() = R;
  c.T_cam_lidar.translation() = Eigen::Vector3d(0, -0.08, -0.27);
  return c;
}

TEST(PinholeCamera, ProjectsAheadAndRejectsBehind) {
  const auto c = kittiLikeCamera();
  const auto ahead = c.project({20, 0, 0});
  ASSERT_TRUE(ahead.has_value());
  EXPECT_NEAR(ahead->x(), 609.6 + 44.86 / 20.0, 0.5);  // near the principal point
  EXPECT_FALSE(c.project({-20, 0, 0}).has_value());    // behind
  EXPECT_FALSE(c.project({2, 30, 0}).has_value());     // far to the left, outside the image
}

TEST(PinholeCamera, OpticalFrameReproducesProjection) {
  const auto c = kittiLikeCamera();
  const Eigen::Vector3d p(15, 2, -1);
  const Eigen::Vector3d q = c.opticalFromLidar() * p;
  const Eigen::Vector3d uvw_opt = c.K() * q;
  const Eigen::Vector3d uvw = c.lidarToPixel() * p.homogeneous();
  EXPECT_NEAR(uvw_opt.x() / uvw_opt.z(), uvw.x() / uvw.z(), 1e-6);
  EXPECT_NEAR(uvw_opt.y() / uvw_opt.z(), uvw.y() / uvw.z(), 1e-6);
}

// The one parallel loop: every index exactly once, worker ids in range, whatever the split.
TEST(ParallelFor, EveryIndexOnceWorkersInRange) {
  for (int threads : {1, 2, 3, 8})
    for (std::size_t chunk : {std::size_t(1), std::size_t(7), std::size_t(512)})
      for (std::size_t n : {std::size_t(0), std::size_t(1), std::size_t(100), std::size_t(5000)}) {
        std::vector<std::atomic<int>> hits(n);
        std::atomic<bool> bad_worker{false};
        parallelFor(
            n, threads,
            [&](std::size_t i, int w) {
              hits[i].fetch_add(1);
              if (w < 0 || w >= threads) bad_worker = true;
            },
            chunk);
        for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(hits[i].load(), 1) << "n " << n << " i " << i;
        EXPECT_FALSE(bad_worker);
      }
  // Per-worker accumulators sum to the serial result.
  std::vector<long> acc(4, 0);
  parallelFor(
      10000, 4, [&](std::size_t i, int w) { acc[std::size_t(w)] += long(i); }, 64);
  EXPECT_EQ(std::accumulate(acc.begin(), acc.end(), 0L), 10000L * 9999L / 2);
}

// The helpers are kept from one loop to the next (issue #16): every loop of a thread runs its
// worker 1 on the same kernel thread, and a wider loop adds helpers without losing the first.
// Each index waits for the loop's other indices to start, so each worker takes exactly one.
TEST(ParallelFor, KeepsItsHelperThreadsBetweenLoops) {
  auto tid = [] { return static_cast<long>(::syscall(SYS_gettid)); };
  auto loop = [&](int width) {
    std::vector<long> by_worker(std::size_t(width), 0);
    std::atomic<int> started{0};
    parallelFor(
        std::size_t(width), width,
        [&](std::size_t, int w) {
          ++started;
          while (started.load() < width) std::this_thread::yield();
          by_worker[std::size_t(w)] = tid();
        },
        1);
    return by_worker;
  };
  std::thread([&] {  // a fresh calling thread: its helpers start with its first loop
    std::set<long> helper;
    for (int k = 0; k < 100; ++k) {
      const auto w = loop(2);
      EXPECT_EQ(w[0], tid());
      helper.insert(w[1]);
    }
    EXPECT_EQ(helper.size(), 1u);  // a thread started per loop would be 100 kernel threads
    const auto w = loop(4);
    EXPECT_EQ(w[0], tid());
    EXPECT_EQ(w[1], *helper.begin());
    EXPECT_EQ(std::set<long>(w.begin(), w.end()).size(), 4u);
  })
      .join();
}

// A gate the jobs of a test wait at until the test opens it.
struct Gate {
  std::mutex mu;
  std::condition_variable cv;
  bool open = false;
  void pass() {
    std::unique_lock<std::mutex> lock(mu);
    cv.wait(lock, [&] { return open; });
  }
  void openIt() {
    {
      std::lock_guard<std::mutex> lock(mu);
      open = true;
    }
    cv.notify_all();
  }
};

// The free-space insertions, the label files and the MRPT outputs run through one SerialWorker:
// jobs in the order pushed on one thread, at most max_pending at a time, waits by tag, and the
// first error kept: the jobs queued behind it dropped, every later call rethrowing it.
TEST(SerialWorker, RunsInOrderBoundedWaitsByTagAndKeepsTheFirstError) {
  std::vector<int> ran;  // written by the worker only; read after wait()
  std::set<std::thread::id> threads;
  std::atomic<int> running{0}, most{0};
  Gate gate;
  SerialWorker<int> w(
      [&](int& v) {
        const int now = ++running;
        most = std::max(most.load(), now);
        if (v == 0) gate.pass();
        if (v < 0) throw std::runtime_error("job " + std::to_string(v));
        ran.push_back(v);
        threads.insert(std::this_thread::get_id());
        --running;
      },
      2);
  w.push(0, 0);  // held at the gate
  w.push(1, 1);
  EXPECT_FALSE(w.doneThrough(0));
  EXPECT_FALSE(w.doneThrough(1));
  std::atomic<bool> third_queued{false};
  std::thread pusher([&] {
    w.push(2, 2);  // waits: two pending already
    third_queued = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_FALSE(third_queued.load());
  gate.openIt();
  pusher.join();
  w.waitThrough(1);
  EXPECT_TRUE(w.doneThrough(1));
  for (int v = 3; v < 40; ++v) w.push(int(v), v);
  w.wait();
  EXPECT_TRUE(w.doneThrough(1000));
  ASSERT_EQ(ran.size(), 40u);
  for (int v = 0; v < 40; ++v) EXPECT_EQ(ran[std::size_t(v)], v);
  EXPECT_EQ(threads.size(), 1u);
  EXPECT_EQ(most.load(), 1);
  EXPECT_GE(w.takeMs(), 0.0);
  EXPECT_EQ(w.takeMs(), 0.0);  // taken

  // The first error: the jobs behind it are dropped, and every later call rethrows it.
  Gate hold;
  SerialWorker<int> f([&](int& v) {
    if (v == 100) hold.pass();
    if (v < 0) throw std::runtime_error("job " + std::to_string(v));
    ran.push_back(v);
  });
  f.push(100, 0);
  f.push(-1, 1);
  f.push(-2, 2);
  f.push(101, 3);
  hold.openIt();
  f.waitThrough(3);
  for (int k = 0; k < 2; ++k) {
    try {
      f.wait();
      ADD_FAILURE() << "no error";
    } catch (const std::runtime_error& e) {
      EXPECT_EQ(std::string(e.what()), "job -1");
    }
  }
  EXPECT_THROW(f.takeMs(), std::runtime_error);
  EXPECT_THROW(f.push(102, 4), std::runtime_error);
  EXPECT_EQ(ran.back(), 100);  // 101 and 102 never ran

  // stop() drops the queued jobs and waits for the running one.
  Gate last;
  std::atomic<int> count{0};
  std::atomic<bool> started{false};
  SerialWorker<int> s([&](int& v) {
    if (v == 0) {
      started = true;
      last.pass();
    }
    ++count;
  });
  s.push(0);
  s.push(1);
  s.push(2);
  while (!started) std::this_thread::yield();  // job 0 is running: 1 and 2 are queued
  std::thread opener([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    last.openIt();
  });
  s.stop();
  opener.join();
  EXPECT_EQ(count.load(), 1);
  s.push(3);  // starts again
  s.wait();
  EXPECT_EQ(count.load(), 2);
}

// An exception thrown by an index reaches the caller once every worker is done, and the loop
// can be used again; loops nested in a worker and loops of other threads get their own workers.
TEST(ParallelFor, RethrowsAndNestsAndRunsFromSeveralThreads) {
  for (int thrower : {0, 1, 2})
    for (int round = 0; round < 2; ++round) {
      std::atomic<int> done{0};
      try {
        parallelFor(
            3, 3,
            [&](std::size_t i, int) {
              if (int(i) == thrower) throw std::runtime_error("index " + std::to_string(i));
              ++done;
            },
            1);
        ADD_FAILURE() << "no exception from index " << thrower;
      } catch (const std::runtime_error& e) {
        EXPECT_EQ(std::string(e.what()), "index " + std::to_string(thrower));
      }
      EXPECT_EQ(done.load(), 2);  // the other indices ran
    }
  auto sum_squares = [](std::size_t n, int threads) {
    std::vector<long> acc(std::size_t(threads), 0);
    parallelFor(
        n, threads, [&](std::size_t i, int w) { acc[std::size_t(w)] += long(i * i); }, 16);
    return std::accumulate(acc.begin(), acc.end(), 0L);
  };
  const long expect = sum_squares(1000, 1);
  std::vector<long> nested(8, 0);
  parallelFor(
      8, 2, [&](std::size_t i, int) { nested[i] = sum_squares(1000, 2); }, 1);
  for (const long v : nested) EXPECT_EQ(v, expect);
  std::vector<long> from_threads(4, 0);
  std::vector<std::thread> callers;
  for (std::size_t c = 0; c < from_threads.size(); ++c)
    callers.emplace_back([&, c] {
      for (int k = 0; k < 50; ++k) from_threads[c] += sum_squares(1000, 3);
    });
  for (auto& t : callers) t.join();
  for (const long v : from_threads) EXPECT_EQ(v, 50 * expect);
}

TEST(CellKey, FloorNeighboursAndShift) {
  EXPECT_EQ(floorToCell(-0.01, 10.0), -1);
  EXPECT_EQ(floorToCell(0.0, 10.0), 0);
  EXPECT_EQ(floorToCell(0.299f, 1.0f / 0.3f), 0);
  EXPECT_EQ(floorToCell(-2.5, 1.0), -3);
  std::set<uint64_t> around;
  const uint64_t c = cellKeyOf(-3.2, 7.9, 0.05, 2.0);
  forEachNeighbour27([&](int dx, int dy, int dz) { around.insert(cellKeyShift(c, dx, dy, dz)); });
  EXPECT_EQ(around.size(), 27u);
  EXPECT_TRUE(around.count(c));
  EXPECT_EQ(cellKeyShift(c, 1, -1, 0), cellKey(-7 + 1, 15 - 1, 0));
  EXPECT_EQ(cellKeyShift(cellKeyShift(c, 5, -9, 2), -5, 9, -2), c);
  // Negative and positive cells never collide within +-2^20.
  EXPECT_NE(cellKey(-1, 0, 0), cellKey(1, 0, 0));
  EXPECT_NE(cellKey(0, -(1 << 20), 0), cellKey(0, (1 << 20) - 1, 0));
}

TEST(CellKey, HalfNeighbourhoodMeetsEachPairOnce) {
  // forEachNeighbour13 (the object consensus's unions): 13 offsets, none the cell itself, and of
  // each offset and its opposite exactly one, so visiting them from every cell meets each pair
  // of neighbouring cells once.
  std::set<std::array<int, 3>> half;
  forEachNeighbour13([&](int dx, int dy, int dz) { half.insert({dx, dy, dz}); });
  EXPECT_EQ(half.size(), 13u);
  EXPECT_FALSE(half.count({0, 0, 0}));
  forEachNeighbour27([&](int dx, int dy, int dz) {
    if (dx == 0 && dy == 0 && dz == 0) return;
    EXPECT_NE(half.count({dx, dy, dz}), half.count({-dx, -dy, -dz})) << dx << dy << dz;
  });
}

TEST(CellMap, HoldsWhatStdUnorderedMapHolds) {
  // Issue #16's flat cell map against std::unordered_map: random cells (negative coordinates
  // included), growth from empty, lookups of present and absent keys, every entry visited once.
  std::mt19937 rng(16);
  std::uniform_int_distribution<int> c(-3000, 3000);
  CellMap<uint32_t> flat;
  std::unordered_map<uint64_t, uint32_t> ref;
  for (uint32_t i = 0; i < 50000; ++i) {
    const uint64_t k = cellKey(c(rng), c(rng), c(rng) / 100);
    bool fresh = false;
    uint32_t& v = flat.get(k, &fresh);
    EXPECT_EQ(fresh, ref.count(k) == 0);
    if (fresh) v = i;
    ref.emplace(k, i);
  }
  ASSERT_EQ(flat.size(), ref.size());
  EXPECT_LE(2 * flat.size(), flat.capacity());  // at most half full
  for (const auto& [k, v] : ref) {
    const uint32_t* f = flat.find(k);
    ASSERT_NE(f, nullptr);
    EXPECT_EQ(*f, v);
  }
  std::size_t absent = 0;
  for (int i = 0; i < 10000; ++i) {
    const uint64_t k = cellKey(c(rng), c(rng), 5000 + i);  // z outside every inserted cell
    absent += flat.find(k) == nullptr;
  }
  EXPECT_EQ(absent, 10000u);
  std::size_t visited = 0;
  flat.forEach([&](uint64_t k, uint32_t v) {
    ++visited;
    EXPECT_EQ(ref.at(k), v);
  });
  EXPECT_EQ(visited, ref.size());
  const CellMap<uint32_t> none;
  EXPECT_EQ(none.find(cellKey(0, 0, 0)), nullptr);
}

TEST(CellMap, ClearedAndRefilledPastItsReserveKeepsEveryFirstValue) {
  // A per-scan grid (the registration's voxels): reserved for fewer keys than come, cleared and
  // filled again; the first value given to a key stays, and no key of the scan before is left.
  CellMap<uint32_t> m;
  for (const uint32_t n : {5000u, 300u}) {
    m.clear();
    m.reserve(n / 8);
    for (uint32_t k = 0; k < n; ++k) {
      const uint64_t key = uint64_t(k) * 7919u + 3;
      bool fresh = false;
      uint32_t& v = m.get(key, &fresh);
      ASSERT_TRUE(fresh) << k;
      v = k;
      EXPECT_FALSE(m.insert(key));  // present: the value stays
    }
    EXPECT_EQ(m.size(), n);
    EXPECT_LE(2 * m.size(), m.capacity());
    for (uint32_t k = 0; k < n; ++k) {
      const uint32_t* v = m.find(uint64_t(k) * 7919u + 3);
      ASSERT_TRUE(v && *v == k) << k;
    }
    EXPECT_EQ(m.find(1), nullptr);
  }
  EXPECT_EQ(m.find(uint64_t(4000) * 7919u + 3), nullptr);  // the first fill's, cleared
}

TEST(CellSet, AnswersAsASetOfCellKeys) {
  // The scene's blocked voxel filter against a CellMap of cellKey: walks (consecutive cells
  // near each other, as points of a scan) and random jumps, negative coordinates, block edges,
  // and coordinates 2^21 apart, which cellKey wraps to the same cell.
  std::mt19937 rng(18);
  std::uniform_int_distribution<int> jump(-200000, 200000), step(-2, 2), pick(0, 99);
  CellSet blocked;
  CellMap<uint8_t> keys;
  int64_t x = 0, y = -8, z = 7;
  std::size_t fresh = 0;
  for (int i = 0; i < 200000; ++i) {
    if (pick(rng) == 0) {
      x = jump(rng), y = jump(rng), z = jump(rng) / 1000;
    } else {
      x += step(rng), y += step(rng), z += step(rng);
    }
    const int64_t wrap = pick(rng) < 5 ? (int64_t(1) << 21) : 0;
    const bool a = blocked.insert(x + wrap, y, z - wrap);
    ASSERT_EQ(a, keys.insert(cellKey(x, y, z))) << x << " " << y << " " << z;
    fresh += a;
  }
  EXPECT_EQ(blocked.size(), keys.size());
  EXPECT_EQ(blocked.size(), fresh);
  EXPECT_LT(blocked.blocks(), keys.size() / 4);  // walks fill blocks: fewer blocks than cells
  // Points: the cell of floor(v / side), as cellKeyOf.
  CellSet pts;
  EXPECT_TRUE(pts.insertPoint(-0.01, 0.0, 0.19, 1.0 / 0.2));
  EXPECT_FALSE(pts.insertPoint(-0.19, 0.01, 0.01, 1.0 / 0.2));
  EXPECT_TRUE(pts.insertPoint(0.01, 0.0, 0.19, 1.0 / 0.2));
}

TEST(CellMap, EraseKeepsEveryOtherKeyFindable) {
  // Keys come and go as in the duplicate filter's window, in a small key space (long probe runs
  // that wrap around the array): after each erase every remaining key is found with its value.
  std::mt19937 rng(17);
  std::uniform_int_distribution<int> c(-40, 40);
  CellMap<std::vector<int>> flat;
  std::unordered_map<uint64_t, int> ref;
  for (int i = 0; i < 200000; ++i) {
    const uint64_t k = cellKey(c(rng), c(rng), 0);
    if (i % 3 == 2) {
      EXPECT_EQ(flat.erase(k), ref.erase(k) == 1);
    } else {
      flat.get(k) = {i};
      ref[k] = i;
    }
    if (i % 997 == 0) {
      ASSERT_EQ(flat.size(), ref.size());
      for (const auto& [key, v] : ref) {
        const auto* f = flat.find(key);
        ASSERT_NE(f, nullptr) << "step " << i;
        ASSERT_EQ(f->front(), v);
      }
      std::size_t n = 0;
      flat.forEach([&](uint64_t, const std::vector<int>&) { ++n; });
      ASSERT_EQ(n, ref.size());
    }
  }
  for (const auto& [key, v] : ref) EXPECT_TRUE(flat.erase(key));
  EXPECT_TRUE(flat.empty());
  EXPECT_FALSE(flat.erase(cellKey(0, 0, 0)));
}
