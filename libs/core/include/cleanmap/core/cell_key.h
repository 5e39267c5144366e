// SPDX-License-Identifier: BSD-3-Clause
// Integer grid cells, the one copy used by every voxel grid of the project (duplicate filter,
// object consensus, hysteresis, map scores): floor-to-cell, a 64-bit hash key and the 27-cell
// neighbourhood. Keys hold 21 bits per axis, two's complement masked, so +-2^20 cells are
// distinct (+-300 km at 0.3 m); cells 2^21 apart share a key, which only merges hash buckets
// (every user compares the points themselves).
#pragma once
#include <cmath>
#include <cstdint>

namespace cleanmap {

/// The index of the cell of side 1 / inv_side holding coordinate v. T is float or double: callers
/// keep the precision they compute in, so a refactor never moves a point to another cell.
template <class T>
inline int64_t floorToCell(T v, T inv_side) {
  return static_cast<int64_t>(std::floor(v * inv_side));
}

inline uint64_t cellKey(int64_t x, int64_t y, int64_t z) {
  auto u = [](int64_t v) { return static_cast<uint64_t>(v) & 0x1FFFFFu; };
  return (u(x) << 42) | (u(y) << 21) | u(z);
}

/// The key of the cell containing (x, y, z) for cells of side 1 / inv_side.
template <class T>
inline uint64_t cellKeyOf(T x, T y, T z, T inv_side) {
  return cellKey(floorToCell(x, inv_side), floorToCell(y, inv_side), floorToCell(z, inv_side));
}

/// The key of the cell (dx, dy, dz) cells away.
inline uint64_t cellKeyShift(uint64_t key, int64_t dx, int64_t dy, int64_t dz) {
  auto get = [key](int s) { return static_cast<int64_t>((key >> s) & 0x1FFFFFu); };
  return cellKey(get(42) + dx, get(21) + dy, get(0) + dz);
}

/// Calls f(dx, dy, dz) for the 27 offsets of a cell's neighbourhood, itself included, in a fixed
/// order (dx outermost, dz innermost).
template <class F>
inline void forEachNeighbour27(F&& f) {
  for (int dx = -1; dx <= 1; ++dx)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dz = -1; dz <= 1; ++dz) f(dx, dy, dz);
}

/// Calls f(dx, dy, dz) for the 13 offsets of the neighbourhood that come after (0, 0, 0) in
/// forEachNeighbour27's order: visiting them from every cell meets each pair of neighbouring
/// cells once (a symmetric relation, such as connectivity, needs no more).
template <class F>
inline void forEachNeighbour13(F&& f) {
  forEachNeighbour27([&](int dx, int dy, int dz) {
    if (dx > 0 || (dx == 0 && (dy > 0 || (dy == 0 && dz > 0)))) f(dx, dy, dz);
  });
}

}  // namespace cleanmap
