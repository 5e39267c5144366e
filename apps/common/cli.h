// SPDX-License-Identifier: BSD-3-Clause
// Command-line walking shared by the apps: one usage error format ("prog: what (see --help)",
// exit 2) and checked number parsing.
#pragma once
#include <algorithm>
#include <cstdlib>
#include <exception>
#include <thread>
#if defined(__GLIBC__)
#include <malloc.h>
#include <unistd.h>
#endif
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

namespace cleanmap::cli {

/// The one line to print for an exception. MRPT's exceptions hold a banner, "Message: ...", the
/// location and a stack trace: their message is kept; any text is cut at its first newline.
inline std::string errorLine(const std::exception& e) {
  std::string what = e.what();
  if (const auto m = what.rfind("Message: "); m != std::string::npos) what = what.substr(m + 9);
  return what.substr(0, what.find('\n'));
}

/// Each scan allocates and frees a few MB (beam index, masks, spooled points). glibc returns such
/// blocks to the kernel (mmap above 128 KiB, heap trimming), so the next scan page-faults them
/// back, zeroed: 10 ms a scan on the beam index alone in a VM (doc/BENCHMARK.md, Clean map).
/// The apps keep freed memory for reuse instead; peak RSS is unchanged within a few MiB.
/// The heap also grows in 64 MiB steps, not by what a call needs plus 128 KiB: a transparent huge
/// page (useHugePages) backs only a 2 MiB span that lies whole inside the heap, so small steps
/// left most of it to 4 KiB faults (58,000 on kitti_highway; 9,600 in large steps, whole process
/// 0.84x the wall, peak RSS +25 MiB: doc/BENCHMARK.md, sixteenth session).
/// One malloc arena per core, not glibc's eight per core: memory freed by one thread is reused by
/// the others instead of each arena growing to its own peak (peak RSS -45 to -57 MiB on the
/// labelled sets, wall A/B 0.97-0.99: doc/BENCHMARK.md, nineteenth session).
inline void keepFreedMemory() {
#if defined(__GLIBC__)
  mallopt(M_MMAP_THRESHOLD, 32 << 20);  // glibc's largest
  mallopt(M_TRIM_THRESHOLD, 256 << 20);
  mallopt(M_TOP_PAD, 64 << 20);
  mallopt(M_ARENA_MAX, static_cast<int>(std::max(2u, std::thread::hardware_concurrency())));
#endif
}

/// Issue #16: a run's memory grows by page faults of 4 KiB, each costly in a VM: 78,000 faults on
/// kitti_highway, 15 % of the process' CPU (doc/BENCHMARK.md, Speed). glibc (2.35 and later)
/// backs its heap with transparent huge pages under the tunable glibc.malloc.hugetlb=1, which it
/// reads only at start-up. Sets it in the environment for a process about to be executed, where
/// the kernel offers huge pages; false if it is not wanted or already set. CLEANMAP_HUGEPAGES=0
/// turns this off; under valgrind it is skipped.
inline bool setHugePageTunable() {
#if defined(__GLIBC__) && defined(__linux__)
  const auto env = [](const char* name) {
    const char* v = std::getenv(name);
    return std::string(v ? v : "");
  };
  if (env("CLEANMAP_HUGEPAGES") == "0" || env("LD_PRELOAD").find("vgpreload") != std::string::npos)
    return false;
  const std::string tunables = env("GLIBC_TUNABLES");
  if (tunables.find("glibc.malloc.hugetlb") != std::string::npos) return false;  // set: done
  std::string thp;
  std::getline(std::ifstream("/sys/kernel/mm/transparent_hugepage/enabled"), thp);
  if (thp.empty() || thp.find("[never]") != std::string::npos) return false;
  const std::string v = (tunables.empty() ? "" : tunables + ":") + "glibc.malloc.hugetlb=1";
  return setenv("GLIBC_TUNABLES", v.c_str(), 1) == 0;
#else
  return false;
#endif
}

/// The running executable's path ("" if unknown): an app re-executing itself keeps its name (ps,
/// top) rather than "exe"; the launcher finds the app beside it.
inline std::string executablePath() {
#if defined(__linux__)
  char self[4096];
  const ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
  if (n > 0) return std::string(self, static_cast<std::size_t>(n));
#endif
  return "";
}

/// The directory of the running executable, with its trailing '/' ("" if unknown).
inline std::string executableDir() {
  const std::string s = executablePath();
  return s.substr(0, s.rfind('/') + 1);
}

/// The app re-executes itself once with the tunable set (setHugePageTunable). The `cleanmap`
/// command sets it in its launcher (apps/cleanmap/launcher.cpp), which loads no library: this
/// app then runs once, and MRPT's libraries are loaded once (0.1 s a run).
inline void useHugePages(char** argv) {
#if defined(__GLIBC__) && defined(__linux__)
  const char* old = std::getenv("GLIBC_TUNABLES");
  const std::string tunables = old ? old : "";
  if (!setHugePageTunable()) return;
  if (const std::string self = executablePath(); !self.empty())
    execv(self.c_str(), argv);  // returns only if it failed: go on as we are
  if (tunables.empty())
    unsetenv("GLIBC_TUNABLES");
  else
    setenv("GLIBC_TUNABLES", tunables.c_str(), 1);
#else
  (void)argv;
#endif
}

class Args {
 public:
  Args(std::string prog, int argc, char** argv, int start = 1)
      : prog_(std::move(prog)), argc_(argc), argv_(argv), i_(start) {}

  bool done() const { return i_ >= argc_; }
  /// The next argument.
  std::string next() { return argv_[i_++]; }
  /// The argument after `flag`; a usage error if there is none.
  std::string value(const std::string& flag) {
    if (done()) fail(flag + " needs a value");
    return next();
  }
  /// An integer >= min (0 or 1 in practice) and below 2^31 (what an ini file takes) after `flag`.
  long integer(const std::string& flag, long min = 0) {
    const std::string v = value(flag);
    try {
      std::size_t used = 0;
      const long x = std::stol(v, &used);
      if (used == v.size() && x >= min && x <= 2147483647L) return x;
    } catch (const std::exception&) {
    }
    fail(flag + " needs a " +
         (min == 1   ? std::string("positive")
          : min == 0 ? "non-negative"
                     : ">= " + std::to_string(min)) +
         " integer below 2^31, got '" + v + "'");
  }
  /// A number >= 0 after `flag`.
  double number(const std::string& flag) { return toNumber(flag, value(flag)); }
  /// A comma-separated list of numbers >= 0 after `flag`.
  std::vector<double> numbers(const std::string& flag) {
    std::vector<double> out;
    std::stringstream ss(value(flag));
    for (std::string item; std::getline(ss, item, ',');) out.push_back(toNumber(flag, item));
    if (out.empty()) fail(flag + " needs a comma-separated list");
    return out;
  }
  /// `v` (the value of `flag`) as a number >= 0; a usage error otherwise.
  double toNumber(const std::string& flag, const std::string& v) const {
    try {
      std::size_t used = 0;
      const double x = std::stod(v, &used);
      if (used == v.size() && x >= 0) return x;
    } catch (const std::exception&) {
    }
    fail(flag + " needs a non-negative number, got '" + v + "'");
  }
  [[noreturn]] void fail(const std::string& msg) const {
    std::cerr << prog_ << ": " << msg << " (see --help)\n";
    std::exit(2);
  }
  /// "unknown option" for a dash argument, "unexpected argument" otherwise.
  [[noreturn]] void unexpected(const std::string& a) const {
    fail(!a.empty() && a[0] == '-' ? "unknown option '" + a + "'"
                                   : "unexpected argument '" + a + "'");
  }

 private:
  std::string prog_;
  int argc_;
  char** argv_;
  int i_;
};

}  // namespace cleanmap::cli
