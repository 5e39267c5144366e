// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2e: the free space that cleans the map is kept for the whole run and grows with the
// ground covered (0.4-0.8 GiB per km of street, doc/BENCHMARK.md "Memory over distance"). The
// apps that fill it warn once, in one line, when it passes half of the memory here.
#pragma once
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <utility>

#include "cleanmap/core/error.h"

namespace cleanmap::cli {

/// The memory the warning compares with, bytes (0: unknown): CLEANMAP_MEMORY_MIB, or the
/// machine's, or its control group's limit where that is lower (a cluster's job). A bad
/// CLEANMAP_MEMORY_MIB is a cleanmap::Error naming it.
inline std::size_t memoryHere() {
  if (const char* v = std::getenv("CLEANMAP_MEMORY_MIB")) {
    const std::string s(v);
    const bool digits =
        !s.empty() && s.size() < 10 && s.find_first_not_of("0123456789") == std::string::npos;
    if (!digits || std::stoull(s) == 0)
      throw Error("CLEANMAP_MEMORY_MIB",
                  "is '" + s + "': give the memory in MiB, a positive integer");
    return static_cast<std::size_t>(std::stoull(s)) << 20;
  }
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
  std::size_t bytes = pages > 0 && page > 0 ? std::size_t(pages) * std::size_t(page) : 0;
  std::string limit;  // cgroup v2: a number, or "max"
  std::getline(std::ifstream("/sys/fs/cgroup/memory.max"), limit);
  if (!limit.empty() && limit.size() < 20 &&
      limit.find_first_not_of("0123456789") == std::string::npos)
    bytes = bytes ? std::min<std::size_t>(bytes, std::stoull(limit)) : std::stoull(limit);
  return bytes;
}

/// One warning per run, the first time the free space holds more than half of memoryHere().
class FreeSpaceWarning {
 public:
  /// `split`: how to split a drive with this app ("with --first/--last").
  FreeSpaceWarning(std::string app, std::string split)
      : app_(std::move(app)), split_(std::move(split)), memory_(memoryHere()) {}
  /// `held`: the free space's bytes now; `scans`: how many it has seen; `newline`: end a
  /// progress line first. True where it warned now.
  bool check(std::size_t held, std::size_t scans, bool newline = false) {
    if (warned_ || memory_ == 0 || held <= memory_ / 2) return false;
    warned_ = true;
    std::fprintf(stderr,
                 "%s%s: warning: the free-space map holds %s after %zu scan%s, over half of the %s "
                 "of memory here; it grows with the ground covered (0.4-0.8 GiB per km of "
                 "street): split a longer drive %s, or run without it (static_map.clean = 0)\n",
                 newline ? "\n" : "", app_.c_str(), size(held).c_str(), scans,
                 scans == 1 ? "" : "s", size(memory_).c_str(), split_.c_str());
    return true;
  }

 private:
  static std::string size(std::size_t b) {  // "1.5 GiB", "37 MiB"
    char t[32];
    const double mib = double(b) / (1024.0 * 1024.0);
    if (mib >= 1024)
      std::snprintf(t, sizeof t, "%.1f GiB", mib / 1024);
    else
      std::snprintf(t, sizeof t, "%.0f MiB", mib);
    return t;
  }
  std::string app_, split_;
  std::size_t memory_;
  bool warned_ = false;
};

}  // namespace cleanmap::cli
