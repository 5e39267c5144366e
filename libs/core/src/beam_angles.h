// SPDX-License-Identifier: BSD-3-Clause
// The beam index's bulk angle computation (issue #16), in its own file for its compile options.
#pragma once
#include <cstddef>

namespace cleanmap::detail {

/// el[i] = fast::asin(dz[i]), az[i] = fast::atan2(dy[i], dx[i]) for i < n (fast_math.h bounds).
void approxAngles(const float* dx, const float* dy, const float* dz, std::size_t n, float* el,
                  float* az);

}  // namespace cleanmap::detail
