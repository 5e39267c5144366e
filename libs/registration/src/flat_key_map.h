// SPDX-License-Identifier: BSD-3-Clause
// Open-addressing map from cell keys (cell_key.h, 63 bits) to uint32 values, for the per-scan
// grids of the registration: one allocation, linear probing, no per-entry nodes.
#pragma once
#include <cstdint>
#include <vector>

namespace cleanmap::reg {

class FlatKeyMap {
 public:
  static constexpr uint64_t kEmpty = ~0ull;  // cell keys use 63 bits: never a key

  explicit FlatKeyMap(std::size_t expected) {
    std::size_t cap = 16;
    while (cap < 2 * expected) cap <<= 1;
    keys_.assign(cap, kEmpty);
    values_.resize(cap);
    mask_ = cap - 1;
  }
  /// Inserts (key, value) if key is absent; returns the value stored for key and whether it is new.
  std::pair<uint32_t, bool> emplace(uint64_t key, uint32_t value) {
    for (std::size_t i = slot(key);; i = (i + 1) & mask_) {
      if (keys_[i] == key) return {values_[i], false};
      if (keys_[i] == kEmpty) {
        keys_[i] = key;
        values_[i] = value;
        return {value, true};
      }
    }
  }
  /// The value of key, or nullptr.
  const uint32_t* find(uint64_t key) const {
    for (std::size_t i = slot(key);; i = (i + 1) & mask_) {
      if (keys_[i] == key) return &values_[i];
      if (keys_[i] == kEmpty) return nullptr;
    }
  }

 private:
  std::size_t slot(uint64_t key) const {
    return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> 20) & mask_;
  }
  std::vector<uint64_t> keys_;
  std::vector<uint32_t> values_;
  std::size_t mask_;
};

}  // namespace cleanmap::reg
