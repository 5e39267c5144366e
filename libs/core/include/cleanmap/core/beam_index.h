// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2b: per-scan spherical beam index (azimuth x elevation bins), built once per scan in the
// sensor frame and reused by every frame whose window holds the scan.
#pragma once
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "cleanmap/core/fast_math.h"
#include "cleanmap/core/grazing.h"
#include "cleanmap/core/types.h"

namespace cleanmap {

class BeamIndex {
 public:
  /// A beam as the queries give it: its stored direction and range, decoded (PackedBeam).
  struct Beam {
    Eigen::Vector3f dir;  ///< direction, sensor frame: unit to within 4e-5
    float range;          ///< |OQ|, m
  };
  /// A beam as the index stores it (issue #16: 8 bytes instead of 16, half the index's memory and
  /// the moving test's loads): the unit direction's components in steps of kDirUnit (2^-15, about
  /// 3e-5 rad, against the cone's 1e-2) and the range in steps of rangeUnit() (2^-9 m, coarser
  /// powers of two only for returns beyond 128 m). Both steps are powers of two, so decoding is
  /// exact in float.
  struct PackedBeam {
    int16_t x, y, z;
    uint16_t range;
  };
  static constexpr float kDirUnit = 1.0f / 32768.0f;
  /// A stored direction lies within this angle of its return's (components rounded to
  /// kDirUnit / 2, one clamped at 1 - kDirUnit: at most 3.1e-5 rad). A beam's bin is its return's;
  /// the queries widen their bounds by this.
  static constexpr double kDirError = 5e-5;  // rad

  /// How a beam's bin is found. Both give the same index, bit for bit: a beam's bins are those
  /// of libm's double asin / atan2 of its direction. kFast computes them with the vectorised
  /// float fast::asin / fast::atan2 and falls back to libm for the few beams that lie within
  /// kBinTolerance of a bin edge (issue #16); kExact calls libm for every beam (the reference).
  enum class Binning { kFast, kExact };
  /// Error bound used for fast::asin / fast::atan2 here: 3x their measured errors (fast_math.h).
  static constexpr double kAngleError = 1e-6;  // rad
  /// kFast recomputes a beam exactly when its approximate bin coordinate is this close to an edge
  /// (a fraction of a bin; 5e-6 rad, so above kAngleError and the rounding of the bin arithmetic).
  static constexpr double kBinTolerance = 5e-4;

  BeamIndex() = default;
  /// Indexes every point of the scan (ground and far points included: they are beams too).
  /// `bin` is the angular bin size in rad (use the search radius). With `grazing` (computed for
  /// these points), each beam keeps the stretch where it grazes a flat surface (grazing()).
  BeamIndex(const std::vector<PointXYZI>& points, double bin, Binning binning = Binning::kFast,
            const GrazingStretches* grazing = nullptr);

  /// Calls f(const Beam&) for every beam whose bin could lie within `radius` rad of `dir`
  /// (unit, sensor frame); f filters by the exact angle. Any radius (a wider one spans more
  /// bins; the moving test's conflict check widens it with the pose error). The bins are found with
  /// fast::asin / fast::atan2 and widened by kAngleError and kDirError, so they hold every beam
  /// whose stored direction lies within `radius`; beams come in bin order (azimuth-major; a full
  /// circle from azimuth bin 0).
  template <class F>
  void forEachNear(const Eigen::Vector3f& dir, double radius, F&& f) const;
  /// The same beams as forEachNear, still packed, as runs: f(const PackedBeam* first, const
  /// PackedBeam* last) for each non-empty run of consecutive beams, in the same order.
  template <class F>
  void forEachRunNear(const Eigen::Vector3f& dir, double radius, F&& f) const;
  /// forEachNear over a box instead of a disc: the beams whose bin could lie within `az_radius`
  /// of `dir` across (an angle on the sphere, as `radius`) and `el_radius` in elevation
  /// (the scan-conflict check's band of rings, MovingTest::scanMass).
  template <class F>
  void forEachNearBox(const Eigen::Vector3f& dir, double az_radius, double el_radius, F&& f) const;

  float farthest() const { return farthest_; }  ///< |OB| (the return's range, not rounded)
  std::size_t size() const { return beams_.size(); }
  bool empty() const { return beams_.empty(); }
  const std::vector<PackedBeam>& beams() const { return beams_; }  ///< sorted by bin
  float rangeUnit() const { return range_unit_; }                  ///< m per PackedBeam::range
  /// Per beam (parallel to beams()), the stretch along it that grazes a flat surface
  /// (GrazingStretches, DESIGN §2b), in rangeUnit() steps: from in the low 16 bits, to in the
  /// high ones (from 0xFFFF, to 0: none). Empty where the index was built without it.
  const std::vector<uint32_t>& grazing() const { return graze_; }
  Beam decode(const PackedBeam& q) const {
    return {Eigen::Vector3f(q.x * kDirUnit, q.y * kDirUnit, q.z * kDirUnit),
            static_cast<float>(q.range) * range_unit_};
  }
  /// CSR over bins (azimuth-major, bin a * elevation bins + e): the beams of bin b are
  /// [offsets()[b], offsets()[b + 1]).
  const std::vector<uint32_t>& offsets() const { return offsets_; }

 private:
  int azBin(double az) const;
  template <class F>
  void forEachRunInBox(const Eigen::Vector3f& dir, double az_radius, double el_radius, F&& f) const;
  double bin_ = 0.01;
  int n_az_ = 0, n_el_ = 0;
  double el_min_ = 0;
  float farthest_ = 0;
  float range_unit_ = 1.0f / 512.0f;
  std::vector<PackedBeam> beams_;  // sorted by bin
  std::vector<uint32_t> offsets_;  // CSR over the bins, azimuth-major (offsets())
  std::vector<uint32_t> graze_;    // parallel to beams_ (grazing())
};

template <class F>
void BeamIndex::forEachNear(const Eigen::Vector3f& dir, double radius, F&& f) const {
  forEachRunNear(dir, radius, [&](const PackedBeam* first, const PackedBeam* last) {
    for (const PackedBeam* q = first; q != last; ++q) f(decode(*q));
  });
}

template <class F>
void BeamIndex::forEachNearBox(const Eigen::Vector3f& dir, double az_radius, double el_radius,
                               F&& f) const {
  forEachRunInBox(dir, az_radius, el_radius, [&](const PackedBeam* first, const PackedBeam* last) {
    for (const PackedBeam* q = first; q != last; ++q) f(decode(*q));
  });
}

template <class F>
void BeamIndex::forEachRunNear(const Eigen::Vector3f& dir, double radius, F&& f) const {
  forEachRunInBox(dir, radius, radius, std::forward<F>(f));
}

template <class F>
void BeamIndex::forEachRunInBox(const Eigen::Vector3f& dir, double az_radius, double el_radius,
                                F&& f) const {
  if (beams_.empty()) return;
  // Approximate angles, every bound widened by their error: the bins hold all that libm's
  // angles would give (the exact filter is f's).
  const float z = std::clamp(dir.z(), -1.0f, 1.0f);
  const double el = fast::asin(z), az = fast::atan2(dir.y(), dir.x());
  const double r = el_radius + kAngleError + kDirError, ra = az_radius + kAngleError + kDirError;
  const int e0 = static_cast<int>(std::floor((el - r - el_min_) / bin_));
  const int e1 = static_cast<int>(std::floor((el + r - el_min_) / bin_));
  if (e1 < 0 || e0 >= n_el_) return;
  // Azimuth spans widen by 1 / cos(elevation) away from the horizon. A lower bound of
  // cos(|el| + r), without trigonometry: cos|el| cos r - sin|el| sin r with cos r >= 1 - r^2 / 2,
  // sin r <= r, cos|el| = sqrt(1 - z^2).
  const double zd = z, cos_el = std::sqrt(std::max(0.0, 1.0 - zd * zd));
  const double c = std::max(cos_el * (1.0 - 0.5 * r * r) - std::abs(zd) * r - 1e-9, 1e-3);
  const double daz = std::min(ra / c, M_PI);
  const int a_lo = static_cast<int>(std::floor((az - daz + M_PI) / bin_));
  const int a_hi = static_cast<int>(std::floor((az + daz + M_PI) / bin_));
  const int span = std::min(a_hi - a_lo, n_az_ - 1);
  const int a_first = span == n_az_ - 1 ? 0 : (a_lo % n_az_ + n_az_) % n_az_;
  const int lo = std::max(e0, 0), hi = std::min(e1, n_el_ - 1);
  // Azimuth-major: an azimuth bin's elevations lo .. hi are one range of beams_, and the ranges
  // of neighbouring bins join where they span every elevation.
  // The runs are gathered a few at a time and their beams prefetched before f reads them: each
  // run lies in another azimuth column, far from the last one in memory (issue #16).
  const PackedBeam* b = beams_.data();
  constexpr int kRuns = 8;
  uint32_t run_first[kRuns], run_last[kRuns];
  int runs = 0;
  const auto flush = [&] {
    for (int j = 0; j < runs; ++j) f(b + run_first[j], b + run_last[j]);
    runs = 0;
  };
  const auto add = [&](uint32_t from, uint32_t to) {
    __builtin_prefetch(b + from);
    __builtin_prefetch(b + to - 1);
    run_first[runs] = from;
    run_last[runs] = to;
    if (++runs == kRuns) flush();
  };
  uint32_t first = 0, last = 0;
  for (int k = 0; k <= span; ++k) {
    const int a = a_first + k < n_az_ ? a_first + k : a_first + k - n_az_;
    const uint32_t* col = offsets_.data() + static_cast<std::size_t>(a) * n_el_;
    const uint32_t from = col[lo], to = col[hi + 1];
    if (from == last) {  // the next bin of offsets_: the range goes on
      last = to;
      continue;
    }
    if (first < last) add(first, last);
    first = from;
    last = to;
  }
  if (first < last) add(first, last);
  flush();
}

}  // namespace cleanmap
