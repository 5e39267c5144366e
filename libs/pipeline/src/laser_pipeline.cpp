// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/pipeline/laser_pipeline.h"

#include "cleanmap/core/object_consensus.h"

#include <atomic>
#include <chrono>
#include <cmath>
#include <thread>

#include "cleanmap/core/cell_key.h"
#include "cleanmap/core/error.h"
#include "cleanmap/core/ground.h"
#include "cleanmap/core/octree_sampling.h"

namespace cleanmap {
namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// Runs f(i) for i in [0, n) on `threads` threads (serial path for 1); results must not depend on
// the split, so runs are identical whatever the thread count.
template <class F>
void parallelFor(std::size_t n, int threads, F&& f) {
  const std::size_t t = std::max(1, threads);
  if (t == 1 || n < 256) {
    for (std::size_t i = 0; i < n; ++i) f(i);
    return;
  }
  // Chunks handed out from a counter: balanced load, no two threads writing the same cache line
  // (each index's result does not depend on which thread computes it).
  constexpr std::size_t kChunk = 512;
  std::atomic<std::size_t> next{0};
  auto work = [&] {
    for (std::size_t b; (b = next.fetch_add(kChunk)) < n;)
      for (std::size_t i = b; i < std::min(n, b + kChunk); ++i) f(i);
  };
  std::vector<std::thread> pool;
  for (std::size_t w = 1; w < t; ++w) pool.emplace_back(work);
  work();
  for (auto& th : pool) th.join();
}

PointXYZI toWorld(const Eigen::Isometry3d& T, const PointXYZI& p) {
  const Eigen::Vector3d w = T * Eigen::Vector3d(p.x, p.y, p.z);
  return {static_cast<float>(w.x()), static_cast<float>(w.y()), static_cast<float>(w.z()),
          p.intensity};
}

}  // namespace

StageTimes& StageTimes::operator+=(const StageTimes& o) {
  index += o.index;
  ground += o.ground;
  duplicates += o.duplicates;
  octree += o.octree;
  classify += o.classify;
  objects += o.objects;
  total += o.total;
  return *this;
}

struct LaserPipeline::Prepared {
  std::size_t index;
  std::string stem;
  Scan scan;
  BeamIndex beams;
  std::vector<uint8_t> in_crop, ground;
  Eigen::Isometry3d world_to_sensor;
  ScanStats stats;
};

uint64_t LaserPipeline::persistCell(const Eigen::Vector3d& w) const {
  return cellKeyOf(w.x(), w.y(), w.z(), 1.0 / p_.object.persist_radius);
}

LaserPipeline::LaserPipeline(const PipelineParams& params, Sink sink)
    : p_(params), sink_(std::move(sink)), test_(params.ds), dup_(params.filter) {}

LaserPipeline::~LaserPipeline() = default;

std::unique_ptr<LaserPipeline::Prepared> LaserPipeline::prepare(Frame&& f) {
  if (!f.scan.has_pose)
    throw Error("scan " + f.stem,
                "has no pose: give a posed input (KITTI poses.txt / OXTS, rawlog "
                "CObservationRobotPose); GICP registration (--poses gicp) is not available yet");
  auto s = std::make_unique<Prepared>();
  s->index = f.index;
  s->stem = f.stem;
  s->scan = std::move(f.scan);
  s->world_to_sensor = s->scan.pose.inverse();
  auto& st = s->stats;
  st.points = s->scan.original_size ? s->scan.original_size : s->scan.size();
  st.invalid = s->scan.dropped_invalid;
  st.empty = s->scan.empty();

  auto t0 = Clock::now();
  // Every valid point is a beam (ground and far points included, SPEC §2.4).
  s->beams = BeamIndex(s->scan.points, test_.searchRadius());
  st.ms.index = msSince(t0);

  t0 = Clock::now();
  const auto& pts = s->scan.points;
  const float tau = static_cast<float>(p_.filter.crop_tau);
  s->in_crop.resize(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i)  // SPEC §2.2: per-axis crop in the sensor frame
    s->in_crop[i] = std::abs(pts[i].x) <= tau && std::abs(pts[i].y) <= tau &&
                    std::abs(pts[i].z) <= tau;
  s->ground = segmentGround(pts, p_.ground, p_.filter.crop_tau);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    s->ground[i] = s->ground[i] && s->in_crop[i];
    st.in_crop += s->in_crop[i];
    st.ground += s->ground[i];
  }
  st.ms.ground = msSince(t0);
  return s;
}

void LaserPipeline::push(Frame&& frame) {
  if (static_cast<long>(frame.index) <= prev_index_)
    throw Error("scan " + frame.stem, "arrives out of order");
  prev_index_ = static_cast<long>(frame.index);
  buf_.push_back(prepare(std::move(frame)));
  decideReady(static_cast<std::size_t>(p_.ds.window_k));
}

void LaserPipeline::finish() {
  decideReady(0);  // the windows shrink at the end
  buf_.clear();
  next_ = 0;
}

// Decides every buffered scan that has at least `future` scans after it, then keeps only the K
// scans before the next one to decide.
void LaserPipeline::decideReady(std::size_t future) {
  const std::size_t K = static_cast<std::size_t>(p_.ds.window_k);
  while (next_ < buf_.size() && buf_.size() - 1 - next_ >= future) {
    decide(next_);
    ++next_;
    while (next_ > K) {
      buf_.pop_front();
      --next_;
    }
  }
}

void LaserPipeline::decide(std::size_t pos) {
  Prepared& s = *buf_[pos];
  ScanStats& st = s.stats;
  const auto t_start = Clock::now();
  const auto& pts = s.scan.points;
  const auto k = static_cast<long>(s.index);

  std::vector<WindowScan> window;
  for (std::size_t j = 0; j < buf_.size(); ++j)
    if (j != pos && !buf_[j]->beams.empty())
      window.push_back({&buf_[j]->beams, buf_[j]->world_to_sensor});
  st.window = window.size();

  // SPEC §2.3: duplicates of the recent static map are static, neither tested nor inserted.
  auto t0 = Clock::now();
  std::vector<uint32_t> cand;
  std::vector<Eigen::Vector3d> cand_world;
  std::vector<uint8_t> duplicate(pts.size(), 0);
  parallelFor(pts.size(), p_.threads, [&](std::size_t i) {  // read-only queries
    if (s.in_crop[i] && !s.ground[i])
      duplicate[i] = dup_.isDuplicate((s.scan.pose * pts[i].xyz().cast<double>()).cast<float>(), k);
  });
  for (uint32_t i = 0; i < pts.size(); ++i) {
    if (!s.in_crop[i] || s.ground[i]) continue;
    if (duplicate[i]) {
      ++st.duplicates;
      continue;
    }
    cand.push_back(i);
    cand_world.push_back(s.scan.pose * pts[i].xyz().cast<double>());
  }
  st.candidates = cand.size();
  st.ms.duplicates = msSince(t0);

  // SPEC §2c: octree leaves, a seeded random subset of each dense leaf is tested.
  t0 = Clock::now();
  std::mt19937_64 rng(p_.seed * 0x9E3779B97F4A7C15ull + static_cast<uint64_t>(k));
  const std::vector<Leaf> leaves = planLeaves(cand_world, p_.octree, rng);
  std::vector<uint32_t> tested;
  for (const auto& leaf : leaves) tested.insert(tested.end(), leaf.tested.begin(), leaf.tested.end());
  st.tested = tested.size();
  st.ms.octree = msSince(t0);

  // SPEC §2b: the moving-point test against the window.
  t0 = Clock::now();
  std::vector<uint8_t> moving_tested(cand.size(), 0);
  std::vector<MovingTestStats> per_point(tested.size());
  parallelFor(tested.size(), p_.threads, [&](std::size_t t) {
    const uint32_t c = tested[t];
    moving_tested[c] = test_.isMoving(cand_world[c], window, &per_point[t]);
  });
  for (const auto& m : per_point) {
    st.total_conflicts += m.total_conflicts;
    st.no_evidence += m.no_evidence;
    st.conflicting_scans += m.conflicting_scans;
  }
  st.ms.classify = msSince(t0);

  // Leaf decision, labels, maps.
  ScanResult r;
  r.index = s.index;
  r.stem = s.stem;
  r.timestamp = s.scan.timestamp;
  r.pose = s.scan.pose;
  r.labels.assign(st.points, kUnclassified);
  std::vector<uint8_t> moving(pts.size(), 0);
  for (const auto& leaf : leaves) {
    std::size_t mv = 0;
    for (uint32_t c : leaf.tested) mv += moving_tested[c];
    if (leafIsMoving(mv, leaf.tested.size()))
      for (uint32_t c : leaf.members) moving[cand[c]] = 1;
  }
  // Object consensus (doc/OBJECTS.md): duplicates included, they belong to the same objects.
  {
    t0 = Clock::now();
    std::vector<uint8_t> member(pts.size(), 0);
    for (uint32_t i = 0; i < pts.size(); ++i) member[i] = s.in_crop[i] && !s.ground[i];
    std::vector<uint8_t> near_prev;
    if (!prev_moving_cells_.empty()) {
      near_prev.assign(pts.size(), 0);
      for (uint32_t i = 0; i < pts.size(); ++i)
        if (member[i])
          near_prev[i] = prev_moving_cells_.count(persistCell(s.scan.pose * pts[i].xyz().cast<double>())) > 0;
    }
    const auto oc = objectConsensus(pts, member, moving, p_.object, near_prev.empty() ? nullptr : &near_prev);
    st.objects_persisted = oc.persisted;
    st.objects_moving = oc.moving_objects;
    st.consensus_points = oc.points_added;
    st.consensus_removed = oc.points_removed;
    st.ms.objects = msSince(t0);
  }
  std::vector<Eigen::Vector3f> inserted;
  for (uint32_t i = 0; i < pts.size(); ++i) {
    if (!s.in_crop[i]) continue;
    const uint32_t orig = s.scan.originalIndex(i);
    const PointXYZI w = toWorld(s.scan.pose, pts[i]);
    if (s.ground[i]) {
      r.labels[orig] = kGround;
      r.static_full.push_back(w);
    } else if (moving[i]) {
      r.labels[orig] = kMoving;
      r.moving.push_back(w);
      ++st.moving;
    } else {
      r.labels[orig] = kStatic;
      r.static_full.push_back(w);
      ++st.static_points;
      if (!duplicate[i]) {
        r.static_compact.push_back(w);
        inserted.emplace_back(w.x, w.y, w.z);
      }
    }
  }
  dup_.insert(inserted, k);
  // This scan's moving points, dilated by one cell, for the next scan's hysteresis.
  prev_moving_cells_.clear();
  if (p_.object.enabled && p_.object.persist_radius > 0) {
    std::unordered_set<uint64_t> cells;
    for (const auto& w : r.moving) cells.insert(persistCell(w.xyz().cast<double>()));
    for (const uint64_t c : cells)
      for (int dx = -1; dx <= 1; ++dx)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dz = -1; dz <= 1; ++dz) prev_moving_cells_.insert(cellKeyShift(c, dx, dy, dz));
  }
  st.ms.total = msSince(t_start) + st.ms.index + st.ms.ground;
  r.stats = st;
  ++decided_;
  sink_(std::move(r));
}

}  // namespace cleanmap
