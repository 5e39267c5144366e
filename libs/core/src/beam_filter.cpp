// SPDX-License-Identifier: BSD-3-Clause
// Compiled with -ffp-contract=off (no fused multiply-add, so every instruction set gives the bits
// of the scalar expressions), -fno-trapping-math and -fno-math-errno (the square root and the
// comparisons vectorise), as beam_angles.cpp.
#include "cleanmap/core/beam_filter.h"
#include "per_isa.h"

#include <cmath>

namespace cleanmap::detail {

// One clone per instruction set (per_isa.h).
CLEANMAP_PER_ISA void filterBeams(const float* __restrict beams, int m, float dx, float dy,
                                  float dz, float df, float r2max, float r_far, float* __restrict r,
                                  float* __restrict theta2, int32_t* __restrict keep) {
  for (int k = 0; k < m; ++k) {
    const float* q = beams + 4 * k;
    const float cx = dy * q[2] - dz * q[1], cy = dz * q[0] - dx * q[2], cz = dx * q[1] - dy * q[0];
    const float t2 = cx * cx + (cy * cy + cz * cz);
    const float rr = df * std::sqrt(1.0f - t2) - q[3];
    const float dot = dx * q[0] + (dy * q[1] + dz * q[2]);
    r[k] = rr;
    theta2[k] = t2;
    keep[k] = (t2 <= r2max) & (dot > 0.0f) & (rr <= r_far);
  }
}

}  // namespace cleanmap::detail
