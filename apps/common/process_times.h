// SPDX-License-Identifier: BSD-3-Clause
// The whole command's wall and CPU time for an app's last line, as `time` would say them: the
// loading of MRPT's libraries and a re-execution (cli::useHugePages) included (doc/FORMATS.md,
// report.json `process`).
#pragma once
#include <cstdio>
#include <string>

#include "cleanmap/io/output.h"

namespace cleanmap::cli {

/// " in 3.4 s (CPU 4.1 s)" so far; empty where the process's age cannot be read (no /proc).
inline std::string processTimesText() {
  const auto age = io::processAgeSeconds();
  if (!age) return {};
  char buf[64];
  std::snprintf(buf, sizeof buf, " in %.1f s (CPU %.1f s)", *age, io::processCpuSeconds());
  return buf;
}

}  // namespace cleanmap::cli
