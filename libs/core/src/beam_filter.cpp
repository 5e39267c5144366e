// SPDX-License-Identifier: BSD-3-Clause
// Compiled with -ffp-contract=off (no fused multiply-add, so every instruction set gives the bits
// of the scalar expressions), -fno-trapping-math and -fno-math-errno (the square root and the
// comparisons vectorise), as beam_angles.cpp.
#include "cleanmap/core/beam_filter.h"
#include "per_isa.h"

#include <cmath>

namespace cleanmap::detail {

// One clone per instruction set (per_isa.h).
CLEANMAP_PER_ISA void filterBeams(const BeamIndex::PackedBeam* __restrict beams, int m,
                                  float range_unit, float dx, float dy, float dz, float df,
                                  float r2max, float r_far, float* __restrict r,
                                  float* __restrict theta2, int32_t* __restrict keep) {
  // Decoding multiplies a component by kDirUnit, a power of two: dy * (c * kDirUnit) and
  // (dy * kDirUnit) * c are the same float, so P's direction is scaled once instead.
  constexpr float u = BeamIndex::kDirUnit;
  dx *= u;
  dy *= u;
  dz *= u;
  for (int k = 0; k < m; ++k) {
    const BeamIndex::PackedBeam& b = beams[k];
    const float q0 = b.x, q1 = b.y, q2 = b.z, range = b.range * range_unit;
    const float cx = dy * q2 - dz * q1, cy = dz * q0 - dx * q2, cz = dx * q1 - dy * q0;
    const float t2 = cx * cx + (cy * cy + cz * cz);
    const float rr = df * std::sqrt(1.0f - t2) - range;
    const float dot = dx * q0 + (dy * q1 + dz * q2);
    r[k] = rr;
    theta2[k] = t2;
    keep[k] = (t2 <= r2max) & (dot > 0.0f) & (rr <= r_far);
  }
}

}  // namespace cleanmap::detail
