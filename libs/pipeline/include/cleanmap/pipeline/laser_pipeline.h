// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2: the laser pipeline over a stream of posed scans, with a delay of K scans and memory
// bounded by the window (2K + 1 scans), not by the sequence.
#pragma once
#include <atomic>
#include <deque>
#include <exception>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include "cleanmap/core/cell_map.h"
#include "cleanmap/core/duplicate_filter.h"
#include "cleanmap/core/frame.h"
#include "cleanmap/core/free_space.h"
#include "cleanmap/core/grazing.h"
#include "cleanmap/core/moving_test.h"
#include "cleanmap/core/params.h"
#include "cleanmap/core/scan_result.h"

namespace cleanmap {
namespace reg {
class Odometry;
}

class LaserPipeline {
 public:
  using Sink = std::function<void(ScanResult&&)>;
  /// Throws cleanmap::Error naming "parameters" if `params` fail validate().
  LaserPipeline(const PipelineParams& params, Sink sink);
  ~LaserPipeline();

  /// Adds the next scan. Its pose is the given one, or GICP's (DESIGN §2.1, PipelineParams::poses).
  /// Scans are decided K scans later and handed to the sink ceil(K / 2) decided scans after that
  /// (doc/OBJECTS.md rule 4 backwards; at once with the object rules or persistence off), or at
  /// finish().
  void push(Frame&& frame);
  /// Decides the remaining scans (windows shrink at the end).
  void finish();

  std::size_t decided() const { return decided_; }
  /// DESIGN §2b: the window's K, ds.window_k or, where that is auto, resolved from the scan rate
  /// once kRateScans scans (or all, at finish()) have been pushed; 0 until then.
  std::size_t windowK() const { return k_; }
  /// The scan rate an auto K was resolved from (Hz; 0: set K, not resolved yet, or no timestamps).
  double scanRateHz() const { return rate_hz_; }
  /// The window's stride (ds.window_stride, or auto from K); 1 until K is resolved.
  std::size_t windowStride() const { return stride_; }
  /// Scans pushed but not yet handed to the sink: not decided (at most K until finish(), K + 1
  /// registering ahead), or decided and held (ceil(K / 2) + 2; a run's first ones until twice
  /// that many are decided, doc/OBJECTS.md rule 4 backwards).
  std::size_t pending() const;
  /// A deep copy of the whole state (window, duplicate history, odometry map) handing its
  /// results to `sink`: fed the same scans, it decides them exactly as this pipeline would.
  std::unique_ptr<LaserPipeline> clone(Sink sink) const;
  const PipelineParams& params() const { return p_; }
  /// DESIGN §2e: the free space every scan decided so far has seen (null with static_map.clean
  /// off). Waits for the decided scans' insertions, which run beside the pipeline's work.
  const FreeSpaceMap* freeSpace() const {
    joinFreeSpace();
    return free_.get();
  }
  /// DESIGN §2e: the memory the free space held when its last finished insertion ended (bytes;
  /// 0 with static_map.clean off). It does not wait, so it may lag the scans decided by the
  /// insertions still queued; any thread may ask it while scans are pushed. It grows with the
  /// ground covered, not the scans (about 0.4-0.8 GiB per km of street, doc/BENCHMARK.md).
  std::size_t freeSpaceBytes() const { return free_bytes_.load(std::memory_order_relaxed); }
  /// DESIGN §2f: only the scans with an index in [first, last] add to the free space: a chunk
  /// of a long drive inserts the scans it owns, not its overlap with the chunks beside it, so the
  /// chunks' accumulators merge (FreeSpaceMap::merge) into the whole run's.
  void setMapScans(long first, long last) {
    map_first_ = first;
    map_last_ = last;
  }
  /// Hand each scan's points to the sink too (ScanResult::scan), for outputs made per scan.
  void keepScans(bool on) { keep_scans_ = on; }
  /// DESIGN §3: the camera of the frames' images (FrameSource::camera()). With a camera and
  /// params().image.enabled, every frame with an image has its moving candidates checked in the
  /// images of its window; frames without one keep the laser labels. It applies to the frames
  /// pushed after it (a rawlog's camera is known from its first image).
  void setCamera(std::optional<PinholeCamera> camera) { camera_ = std::move(camera); }
  const std::optional<PinholeCamera>& camera() const { return camera_; }
  /// Hand each scan's camera image with its points drawn over it to the sink (ScanResult::overlay).
  void saveOverlays(bool on) { overlays_ = on; }
  /// Issue #16: with GICP poses and threads > 1, register each pushed scan on a thread of its own
  /// while push() decides the scans before it (the results are the same; a scan is then decided
  /// one push later, and a registration error surfaces at the next push() or finish()). It may be
  /// turned on or off between pushes.
  void registerAhead(bool on) { register_ahead_ = on; }

 private:
  struct Prepared;  // a buffered scan: beams, crop and ground masks
  struct Work;      // the scan being decided: world points, candidates, tests, moving mask
  // A pushed frame, registered (or to be), with what push() saw with it.
  struct Registered {
    Frame frame;
    long seq = 0;  // its place in the pushed sequence, from 0
    std::optional<PinholeCamera> camera;
    PoseInfo pose_info;
    double ms = 0;  // registration wall time
    std::exception_ptr error;
    double deskew_shift = -1;  // DESIGN §2.0: the largest shift of its de-skew; -1: none
  };
  struct RegQueue;  // one registration at a time on a thread of its own (registerAhead)
  std::unique_ptr<Prepared> prepare(Registered&& r, bool registered_beside);
  uint8_t edgeBits(const Prepared& s, uint32_t i, const WindowScan& own) const;
  double groundBelowSensor(Prepared& s, const std::vector<PointXYZI>& levelled) const;
  PoseSource resolveSource(const Frame& f);
  void registerScan(Registered& r);
  PoseInfo registerFrame(Frame& f);
  void applyDrops(long seq);
  void decideReady(std::size_t future);
  void releasePoints();
  void decide(std::size_t pos);

  // The stages of decide(), in order.
  // from > 0: only the scans at least `from` after pos; before > 0: only those at most `before`
  // before it (rule 4 under static_fraction, doc/OBJECTS.md).
  std::vector<WindowScan> windowAround(std::size_t pos, std::size_t from = 0,
                                       std::size_t before = 0) const;
  // The window scan of buf_[j] as the scan at `pos` compares with it; nullopt if it is not one.
  std::optional<WindowScan> windowScan(std::size_t pos, std::size_t j) const;
  // DESIGN §3 "Camera poses": each buffered scan's pose as the scan at `pos` sees it, through the
  // corrected relative poses between neighbours; nullopt where no correction lies between them.
  std::vector<std::optional<Eigen::Isometry3d>> posesAround(std::size_t pos) const;
  void findDuplicates(Prepared& s, Work& w) const;
  void sampleLeaves(Prepared& s, Work& w) const;
  void classify(const std::vector<WindowScan>& window, Prepared& s, Work& w) const;
  void decideLeaves(const Prepared& s, Work& w) const;
  void dropSelfReturns(const std::vector<WindowScan>& window, Prepared& s, Work& w) const;
  void objectConsensus(std::size_t pos, Prepared& s, Work& w) const;
  void validateImages(std::size_t pos, Prepared& s, Work& w) const;
  void linkToPrevious(const Prepared& prev, Prepared& s, const PinholeCamera& camera) const;
  ScanResult collect(Prepared& s, const Work& w) const;
  static std::vector<uint8_t> overlayKinds(const Prepared& s, const Work& w);
  void moverFeet(Prepared& s, Work& w) const;
  void moverRoofs(Prepared& s, Work& w) const;
  void remember(const ScanResult& r, long index, const Prepared& s, const Work& w);
  void startEpoch(long index);

  void resolveWindow();  // DESIGN §2b: k_ from the pushed scans' timestamps (auto K)
  bool inWindow(std::size_t j, std::size_t pos) const {
    const std::size_t d = j < pos ? pos - j : j - pos;
    return d > 0 && d <= k_ && d % stride_ == 0;
  }

  PipelineParams p_;
  Sink sink_;
  std::size_t k_ = 0;           // the window's K; 0 until resolved (resolveWindow)
  std::size_t stride_ = 1;      // the window's stride (ds.window_stride), with k_
  double rate_hz_ = 0;          // the scan rate it was resolved from
  std::vector<double> stamps_;  // the first pushed scans' timestamps, until k_ is resolved
  MovingTest test_;
  GrazingStretches graze_;  // scratch of prepare(): the stretches its beam index keeps
  DuplicateFilter dup_;
  std::deque<std::unique_ptr<Prepared>> buf_;  // scans k-K .. k+K around the next to decide
  std::size_t next_ = 0;                       // position in buf_ of the next scan to decide
  std::size_t decided_ = 0;
  bool keep_scans_ = false;
  bool overlays_ = false;
  bool register_ahead_ = false;
  std::optional<PinholeCamera> camera_;  // DESIGN §3
  long prev_index_ = -1;
  long pushed_ = 0;  // frames pushed
  long epoch_ = -1;  // DESIGN §2f: the epoch of the last decided scan
  long map_first_ = std::numeric_limits<long>::min(), map_last_ = std::numeric_limits<long>::max();
  CellMap<uint8_t> prev_moving_cells_;  // last decided scan's moving cells, dilated
  // The last decided scan's objects moved whole (its sensor frame) and its world-to-sensor pose.
  std::vector<PointXYZI> prev_whole_;
  std::vector<uint8_t> prev_whole_measured_;  // per point of prev_whole_: rule 7's (carryBack)
  Eigen::Isometry3d prev_pose_inverse_ = Eigen::Isometry3d::Identity();
  // doc/OBJECTS.md rule 4 backwards: the last holdDepth() decided scans (a run's first ones
  // longer), held so that an object a later scan moved whole is carried back to them, then
  // handed on in scan order.
  struct Held;
  std::deque<Held> held_results_;
  void hold(ScanResult&& r, const Prepared& s, const Work& w);
  void carryBack();
  void turnInResult(Held& h, const std::vector<uint32_t>& turned);
  void handOn(std::size_t keep);  // hands on the oldest held results until `keep` remain
  std::size_t holdDepth() const { return (k_ + 1) / 2 + 2; }  // H + 2 (doc/OBJECTS.md rule 4)
  std::unique_ptr<Work> work_;
  std::unique_ptr<FreeSpaceMap> free_;  // DESIGN §2e, whole sequence
  // The decided scans' free-space insertions run in scan order on one thread of their own,
  // beside the pipeline's work (with threads > 1).
  struct FreeQueue;
  double insertFreeSpace(const Prepared& s, const Work& w);  // ms of insertions reported now
  void joinFreeSpace() const;  // waits for every queued insertion; rethrows an error
  std::unique_ptr<FreeQueue> free_queue_;
  std::atomic<std::size_t> free_bytes_{0};          // freeSpaceBytes(): stored after each insertion
  PoseSource source_;                               // resolved on the first scan
  std::unique_ptr<reg::Odometry> odo_;              // with gicp / refine
  std::optional<Eigen::Isometry3d> prev_odometry_;  // the last scan's input odometry ...
  Eigen::Isometry3d prev_pose_ = Eigen::Isometry3d::Identity();  // ... and its estimated pose
  // A decided scan's movers leave GICP's local map before the registration of the scan K + 2
  // pushes after it (applyDrops): (seq, scan index, moving mask), in seq order.
  struct Drop {
    long seq;
    int64_t index;
    std::vector<uint8_t> moving;
  };
  std::deque<Drop> drops_;
  std::unique_ptr<RegQueue> reg_queue_;  // registerAhead: the frame registering now
  std::optional<Registered> held_;       // a clone's copy of its original's registered frame

  // DESIGN §2.0: the de-skew. A pushed scan's point times (given, or from its azimuths, or none);
  // a registered scan's points moved by the motion from the previous scan's pose to its own
  // (the first scan's: to the second's, so it waits for it); then prepared and decided.
  void sweepTimes(Frame& f);
  void admit(Registered&& r, bool registered_beside);
  void takeIn(Registered&& r, bool registered_beside);
  std::vector<double> period_stamps_;  // the first kRateScans timestamps: the sweep's period
  std::optional<std::pair<double, Eigen::Isometry3d>> deskew_prev_;  // last admitted (time, pose)
  std::optional<Registered> deskew_first_;  // the first timed scan, until the second's pose
  bool deskew_first_beside_ = false;
};

}  // namespace cleanmap
