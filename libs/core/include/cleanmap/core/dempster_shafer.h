// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2b / paper §II-C: Dempster-Shafer occupancy of a point from lidar beams.
#pragma once
#include <algorithm>
#include <cmath>

#include "cleanmap/core/params.h"

namespace cleanmap::ds {

/// Masses over {empty, occupied}: e + o + u = 1, u = unknown ({empty, occupied}).
struct Mass {
  double e = 0.0, o = 0.0, u = 1.0;
};

inline double Phi(double x) {
  return 0.5 * std::erfc(-x / M_SQRT2);
}

/// Precomputed constants of the noise model F = N(0, sigma^2), sigma^2 = sigma_m^2 + sigma_r^2.
struct BeamModel {
  double sigma, s1, inv_sqrt_s1, inv_two_lambda2;
  // Single-precision copies for the per-beam hot loop (beamFloat).
  float f_inv_sigma_sqrt2, f_inv_sqrt_s1, f_inv_two_s1, f_inv_two_lambda2;
  explicit BeamModel(const DsParams& p)
      : sigma(std::sqrt(p.sigma_m * p.sigma_m + p.sigma_r * p.sigma_r)),
        s1(1.0 + sigma * sigma),
        inv_sqrt_s1(1.0 / std::sqrt(s1)),
        inv_two_lambda2(1.0 / (2.0 * p.lambda_theta * p.lambda_theta)),
        f_inv_sigma_sqrt2(static_cast<float>(1.0 / (sigma * M_SQRT2))),
        f_inv_sqrt_s1(static_cast<float>(inv_sqrt_s1)),
        f_inv_two_s1(static_cast<float>(1.0 / (2.0 * s1))),
        f_inv_two_lambda2(static_cast<float>(inv_two_lambda2)) {}

  /// m'(P, Q) for a beam at angle theta (rad) from O->P with r = |OP'| - |OQ| (m); Eq. (2)-(5)
  /// with the Gaussian-convolved closed forms:
  ///   e' = f_theta * Phi(-r / sigma)
  ///   o' = exp(-r^2 / (2 (1 + sigma^2))) / sqrt(1 + sigma^2) * Phi(r / (sigma sqrt(1 + sigma^2)))
  Mass beam(double r, double theta) const { return beamFromTheta2(r, theta * theta); }

  /// The same with theta^2 given. Past |r| > 8.5 sigma the Phi factors are 0 or 1 to below
  /// 1e-16 and are not evaluated (most beams of a window pass far in front of or behind P).
  Mass beamFromTheta2(double r, double theta2) const {
    constexpr double kTail = 8.5;
    const double f_theta = std::exp(-theta2 * inv_two_lambda2);
    const double z = r / sigma;
    Mass m;
    if (z < -kTail) {
      m.e = f_theta;
    } else if (z > kTail) {
      m.o = std::exp(-r * r / (2.0 * s1)) * inv_sqrt_s1;
    } else {
      m.e = f_theta * Phi(-z);
      m.o = std::exp(-r * r / (2.0 * s1)) * inv_sqrt_s1 * Phi(z * inv_sqrt_s1);
    }
    m.u = 1.0 - m.e - m.o;
    return m;
  }

  /// beamFromTheta2 in single precision (expf / erfcf): masses within ~1e-6 of the double
  /// version; used by the moving-point test, where it is most of the time.
  Mass beamFloat(float r, float theta2) const {
    // Past |z| = 5.5 the Phi factors are 0 or 1 to 2e-8, below single precision.
    constexpr float kTail = 5.5f * static_cast<float>(M_SQRT1_2);  // compared with z / sqrt(2)
    const float f_theta = std::exp(-theta2 * f_inv_two_lambda2);
    const float x = r * f_inv_sigma_sqrt2;  // z / sqrt(2)
    Mass m;
    if (x < -kTail) {
      m.e = f_theta;
    } else if (x > kTail) {
      m.o = std::exp(-r * r * f_inv_two_s1) * f_inv_sqrt_s1;
    } else {
      m.e = f_theta * 0.5f * std::erfc(x);
      m.o = std::exp(-r * r * f_inv_two_s1) * f_inv_sqrt_s1 * 0.5f * std::erfc(-x * f_inv_sqrt_s1);
    }
    m.u = 1.0 - m.e - m.o;
    return m;
  }

  static constexpr int kBatch = 16;  ///< beams per call of massesFast
  /// beamFloat's e and o for the first n <= kBatch beams, side by side, with the branch-free exp
  /// and erfc of fast_math.h: plain arithmetic and selects, so the loop runs on vector lanes
  /// (issue #16). It evaluates n rounded up to 4, 8 or 16 lanes: every array holds kBatch
  /// entries, and those past n are ignored. Masses within 2e-6 of beamFloat (FastMath tests).
  void massesFast(const float* __restrict r, const float* __restrict theta2, int n,
                  float* __restrict e, float* __restrict o) const;  // beam_masses.cpp
  /// The same with beamFloat (libm's expf and erfcf), one beam at a time: the reference.
  void massesReference(const float* r, const float* theta2, int n, float* e, float* o) const {
    for (int k = 0; k < n; ++k) {
      const Mass m = beamFloat(r[k], theta2[k]);
      e[k] = static_cast<float>(m.e);
      o[k] = static_cast<float>(m.o);
    }
  }
};

/// Dempster's rule (Eq. 6). K = o1 e2 + e1 o2. Total conflict (K = 1) is defined as unknown and
/// reported through `total_conflict`.
inline Mass combine(const Mass& a, const Mass& b, bool* total_conflict = nullptr) {
  const double K = a.o * b.e + a.e * b.o;
  const double norm = 1.0 - K;
  if (norm <= 1e-12) {
    if (total_conflict) *total_conflict = true;
    return Mass{};
  }
  const double inv = 1.0 / norm;
  Mass m;
  m.e = (a.e * b.e + a.e * b.u + a.u * b.e) * inv;
  m.o = (a.o * b.o + a.o * b.u + a.u * b.o) * inv;
  m.u = a.u * b.u * inv;
  return m;
}

/// Xiao et al.'s pairwise measures (Eq. 7).
struct Consistency {
  double conf, cons, unc;
};
inline Consistency xiao(const Mass& a, const Mass& b) {
  return {a.e * b.o + a.o * b.e, a.e * b.e + a.o * b.o + a.u * b.u,
          a.u * (b.e + b.o) + b.u * (a.e + a.o)};
}

/// |OP| / |OB|, at most 1 (1 for a scan without extent).
inline double rangeRatio(double range_p, double range_farthest) {
  return range_farthest > 0 ? std::min(range_p / range_farthest, 1.0) : 1.0;
}
/// l for a given |OP| / |OB| (below).
inline double beliefAtRatio(double ratio, const DsParams& p) {
  return p.r_sup - (p.r_sup - p.r_inf) * ratio;
}
/// l = r_sup - (r_sup - r_inf) |OP| / |OB| (the unnumbered formula before Eq. 8): stronger belief
/// near the sensor.
inline double discreteBelief(double range_p, double range_farthest, const DsParams& p) {
  return beliefAtRatio(rangeRatio(range_p, range_farthest), p);
}

/// Occupied is the largest mass.
inline bool isOccupied(const Mass& m) {
  return m.o > m.e && m.o > m.u;
}

/// Decision: moving iff empty is the largest mass of the window's combined evidence.
inline bool isMoving(const Mass& m) {
  return m.e > m.o && m.e > m.u;
}

/// Eq. (8)-(10): the prevailing state keeps mass l, the rest goes to unknown.
inline Mass discretise(const Mass& m, double l) {
  Mass d;
  d.e = isMoving(m) ? l : 0.0;  // empty prevails
  d.o = isOccupied(m) ? l : 0.0;
  d.u = 1.0 - d.e - d.o;
  return d;
}

}  // namespace cleanmap::ds
