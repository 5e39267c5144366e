// SPDX-License-Identifier: BSD-3-Clause
#pragma once
#include <algorithm>
#include <cstddef>
#include <vector>

namespace cleanmap {

/// A normal distribution's sigma per median absolute deviation: sigma = kMadToSigma * MAD.
constexpr double kMadToSigma = 1.4826;

/// The median of `v` (the upper one of an even count: element size/2 in sorted order), by
/// partial sort of the copy. `v` must not be empty.
template <class T>
T median(std::vector<T> v) {
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace cleanmap
