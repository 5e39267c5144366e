// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/free_space.h"

#include <sys/mman.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <new>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "cleanmap/core/cell_key.h"
#include "cleanmap/core/fast_math.h"
#include "cleanmap/core/sanitized.h"

namespace cleanmap {
namespace {
constexpr int kBits = 3;  // blocks of 8 x 8 x 8 voxels
constexpr int kSide = 1 << kBits;
constexpr int kVoxels = kSide * kSide * kSide;
static_assert(kBits == 3,
              "Block::subOf / innerOf split 8 x 8 x 8 blocks into 2 x 2 x 2 sub-blocks");

inline int localIndex(int64_t x, int64_t y, int64_t z) {
  return static_cast<int>(((x & (kSide - 1)) << (2 * kBits)) | ((y & (kSide - 1)) << kBits) |
                          (z & (kSide - 1)));
}
inline uint64_t blockKey(int64_t x, int64_t y, int64_t z) {
  // Arithmetic shifts floor negative voxel indices (C++20 defines it; GCC and Clang always did).
  return cellKey(x >> kBits, y >> kBits, z >> kBits);
}
}  // namespace

// A block holds only its voxels' counters, in sub-blocks of 2 x 2 x 2 allocated on the first
// write and numbered in 32 bits: about a third of a block's voxels are ever marked, in clumps
// along the surfaces and beams, so most sub-blocks are never needed; the scan's bits are kept
// apart (Marks). The free space is what grows with the ground covered: a quarter less than with
// 4 x 4 x 4 sub-blocks, pointers and the bits in the block, the same time (issue #16;
// doc/BENCHMARK.md "Sub-blocks of 2 x 2 x 2").
//
// A voxel is 16 bytes, four to a cache line and none across two (its sub-block is aligned): the
// counting pass below and the map's lookups miss the cache once per voxel, not up to twice, and
// the map, mostly voxels, holds a fifth less than with 32-bit scan indices (doc/BENCHMARK.md,
// "Memory over distance"). Scan indices are kept in 24 bits, 0 for none (the last ones plus one,
// the first as kMaxScan + 1 minus it, so that every update is a maximum), so a map counts up to
// kMaxScan scans (insertScan refuses more). The insertion runs about 9 % more instructions for
// the bit-fields (callgrind), the whole process the same time (doc/BENCHMARK.md).
struct FreeSpaceMap::Voxel {
  uint16_t count;  // scans that saw it empty (saturating)
  uint16_t hits;   // scans that returned from it (saturating)
  // Runs of empty scans (saturating at 255; scans come in order within an accumulator): those
  // before the first return, those since the last, and whether a run of at least between_scans
  // lay between two returns. Each shares a 32-bit word with a scan index.
  uint32_t first_c : 24;  // kMaxScan + 1 - the first scan that saw it empty (0: none): a maximum
  uint32_t lead : 8;
  uint32_t last1 : 24;  // 1 + the last scan that saw it empty
  uint32_t trail : 8;
  uint32_t last_hit1 : 24;  // 1 + the last scan that returned from it
  uint32_t emptied_between : 8;
  int32_t first() const {
    return first_c ? static_cast<int32_t>(kMaxScan + 1 - int64_t(first_c)) : -1;
  }
  int32_t last() const { return static_cast<int32_t>(last1) - 1; }
  int32_t lastHit() const { return static_cast<int32_t>(last_hit1) - 1; }
};

struct alignas(64) FreeSpaceMap::SubBlock {
  Voxel v[kSubVoxels];
};

// What the scan being inserted did to one block, a bit per voxel (a mask word is one x plane of
// 8 y x 8 z voxels). Kept apart from the blocks, in chunks reused scan after scan, in the order
// the scan visits its blocks: the map holds only the counters.
struct FreeSpaceMap::Marks {
  uint64_t hit[kVoxels / 64];   // voxels holding a return of that scan (not marked by it)
  uint64_t seen[kVoxels / 64];  // voxels that scan has already counted
  uint64_t near[kVoxels / 64];  // voxels within hit_inflate of a return of that scan
  Block* block;
  static void set(uint64_t* m, int i) { m[i >> 6] |= uint64_t(1) << (i & 63); }
};

struct FreeSpaceMap::Block {
  Marks* marks = nullptr;         // the scan being inserted has visited it (null between scans)
  uint32_t sub[kSubBlocks] = {};  // 1 + its number in the pool; 0: none of its voxels written
  // A voxel's local index (x << 6 | y << 3 | z) split into its sub-block and its place there.
  static int subOf(int li) { return ((li >> 7) << 4) | ((li >> 4 & 3) << 2) | (li >> 1 & 3); }
  static int innerOf(int li) { return ((li >> 6 & 1) << 2) | ((li >> 3 & 1) << 1) | (li & 1); }
};

namespace {
// Whether malloc backs its heap with transparent huge pages (glibc.malloc.hugetlb=1, which the
// apps set: apps/common/cli.h): the chunks then ask for them too, as they had from the heap.
[[maybe_unused]] bool hugePagesLikeMalloc() {
  static const bool on = [] {
    const char* t = std::getenv("GLIBC_TUNABLES");
    return t && std::strstr(t, "glibc.malloc.hugetlb=1") != nullptr;
  }();
  return on;
}

// `bytes` (a multiple of 2 MiB) of zeroed pages aligned to 2 MiB (where a huge page can back
// them), from the kernel.
void* mapPages(std::size_t bytes) {
#ifdef CLEANMAP_SANITIZED                   // on the heap, where the sanitizers watch every access
  void* p = std::aligned_alloc(64, bytes);  // SubBlock's alignment
  if (!p) throw std::bad_alloc();
  return std::memset(p, 0, bytes);
#else
  constexpr std::size_t kAlign = std::size_t(2) << 20;
  void* p =
      mmap(nullptr, bytes + kAlign, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) throw std::bad_alloc();
  const auto start = reinterpret_cast<std::uintptr_t>(p);
  const std::uintptr_t aligned = (start + kAlign - 1) & ~(kAlign - 1);
  if (aligned > start) munmap(p, aligned - start);
  if (const std::size_t tail = start + kAlign - aligned)
    munmap(reinterpret_cast<void*>(aligned + bytes), tail);
  void* q = reinterpret_cast<void*>(aligned);
#ifdef MADV_HUGEPAGE
  if (hugePagesLikeMalloc()) madvise(q, bytes, MADV_HUGEPAGE);
#endif
  return q;
#endif
}

void unmapPages(void* p, std::size_t bytes) {
#ifdef CLEANMAP_SANITIZED
  (void)bytes;
  std::free(p);
#else
  munmap(p, bytes);
#endif
}
}  // namespace

template <class T>
FreeSpaceMap::Chunks<T>::~Chunks() {
  static_assert(std::is_trivially_destructible_v<T> && N > 0);
  for (T* c : chunks_) unmapPages(c, kBytes);
}

template <class T>
T& FreeSpaceMap::Chunks<T>::add() {
  if (n_ == chunks_.size() * N) {
    chunks_.reserve(chunks_.size() + 1);  // no leak if it throws
    chunks_.push_back(static_cast<T*>(mapPages(kBytes)));
  }
  most_ = std::max(most_, n_ + 1);
  return *new (&(*this)[n_++]) T();
}

template <class T>
void FreeSpaceMap::Chunks<T>::copyFrom(const Chunks& o) {
  for (T* c : chunks_) unmapPages(c, kBytes);
  chunks_.clear();
  n_ = most_ = 0;
  chunks_.reserve(o.chunks_.size());
  for (std::size_t c = 0; c * N < o.n_; ++c) {
    chunks_.push_back(static_cast<T*>(mapPages(kBytes)));
    const std::size_t k = std::min(N, o.n_ - c * N);
    std::uninitialized_copy(o.chunks_[c], o.chunks_[c] + k, chunks_.back());
  }
  n_ = most_ = o.n_;
}

template <class T>
uint32_t FreeSpaceMap::addNumbered(Chunks<T>& c, const char* what) {
  if (c.size() == std::numeric_limits<uint32_t>::max())  // 512 GiB of sub-blocks, 1 TiB of blocks
    throw std::length_error(std::string("FreeSpaceMap: more ") + what +
                            " than 32-bit numbers: split the drive");
  c.add();
  return static_cast<uint32_t>(c.size());
}

inline const FreeSpaceMap::Voxel* FreeSpaceMap::find(const Block& b, int li) const {
  const uint32_t s = b.sub[Block::subOf(li)];
  return s ? &subs_[s - 1].v[Block::innerOf(li)] : nullptr;
}

// Inline (private, this file only): the counting pass calls it once per voxel, and an exported
// function would be called through the PLT.
inline FreeSpaceMap::Voxel& FreeSpaceMap::voxel(Block& b, int li) {
  uint32_t& s = b.sub[Block::subOf(li)];
  if (!s) s = addNumbered(subs_, "sub-blocks");
  return subs_[s - 1].v[Block::innerOf(li)];
}

PolicyVerdict policyVerdict(const FreeEvidence& e, int64_t scan, const MapParams& p) {
  if (!p.clean || e.count < p.min_free_scans) return PolicyVerdict::kKept;
  // Seen empty by fewer scans than return from it (times free_ratio): see-through (foliage,
  // fences, windows) or grazing beams past a surface, not a place something left.
  // Unless only empty for vacated_scans after its last return: it stood there, then left (every
  // scan after the last hit saw it empty, by definition; see-through space is hit again).
  // Or a run of between_scans scans saw it empty between two of its returns: a queue's cars, a
  // body that left and another that came. Or, under `transient`, arrived_scans saw it empty
  // before its first return: something came and stood (a static surface is not seen through
  // before it is seen, but for its top: arrivalStands; `moving` keeps what came and stayed;
  // DESIGN §2e).
  const bool left = (p.vacated_scans > 0 && e.last - e.last_hit >= p.vacated_scans) ||
                    (p.between_scans > 0 && e.emptied_between);
  const bool arrived = p.policy == MapPolicy::kTransient && p.arrived_scans > 0 && e.hits > 0 &&
                       e.lead >= p.arrived_scans;
  const bool seen_through = double(e.count) < p.free_ratio * double(e.hits);
  if (!left && !arrived && seen_through) return PolicyVerdict::kKept;
  if (p.policy == MapPolicy::kTransient)
    return !left && seen_through ? PolicyVerdict::kIfArrived : PolicyVerdict::kRemoved;
  // kMoving: empty before and after (it came and went)
  return e.first < scan && e.last > scan ? PolicyVerdict::kRemoved : PolicyVerdict::kKept;
}

namespace {
// freeSpaceAzimuthBin for a scan whose azimuths (fast::atan2, as the walk bins them) are given:
// insertScan computes them once for both.
double azimuthBin(const std::vector<PointXYZI>& points, const std::vector<float>& azimuth,
                  double spacing, double* occupancy, std::vector<uint64_t>& bits) {
  if (occupancy) *occupancy = 1.0;
  if (!(spacing > 0)) return spacing;
  // Bands of sin(elevation) 0.02 wide (about 1.15 degrees: a ring, or a few of a dense lidar);
  // bins of `spacing` around each.
  constexpr int kBands = 100, kMaxGap = 16;
  const int nbins = static_cast<int>(std::ceil(2.0 * M_PI / spacing));
  const int words = (nbins + 63) / 64;
  bits.assign(static_cast<std::size_t>(kBands) * words, 0);
  const float inv = static_cast<float>(1.0 / spacing);
  for (std::size_t n = 0; n < points.size(); ++n) {
    const auto& p = points[n];
    const float r2 = p.x * p.x + p.y * p.y + p.z * p.z;
    if (!(r2 > 0)) continue;
    const int band =
        std::clamp(static_cast<int>((p.z / std::sqrt(r2) + 1.f) * (0.5f * kBands)), 0, kBands - 1);
    const int bin = std::clamp(static_cast<int>((azimuth[n] + float(M_PI)) * inv), 0, nbins - 1);
    bits[std::size_t(band) * words + (bin >> 6)] |= uint64_t(1) << (bin & 63);
  }
  // Per band: the bins holding a return among those in gaps of at most kMaxGap empty bins between
  // two that do (a sector with no returns, the sky, a blocked view, does not count).
  std::size_t held = 0, reach = 0;
  for (int b = 0; b < kBands; ++b) {
    const uint64_t* w = &bits[std::size_t(b) * words];
    std::size_t n = 0, gaps = 0;
    int first = -1, prev = -1;
    for (int i = 0; i < words; ++i)
      for (uint64_t m = w[i]; m; m &= m - 1) {
        const int bin = i * 64 + __builtin_ctzll(m);
        if (prev >= 0 && bin - prev - 1 <= kMaxGap) gaps += bin - prev - 1;
        if (first < 0) first = bin;
        prev = bin;
        ++n;
      }
    if (n < 64) continue;  // a few returns (far objects, the sky's edge) say nothing of the step
    if (const int wrap = first + nbins - prev - 1; wrap <= kMaxGap) gaps += wrap;
    held += n;
    reach += n + gaps;
  }
  if (reach == 0) return spacing;
  const double q = double(held) / double(reach);
  if (occupancy) *occupancy = q;
  // Dropouts and absorbing surfaces leave a dense lidar's bins 96-99 % filled (KITTI); a lidar
  // coarser than the bins fills about spacing / step of them (a VLP-16 at 0.2 degrees 86 %).
  // Its bins are then its step, 5 % wider so that each holds a beam.
  return q >= 0.9 ? spacing : spacing / q * 1.05;
}
}  // namespace

double freeSpaceAzimuthBin(const std::vector<PointXYZI>& points, double spacing,
                           double* occupancy) {
  std::vector<float> azimuth(points.size());
  for (std::size_t n = 0; n < points.size(); ++n)
    azimuth[n] = fast::atan2(points[n].y, points[n].x);
  return freeSpaceAzimuthBin(points, azimuth, spacing, occupancy);
}

double freeSpaceAzimuthBin(const std::vector<PointXYZI>& points, const std::vector<float>& azimuth,
                           double spacing, double* occupancy) {
  std::vector<uint64_t> bits;
  return azimuthBin(points, azimuth, spacing, occupancy, bits);
}

FreeSpaceMap::FreeSpaceMap(const MapParams& p) : p_(p), inv_(1.0 / p.voxel) {
  static_assert(sizeof(Voxel) == 16, "four voxels to a cache line");
}
FreeSpaceMap::~FreeSpaceMap() = default;
FreeSpaceMap::FreeSpaceMap(const FreeSpaceMap& o)
    : p_(o.p_), inv_(o.inv_), marked_(o.marked_), bin_min_(o.bin_min_), bin_max_(o.bin_max_) {
  blocks_ = o.blocks_;  // the same numbers: the pools are copied
  pool_.copyFrom(o.pool_);
  subs_.copyFrom(o.subs_);
}

FreeSpaceMap::Marks& FreeSpaceMap::marksOf(uint64_t key) {
  Block& b = blockOf(key);
  if (!b.marks) {
    Marks& m = marks_.add();
    m.block = &b;
    b.marks = &m;
  }
  return *b.marks;
}

FreeSpaceMap::Marks& FreeSpaceMap::recentMarks(uint64_t key) {
  Recent& r = recent_[(key * 0x9E3779B97F4A7C15ull) >> 54];
  if (r.key != key) r = {key, &marksOf(key)};  // neither marks nor blocks move within a scan
  return *r.marks;
}

const FreeSpaceMap::Block* FreeSpaceMap::findBlock(uint64_t key) const {
  const uint32_t* n = blocks_.find(key);
  return n ? &pool_[*n - 1] : nullptr;
}

FreeSpaceMap::Block& FreeSpaceMap::blockOf(uint64_t key) {
  if (const uint32_t* n = blocks_.find(key)) return pool_[*n - 1];
  const uint32_t n = addNumbered(pool_, "blocks");  // a failed add leaves no number in blocks_
  blocks_[key] = n;
  return pool_[n - 1];
}

std::size_t FreeSpaceMap::bytes() const {
  return pool_.bytes() + subs_.bytes() + marks_.bytes() +
         blocks_.capacity() * (sizeof(uint64_t) + sizeof(uint32_t));
}

// Sets the near bits of a voxel box (inclusive x0 x1 y0 y1 z0 z1) block by block: a mask word
// of a block is one x plane of 8 y x 8 z voxels, so the box's share of a plane is one mask.
void FreeSpaceMap::markNear(const std::array<int64_t, 6>& box) {
  // A block's first voxel is blk * kSide: a left shift of a negative index is undefined.
  constexpr int64_t kLast = kSide - 1;
  for (int64_t bx = box[0] >> kBits; bx <= box[1] >> kBits; ++bx)
    for (int64_t by = box[2] >> kBits; by <= box[3] >> kBits; ++by)
      for (int64_t bz = box[4] >> kBits; bz <= box[5] >> kBits; ++bz) {
        Marks& b = recentMarks(cellKey(bx, by, bz));
        const auto lo = [](int64_t v, int64_t blk) { return std::max(v, blk * kSide) & kLast; };
        const auto hi = [](int64_t v, int64_t blk) {
          return std::min(v, blk * kSide + kLast) & kLast;
        };
        const int64_t xa = lo(box[0], bx), xb = hi(box[1], bx);
        const int64_t ya = lo(box[2], by), yb = hi(box[3], by);
        const int64_t za = lo(box[4], bz), zb = hi(box[5], bz);
        const uint64_t zmask = ((uint64_t(1) << (zb - za + 1)) - 1) << za;
        uint64_t m = 0;
        for (int64_t y = ya; y <= yb; ++y) m |= zmask << (y << kBits);
        for (int64_t x = xa; x <= xb; ++x) b.near[x] |= m;
      }
}

void FreeSpaceMap::insertScan(const std::vector<PointXYZI>& points, const Eigen::Isometry3d& pose,
                              int64_t scan, const std::vector<uint8_t>* moving, Stretches grazing) {
  if (moving && moving->size() != points.size())
    throw std::invalid_argument("FreeSpaceMap::insertScan: one moving flag per point needed");
  if (scan < 0 || scan > kMaxScan)
    throw std::out_of_range("FreeSpaceMap::insertScan: scan index " + std::to_string(scan) +
                            " outside 0.." + std::to_string(kMaxScan) +
                            " (the free space counts scans in 24 bits): split the sequence");
  const Eigen::Vector3d o = pose.translation();
  recent_.fill(Recent{});  // a block's marks are made on its first lookup of this scan
  // The scan-conflict rule: the voxels this scan returns from are not seen empty by it.
  {
    uint64_t cached = ~uint64_t(0);
    Marks* b = nullptr;
    std::array<int64_t, 6> last_box{1, 0, 1, 0, 1, 0};  // empty
    for (std::size_t n = 0; n < points.size(); ++n) {
      const Eigen::Vector3d w = pose * points[n].xyz().cast<double>();
      const int64_t x = floorToCell(w.x(), inv_), y = floorToCell(w.y(), inv_),
                    z = floorToCell(w.z(), inv_);
      const uint64_t k = blockKey(x, y, z);
      if (k != cached) {
        b = &recentMarks(k);
        cached = k;
      }
      const int li = localIndex(x, y, z);
      Marks::set(b->near, li);
      Marks::set(b->hit, li);  // its counters are updated with the walk's, below
      if (p_.hit_inflate <= 0 || (moving && (*moving)[n])) continue;
      // The voxels within hit_inflate of the return (per axis) are not seen empty by this scan
      // either: a beam passing a surface's edge crosses the edge's voxel beside the return.
      const double h = p_.hit_inflate;
      const std::array<int64_t, 6> box{floorToCell(w.x() - h, inv_), floorToCell(w.x() + h, inv_),
                                       floorToCell(w.y() - h, inv_), floorToCell(w.y() + h, inv_),
                                       floorToCell(w.z() - h, inv_), floorToCell(w.z() + h, inv_)};
      if (box == last_box) continue;  // neighbours on a ring mostly share it
      last_box = box;
      markNear(box);
    }
  }
  // Each beam, voxel by voxel (Amanatides & Woo), to the margin before its return; a beam longer
  // than the map radius marks up to the radius (its return lies beyond). Near the sensor,
  // neighbouring beams of a ring cross the same voxels, so a beam starts where the beams of its
  // azimuth level alone would leave voxels unvisited: the beams of azimuth bin b (bins of
  // `spacing`) with 2^L dividing b are 2^L bins apart, which at range t is one voxel when
  // t = voxel / (2^L spacing); a beam of level L < kLevels starts at voxel / (2^(L+1) spacing),
  // those of the top level at min_range. That holds only if every bin holds a beam: `spacing` is
  // beam_spacing, or the lidar's own wider azimuth step (a VLP-16, an Ouster at 1024 columns),
  // measured in the scan (freeSpaceAzimuthBin).
  azimuth_.resize(points.size());
  if (p_.beam_spacing > 0 || p_.flat_slope > 0)
    for (std::size_t n = 0; n < points.size(); ++n)
      azimuth_[n] = fast::atan2(points[n].y, points[n].x);
  const double spacing = azimuthBin(points, azimuth_, p_.beam_spacing, nullptr, bin_bits_);
  if (spacing > 0) {
    bin_min_ = std::min(bin_min_, spacing);
    bin_max_ = std::max(bin_max_, spacing);
  }
  const double half_diag = 0.5 * std::sqrt(3.0) * p_.voxel;
  constexpr int kLevels = 5;
  double level_start[kLevels + 1];
  for (int L = 0; L <= kLevels; ++L)
    level_start[L] = L == kLevels || spacing <= 0
                         ? p_.min_range
                         : std::max(p_.min_range, p_.voxel / (std::ldexp(2.0, L) * spacing));
  const double inv_spacing = spacing > 0 ? 1.0 / spacing : 0.0;
  const Eigen::Matrix3d R = pose.linear();
  const bool given = grazing.from && grazing.to && grazing.from->size() == points.size() &&
                     grazing.to->size() == points.size();
  if (p_.flat_slope > 0 && !given)
    grazing_.compute(points, pose.linear().cast<float>(), azimuth_, p_.flat_slope, p_.margin,
                     p_.graze_reach, p_.grazing_sides ? spacing : 0.0, p_.hit_inflate);
  const std::vector<float>& skip_a = given ? *grazing.from : grazing_.from();
  const std::vector<float>& skip_b = given ? *grazing.to : grazing_.to();
  // Grazing sides (DESIGN §2e), where on and given for every point.
  const std::vector<float>* side = given ? grazing.side : &grazing_.side();
  if (p_.flat_slope <= 0 || !p_.grazing_sides || (side && side->size() != points.size()))
    side = nullptr;
  uint64_t cached = ~uint64_t(0);
  Marks* b = nullptr;
  for (std::size_t n = 0; n < points.size(); ++n) {
    const auto& p = points[n];
    const Eigen::Vector3d ps = p.xyz().cast<double>();
    const double r = ps.norm();
    if (!(r > 0)) continue;
    double t1 = r - p_.margin - half_diag;
    // hypot only where the horizontal range may pass the radius (issue #16: same test, same t1).
    if (ps.x() * ps.x() + ps.y() * ps.y() > p_.radius * p_.radius * (1 - 1e-9)) {
      const double rh = std::hypot(ps.x(), ps.y());
      if (rh > p_.radius) t1 = std::min(t1, r * p_.radius / rh);
    }
    int level = kLevels;
    if (inv_spacing > 0) {
      // The azimuth bin from fast::atan2 (error below 3e-7 rad, 1e-4 of a bin), libm's where
      // that lies within 2e-3 of a bin edge: the same bins (issue #16).
      const double ta = (double(azimuth_[n]) + M_PI) * inv_spacing;
      const auto ubin = static_cast<uint64_t>(fast::binOrExact(ta, 2e-3, [&] {
        return static_cast<int64_t>(std::floor((std::atan2(ps.y(), ps.x()) + M_PI) * inv_spacing));
      }));
      level = ubin == 0 ? kLevels : std::min(kLevels, __builtin_ctzll(ubin));
    }
    const double t0 = level_start[level];
    if (t1 <= t0) continue;
    // Grazing: the stretch of the beam (voxel units from t0) that marks nothing.
    double ua = std::numeric_limits<double>::infinity(), ub = -ua;
    if (p_.flat_slope > 0 && skip_b[n] > skip_a[n]) {
      ua = (skip_a[n] - t0) * inv_;
      ub = (skip_b[n] - t0) * inv_;
    }
    // Grazing sides (DESIGN §2e): from there to the beam's end, unless the return is moving.
    if (side && (*side)[n] < r && !(moving && (*moving)[n])) {
      ua = std::min(ua, (double((*side)[n]) - t0) * inv_);
      ub = std::numeric_limits<double>::infinity();
    }
    const Eigen::Vector3d d = R * (ps / r);
    const Eigen::Vector3d a = (o + t0 * d) * inv_;  // voxel units
    const double len = (t1 - t0) * inv_;
    int64_t v[3] = {floorToCell(a.x(), 1.0), floorToCell(a.y(), 1.0), floorToCell(a.z(), 1.0)};
    int step[3];
    double tmax[3], tdelta[3];
    for (int i = 0; i < 3; ++i) {
      if (d[i] > 0) {
        step[i] = 1;
        tdelta[i] = 1.0 / d[i];
        tmax[i] = (double(v[i]) + 1.0 - a[i]) * tdelta[i];
      } else if (d[i] < 0) {
        step[i] = -1;
        tdelta[i] = -1.0 / d[i];
        tmax[i] = (a[i] - double(v[i])) * tdelta[i];
      } else {
        step[i] = 0;
        tdelta[i] = tmax[i] = std::numeric_limits<double>::infinity();
      }
    }
    // The same walk with the axes unrolled into scalars (an indexed tmax[i] spills to memory);
    // ties go to the lower axis. The voxel is kept as its block and its place there: a block
    // is looked up only when the walk leaves it (every 8 steps along an axis, at most), and a
    // mask word of a block is one x plane, so the place gives the word and the bit directly.
    int64_t bx = v[0] >> kBits, by = v[1] >> kBits, bz = v[2] >> kBits;
    int lx = static_cast<int>(v[0] & (kSide - 1)), ly = static_cast<int>(v[1] & (kSide - 1)),
        lz = static_cast<int>(v[2] & (kSide - 1));
    const int sx = step[0], sy = step[1], sz = step[2];
    auto enter = [&] {
      const uint64_t k = cellKey(bx, by, bz);
      if (k != cached) {
        b = &recentMarks(k);
        cached = k;
      }
    };
    enter();
    double tx = tmax[0], ty = tmax[1], tz = tmax[2];
    // One step along an axis: its next crossing, its place, and its block when it leaves one;
    // false where the walk ends (the next block is then not entered).
    auto step_axis = [&](double& tq, double dq, int& lq, int64_t& bq, int sq, double& t) {
      t = tq;
      tq += dq;
      lq += sq;
      if (static_cast<unsigned>(lq) < unsigned(kSide)) return true;
      lq &= kSide - 1;
      bq += sq;
      if (t > len) return false;
      enter();
      return true;
    };
    for (double t = 0; t <= len;) {
      if (t < ua || t > ub) b->seen[lx] |= ~b->near[lx] & (uint64_t(1) << (ly << kBits | lz));
      bool more;
      if (tx < ty && tx < tz)
        more = step_axis(tx, tdelta[0], lx, bx, sx, t);
      else if (!(tx < ty) && ty < tz)
        more = step_axis(ty, tdelta[1], ly, by, sy, t);
      else
        more = step_axis(tz, tdelta[2], lz, bz, sz, t);
      if (!more) break;
    }
  }
  // The loops above only set bits (a few cache lines per block); the voxels this scan returned
  // from and those it saw empty (never the same: a return's voxel is near) are updated here,
  // block by block in memory order, the next block's voxels fetched while this one's are
  // written, instead of one cache miss per return and per step (issue #16).
  const auto s1 = static_cast<uint32_t>(scan + 1);  // as the voxels keep it
  const auto sc = static_cast<uint32_t>(kMaxScan + 1 - scan);
  auto prefetch = [this](const Marks& tm) {
    for (int w = 0; w < kVoxels / 64; ++w)
      for (uint64_t m = tm.hit[w] | tm.seen[w]; m; m &= m - 1) {
        const int li = w * 64 + __builtin_ctzll(m);
        if (const Voxel* x = find(*tm.block, li)) __builtin_prefetch(x, 1);
      }
  };
  const std::size_t nt = marks_.size();
  if (nt > 0) prefetch(marks_[0]);
  for (std::size_t i = 0; i < nt; ++i) {
    if (i + 2 < nt) __builtin_prefetch(marks_[i + 2].block->sub, 0);
    if (i + 1 < nt) prefetch(marks_[i + 1]);
    const Marks& tm = marks_[i];
    Block* tb = tm.block;
    for (int w = 0; w < kVoxels / 64; ++w) {
      for (uint64_t m = tm.hit[w]; m; m &= m - 1) {
        // Updated in registers, stored once: a bit-field's own read-modify-write would chain
        // each field's store into the next field's load.
        Voxel& slot = voxel(*tb, w * 64 + __builtin_ctzll(m));
        Voxel v = slot;
        if (v.hits > 0 && p_.between_scans > 0 && int(v.trail) >= p_.between_scans)
          v.emptied_between = 1;  // something stood here, left, and something came again
        v.trail = 0;
        if (v.hits < 0xFFFF) ++v.hits;
        if (s1 > v.last_hit1) v.last_hit1 = s1;
        slot = v;
      }
      for (uint64_t m = tm.seen[w]; m; m &= m - 1) {
        Voxel& slot = voxel(*tb, w * 64 + __builtin_ctzll(m));
        Voxel x = slot;
        if (x.count < 0xFFFF) ++x.count;
        if (x.trail < 0xFF) ++x.trail;
        if (x.hits == 0 && x.lead < 0xFF) ++x.lead;
        if (sc > x.first_c) x.first_c = sc;
        if (s1 > x.last1) x.last1 = s1;
        slot = x;
        ++marked_;
      }
    }
    tb->marks = nullptr;  // the next scan starts its own
  }
  marks_.clear();
}

namespace {
template <class Voxel>
FreeEvidence evidenceOf(const Voxel* v) {
  FreeEvidence e;
  if (!v) return e;
  e.count = static_cast<int>(v->count);
  e.hits = static_cast<int>(v->hits);
  e.emptied_between = v->emptied_between != 0;
  e.first = v->first();
  e.last = v->last();
  e.last_hit = v->lastHit();
  e.lead = static_cast<int>(v->lead);
  return e;
}
}  // namespace

FreeEvidence FreeSpaceMap::evidence(const Eigen::Vector3f& p) const {
  return Lookup(*this)(p);
}

bool FreeSpaceMap::removed(const Eigen::Vector3f& p, int64_t scan, const MapParams& mp) const {
  return Lookup(*this).removed(p, scan, mp);
}

bool FreeSpaceMap::Lookup::removed(const Eigen::Vector3f& p, int64_t scan, const MapParams& mp) {
  const double inv = m_.inv_;
  const int64_t x = floorToCell(double(p.x()), inv), y = floorToCell(double(p.y()), inv),
                z = floorToCell(double(p.z()), inv);
  const PolicyVerdict v = policyVerdict(at(x, y, z), scan, mp);
  if (v != PolicyVerdict::kIfArrived) return v == PolicyVerdict::kRemoved;
  return arrivalStands(at(x, y, z - 1), mp);  // the voxel right under p's
}

FreeEvidence FreeSpaceMap::Lookup::operator()(const Eigen::Vector3f& p) {
  const double inv = m_.inv_;
  return at(floorToCell(double(p.x()), inv), floorToCell(double(p.y()), inv),
            floorToCell(double(p.z()), inv));
}

FreeEvidence FreeSpaceMap::Lookup::at(int64_t x, int64_t y, int64_t z) {
  const uint64_t k = blockKey(x, y, z);
  if (k != key_) {
    key_ = k;
    block_ = m_.findBlock(k);
  }
  return evidenceOf(block_ ? m_.find(*block_, localIndex(x, y, z)) : nullptr);
}

void FreeSpaceMap::merge(const FreeSpaceMap& o) {
  o.blocks_.forEach([&](uint64_t k, uint32_t on) {
    const Block& ob = o.pool_[on - 1];
    Block& mine = blockOf(k);
    for (int i = 0; i < kVoxels; ++i) {
      const Voxel* tv = o.find(ob, i);
      if (!tv || (tv->count == 0 && tv->hits == 0)) continue;
      const Voxel& theirs = *tv;
      Voxel& m = voxel(mine, i);
      if (m.count == 0 && m.hits == 0) {
        m = theirs;
        continue;
      }
      // The runs join in scan order: the chunks own disjoint ranges of scans, so the one whose
      // last activity is earlier holds only earlier scans.
      const bool mine_first =
          std::max(m.last1, m.last_hit1) < std::max(theirs.last1, theirs.last_hit1);
      const Voxel& a = mine_first ? m : theirs;
      const Voxel& b = mine_first ? theirs : m;
      const auto sat = [](int v) { return std::min(v, 0xFF); };  // bit-fields promote to int
      const int lead = a.hits ? int(a.lead) : sat(a.lead + b.lead);
      const int trail = b.hits ? int(b.trail) : sat(a.trail + b.trail);
      const bool between =
          a.emptied_between || b.emptied_between ||
          (a.hits && b.hits && p_.between_scans > 0 && a.trail + b.lead >= p_.between_scans);
      m.lead = lead;
      m.trail = trail;
      m.emptied_between = between;
      m.count = static_cast<uint16_t>(std::min(0xFFFF, m.count + theirs.count));
      m.hits = static_cast<uint16_t>(std::min(0xFFFF, m.hits + theirs.hits));
      m.first_c = std::max(m.first_c, theirs.first_c);
      m.last1 = std::max(m.last1, theirs.last1);
      m.last_hit1 = std::max(m.last_hit1, theirs.last_hit1);
    }
  });
  marked_ += o.marked_;
  bin_min_ = std::min(bin_min_, o.bin_min_);
  bin_max_ = std::max(bin_max_, o.bin_max_);
}

}  // namespace cleanmap
