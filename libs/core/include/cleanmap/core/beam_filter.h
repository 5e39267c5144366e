// SPDX-License-Identifier: BSD-3-Clause
// The moving test's per-beam cone filter over a run of beams (issue #16), in its own file for its
// compile options.
#pragma once
#include <cstdint>

#include "cleanmap/core/beam_index.h"

namespace cleanmap::detail {

/// For the m packed beams at `beams`, decoded as BeamIndex::decode does (direction q, range in
/// steps of `range_unit`), and the unit direction (dx, dy, dz) of P at range df: theta2 = |dir x
/// q|^2, r = df sqrt(1 - theta2) - range, keep = theta2 <= r2max, dir . q > 0 and r <= r_far. The
/// same operations in the same order as Eigen's cross / squaredNorm / dot (a0 b0 + (a1 b1 + a2
/// b2)), without contraction, so the bits are those of the scalar code (tested).
void filterBeams(const BeamIndex::PackedBeam* beams, int m, float range_unit, float dx, float dy,
                 float dz, float df, float r2max, float r_far, float* r, float* theta2,
                 int32_t* keep);

}  // namespace cleanmap::detail
