// SPDX-License-Identifier: BSD-3-Clause
// Branch-free single-precision exp and erfc for the beam masses of the moving-point test, asin
// and atan2 for the beam index (issue #16): plain arithmetic and selects only, so a loop over a
// batch compiles to vector instructions (SSE2 on any x86-64) and gives the same bits on every
// machine. Their errors are bounded below and checked against the double-precision functions by
// the FastMath tests (tests/unit/beam_math_test.cpp).
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

/// asin(s) for s in [-1, 1]: Cephes' asinf, asin(a) = pi/2 - 2 asin(sqrt((1 - a) / 2)) above
/// a = 0.5, a degree-4 polynomial in s^2 below. Absolute error below 2e-7 rad (1.7e-7 over 20
/// million evenly spaced floats).
inline float asin(float s) {
  const float a = s < 0.0f ? -s : s;
  const bool big = a > 0.5f;
  const float z = big ? 0.5f * (1.0f - a) : a * a;
  const float x = big ? __builtin_sqrtf(z) : a;
  float p =
      ((((4.2163199048e-2f * z + 2.4181311049e-2f) * z + 4.5470025998e-2f) * z + 7.4953002686e-2f) *
           z +
       1.6666752422e-1f) *
          z * x +
      x;
  p = big ? 1.57079632679489662f - 2.0f * p : p;
  return s < 0.0f ? -p : p;
}

/// atan2(y, x) in (-pi, pi]: Cephes' atanf of min / max of |x|, |y| (reduced to |t| <= tan(pi/8)),
/// then the octant. Absolute error below 3e-7 rad (2.8e-7 over 20 million directions). The sign
/// of a zero y is not kept (atan2(-0, x < 0) gives pi, libm -pi).
inline float atan2(float y, float x) {
  const float ax = x < 0.0f ? -x : x, ay = y < 0.0f ? -y : y;
  const float mx = ax > ay ? ax : ay, mn = ax > ay ? ay : ax;
  const float a = mn / (mx > 0.0f ? mx : 1.0f);  // [0, 1]
  const bool big = a > 0.41421356237f;
  const float t = big ? (a - 1.0f) / (a + 1.0f) : a;
  const float z = t * t;
  float r = (((8.05374449538e-2f * z - 1.38776856032e-1f) * z + 1.99777106478e-1f) * z -
             3.33329491539e-1f) *
                z * t +
            t;
  r = big ? r + 0.78539816339744831f : r;
  r = ay > ax ? 1.57079632679489662f - r : r;
  r = x < 0.0f ? 3.14159265358979324f - r : r;
  return y < 0.0f ? -r : r;
}

/// The bin of a coordinate t >= 0 (in bins) computed from these approximations: its integer part,
/// or exact() (the libm computation of the same bin) where t lies within `tol` of a bin edge, where
/// the approximation's error could put it on the other side. A t just below 0 has a negative
/// fraction, so exact() too. `tol` must exceed the error in bin units.
template <class T, class Exact>
inline auto binOrExact(T t, T tol, Exact&& exact) -> decltype(exact()) {
  using Bin = decltype(exact());
  const Bin b = static_cast<Bin>(t);
  const T f = t - static_cast<T>(b);
  return f < tol || f > 1 - tol ? exact() : b;
}

}  // namespace cleanmap::fast
