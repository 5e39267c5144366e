// SPDX-License-Identifier: BSD-3-Clause
// Stage timing (the per-stage times of report.json): a steady clock and milliseconds since a start.
#pragma once
#include <chrono>

namespace cleanmap {

using Clock = std::chrono::steady_clock;

/// Milliseconds elapsed since t0.
inline double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

}  // namespace cleanmap
