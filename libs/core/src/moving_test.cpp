// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/moving_test.h"

#include <algorithm>
#include <cmath>
#include <optional>

namespace cleanmap {

MovingTest::MovingTest(const DsParams& p)
    : p_(p),
      model_(p),
      radius_(p.search_lambdas * p.lambda_theta),
      r_far_(std::sqrt(2.0 * model_.s1 * 40.0)) {}  // exp(-r^2 / 2(1+sigma^2)) < e^-40

ds::Mass MovingTest::scanMass(const Eigen::Vector3d& p_world, const WindowScan& s, double* range_p,
                              MovingTestStats* stats) const {
  const Eigen::Vector3d pl = s.world_to_sensor * p_world;
  const double d = pl.norm();
  if (range_p) *range_p = d;
  ds::Mass m;
  if (d < 1e-3 || !s.beams) return m;
  const Eigen::Vector3f dir = (pl / d).cast<float>();
  // The cone: search_lambdas * lambda_theta, widened to search_lambdas *
  // sqrt(lambda_theta^2 + (noise / d)^2) when the scan's pose relative to P's scan is uncertain
  // (estimated poses): near the sensor that error exceeds the beam width.
  const double radius =
      s.pose_noise2 > 0 ? p_.search_lambdas *
                              std::sqrt(p_.lambda_theta * p_.lambda_theta + s.pose_noise2 / (d * d))
                        : radius_;
  const float r2max = static_cast<float>(radius * radius);
  const float df = static_cast<float>(d), r_far = static_cast<float>(r_far_);
  bool conflict = false;
  float e_max = 0.0f, o_max = 0.0f;  // the scan's most-empty beam, most-occupied return at P
  const float band = static_cast<float>(2.0 * model_.sigma);  // not an occluder in front of P
  std::size_t beams = 0;
  s.beams->forEachNear(dir, radius, [&](const BeamIndex::Beam& q) {
    // Small angles: theta = |a x b| to float precision (a dot product would lose it).
    const float theta2 = dir.cross(q.dir).squaredNorm();
    if (theta2 > r2max || dir.dot(q.dir) <= 0.0f) return;
    const float r = df * std::sqrt(1.0f - theta2) - q.range;  // |OP'| - |OQ|
    if (r > r_far) return;  // far behind the hit: unknown, the identity of Dempster's rule
    ++beams;
    const ds::Mass b = model_.beamFloat(r, theta2);
    e_max = std::max(e_max, static_cast<float>(b.e));
    if (r <= band) o_max = std::max(o_max, static_cast<float>(b.o));  // a return at P's range
    m = ds::combine(m, b, &conflict);
  });
  // doc/SCAN_CONFLICT.md: an empty vote needs a scan whose beams agree. Beams that pass P and
  // beams that return at P's range (|r| <= 2 sigma) in the same scan mean a porous or thin
  // surface (foliage, a fence, a pole), not a vacated space; Dempster's normalisation would hide
  // that conflict.
  if (p_.scan_conflict < 1.0 && m.e > m.o && m.e > m.u &&
      static_cast<double>(e_max) * o_max >= p_.scan_conflict) {
    m = ds::Mass{};
    if (stats) ++stats->conflicting_scans;
  }
  if (stats) {
    stats->total_conflicts += conflict;
    stats->beams += beams;
  }
  return m;
}

// The discretised votes are simple supports of mass l on {empty} or {occupied}. Combined, the
// empty votes give E = 1 - prod(1 - l) and the occupied ones O likewise, and the result is moving
// iff E > O (empty then also beats unknown, as l > 0.5). So the decision is a weighted vote:
// S_e = sum of -ln(1 - l) over empty votes against S_o over occupied ones, and a scan weighs at
// most w_max = -ln(1 - r_sup). Once |S_e - S_o| exceeds what the unvisited scans can add, the
// decision is final. Otherwise the result is Dempster's rule over the whole window, so a point
// close to a tie is decided exactly as without the shortcut.
std::optional<bool> MovingTest::combineWindow(const Eigen::Vector3d& p_world,
                                              const std::vector<WindowScan>& window,
                                              MovingTestStats* stats, bool stop_early,
                                              ds::Mass& acc) const {
  const double w_max = -std::log1p(-p_.r_sup);
  constexpr double kSafety = 1e-6;  // far above the rounding of the sums
  acc = ds::Mass{};
  bool any = false, conflict = false;
  double lead = 0.0;  // S_e - S_o
  for (std::size_t i = 0; i < window.size(); ++i) {
    const double rest = static_cast<double>(window.size() - i) * w_max + kSafety;
    if (stop_early && (lead > rest || -lead > rest)) {  // votes were cast
      if (stats) ++stats->early;
      return lead > 0;
    }
    if (stats) ++stats->scans_visited;
    double d = 0;
    const ds::Mass m = scanMass(p_world, window[i], &d, stats);
    const ds::Mass dm = ds::discretise(m, ds::discreteBelief(d, window[i].beams->farthest(), p_));
    if (dm.e > 0) lead -= std::log1p(-dm.e);
    if (dm.o > 0) lead += std::log1p(-dm.o);
    any = any || dm.u < 1.0;
    acc = ds::combine(acc, dm, &conflict);
  }
  if (stats) {
    stats->no_evidence += !any;
    stats->total_conflicts += conflict;
  }
  return std::nullopt;
}

ds::Mass MovingTest::windowMass(const Eigen::Vector3d& p_world,
                                const std::vector<WindowScan>& window,
                                MovingTestStats* stats) const {
  ds::Mass acc;
  combineWindow(p_world, window, stats, false, acc);
  return acc;
}

bool MovingTest::isMoving(const Eigen::Vector3d& p_world, const std::vector<WindowScan>& window,
                          MovingTestStats* stats) const {
  ds::Mass acc;
  if (const auto early = combineWindow(p_world, window, stats, true, acc)) return *early;
  return ds::isMoving(acc);
}

}  // namespace cleanmap
