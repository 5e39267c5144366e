// SPDX-License-Identifier: BSD-3-Clause
// Open-addressing map from cell keys (cell_key.h) to uint32 values, for the per-scan grids of the
// registration: linear probing, no per-entry nodes, and reusable — reset() clears in O(1) by
// bumping a generation stamp, so a long run allocates (and page-faults) the table once.
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
    if (++gen_ == 0) {  // the stamp wrapped: clear for real once every 2^32 resets
      std::fill(stamp_.begin(), stamp_.end(), 0u);
      gen_ = 1;
    }
  }
  /// Inserts (key, value) if key is absent; returns the value stored for key and whether it is new.
  std::pair<uint32_t, bool> emplace(uint64_t key, uint32_t value) {
    for (std::size_t i = slot(key);; i = (i + 1) & mask_) {
      if (stamp_[i] != gen_) {
        stamp_[i] = gen_;
        keys_[i] = key;
        values_[i] = value;
        return {value, true};
      }
      if (keys_[i] == key) return {values_[i], false};
    }
  }
  /// The value of key, or nullptr.
  const uint32_t* find(uint64_t key) const {
    for (std::size_t i = slot(key);; i = (i + 1) & mask_) {
      if (stamp_[i] != gen_) return nullptr;
      if (keys_[i] == key) return &values_[i];
    }
  }

 private:
  std::size_t slot(uint64_t key) const {
    return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> 20) & mask_;
  }
  std::vector<uint64_t> keys_;
  std::vector<uint32_t> values_, stamp_;
  std::size_t mask_ = 0;
  uint32_t gen_ = 0;
};

}  // namespace cleanmap::reg
