// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/beam_index.h"

#include <algorithm>
#include <cmath>

namespace cleanmap {

int BeamIndex::azBin(double az) const {
  const int a = static_cast<int>(std::floor((az + M_PI) / bin_));
  return std::clamp(a, 0, n_az_ - 1);
}

BeamIndex::BeamIndex(const std::vector<PointXYZI>& points, double bin) : bin_(bin) {
  n_az_ = std::max(1, static_cast<int>(std::ceil(2.0 * M_PI / bin_)));
  bin_ = 2.0 * M_PI / n_az_;  // an integral number of azimuth bins
  std::vector<Beam> beams;
  std::vector<double> el;
  beams.reserve(points.size());
  el.reserve(points.size());
  double el_max = -M_PI;
  el_min_ = M_PI;
  for (const auto& p : points) {
    const Eigen::Vector3f v(p.x, p.y, p.z);
    const float r = v.norm();
    if (!(r > 1e-3f)) continue;  // no direction
    beams.push_back({v / r, r});
    el.push_back(std::asin(std::clamp(static_cast<double>(v.z() / r), -1.0, 1.0)));
    el_min_ = std::min(el_min_, el.back());
    el_max = std::max(el_max, el.back());
    farthest_ = std::max(farthest_, r);
  }
  if (beams.empty()) return;
  n_el_ = static_cast<int>(std::floor((el_max - el_min_) / bin_)) + 1;
  const std::size_t nbins = static_cast<std::size_t>(n_el_) * static_cast<std::size_t>(n_az_);
  std::vector<uint32_t> bin_of(beams.size());
  offsets_.assign(nbins + 1, 0);
  for (std::size_t i = 0; i < beams.size(); ++i) {
    const int e = std::min(static_cast<int>(std::floor((el[i] - el_min_) / bin_)), n_el_ - 1);
    const double az =
        std::atan2(static_cast<double>(beams[i].dir.y()), static_cast<double>(beams[i].dir.x()));
    bin_of[i] = static_cast<uint32_t>(e * n_az_ + azBin(az));
    ++offsets_[bin_of[i] + 1];
  }
  for (std::size_t b = 0; b < nbins; ++b) offsets_[b + 1] += offsets_[b];
  beams_.resize(beams.size());
  std::vector<uint32_t> fill(offsets_.begin(), offsets_.end() - 1);
  for (std::size_t i = 0; i < beams.size(); ++i) beams_[fill[bin_of[i]]++] = beams[i];
}

}  // namespace cleanmap
