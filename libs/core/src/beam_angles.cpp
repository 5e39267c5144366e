// SPDX-License-Identifier: BSD-3-Clause
// Compiled with -fno-trapping-math (the selects become vector blends) and -ffp-contract=off (every
// instruction set gives the same bits), as beam_masses.cpp.
#include "beam_angles.h"

#include "cleanmap/core/fast_math.h"
#include "per_isa.h"

namespace cleanmap::detail {

// One clone per instruction set (per_isa.h).
CLEANMAP_PER_ISA void approxAngles(const float* __restrict dx, const float* __restrict dy,
                                   const float* __restrict dz, std::size_t n, float* __restrict el,
                                   float* __restrict az) {
  for (std::size_t i = 0; i < n; ++i) {
    const float z = dz[i] < -1.0f ? -1.0f : (dz[i] > 1.0f ? 1.0f : dz[i]);
    el[i] = fast::asin(z);
    az[i] = fast::atan2(dy[i], dx[i]);
  }
}

}  // namespace cleanmap::detail
