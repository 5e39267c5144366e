// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2e: the long-horizon free-space accumulator that cleans the map. Every beam of every scan
// marks the voxels it passed through as seen empty by that scan, stopping a margin short of its
// return (the beam model's noise, DESIGN §2b) and skipping the voxels that scan itself hits (the
// scan-conflict rule, doc/SCAN_CONFLICT.md). Per voxel it keeps how many scans saw it empty and
// the first and last of them, and the runs of empty scans before its first return, since its last
// and whether one lay between two returns: sums, minima, maxima and runs joined in scan order, so
// the accumulators of a sequence's chunks (disjoint ranges of scans) merge exactly (merge()
// commutes) and memory grows with the volume the beams swept (the area mapped), not with the
// number of scans.
#pragma once
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include "cleanmap/core/cell_map.h"
#include "cleanmap/core/grazing.h"
#include "cleanmap/core/params.h"
#include "cleanmap/core/types.h"

namespace cleanmap {

/// Per voxel: scans that saw it empty, the first and the last of them (-1: none).
struct FreeEvidence {
  int count = 0;
  int hits = 0;  ///< scans that returned from the voxel
  int64_t first = -1, last = -1;
  int64_t last_hit = -1;  ///< the last scan that returned from it
  int lead = 0;           ///< scans that saw it empty before its first return (saturating at 255)
  /// A run of at least between_scans scans saw it empty between two of its returns.
  bool emptied_between = false;
};

inline bool operator==(const FreeEvidence& a, const FreeEvidence& b) {
  return a.count == b.count && a.hits == b.hits && a.first == b.first && a.last == b.last &&
         a.last_hit == b.last_hit && a.lead == b.lead && a.emptied_between == b.emptied_between;
}

/// How the policy decides a map point (non-ground) of scan `scan` from its voxel's evidence
/// (DESIGN §2e, "Decision"): kept, removed, or removed only by the arrival rule, which stands
/// unless the voxel under it says otherwise (arrivalStands).
enum class PolicyVerdict { kKept, kRemoved, kIfArrived };
PolicyVerdict policyVerdict(const FreeEvidence& e, int64_t scan, const MapParams& p);

/// policyVerdict of one voxel alone, an arrival taken as it stands (FreeSpaceMap::removed asks
/// the voxel under it too).
inline bool removedByPolicy(const FreeEvidence& e, int64_t scan, const MapParams& p) {
  return policyVerdict(e, scan, p) != PolicyVerdict::kKept;
}

/// The arrival rule's second look (DESIGN §2e, "Decision"): given the evidence of the voxel right
/// under the arriving one, whether something came there. Not where that voxel was returned from
/// with a lead under arrived_scans: a surface stood under it from its first return on, and the
/// voxel over it is that surface's top, seen through at a grazing angle from afar before the
/// rings came close enough to meet it.
inline bool arrivalStands(const FreeEvidence& below, const MapParams& p) {
  return !(below.hits > 0 && below.lead < p.arrived_scans);
}

/// DESIGN §2e: the azimuth bin of the free-space walk's levels for one scan (sensor frame): the
/// configured `spacing` (static_map.beam_spacing), or wider where the lidar's returns are
/// sparser in azimuth than that, so that every bin holds a beam (the levels' spacing assumes it).
/// Measured per band of elevation as the share of bins holding a return among the bins in gaps
/// of at most 16 between two that do; `occupancy`, if given, receives that share.
double freeSpaceAzimuthBin(const std::vector<PointXYZI>& points, double spacing,
                           double* occupancy = nullptr);
/// The same with the points' azimuths given (fast::atan2(y, x) per point).
double freeSpaceAzimuthBin(const std::vector<PointXYZI>& points, const std::vector<float>& azimuth,
                           double spacing, double* occupancy = nullptr);

/// A scan's GrazingStretches::from() / to() (and side(), optional), given to
/// FreeSpaceMap::insertScan.
struct GrazingSpans {
  const std::vector<float>* from = nullptr;
  const std::vector<float>* to = nullptr;
  const std::vector<float>* side = nullptr;
};

class FreeSpaceMap {
 public:
  explicit FreeSpaceMap(const MapParams& p);
  ~FreeSpaceMap();
  FreeSpaceMap(const FreeSpaceMap& o);
  FreeSpaceMap& operator=(const FreeSpaceMap&) = delete;

  /// Adds one scan: `points` in the sensor frame (every valid return is a beam), `pose` sensor to
  /// world, `scan` its index in the sequence (each once; in increasing order, or the runs of empty
  /// scans mean nothing). `moving` (optional, per point): the returns decided moving, around which
  /// hit_inflate does not apply (a slow mover's own neighbourhood is what it leaves empty next).
  /// `grazing` (optional): the scan's GrazingStretches::from() / to() / side(), computed with this
  /// map's flat_slope, margin, graze_reach, hit_inflate, the pose's rotation and the scan's
  /// freeSpaceAzimuthBin (the pipeline's, once per scan); otherwise the map computes them. A
  /// moving return's beam keeps its side stretch out (hit_inflate does not apply there either).
  using Stretches = GrazingSpans;
  /// Throws std::out_of_range for a scan index outside [0, kMaxScan] (the voxels keep 24 bits).
  void insertScan(const std::vector<PointXYZI>& points, const Eigen::Isometry3d& pose, int64_t scan,
                  const std::vector<uint8_t>* moving = nullptr, Stretches grazing = {});
  /// The largest scan index a map counts: 16,777,214 (19 days of a 10 Hz lidar in one run).
  static constexpr int64_t kMaxScan = (int64_t(1) << 24) - 2;
  /// The evidence of the voxel holding world point p.
  FreeEvidence evidence(const Eigen::Vector3f& p) const;
  /// Whether the policy `mp` removes world point p (non-ground) of scan `scan`: policyVerdict,
  /// and where only the arrival rule removes it, arrivalStands on the voxel under p's.
  bool removed(const Eigen::Vector3f& p, int64_t scan, const MapParams& mp) const;
  /// evidence() for many points in a row (below).
  class Lookup;
  /// Adds another accumulator of the same parameters (another chunk of the sequence, whose scans
  /// all come before or all after this one's); the result does not depend on the order of
  /// merging.
  void merge(const FreeSpaceMap& o);

  std::size_t blocks() const { return blocks_.size(); }
  std::size_t bytes() const;                              ///< memory held by the voxels
  std::size_t subBlocks() const { return subs_.size(); }  ///< 2 x 2 x 2 voxel groups written
  std::size_t voxelsMarked() const { return marked_; }    ///< voxel visits that counted, so far
  /// The narrowest and widest azimuth bin the scans so far were walked with
  /// (freeSpaceAzimuthBin); 0 before any scan, or with beam_spacing 0.
  double azimuthBinMin() const { return bin_max_ > 0 ? bin_min_ : 0.0; }
  double azimuthBinMax() const { return bin_max_; }
  const MapParams& params() const { return p_; }

 private:
  struct Voxel;
  struct SubBlock;
  struct Block;
  struct Marks;

 public:
  /// evidence() for many points in a row, remembering the last block: consecutive points of a
  /// scan mostly share one, and its lookup is then skipped (the same answers).
  class Lookup {
   public:
    explicit Lookup(const FreeSpaceMap& m) : m_(m) {}
    FreeEvidence operator()(const Eigen::Vector3f& p);
    /// FreeSpaceMap::removed() for many points in a row.
    bool removed(const Eigen::Vector3f& p, int64_t scan, const MapParams& mp);

   private:
    FreeEvidence at(int64_t x, int64_t y, int64_t z);  // the voxel of cell indices x, y, z
    const FreeSpaceMap& m_;
    uint64_t key_ = ~uint64_t(0);
    const Block* block_ = nullptr;
  };

 private:
  static constexpr int kSubVoxels = 8, kSubBlocks = 64;  // 2 x 2 x 2 voxels, 64 per block
  // Objects in chunks of 2 MiB that never move, numbered in the order added. The chunks are pages
  // of their own, outside malloc's arenas: the map's memory lives the whole run, and carved from
  // the holes a scan's freed buffers leave it would pin them, the arenas growing with the drive
  // (doc/BENCHMARK.md, "The free space in pages of its own"). Untouched pages cost no memory.
  template <class T>
  class Chunks {
   public:
    static constexpr std::size_t kBytes = std::size_t(2) << 20, N = kBytes / sizeof(T);
    Chunks() = default;
    Chunks(const Chunks&) = delete;
    Chunks& operator=(const Chunks&) = delete;
    ~Chunks();
    T& add();  // a value-initialized one
    T& operator[](std::size_t i) { return chunks_[i / N][i % N]; }
    const T& operator[](std::size_t i) const { return chunks_[i / N][i % N]; }
    std::size_t size() const { return n_; }
    void clear() { n_ = 0; }  // the chunks are kept for the next ones
    std::size_t bytes() const { return most_ * sizeof(T); }  // of the pages written so far
    void copyFrom(const Chunks& o);  // the same objects under the same numbers

   private:
    std::vector<T*> chunks_;
    std::size_t n_ = 0, most_ = 0;
  };
  // A new (value-initialized) object of `c` and its number, 1 + its place: the blocks and
  // sub-blocks are numbered in 32 bits (0: none); beyond, a one-line error naming `what`.
  template <class T>
  static uint32_t addNumbered(Chunks<T>& c, const char* what);
  const Voxel* find(const Block& b, int li) const;  // null: its sub-block is not written yet
  Voxel& voxel(Block& b, int li);                   // allocates its sub-block if needed
  Marks& marksOf(uint64_t key);  // the block's marks for the scan being inserted (made if new)
  const Block* findBlock(uint64_t key) const;
  Block& blockOf(uint64_t key);  // made if new
  void markNear(const std::array<int64_t, 6>& box);
  MapParams p_;
  double inv_;
  CellMap<uint32_t> blocks_;        // block key -> 1 + its number in pool_
  std::vector<float> azimuth_;      // the scan being inserted: each return's fast::atan2(y, x)
  std::vector<uint64_t> bin_bits_;  // and its azimuth bins holding a return, per elevation band
  // The marks of the blocks the scan being inserted visits, in the order visited (their voxels
  // are updated last); chunks kept from scan to scan.
  Chunks<Marks> marks_;
  // The scan's recent blocks, direct-mapped by key (cleared per scan): neighbouring beams and
  // returns meet the same blocks, so most lookups end here in L1 (issue #16).
  struct Recent {
    uint64_t key = ~uint64_t(0);
    Marks* marks = nullptr;
  };
  std::array<Recent, 1024> recent_{};
  Marks& recentMarks(uint64_t key);
  std::size_t marked_ = 0;
  GrazingStretches grazing_;  // grazing beams, per scan (DESIGN §2e)
  double bin_min_ = std::numeric_limits<double>::infinity(), bin_max_ = 0;
  Chunks<Block> pool_;     // the blocks (blocks_ numbers them)
  Chunks<SubBlock> subs_;  // the sub-blocks (blocks number them)
};

}  // namespace cleanmap
