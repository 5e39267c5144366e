// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2b: per-scan spherical beam index (azimuth x elevation bins), built once per scan in the
// sensor frame and reused by every frame whose window holds the scan.
#pragma once
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "cleanmap/core/types.h"

namespace cleanmap {

class BeamIndex {
 public:
  struct Beam {
    Eigen::Vector3f dir;  ///< unit direction, sensor frame
    float range;          ///< |OQ|, m
  };

  BeamIndex() = default;
  /// Indexes every point of the scan (ground and far points included: they are beams too).
  /// `bin` is the angular bin size in rad (use the search radius).
  BeamIndex(const std::vector<PointXYZI>& points, double bin);

  /// Calls f(const Beam&) for every beam whose bin could lie within `radius` rad of `dir`
  /// (unit, sensor frame); f filters by the exact angle. radius <= bin.
  template <class F>
  void forEachNear(const Eigen::Vector3f& dir, double radius, F&& f) const;

  float farthest() const { return farthest_; }  ///< |OB|
  std::size_t size() const { return beams_.size(); }
  bool empty() const { return beams_.empty(); }

 private:
  int azBin(double az) const;
  double bin_ = 0.01;
  int n_az_ = 0, n_el_ = 0;
  double el_min_ = 0;
  float farthest_ = 0;
  std::vector<Beam> beams_;        // sorted by bin
  std::vector<uint32_t> offsets_;  // CSR: beams of bin b are [offsets_[b], offsets_[b+1])
};

template <class F>
void BeamIndex::forEachNear(const Eigen::Vector3f& dir, double radius, F&& f) const {
  if (beams_.empty()) return;
  const double el = std::asin(std::clamp(static_cast<double>(dir.z()), -1.0, 1.0));
  const double az = std::atan2(static_cast<double>(dir.y()), static_cast<double>(dir.x()));
  const int e0 = static_cast<int>(std::floor((el - radius - el_min_) / bin_));
  const int e1 = static_cast<int>(std::floor((el + radius - el_min_) / bin_));
  if (e1 < 0 || e0 >= n_el_) return;
  // Azimuth spans widen by 1 / cos(elevation) away from the horizon.
  const double c = std::max(std::cos(std::abs(el) + radius), 1e-3);
  const double daz = std::min(radius / c, M_PI);
  const int a_lo = static_cast<int>(std::floor((az - daz + M_PI) / bin_));
  const int a_hi = static_cast<int>(std::floor((az + daz + M_PI) / bin_));
  const int span = std::min(a_hi - a_lo, n_az_ - 1);
  // A row's bins a_first .. a_first + span are one range of beams_ (two where they wrap at 2 pi).
  const int a_first = (a_lo % n_az_ + n_az_) % n_az_;
  const int a_end = a_first + span + 1;
  for (int e = std::max(e0, 0); e <= std::min(e1, n_el_ - 1); ++e) {
    const uint32_t* row = offsets_.data() + static_cast<std::size_t>(e) * n_az_;
    for (uint32_t q = row[a_first], end = row[std::min(a_end, n_az_)]; q < end; ++q) f(beams_[q]);
    if (a_end > n_az_)
      for (uint32_t q = row[0], end = row[a_end - n_az_]; q < end; ++q) f(beams_[q]);
  }
}

}  // namespace cleanmap
