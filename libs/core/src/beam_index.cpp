// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/beam_index.h"

#include <algorithm>
#include <cmath>

#include "beam_angles.h"

namespace cleanmap {

int BeamIndex::azBin(double az) const {
  const int a = static_cast<int>(std::floor((az + M_PI) / bin_));
  return std::clamp(a, 0, n_az_ - 1);
}

BeamIndex::BeamIndex(const std::vector<PointXYZI>& points, double bin, Binning binning,
                     const GrazingStretches* grazing)
    : bin_(bin) {
  n_az_ = std::max(1, static_cast<int>(std::ceil(2.0 * M_PI / bin_)));
  bin_ = 2.0 * M_PI / n_az_;  // an integral number of azimuth bins
  // The returns' unit directions (the bins are theirs), then the beams packed (PackedBeam).
  std::vector<float> dx, dy, dz, ranges;  // one array per axis (vector loads)
  for (auto* v : {&dx, &dy, &dz, &ranges}) v->reserve(points.size());
  const bool graze = grazing && grazing->from().size() == points.size();
  std::vector<uint32_t> graze_of;  // per beam, its stretch packed (grazing())
  if (graze) graze_of.reserve(points.size());
  for (std::size_t k = 0; k < points.size(); ++k) {
    const auto& p = points[k];
    const Eigen::Vector3f v(p.x, p.y, p.z);
    const float r = v.norm();
    if (!(r > 1e-3f) || !std::isfinite(r)) continue;  // no direction
    const Eigen::Vector3f u = v / r;
    dx.push_back(u.x());
    dy.push_back(u.y());
    dz.push_back(u.z());
    ranges.push_back(r);
    farthest_ = std::max(farthest_, r);
    if (graze) graze_of.push_back(k);  // the point, packed below once the unit is known
  }
  while (farthest_ / range_unit_ > 65535.0f) range_unit_ *= 2.0f;
  if (graze) {
    // The stretch widened outwards to whole range units (from floored, to ceiled); none: 0xFFFF, 0.
    const float inv_unit = 1.0f / range_unit_;
    for (uint32_t& g : graze_of) {
      const float a = grazing->from()[g], b = grazing->to()[g];
      uint32_t lo = 0xFFFFu, hi = 0u;
      if (b >= a && b > 0.0f) {
        lo = static_cast<uint32_t>(std::clamp(std::floor(a * inv_unit), 0.0f, 65535.0f));
        hi = static_cast<uint32_t>(std::clamp(std::ceil(b * inv_unit), 0.0f, 65535.0f));
      }
      g = lo | hi << 16;
    }
  }
  std::vector<PackedBeam> beams(ranges.size());
  {
    // Round to nearest (the magnitudes are below 2^16, where adding and subtracting 1.5 * 2^23
    // rounds a float to an integer, ties to even), in vector lanes.
    auto round = [](float x) { return (x + 12582912.0f) - 12582912.0f; };
    const float inv_unit = 1.0f / range_unit_;
    for (std::size_t i = 0; i < beams.size(); ++i) {
      auto component = [&](float c) {
        return static_cast<int16_t>(std::clamp(round(c * 32768.0f), -32767.0f, 32767.0f));
      };
      beams[i] = {component(dx[i]), component(dy[i]), component(dz[i]),
                  static_cast<uint16_t>(std::min(round(ranges[i] * inv_unit), 65535.0f))};
    }
  }
  if (beams.empty()) return;
  const std::size_t n = beams.size();
  // The reference angles (libm, double), and the bins they give.
  auto exact_el = [&](std::size_t i) { return std::asin(std::clamp(double(dz[i]), -1.0, 1.0)); };
  auto exact_az = [&](std::size_t i) { return std::atan2(double(dy[i]), double(dx[i])); };
  auto el_bin = [&](double el) {
    return std::min(static_cast<int>(std::floor((el - el_min_) / bin_)), n_el_ - 1);
  };
  std::vector<uint32_t> bin_of(n);
  double el_max = -M_PI;
  el_min_ = M_PI;
  if (binning == Binning::kExact) {
    std::vector<double> el(n);
    for (std::size_t i = 0; i < n; ++i) {
      el[i] = exact_el(i);
      el_min_ = std::min(el_min_, el[i]);
      el_max = std::max(el_max, el[i]);
    }
    n_el_ = static_cast<int>(std::floor((el_max - el_min_) / bin_)) + 1;
    for (std::size_t i = 0; i < n; ++i)
      bin_of[i] = static_cast<uint32_t>(azBin(exact_az(i)) * n_el_ + el_bin(el[i]));
  } else {
    std::vector<float> el(n), az(n);
    detail::approxAngles(dx.data(), dy.data(), dz.data(), n, el.data(), az.data());
    // The exact extremes are among the beams whose approximate elevation is within twice the
    // error bound of the approximate extremes.
    const auto [lo, hi] = std::minmax_element(el.begin(), el.end());
    const float near_lo = *lo + 2 * float(kAngleError), near_hi = *hi - 2 * float(kAngleError);
    for (std::size_t i = 0; i < n; ++i)
      if (el[i] <= near_lo || el[i] >= near_hi) {
        const double e = exact_el(i);
        el_min_ = std::min(el_min_, e);
        el_max = std::max(el_max, e);
      }
    n_el_ = static_cast<int>(std::floor((el_max - el_min_) / bin_)) + 1;
    // A bin coordinate more than kBinTolerance from an edge floors as the exact one would.
    const double inv = 1.0 / bin_;
    for (std::size_t i = 0; i < n; ++i) {
      const double te = (double(el[i]) - el_min_) * inv, ta = (double(az[i]) + M_PI) * inv;
      const int e = std::min(
          fast::binOrExact(te, kBinTolerance, [&] { return el_bin(exact_el(i)); }), n_el_ - 1);
      const int a = std::clamp(
          fast::binOrExact(ta, kBinTolerance, [&] { return azBin(exact_az(i)); }), 0, n_az_ - 1);
      bin_of[i] = static_cast<uint32_t>(a * n_el_ + e);
    }
  }
  const std::size_t nbins = static_cast<std::size_t>(n_el_) * static_cast<std::size_t>(n_az_);
  offsets_.assign(nbins + 1, 0);
  for (std::size_t i = 0; i < n; ++i) ++offsets_[bin_of[i] + 1];
  for (std::size_t b = 0; b < nbins; ++b) offsets_[b + 1] += offsets_[b];
  beams_.resize(n);
  std::vector<uint32_t> fill(offsets_.begin(), offsets_.end() - 1);
  if (graze) graze_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const uint32_t at = fill[bin_of[i]]++;
    beams_[at] = beams[i];
    if (graze) graze_[at] = graze_of[i];
  }
}

}  // namespace cleanmap
