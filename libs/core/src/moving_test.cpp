// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/moving_test.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <tuple>
#include <type_traits>

#include "cleanmap/core/beam_filter.h"
#include "cleanmap/core/fast_math.h"

namespace cleanmap {

MovingTest::MovingTest(const DsParams& p, BeamMath math)
    : p_(p),
      math_(math),
      model_(p),
      radius_(p.search_lambdas * p.lambda_theta),
      r_far_(std::sqrt(2.0 * model_.s1 * 40.0)) {  // exp(-r^2 / 2(1+sigma^2)) < e^-40
  // l is linear in |OP| / |OB|, so a cell's largest weight is at one of its ends.
  const auto weight = [&](int j) {
    return -std::log1p(-ds::beliefAtRatio(double(j) / kWeightCells, p_));
  };
  for (int j = 0; j < kWeightCells; ++j) w_bound_[j] = std::max(weight(j), weight(j + 1));
  w_bound_[kWeightCells] = weight(kWeightCells);
}

std::vector<uint32_t> MovingTest::testOrder(const std::vector<Eigen::Vector3f>& points) const {
  // The test is bound by loading the window's beams: the octree gives the points ring by ring,
  // so each point's bins were last loaded a ring earlier, long evicted (doc/BENCHMARK.md).
  struct Key {
    int32_t column;
    float sin_el;
    uint32_t i;
  };
  std::vector<Key> keys(points.size());
  const double inv_col = 1.0 / (2.0 * radius_);
  for (uint32_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3f& q = points[i];
    const float r = q.norm();
    const double az = fast::atan2(q.y(), q.x()) + M_PI;
    keys[i] = {static_cast<int32_t>(std::floor(az * inv_col)), r > 0 ? q.z() / r : 0.0f, i};
  }
  std::sort(keys.begin(), keys.end(), [](const Key& a, const Key& b) {
    return std::tie(a.column, a.sin_el, a.i) < std::tie(b.column, b.sin_el, b.i);
  });
  std::vector<uint32_t> order(points.size());
  for (std::size_t k = 0; k < keys.size(); ++k) order[k] = keys[k].i;
  return order;
}

ds::Mass MovingTest::scanMass(const Eigen::Vector3d& p_world, const WindowScan& s, double* range_p,
                              MovingTestStats* stats, uint8_t edges) const {
  const Eigen::Vector3d pl = s.world_to_sensor * p_world;
  const double d = pl.norm();
  if (range_p) *range_p = d;
  if (d < 1e-3 || !s.beams) return ds::Mass{};
  return scanMassAt(pl, d, s, stats, edges);
}

namespace {

// P's direction's horizontal normal (east) and vertical one (up), both unit and across `dir`;
// false where P lies straight above or below the sensor.
bool acrossAxes(const Eigen::Vector3f& dir, Eigen::Vector3f& east, Eigen::Vector3f& up) {
  const Eigen::Vector3f east_raw(-dir.y(), dir.x(), 0.0f);
  const float norm = east_raw.norm();
  if (!(norm > 1e-6f)) return false;
  east = east_raw / norm;
  up = dir.cross(east);
  return true;
}

// The beams of `beams` within az_max of P's direction across it (the projection on east) whose
// elevation offset el (the projection on up) has lo <= |el| <= hi: f(beam, el). The box query
// holds them all: |el| <= hi means an elevation below asin(hi) plus a term of the azimuth offset
// squared (< 1e-4 rad here).
template <class F>
void forEachInBand(const BeamIndex& beams, const Eigen::Vector3f& dir, const Eigen::Vector3f& east,
                   const Eigen::Vector3f& up, float az_max, float lo, float hi, F&& f) {
  beams.forEachNearBox(dir, 1.01 * az_max, 1.01 * hi + 2e-4, [&](const BeamIndex::Beam& q) {
    const float el = q.dir.dot(up);
    if (!(dir.dot(q.dir) > 0.0f) || std::abs(q.dir.dot(east)) > az_max || std::abs(el) < lo ||
        std::abs(el) > hi)
      return;
    f(q, el);
  });
}

// The beams of `index` within `radius` of `dir` through detail::filterBeams, kRun at a time:
// chunk(first, run, r, theta2, keep) per piece of a run; one returning bool stops at false.
template <class Chunk>
void forEachFilteredRun(const BeamIndex& index, const Eigen::Vector3f& dir, double radius, float df,
                        float r2max, float r_far, Chunk&& chunk) {
  constexpr int kRun = 32;
  alignas(64) float r[kRun], theta2[kRun];
  alignas(64) int32_t keep[kRun];
  bool more = true;
  index.forEachRunNear(
      dir, radius, [&](const BeamIndex::PackedBeam* q, const BeamIndex::PackedBeam* last) {
        while (more && q < last) {
          const int run = static_cast<int>(std::min<std::ptrdiff_t>(last - q, kRun));
          detail::filterBeams(q, run, index.rangeUnit(), dir.x(), dir.y(), dir.z(), df, r2max,
                              r_far, r, theta2, keep);
          if constexpr (std::is_same_v<decltype(chunk(q, run, r, theta2, keep)), bool>)
            more = chunk(q, run, r, theta2, keep);
          else
            chunk(q, run, r, theta2, keep);
          q += run;
        }
      });
}

}  // namespace

uint8_t MovingTest::edgesOf(const Eigen::Vector3f& p, const WindowScan& own) const {
  const bool rings = own.ring_gap > radius_, columns = own.column_step > 0;
  if (!own.beams || !(rings || columns)) return 0;
  const float d = p.norm();
  Eigen::Vector3f east, up;
  if (!(d > 1e-3f)) return 0;
  const Eigen::Vector3f dir = p / d;
  if (!acrossAxes(dir, east, up)) return 0;
  uint8_t bits = 0;
  if (rings) {
    const auto gap = static_cast<float>(own.ring_gap);
    const uint8_t at = ringsAtRange(dir, d, east, up, own, 0.5f * gap, 1.5f * gap);
    bits |=
        static_cast<uint8_t>(((at & kAbove) ? 0 : kTopEdge) | ((at & kBelow) ? 0 : kBottomEdge));
  }
  if (columns) bits |= columnIsolated(dir, d, east, up, own) ? kColumnIsolated : 0;
  return bits;
}

bool MovingTest::ringsReturnAt(const Eigen::Vector3d& p_world, const WindowScan& s) const {
  if (!s.beams || !(s.ring_gap > radius_)) return false;
  const Eigen::Vector3f p = (s.world_to_sensor * p_world).cast<float>();
  const float d = p.norm();
  Eigen::Vector3f east, up;
  if (!(d > 1e-3f)) return false;
  const Eigen::Vector3f dir = p / d;
  if (!acrossAxes(dir, east, up)) return false;
  return ringsAtRange(dir, d, east, up, s, 0.0f, static_cast<float>(s.ring_gap)) != 0;
}

// The rings of sparse scan s around P (direction `dir`, range d, axes east / up): beams within
// the cone in azimuth and lo..hi off P's direction in elevation whose return lies within
// max(2 sigma, d * gap) of d, a surface at most 45 degrees from facing the ray (edgesOf's and
// ringsReturnAt's reach). kAbove where one lies above P's direction, kBelow where one lies below.
uint8_t MovingTest::ringsAtRange(const Eigen::Vector3f& dir, float d, const Eigen::Vector3f& east,
                                 const Eigen::Vector3f& up, const WindowScan& s, float lo,
                                 float hi) const {
  const float tol =
      std::max(static_cast<float>(2.0 * model_.sigma), d * static_cast<float>(s.ring_gap));
  uint8_t at = 0;
  forEachInBand(*s.beams, dir, east, up, static_cast<float>(radius_), lo, hi,
                [&](const BeamIndex::Beam& q, float el) {
                  if (std::abs(q.range - d) <= tol) at |= el > 0.0f ? kAbove : kBelow;
                });
  return at;
}

// DESIGN §2b, "Coarse columns": the nearest return of P's ring 0.5-1.5 column steps to either
// side of P's direction (within half a ring step in elevation, or half a column step where the
// rings are not measured); P is isolated where both lie beyond it, or are missing.
bool MovingTest::columnIsolated(const Eigen::Vector3f& dir, float d, const Eigen::Vector3f& east,
                                const Eigen::Vector3f& up, const WindowScan& own) const {
  const auto step = static_cast<float>(own.column_step);
  const float el_half =
      0.5f * static_cast<float>(own.ring_gap > 0 ? own.ring_gap : own.column_step);
  constexpr float kNone = std::numeric_limits<float>::infinity();
  float a_left = kNone, a_right = kNone, r_left = kNone, r_right = kNone;
  own.beams->forEachNearBox(dir, 1.01 * 1.5 * step, 1.01 * el_half + 2e-4,
                            [&](const BeamIndex::Beam& q) {
                              const float a = q.dir.dot(east), el = q.dir.dot(up);
                              if (!(dir.dot(q.dir) > 0.0f) || std::abs(el) > el_half ||
                                  std::abs(a) < 0.5f * step || std::abs(a) > 1.5f * step)
                                return;
                              if (a > 0.0f && a < a_left) {
                                a_left = a;
                                r_left = q.range;
                              } else if (a < 0.0f && -a < a_right) {
                                a_right = -a;
                                r_right = q.range;
                              }
                            });
  const float tol = std::max(static_cast<float>(2.0 * model_.sigma), d * step);
  const float beyond_left = r_left - d, beyond_right = r_right - d;  // inf where missing
  return beyond_left > tol + std::max(0.0f, -beyond_right) &&
         beyond_right > tol + std::max(0.0f, -beyond_left);
}

// Issue #15 (DESIGN §2b, "Sparse lidars"). A sparse scan's rings lie further apart than the cone,
// so most of its scans hold no beam near P's direction and vote unknown, and a small mover is
// found by few of them. Where the ring just above P and the ring just below (within the cone in
// azimuth, 1.5 ring steps in elevation) both pass beyond P, an object at P would have to fit
// between them: the scan votes empty, as a beam through P would (Eq. 5 at theta = 0, the smaller
// Phi(-r / sigma) of the two). It does not where a return of the scan lies near P: within a ring
// step in azimuth and 1.5 in elevation (widened by the pose error), from 1 m in front of P to
// max(2 sigma, d * gap) beyond it. Such a return may be the surface P lies on, seen grazing (a
// car's roof: both rings pass over it, the next one down meets it in front of P) or through
// glass, or its edge: those were the false alarms of the plain rule (doc/BENCHMARK.md).
// With estimated poses both rings must also pass P by 1 m: a sparse scan's GICP pose was measured
// 0.5 m off between neighbouring scans, far beyond registration.relative_error's model.
double MovingTest::ringVote(const Eigen::Vector3f& dir, float d, const WindowScan& s) const {
  Eigen::Vector3f east, up;
  if (!acrossAxes(dir, east, up)) return 0.0;
  const auto gap = static_cast<float>(s.ring_gap);
  const auto noise = static_cast<float>(std::sqrt(s.pose_noise2));
  const float sigma = static_cast<float>(std::sqrt(model_.sigma * model_.sigma + s.pose_noise2));
  const float widen = static_cast<float>(p_.search_lambdas) * noise / d;  // the pose error's angle
  const float near_behind = std::max(static_cast<float>(2.0 * model_.sigma), d * gap) + noise;
  const float near_front = std::max(near_behind, kRingFront + noise);
  const float el_band = 1.5f * gap + widen;
  auto offset = [&](const BeamIndex::Beam& q) {  // r = |OP'| - |OQ|, as scanMassAt's
    return d * std::sqrt(1.0f - dir.cross(q.dir).squaredNorm()) - q.range;
  };
  auto is_near = [&](float r) { return r >= -near_behind && r <= near_front; };
  // The rings around P first (the cone's width in azimuth): most static points end here, the
  // rings meeting P's surface. Then the rest of the neighbourhood, a ring step to either side.
  float el_above = 2.0f, r_above = 0.0f, el_below = -2.0f, r_below = 0.0f;
  bool near = false;
  forEachInBand(*s.beams, dir, east, up, static_cast<float>(radius_), 0.0f, el_band,
                [&](const BeamIndex::Beam& q, float el) {
                  const float r = offset(q);
                  near = near || is_near(r);
                  if (el > 0.0f && el < el_above) {
                    el_above = el;
                    r_above = r;
                  } else if (el <= 0.0f && el > el_below) {
                    el_below = el;
                    r_below = r;
                  }
                });
  const float pass = s.pose_noise2 > 0 ? std::max(2.0f * sigma, kRingFront) : 2.0f * sigma;
  if (near || el_above > 1.0f || el_below < -1.0f || !(r_above < -pass && r_below < -pass))
    return 0.0;
  forEachInBand(*s.beams, dir, east, up, gap + widen, 0.0f, el_band,
                [&](const BeamIndex::Beam& q, float) { near = near || is_near(offset(q)); });
  if (near) return 0.0;
  return ds::Phi(-std::max(r_above, r_below) / sigma);
}

ds::Mass MovingTest::scanMassAt(const Eigen::Vector3d& pl, double d, const WindowScan& s,
                                MovingTestStats* stats, uint8_t edges) const {
  ds::Mass m;
  if (edges & kColumnIsolated) return m;  // DESIGN §2b, "Coarse columns": no vote
  const Eigen::Vector3f dir = (pl / d).cast<float>();
  // Issue #15: on an edge's open side (edgesOf) a beam passing P may pass over the edge; such
  // beams are left out.
  Eigen::Vector3f east_e, up_e;
  const bool on_flat = (edges & kFlatSurface) != 0;
  edges &= kTopEdge | kBottomEdge;
  if (edges && !acrossAxes(dir, east_e, up_e)) edges = 0;
  const bool drop_above = (edges & kTopEdge) != 0, drop_below = (edges & kBottomEdge) != 0;
  auto open_side = [&](const Eigen::Vector3f& q_dir) {
    const float el = q_dir.dot(up_e);
    return (drop_above && el > 0.0f) || (drop_below && el < 0.0f);
  };
  // The cone: search_lambdas * lambda_theta. DESIGN §2b, "Coarse columns' beams spread over their
  // step": a scan whose columns lie further apart than the cone (an Ouster at 512 columns, 0.70
  // degrees) has its nearest beams up to half a column step from P's direction; its beams spread
  // over kColumnSpread of a column step, so that the nearest weigh as a dense lidar's do
  // (f_theta of Eq. 3).
  const double spread = std::max(p_.lambda_theta, kColumnSpread * s.column_step);
  std::optional<ds::BeamModel> coarse;
  if (spread > p_.lambda_theta) {
    coarse = model_;
    coarse->inv_two_lambda2 = 1.0 / (2.0 * spread * spread);
    coarse->f_inv_two_lambda2 = static_cast<float>(coarse->inv_two_lambda2);
  }
  const ds::BeamModel& model = coarse ? *coarse : model_;
  const double radius = p_.search_lambdas * spread;  // radius_ where the columns are dense
  const float r2max = static_cast<float>(radius * radius);
  const float df = static_cast<float>(d), r_far = static_cast<float>(r_far_);
  // Dempster's rule over the beams (Eq. 6) in product form: on {empty, occupied} the
  // commonalities multiply, Q(E) = prod(1 - o), Q(O) = prod(1 - e), Q(Theta) = prod(u), and the
  // normalised result is e = (Q(E) - Q(Theta)) / N, o = (Q(O) - Q(Theta)) / N, u = Q(Theta) / N,
  // N = Q(E) + Q(O) - Q(Theta) = 1 - K. Equal to the pairwise rule, without its division per beam.
  double qe = 1.0, qo = 1.0, qu = 1.0;
  float e_max = 0.0f, o_max = 0.0f;  // the scan's most-empty beam, most-occupied return at P
  const float band = static_cast<float>(2.0 * model_.sigma);  // not an occluder in front of P
  // Whether a beam passed P by more than the range noise (doc/SCAN_CONFLICT.md, "A return at P").
  const float past = -static_cast<float>(p_.sigma_m);
  bool passed = false;
  std::size_t beams = 0;
  // The beams in the cone are gathered kBatch at a time; their masses are then computed side by
  // side (BeamModel::massesFast) and multiplied in, in the order the index gave them.
  constexpr int kBatch = ds::BeamModel::kBatch;
  alignas(64) float r_b[kBatch] = {}, t2_b[kBatch] = {}, e_b[kBatch], o_b[kBatch];
  int n = 0;
  auto flush = [&] {
    if (math_ == BeamMath::kFast)
      model.massesFast(r_b, t2_b, n, e_b, o_b);
    else
      model.massesReference(r_b, t2_b, n, e_b, o_b);
    // In registers: the products are chains from beam to beam, and through memory (the
    // captures) each step waited for a store (issue #16). Same order, same bits.
    double pe = qe, po = qo, pu = qu;
    float em = e_max, om = o_max;
    bool ps = passed;
    for (int k = 0; k < n; ++k) {
      em = std::max(em, e_b[k]);
      if (r_b[k] <= band) om = std::max(om, o_b[k]);  // a return at P's range
      ps = ps || r_b[k] < past;
      const double e = e_b[k], o = o_b[k];
      pe *= 1.0 - o;
      po *= 1.0 - e;
      pu *= 1.0 - e - o;
    }
    qe = pe;
    qo = po;
    qu = pu;
    e_max = em;
    o_max = om;
    passed = ps;
    beams += static_cast<std::size_t>(n);
    n = 0;
  };
  // DESIGN §2b, grazing beams: where P lies on a flat surface of its own scan (kFlatSurface), a
  // beam that passes P (by more than sigma_m, as `passed`) within the stretch where it runs
  // within margin of a flat surface of its own scan (GrazingStretches) votes nothing: it may pass
  // over or meet, at a grazing angle, the surface P lies on, as the clean map's free space (§2e)
  // has it. Those meeting it within 2 sigma beyond P too: each leans empty (Eq. 3).
  const BeamIndex& index = *s.beams;
  const uint32_t* graze = on_flat && !index.grazing().empty() ? index.grazing().data() : nullptr;
  const float inv_unit = 1.0f / index.rangeUnit();
  auto grazes = [&](const BeamIndex::PackedBeam* q, float r) {
    if (!graze || !(r < past)) return false;
    const uint32_t g = graze[q - index.beams().data()];
    const float t = r * inv_unit + static_cast<float>(q->range);  // |OP'|, in range units
    return t >= static_cast<float>(g & 0xFFFFu) && t <= static_cast<float>(g >> 16);
  };
  // A beam's angle to P (theta^2) and r = |OP'| - |OQ| (the scalar expressions; filterBeams has
  // the same bits). Small angles: theta = |a x b| to float precision (a dot product would lose
  // it); theta2 <= 1, so the root is real for every beam.
  auto geometry = [&](const BeamIndex::Beam& q, float& theta2, float& r) {
    theta2 = dir.cross(q.dir).squaredNorm();
    r = df * std::sqrt(1.0f - theta2) - q.range;
  };
  auto filter = [&](const BeamIndex::Beam& q, const BeamIndex::PackedBeam* packed) {
    float theta2, r;
    geometry(q, theta2, r);
    // In the cone, in front of the sensor, and not far behind the hit (there a beam is unknown,
    // the identity of Dempster's rule). About half the beams of the bins pass, unpredictably:
    // each is written and kept by a count, not a branch.
    const unsigned keep = unsigned(theta2 <= r2max) & unsigned(dir.dot(q.dir) > 0.0f) &
                          unsigned(r <= r_far) & unsigned(!(edges && open_side(q.dir))) &
                          unsigned(!grazes(packed, r));
    r_b[n] = r;
    t2_b[n] = theta2;
    n += keep;
    if (n == kBatch) flush();
  };
  if (math_ == BeamMath::kFast) {
    // The same filter in vector lanes (beam_filter.cpp, the same bits); the kept ones are then
    // gathered in order by a count, as above.
    forEachFilteredRun(index, dir, radius, df, r2max, r_far,
                       [&](const BeamIndex::PackedBeam* q, int run, const float* r_run,
                           const float* t2_run, int32_t* keep_run) {
                         if (edges)
                           for (int k = 0; k < run; ++k)
                             keep_run[k] &= open_side(index.decode(q[k]).dir) ? 0 : 1;
                         if (graze)
                           for (int k = 0; k < run; ++k)
                             keep_run[k] &= grazes(q + k, r_run[k]) ? 0 : 1;
                         for (int k = 0; k < run; ++k) {
                           r_b[n] = r_run[k];
                           t2_b[n] = t2_run[k];
                           n += keep_run[k];
                           if (n == kBatch) flush();
                         }
                       });
  } else {
    index.forEachRunNear(dir, radius,
                         [&](const BeamIndex::PackedBeam* q, const BeamIndex::PackedBeam* last) {
                           for (; q != last; ++q) filter(index.decode(*q), q);
                         });
  }
  if (n > 0) flush();
  const double norm = qe + qo - qu;
  const bool conflict = beams > 0 && norm <= 1e-12;  // K = 1: unknown, as ds::combine
  if (beams > 0 && !conflict) {
    const double inv = 1.0 / norm;
    m.e = (qe - qu) * inv;
    m.o = (qo - qu) * inv;
    m.u = qu * inv;
  }
  // Issue #15: a sparse scan whose cone decides nothing (no return near P, empty not the largest
  // mass) votes through its rings (ringVote), unless P's own scan ends at P on both sides (an
  // isolated ring point: a thin bar, whose vote the rings cannot give). The checks below look
  // at returns near P, which ringVote has already ruled out.
  bool ring = false;
  if (p_.ring_vote && s.ring_gap > radius_ && m.o < 0.05 && !(m.e > m.u) &&
      edges != (kTopEdge | kBottomEdge)) {
    const double e = ringVote(dir, df, s);
    if (e > 0.0) {
      m = ds::Mass{e, 0.0, 1.0 - e};
      ring = true;
      if (stats) ++stats->ring_votes;
    }
  }
  // doc/SCAN_CONFLICT.md, "A return at P": an empty vote needs a beam that passed P by more than
  // the range noise sigma_m. Beams returning within it give e' and o' near 0.5 each (Eq. 3-5 at
  // r = 0), and the discretisation (Eq. 8-10) would turn the noise's lean into a full vote.
  if (!ring && p_.scan_conflict < 1.0 && m.e > m.o && m.e > m.u && !passed) {
    m = ds::Mass{};
    if (stats) ++stats->conflicting_scans;
  }
  // doc/SCAN_CONFLICT.md: an empty vote needs a scan whose beams agree. Beams that pass P and
  // beams that return at P's range (|r| <= 2 sigma) in the same scan mean a porous or thin
  // surface (foliage, a fence, a pole), not a vacated space; Dempster's normalisation would hide
  // that conflict.
  // Issue #11: where the scan's pose relative to P's is uncertain (estimated poses), a return at
  // P's range within that error is the surface P lies on, displaced by it (a pole 5 m away is
  // missed by 2 cm of error): the check looks for returns within search_lambdas *
  // sqrt(spread^2 + (noise / d)^2), spread the masses' (lambda_theta, or a coarse scan's), a
  // cone that widens only near the sensor; its returns weigh as the masses' (`model`). The masses
  // keep their cone, so this only takes empty votes away.
  if (!ring && p_.scan_conflict < 1.0 && s.pose_noise2 > 0 && m.e > m.o && m.e > m.u &&
      static_cast<double>(e_max) * o_max < p_.scan_conflict) {
    const double wide = p_.search_lambdas * std::sqrt(spread * spread + s.pose_noise2 / (d * d));
    const float r2w = static_cast<float>(wide * wide);
    if (math_ == BeamMath::kFast) {
      // The same beams through filterBeams (r <= band there, r >= -band here), until the
      // conflict is found: o_max only grows, so the rest cannot change the outcome.
      forEachFilteredRun(
          index, dir, wide, df, r2w, band,
          [&](const BeamIndex::PackedBeam*, int run, const float* r_run, const float* t2_run,
              const int32_t* keep_run) {
            for (int k = 0; k < run; ++k)
              if (keep_run[k] && r_run[k] >= -band)
                o_max = std::max(o_max, static_cast<float>(model.beamFloat(r_run[k], t2_run[k]).o));
            return static_cast<double>(e_max) * o_max < p_.scan_conflict;
          });
    } else {
      s.beams->forEachNear(dir, wide, [&](const BeamIndex::Beam& q) {
        float theta2, r;
        geometry(q, theta2, r);
        if (theta2 <= r2w && dir.dot(q.dir) > 0.0f && std::abs(r) <= band)
          o_max = std::max(o_max, static_cast<float>(model.beamFloat(r, theta2).o));
      });
    }
  }
  // Issue #15: a sparse lidar's rings lie further apart than the cone, so a beam that passes just
  // over an object's top edge (or under a bumper) has no neighbour in the cone that returns from
  // the object, and its scan would vote empty at every static edge point. The check also looks
  // at the rings just above and below: returns at P's range within the cone in azimuth and
  // within one ring step in elevation. Dense lidars (rings closer than the cone: the HDL-64E,
  // KITTI) are unchanged.
  if (!ring && p_.scan_conflict < 1.0 && s.ring_gap > radius_ && m.e > m.o && m.e > m.u &&
      static_cast<double>(e_max) * o_max < p_.scan_conflict) {
    Eigen::Vector3f east, up;
    if (acrossAxes(dir, east, up))
      forEachInBand(*s.beams, dir, east, up, static_cast<float>(radius), 0.0f,
                    static_cast<float>(s.ring_gap), [&](const BeamIndex::Beam& q, float) {
                      float theta2, r;
                      geometry(q, theta2, r);
                      if (std::abs(r) <= band)
                        o_max = std::max(o_max, static_cast<float>(model.beamFloat(r, theta2).o));
                    });
  }
  if (!ring && p_.scan_conflict < 1.0 && m.e > m.o && m.e > m.u &&
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

namespace {

// A buffer of n values, in place up to N (windows are 2K + 1 scans), on the heap beyond: the
// test's per-point scratch, without an allocation per point.
template <class T, std::size_t N = 64>
class SmallBuffer {
 public:
  explicit SmallBuffer(std::size_t n) {
    if (n > N) heap_.resize(n);
    data_ = n > N ? heap_.data() : inline_.data();
  }
  SmallBuffer(const SmallBuffer&) = delete;
  SmallBuffer& operator=(const SmallBuffer&) = delete;
  T* data() { return data_; }
  T& operator[](std::size_t i) { return data_[i]; }

 private:
  std::array<T, N> inline_;
  std::vector<T> heap_;
  T* data_;
};

// Sorts a[0, n) by key, largest first, ties kept in order: an insertion sort (windows are short;
// std::stable_sort may take a buffer from the heap, once per tested point).
template <class T, class Key>
void sortDescending(T* a, std::size_t n, Key&& key) {
  for (std::size_t i = 1; i < n; ++i) {
    const T v = a[i];
    std::size_t j = i;
    for (; j > 0 && key(a[j - 1]) < key(v); --j) a[j] = a[j - 1];
    a[j] = v;
  }
}

}  // namespace

MovingTest::ScanView MovingTest::view(const Eigen::Vector3d& p_world, const WindowScan& s) const {
  ScanView v;
  v.pl = s.world_to_sensor * p_world;
  v.d = v.pl.norm();
  v.seen = s.beams && !s.beams->empty() && v.d >= 1e-3;
  v.ratio = ds::rangeRatio(v.d, v.seen ? s.beams->farthest() : 0.0);
  return v;
}

// A seen scan's mass at P discretised by l at P's range ratio (Eq. 8-10): its vote.
ds::Mass MovingTest::discreteMass(const ScanView& v, const WindowScan& s, MovingTestStats* stats,
                                  uint8_t edges) const {
  if (stats) ++stats->scans_visited;
  return ds::discretise(scanMassAt(v.pl, v.d, s, stats, edges), ds::beliefAtRatio(v.ratio, p_));
}

// The discretised votes are simple supports of mass l on {empty} or {occupied}. Combined, the
// empty votes give E = 1 - prod(1 - l) and the occupied ones O likewise, and the result is moving
// iff E > O (empty then also beats unknown, as l > 0.5). So the decision is a weighted vote:
// S_e = sum of -ln(1 - l) over empty votes against S_o over occupied ones, and scan i can add at
// most w_i = -ln(1 - l_i), its l known from P's range before any beam is looked at (w_bound_
// tabulates an upper bound of it). Once |S_e - S_o| exceeds the sum of the unvisited scans' w_i,
// the decision is final; the scans are visited heaviest first, so that sum shrinks fastest
// (issue #16). Otherwise the result is Dempster's rule over the whole window, so a point close to
// a tie is decided exactly as without the shortcut.
std::optional<bool> MovingTest::combineWindow(const Eigen::Vector3d& p_world,
                                              const std::vector<WindowScan>& window,
                                              MovingTestStats* stats, bool stop_early,
                                              ds::Mass& acc, uint8_t edges, int8_t* votes) const {
  if (stats) ++stats->points;
  constexpr double kSafety = 1e-6;  // far above the rounding of the sums
  struct Visit {
    ScanView v;
    double w;  // the bound of the scan's vote weight
    std::size_t i;
  };
  SmallBuffer<Visit> visits(window.size());
  double rest = kSafety;
  for (std::size_t i = 0; i < window.size(); ++i) {
    const ScanView v = view(p_world, window[i]);
    const double w = v.seen ? w_bound_[static_cast<std::size_t>(v.ratio * kWeightCells)] : 0.0;
    visits[i] = {v, w, i};
    rest += w;
  }
  if (stop_early)  // heaviest first, ties in window order
    sortDescending(visits.data(), window.size(), [](const Visit& v) { return v.w; });
  acc = ds::Mass{};
  bool any = false, conflict = false;
  double lead = 0.0;  // S_e - S_o
  for (std::size_t k = 0; k < window.size(); ++k) {
    if (stop_early && (lead > rest || -lead > rest)) {  // votes were cast
      if (stats) ++stats->early;
      return lead > 0;
    }
    const Visit& v = visits[k];
    rest -= v.w;
    if (v.w == 0.0) {  // no beams, or P at the sensor: unknown
      if (votes) votes[v.i] = kUnknown;
      continue;
    }
    const ds::Mass dm = discreteMass(v.v, window[v.i], stats, edges);
    if (votes) votes[v.i] = voteOf(dm);
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
                          MovingTestStats* stats, uint8_t edges, bool empty_run,
                          bool* by_run) const {
  ds::Mass acc;
  if (by_run) *by_run = false;
  if (!empty_run || p_.empty_run <= 0) {
    if (const auto early = combineWindow(p_world, window, stats, true, acc, edges)) return *early;
    return ds::isMoving(acc);
  }
  SmallBuffer<int8_t> votes(window.size());
  std::fill(votes.data(), votes.data() + window.size(), kNotCast);
  const auto early = combineWindow(p_world, window, stats, true, acc, edges, votes.data());
  if (early ? *early : ds::isMoving(acc)) return true;
  const bool run = emptyRun(p_world, window, votes.data(), stats, edges);
  if (by_run) *by_run = run;
  return run;
}

bool MovingTest::hasEmptyRun(const Eigen::Vector3d& p_world, const std::vector<WindowScan>& window,
                             MovingTestStats* stats, uint8_t edges) const {
  if (p_.empty_run <= 0) return false;
  SmallBuffer<int8_t> votes(window.size());
  std::fill(votes.data(), votes.data() + window.size(), kNotCast);
  return emptyRun(p_world, window, votes.data(), stats, edges);
}

int8_t MovingTest::vote(const Eigen::Vector3d& p_world, const WindowScan& s, MovingTestStats* stats,
                        uint8_t edges) const {
  const ScanView v = view(p_world, s);
  return v.seen ? voteOf(discreteMass(v, s, stats, edges)) : kUnknown;  // as combineWindow
}

// DESIGN §2b, "Empty runs". Each side of the window is read from the scan furthest in time
// towards P's own; the votes combineWindow did not cast are cast here, until the run is long
// enough, meets an occupied vote, or cannot be long enough with the scans left.
bool MovingTest::emptyRun(const Eigen::Vector3d& p_world, const std::vector<WindowScan>& window,
                          int8_t* votes, MovingTestStats* stats, uint8_t edges) const {
  std::size_t before = 0, after = 0;
  for (const WindowScan& s : window) {
    before += s.offset < 0;
    after += s.offset > 0;
  }
  const auto need = static_cast<std::size_t>(
      std::max(1.0, std::ceil(p_.empty_run * static_cast<double>(std::max(before, after)) - 1e-9)));
  SmallBuffer<uint32_t> order(window.size());
  for (const int side : {-1, 1}) {
    const std::size_t n = side < 0 ? before : after;
    if (n < need) continue;
    // An occupied vote already cast with fewer than `need` scans further out ends every run
    // before it is long enough: most static points, at no extra visit (issue #16).
    int o_far = 0;
    for (std::size_t i = 0; i < window.size(); ++i)
      if (votes[i] == kOccupied) o_far = std::max(o_far, window[i].offset * side);
    std::size_t further = 0;
    for (const WindowScan& w : window) further += w.offset * side > o_far;
    if (o_far > 0 && further < need) continue;
    // This side's scans, furthest first; of scans sharing an offset the first counts.
    std::size_t m = 0;
    for (std::size_t i = 0; i < window.size(); ++i)
      if (window[i].offset * side > 0) order[m++] = static_cast<uint32_t>(i);
    const auto away = [&](uint32_t i) { return window[i].offset * side; };
    sortDescending(order.data(), m, away);
    m = static_cast<std::size_t>(
        std::unique(order.data(), order.data() + m,
                    [&](uint32_t a, uint32_t b) { return away(a) == away(b); }) -
        order.data());
    std::size_t run = 0;
    for (std::size_t k = 0; k < m && run + (m - k) >= need; ++k) {
      const uint32_t i = order[k];
      if (votes[i] == kNotCast) votes[i] = vote(p_world, window[i], stats, edges);
      if (votes[i] == kOccupied) break;
      if (votes[i] == kEmpty && ++run >= need) return true;
    }
  }
  return false;
}

}  // namespace cleanmap
