// SPDX-License-Identifier: BSD-3-Clause
// A flat hash map from cell keys (cell_key.h) to values, for the grids that are filled and looked
// up per point (issue #16): open addressing with linear probing in one array, so a lookup is one
// or two cache lines where std::unordered_map follows a bucket and a node. Cell keys use 63 bits,
// so ~0 marks an empty slot. Erase shifts the following entries back (no tombstones, so a map
// whose keys come and go keeps short probes). Iteration order is the slot order (callers must
// not depend on it). CellMap<uint8_t> serves as a set (insert, contains).
#pragma once
#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "cleanmap/core/cell_key.h"

namespace cleanmap {

template <class V>
class CellMap {
 public:
  static constexpr uint64_t kEmpty = ~uint64_t(0);

  /// Room for n keys without growing.
  void reserve(std::size_t n) {
    if (2 * n > keys_.size()) rehash(capacityFor(n));
  }
  std::size_t size() const { return size_; }
  /// Empties the map, keeping its slots (a per-scan grid reuses its memory).
  void clear() {
    std::fill(keys_.begin(), keys_.end(), kEmpty);
    for (auto& v : values_) v = V{};
    size_ = 0;
  }
  /// Set use: adds `key`; true if it was not there.
  bool insert(uint64_t key) {
    bool fresh = false;
    get(key, &fresh);
    return fresh;
  }
  bool contains(uint64_t key) const { return find(key) != nullptr; }
  std::size_t capacity() const { return keys_.size(); }  ///< slots (key + value each)
  bool empty() const { return size_ == 0; }

  /// The value of `key`, inserted default-constructed if absent; `inserted` tells which.
  V& get(uint64_t key, bool* inserted = nullptr) {
    if (2 * (size_ + 1) > keys_.size()) rehash(capacityFor(size_ + 1));
    std::size_t i = slot(key);
    while (keys_[i] != kEmpty) {
      if (keys_[i] == key) {
        if (inserted) *inserted = false;
        return values_[i];
      }
      i = (i + 1) & mask_;
    }
    keys_[i] = key;
    values_[i] = V{};
    ++size_;
    if (inserted) *inserted = true;
    return values_[i];
  }
  V& operator[](uint64_t key) { return get(key); }

  const V* find(uint64_t key) const {
    if (keys_.empty()) return nullptr;
    for (std::size_t i = slot(key);; i = (i + 1) & mask_) {
      if (keys_[i] == key) return &values_[i];
      if (keys_[i] == kEmpty) return nullptr;
    }
  }
  V* find(uint64_t key) { return const_cast<V*>(std::as_const(*this).find(key)); }
  /// Starts loading `key`'s home slot, so that a lookup of it soon after finds it in cache.
  void prefetch(uint64_t key) const {
    if (keys_.empty()) return;
    const std::size_t i = slot(key);
    __builtin_prefetch(&keys_[i]);
    __builtin_prefetch(&values_[i]);
  }

  /// Removes `key` (its value is destroyed); false if it was absent. Backward-shift deletion: the
  /// entries after the slot that probed past it move back, so every lookup still finds its key.
  bool erase(uint64_t key) {
    if (keys_.empty()) return false;
    std::size_t i = slot(key);
    for (; keys_[i] != key; i = (i + 1) & mask_)
      if (keys_[i] == kEmpty) return false;
    for (std::size_t j = (i + 1) & mask_; keys_[j] != kEmpty; j = (j + 1) & mask_) {
      const std::size_t h = slot(keys_[j]);  // the entry at j may stay only if h lies in (i, j]
      const bool stays = i <= j ? (i < h && h <= j) : (i < h || h <= j);
      if (stays) continue;
      keys_[i] = keys_[j];
      values_[i] = std::move(values_[j]);
      i = j;
    }
    keys_[i] = kEmpty;
    values_[i] = V{};
    --size_;
    return true;
  }

  /// f(key, value) for every entry, in slot order.
  template <class F>
  void forEach(F&& f) const {
    for (std::size_t i = 0; i < keys_.size(); ++i)
      if (keys_[i] != kEmpty) f(keys_[i], values_[i]);
  }

 private:
  static std::size_t capacityFor(std::size_t n) {  // a power of two, at most half full
    std::size_t c = 16;
    while (c < 2 * n) c *= 2;
    return c;
  }
  std::size_t slot(uint64_t key) const {
    return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> shift_);
  }
  void rehash(std::size_t capacity) {
    std::vector<uint64_t> keys(capacity, kEmpty);
    std::vector<V> values(capacity);
    std::swap(keys, keys_);
    std::swap(values, values_);
    mask_ = capacity - 1;
    shift_ = 64;
    for (std::size_t c = capacity; c > 1; c >>= 1) --shift_;
    for (std::size_t j = 0; j < keys.size(); ++j) {
      if (keys[j] == kEmpty) continue;
      std::size_t i = slot(keys[j]);
      while (keys_[i] != kEmpty) i = (i + 1) & mask_;
      keys_[i] = keys[j];
      values_[i] = std::move(values[j]);
    }
  }
  std::vector<uint64_t> keys_;
  std::vector<V> values_;
  std::size_t size_ = 0, mask_ = 0;
  int shift_ = 64;
};

/// A set of cells (the cells of cellKey(x, y, z): coordinates wrapped to 21 bits, so the same
/// cells, the same answers as a CellMap<uint8_t> of those keys) kept as 8 x 8 x 8 blocks of bits.
/// Points met in scan order mostly fall in the block of the point before, so an insert is a bit
/// test in a cache line already loaded instead of a probe into a table as large as the map
/// (issue #16: the scene's voxel filter, one probe per map point).
class CellSet {
 public:
  /// Adds cell (x, y, z); true if it was not there.
  bool insert(int64_t x, int64_t y, int64_t z) {
    const auto u = [](int64_t v) { return static_cast<uint64_t>(v) & 0x1FFFFFu; };
    const uint64_t ux = u(x), uy = u(y), uz = u(z);
    const uint64_t block = ((ux >> 3) << 42) | ((uy >> 3) << 21) | (uz >> 3);  // never ~0
    if (block != last_key_) {
      last_ = &blocks_[block];  // valid until the next block is added (a rehash moves them)
      last_key_ = block;
    }
    uint64_t& word = (*last_)[ux & 7];
    const uint64_t bit = uint64_t(1) << (((uy & 7) << 3) | (uz & 7));
    if (word & bit) return false;
    word |= bit;
    ++size_;
    return true;
  }
  template <class T>
  bool insertPoint(T x, T y, T z, T inv_side) {
    return insert(floorToCell(x, inv_side), floorToCell(y, inv_side), floorToCell(z, inv_side));
  }
  std::size_t size() const { return size_; }
  std::size_t blocks() const { return blocks_.size(); }

 private:
  CellMap<std::array<uint64_t, 8>> blocks_;  // per block, one 64-bit word per x plane
  std::array<uint64_t, 8>* last_ = nullptr;
  uint64_t last_key_ = ~uint64_t(0);
  std::size_t size_ = 0;
};

}  // namespace cleanmap
