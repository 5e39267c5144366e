// SPDX-License-Identifier: BSD-3-Clause
// Branch-free single-precision exp and erfc for the beam masses of the moving-point test
// (issue #16): plain arithmetic and selects only, so a loop over a batch of beams compiles to
// vector instructions (SSE2 on any x86-64) and gives the same bits on every machine. Their
// errors are bounded below and checked against the double-precision functions by the FastMath
// tests (tests/unit/fast_math_test.cpp).
#pragma once
#include <cstdint>
#include <cstring>

namespace cleanmap::fast {

/// e^x for x <= 0 (arguments below -87 give e^-87 ~ 1.6e-38, i.e. 0 for a mass). Cody-Waite
/// reduction x = n ln2 + g, |g| <= ln2 / 2, with Cephes' degree-7 expf polynomial for e^g:
/// relative error below 1e-7 (8.2e-8, every float in [-87, 0] checked).
inline float expNeg(float x) {
  x = x < -87.0f ? -87.0f : x;
  constexpr float kRound = 12582912.0f;  // 1.5 * 2^23: adding it rounds to an integer
  const float n = (x * 1.44269504088896341f + kRound) - kRound;
  const float g = (x - n * 0.693359375f) - n * -2.12194440e-4f;  // ln2 in two parts
  const float z = g * g;
  const float p = ((((((1.9875691500e-4f * g + 1.3981999507e-3f) * g + 8.3334519073e-3f) * g +
                      4.1665795894e-2f) *
                         g +
                     1.6666665459e-1f) *
                        g +
                    5.0000001201e-1f) *
                       z +
                   g) +
                  1.0f;
  const int32_t bits = (static_cast<int32_t>(n) + 127) * (1 << 23);  // 2^n, n in [-126, 0]
  float scale;
  std::memcpy(&scale, &bits, sizeof scale);
  return p * scale;
}

/// erfc(x) for |x| <= 9: the Chebyshev fit of Numerical Recipes (2nd ed., section 6.2),
/// erfc(z) = t exp(-z^2 + P(t)), t = 1 / (1 + z / 2), z = |x|, relative error below 1.2e-7 in
/// exact arithmetic; erfc(-z) = 2 - erfc(z). In float: absolute error below 6e-7 (5.2e-7, every
/// float in [-9, 9] checked), relative below 2e-6 for |x| <= 4.
inline float erfc(float x) {
  const float z = x < 0.0f ? -x : x;
  const float t = 1.0f / (1.0f + 0.5f * z);
  const float poly =
      -1.26551223f +
      t * (1.00002368f +
           t * (0.37409196f +
                t * (0.09678418f +
                     t * (-0.18628806f +
                          t * (0.27886807f +
                               t * (-1.13520398f +
                                    t * (1.48851587f + t * (-0.82215223f + t * 0.17087277f))))))));
  const float r = t * expNeg(-z * z + poly);
  return x < 0.0f ? 2.0f - r : r;
}

}  // namespace cleanmap::fast
