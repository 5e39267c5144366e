// SPDX-License-Identifier: BSD-3-Clause
// BeamModel::massesFast on its own: this file is compiled with -fno-trapping-math (the project
// never traps on floating-point exceptions), which lets the compiler turn the selects of the loop
// into vector blends, and -ffp-contract=off, so that every instruction set gives the same bits.
#include "cleanmap/core/dempster_shafer.h"
#include "cleanmap/core/fast_math.h"
#include "per_isa.h"

namespace cleanmap::ds {

namespace {

// N beams, N fixed: one loop without a remainder, all lanes busy.
template <int N>
inline void masses(const BeamModel& m, const float* __restrict r, const float* __restrict theta2,
                   float* __restrict e, float* __restrict o) {
  constexpr float kTail = 5.5f * static_cast<float>(M_SQRT1_2);  // as beamFloat
  for (int k = 0; k < N; ++k) {
    const float f_theta = fast::expNeg(-theta2[k] * m.f_inv_two_lambda2);
    const float x = r[k] * m.f_inv_sigma_sqrt2;
    const float g = fast::expNeg(-r[k] * r[k] * m.f_inv_two_s1) * m.f_inv_sqrt_s1;
    const float e_mid = f_theta * 0.5f * fast::erfc(x);
    const float o_mid = g * 0.5f * fast::erfc(-x * m.f_inv_sqrt_s1);
    e[k] = x < -kTail ? f_theta : (x > kTail ? 0.0f : e_mid);
    o[k] = x < -kTail ? 0.0f : (x > kTail ? g : o_mid);
  }
}

}  // namespace

// One clone per instruction set (per_isa.h).
CLEANMAP_PER_ISA void BeamModel::massesFast(const float* __restrict r,
                                            const float* __restrict theta2, int n,
                                            float* __restrict e, float* __restrict o) const {
  if (n <= 4)
    masses<4>(*this, r, theta2, e, o);
  else if (n <= 8)
    masses<8>(*this, r, theta2, e, o);
  else
    masses<kBatch>(*this, r, theta2, e, o);
}

}  // namespace cleanmap::ds
