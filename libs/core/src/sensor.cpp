// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/sensor.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "cleanmap/core/fast_math.h"
#include "cleanmap/core/median.h"

namespace cleanmap {

const std::vector<SensorPreset>& sensorPresets() {
  // Datasheets: HDL-64E S2 (+2 .. -24.33 deg, 0.17 deg at 10 Hz), HDL-32E (+10.67 .. -30.67,
  // 0.16), VLP-16 (+-15, 0.2), Ouster OS1-64 gen 1 (+-16.6) and OS1-128 (+-22.5) at 1024 x 10.
  static const std::vector<SensorPreset> p = {
      {SensorModel::kHdl64, "hdl64", 64, -24.33, 2.0, 0.18},
      {SensorModel::kHdl32, "hdl32", 32, -30.67, 10.67, 0.16},
      {SensorModel::kVlp16, "vlp16", 16, -15.0, 15.0, 0.2},
      {SensorModel::kOs1_64, "os1-64", 64, -16.6, 16.6, 360.0 / 1024},
      {SensorModel::kOs1_128, "os1-128", 128, -22.5, 22.5, 360.0 / 1024},
  };
  return p;
}

const SensorPreset& sensorPreset(SensorModel m) {
  for (const auto& p : sensorPresets())
    if (p.model == m) return p;
  throw std::invalid_argument("sensorPreset: no preset for sensor model auto");
}

std::optional<SensorModel> sensorModelByName(const std::string& name) {
  if (name == "auto") return SensorModel::kAuto;
  for (const auto& p : sensorPresets())
    if (name == p.name) return p.model;
  return std::nullopt;
}

const char* sensorModelName(SensorModel m) {
  return m == SensorModel::kAuto ? "auto" : sensorPreset(m).name;
}

std::vector<double> evenElevations(int rings, double lo_deg, double hi_deg) {
  if (rings < 2 || !(lo_deg < hi_deg))
    throw std::invalid_argument("evenElevations: need rings >= 2 and lo < hi");
  std::vector<double> e;
  for (int i = 0; i < rings; ++i)
    e.push_back((hi_deg - i * (hi_deg - lo_deg) / (rings - 1)) * M_PI / 180);
  return e;
}

std::vector<double> ringElevations(SensorModel m) {
  if (m == SensorModel::kHdl64) {
    std::vector<double> v;
    for (int i = 0; i < 32; ++i) v.push_back((2.0 - i * (10.33 / 31.0)) * M_PI / 180);
    for (int i = 0; i < 32; ++i) v.push_back((-8.83 - i * (15.5 / 31.0)) * M_PI / 180);
    return v;
  }
  const auto& p = sensorPreset(m);
  return evenElevations(p.rings, p.fov_lo_deg, p.fov_hi_deg);
}

AngularResolution presetResolution(SensorModel m) {
  const auto& p = sensorPreset(m);
  return {(p.fov_hi_deg - p.fov_lo_deg) / (p.rings - 1), p.azimuth_step_deg};
}

std::optional<AngularResolution> measureResolution(const std::vector<PointXYZI>& points,
                                                   double* rings_deg) {
  constexpr double kBin = 0.05;  // degrees
  constexpr int kBins = static_cast<int>(180 / kBin);
  std::vector<uint32_t> count(kBins, 0);
  std::vector<double> sum(kBins, 0.0);
  std::size_t used = 0;
  std::vector<std::pair<int, const PointXYZI*>> binned;  // elevation bin of each used return
  binned.reserve(points.size());
  // Issue #16: the elevation bin from fast::atan2 (float), libm's double atan2 / hypot for the
  // returns within kEdge of a bin edge or of the 5 / 100 m bounds, so the bins are libm's; the
  // bins' mean elevations take the fast angle (error below 1e-6 degrees).
  constexpr double kEdge = 5e-3;  // of a bin: 25x the fast angle's error (3e-7 rad + rounding)
  constexpr float kDeg = static_cast<float>(180 / M_PI);
  for (const auto& p : points) {
    const double rh2 = double(p.x) * p.x + double(p.y) * p.y;
    if (!(rh2 >= 25 * (1 - 1e-9) && rh2 <= 1e4 * (1 + 1e-9)) || !std::isfinite(p.z)) continue;
    const bool at_bound = rh2 <= 25 * (1 + 1e-9) || rh2 >= 1e4 * (1 - 1e-9);
    if (at_bound &&
        !(std::hypot(double(p.x), double(p.y)) >= 5 && std::hypot(double(p.x), double(p.y)) <= 100))
      continue;
    const float el_fast = fast::atan2(p.z, std::sqrt(static_cast<float>(rh2))) * kDeg;
    const double t = (double(el_fast) + 90) / kBin;
    int b = fast::binOrExact(t, kEdge, [&] {
      const double el = std::atan2(double(p.z), std::hypot(double(p.x), double(p.y))) * 180 / M_PI;
      return static_cast<int>(std::floor((el + 90) / kBin));
    });
    b = std::clamp(b, 0, kBins - 1);
    ++count[static_cast<std::size_t>(b)];
    sum[static_cast<std::size_t>(b)] += el_fast;
    binned.emplace_back(b, &p);
    ++used;
  }
  if (used < 1000) return std::nullopt;
  // Rings: runs of bins holding returns; a bin with a few stray returns (0.02 % of the used ones)
  // does not join two rings.
  const auto min_count = static_cast<uint32_t>(std::max<std::size_t>(1, used / 5000));
  struct Ring {
    double el_sum = 0;
    std::size_t n = 0;
    int first = 0, last = 0;
  };
  std::vector<Ring> rings;
  for (int b = 0; b < kBins; ++b) {
    const auto i = static_cast<std::size_t>(b);
    if (count[i] < min_count) continue;
    if (rings.empty() || b > rings.back().last + 1) rings.push_back({0, 0, b, b});
    rings.back().el_sum += sum[i];
    rings.back().n += count[i];
    rings.back().last = b;
  }
  // Real rings hold a turn of returns; short runs between them are returns whose elevation is
  // shifted (a laser's offset from the sensor origin, seen at short range: KITTI's HDL-64E) and
  // would halve the gaps. Keep runs with an eighth of a typical (upper-quartile) ring's returns.
  if (rings.size() < 8) return std::nullopt;
  {
    std::vector<std::size_t> n;
    for (const auto& r : rings) n.push_back(r.n);
    std::nth_element(n.begin(), n.begin() + std::ptrdiff_t(n.size() * 3 / 4), n.end());
    const std::size_t keep = n[n.size() * 3 / 4] / 8;
    rings.erase(
        std::remove_if(rings.begin(), rings.end(), [keep](const Ring& r) { return r.n < keep; }),
        rings.end());
  }
  if (rings.size() < 8) return std::nullopt;
  std::vector<double> gaps;
  for (std::size_t k = 1; k < rings.size(); ++k)
    gaps.push_back(rings[k].el_sum / double(rings[k].n) -
                   rings[k - 1].el_sum / double(rings[k - 1].n));
  const double vertical = median(std::move(gaps));
  // The azimuth step: per ring, the median gap between neighbouring returns; the median over
  // rings, so that a run where several lasers blur together (a smaller gap) is outvoted.
  std::vector<std::vector<float>> az(rings.size());
  for (const auto& [b, p] : binned) {
    const auto r = std::partition_point(rings.begin(), rings.end(),
                                        [b = b](const Ring& g) { return g.last < b; });
    if (r != rings.end() && b >= r->first)
      az[std::size_t(r - rings.begin())].push_back(fast::atan2(p->y, p->x) * kDeg);
  }
  std::vector<double> ring_steps;
  for (auto& a : az) {
    std::sort(a.begin(), a.end());
    std::vector<double> steps;
    for (std::size_t k = 1; k < a.size(); ++k)
      if (double(a[k]) - a[k - 1] > 1e-4) steps.push_back(double(a[k]) - a[k - 1]);
    if (steps.size() >= 100) ring_steps.push_back(median(std::move(steps)));
  }
  if (ring_steps.size() < 4) return std::nullopt;
  const double azimuth = median(std::move(ring_steps));
  // Rings closer than 0.8 degrees may be the HDL-64E's blurring together (KITTI's do): the scale
  // stays 1 there, unless the columns are clearly coarser than the HDL-64E's 0.17-0.18 degrees
  // (an Ouster at 1024 columns: 0.35), whose rings stand apart.
  if (rings_deg) *rings_deg = vertical;
  if (vertical < kDenseRingsDeg && !(azimuth > kCoarseColumnsDeg)) return std::nullopt;
  return AngularResolution{vertical, azimuth};
}

double densityScale(const AngularResolution& r) {
  const AngularResolution ref = presetResolution(SensorModel::kHdl64);
  if (!(r.vertical_deg > 0 && r.azimuth_deg > 0)) return 1.0;
  return std::clamp(ref.vertical_deg * ref.azimuth_deg / (r.vertical_deg * r.azimuth_deg), 0.05,
                    4.0);
}

int scaledCount(double n, double density) {
  return std::max(1, static_cast<int>(std::lround(n * density)));
}

}  // namespace cleanmap
