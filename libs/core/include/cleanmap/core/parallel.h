// SPDX-License-Identifier: BSD-3-Clause
// The one parallel loop of the project: threads are an explicit parameter with a serial path, and
// work is handed out in contiguous chunks from a counter (balanced, no false sharing). Callers
// must make each index's result independent of the thread that computes it, so a run is the same
// bit for bit whatever the thread count; per-thread accumulators are indexed by `worker`.
#pragma once
#include <algorithm>
#include <atomic>
#include <cstddef>
#include <functional>
#include <type_traits>

namespace cleanmap {
namespace detail {
/// Calls work(w) for every w in [0, t): w = 0 on the calling thread, the others on helper
/// threads that the calling thread keeps from one call to the next (issue #16: starting a thread
/// costs 45-80 us in this VM, a fresh stack's page faults included, and GICP asks for two an
/// iteration). Returns when every call has returned, then rethrows the first exception one threw.
/// A call made from inside work(0) (the caller's helpers are then busy), or in a fork's child,
/// starts threads of its own.
void runOnWorkers(int t, const std::function<void(int)>& work);
}  // namespace detail

/// Runs f(i) or f(i, worker) for every i in [0, n), worker in [0, threads). Serial (worker 0) when
/// threads <= 1 or n <= chunk. An exception thrown by f is rethrown here once every worker is done.
template <class F>
void parallelFor(std::size_t n, int threads, F&& f, std::size_t chunk = 512) {
  auto call = [&f](std::size_t i, int worker) {
    if constexpr (std::is_invocable_v<F&, std::size_t, int>)
      f(i, worker);
    else
      f(i);
  };
  chunk = std::max<std::size_t>(chunk, 1);
  const std::size_t chunks = (n + chunk - 1) / chunk;
  const int t = static_cast<int>(std::min<std::size_t>(std::max(threads, 1), chunks));
  if (t <= 1) {
    for (std::size_t i = 0; i < n; ++i) call(i, 0);
    return;
  }
  std::atomic<std::size_t> next{0};
  detail::runOnWorkers(t, [&](int worker) {
    for (std::size_t b; (b = next.fetch_add(chunk)) < n;)
      for (std::size_t i = b, e = std::min(n, b + chunk); i < e; ++i) call(i, worker);
  });
}

}  // namespace cleanmap
