// SPDX-License-Identifier: BSD-3-Clause
// Open-addressing map from cell keys (cell_key.h) to uint32 values, for the per-scan grids of the
// registration: linear probing, no per-entry nodes, and reusable — reset() clears in O(1) by
// bumping a generation stamp, so a long run allocates (and page-faults) the table once. It grows
// (doubling) whenever it would be more than half full, whatever `expected` said: a full table
// would make emplace() probe forever.
#pragma once
#include <algorithm>
#include <cstdint>
#include <utility>
#include <vector>

namespace cleanmap::reg {

class FlatKeyMap {
 public:
  FlatKeyMap() = default;
  explicit FlatKeyMap(std::size_t expected) { reset(expected); }

  /// Empties the map, sized for `expected` keys (grows the storage only when needed).
  void reset(std::size_t expected) {
    std::size_t cap = 16;
    while (cap < 2 * expected) cap <<= 1;
    if (cap > keys_.size()) {
      keys_.assign(cap, 0);
      values_.assign(cap, 0);
      stamp_.assign(cap, 0);
      gen_ = 0;
    }
    mask_ = keys_.size() - 1;
    size_ = 0;
    if (++gen_ == 0) {  // the stamp wrapped: clear for real once every 2^32 resets
      std::fill(stamp_.begin(), stamp_.end(), 0u);
      gen_ = 1;
    }
  }
  /// Inserts (key, value) if key is absent; returns the value stored for key and whether it is new.
  std::pair<uint32_t, bool> emplace(uint64_t key, uint32_t value) {
    if (2 * (size_ + 1) > keys_.size()) grow();
    for (std::size_t i = slot(key);; i = (i + 1) & mask_) {
      if (stamp_[i] != gen_) {
        stamp_[i] = gen_;
        keys_[i] = key;
        values_[i] = value;
        ++size_;
        return {value, true};
      }
      if (keys_[i] == key) return {values_[i], false};
    }
  }
  std::size_t size() const { return size_; }
  std::size_t capacity() const { return keys_.size(); }
  /// The value of key, or nullptr.
  const uint32_t* find(uint64_t key) const {
    if (keys_.empty()) return nullptr;
    for (std::size_t i = slot(key);; i = (i + 1) & mask_) {
      if (stamp_[i] != gen_) return nullptr;
      if (keys_[i] == key) return &values_[i];
    }
  }

 private:
  // Twice the slots, the live entries moved over (their order of insertion does not matter: a
  // key's value is the one it was given first).
  void grow() {
    const std::vector<uint64_t> keys = std::move(keys_);
    const std::vector<uint32_t> values = std::move(values_), stamp = std::move(stamp_);
    const uint32_t live = gen_;
    const std::size_t cap = std::max<std::size_t>(16, 2 * keys.size());
    keys_.assign(cap, 0);
    values_.assign(cap, 0);
    stamp_.assign(cap, 0);
    mask_ = cap - 1;
    gen_ = 1;
    for (std::size_t j = 0; j < keys.size(); ++j) {
      if (stamp[j] != live) continue;
      std::size_t i = slot(keys[j]);
      while (stamp_[i] == gen_) i = (i + 1) & mask_;
      stamp_[i] = gen_;
      keys_[i] = keys[j];
      values_[i] = values[j];
    }
  }
  std::size_t slot(uint64_t key) const {
    return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> 20) & mask_;
  }
  std::vector<uint64_t> keys_;
  std::vector<uint32_t> values_, stamp_;
  std::size_t mask_ = 0, size_ = 0;
  uint32_t gen_ = 0;
};

}  // namespace cleanmap::reg
