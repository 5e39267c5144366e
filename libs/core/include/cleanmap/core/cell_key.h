// SPDX-License-Identifier: BSD-3-Clause
// Integer grid cells as one hash key: 21 bits per axis, two's complement masked, so +-2^20 cells
// are distinct (+-300 km at 0.3 m); cells 2^21 apart share a key, which only merges buckets.
#pragma once
#include <cmath>
#include <cstdint>

namespace cleanmap {

inline uint64_t cellKey(int64_t x, int64_t y, int64_t z) {
  auto u = [](int64_t v) { return static_cast<uint64_t>(v) & 0x1FFFFFu; };
  return (u(x) << 42) | (u(y) << 21) | u(z);
}

/// The key of the cell containing (x, y, z) for cells of side 1 / inv_side.
inline uint64_t cellKeyOf(double x, double y, double z, double inv_side) {
  return cellKey(static_cast<int64_t>(std::floor(x * inv_side)), static_cast<int64_t>(std::floor(y * inv_side)),
                 static_cast<int64_t>(std::floor(z * inv_side)));
}

/// The key of the cell (dx, dy, dz) cells away.
inline uint64_t cellKeyShift(uint64_t key, int dx, int dy, int dz) {
  auto get = [key](int s) { return static_cast<int64_t>((key >> s) & 0x1FFFFFu); };
  return cellKey(get(42) + dx, get(21) + dy, get(0) + dz);
}

}  // namespace cleanmap
