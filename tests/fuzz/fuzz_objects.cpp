// SPDX-License-Identifier: BSD-3-Clause
// objects.json, the per-object ground truth of simulated scenes (cleanmap::io::readObjects).
#include <cmath>

#include "cleanmap/io/objects.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace cleanmap;
  const std::string path = fuzz::writeInput("objects.json", data, size);
  fuzz::expectCleanError(path, [&] {
    for (const auto& o : io::readObjects(path))
      for (const auto& [i, s] : o.frames) {
        (void)i;
        if (!s.center.allFinite() || !s.size.allFinite() || !std::isfinite(s.yaw))
          fuzz::finding("a non-finite box was delivered", path);
        if ((s.size.array() < 0).any()) fuzz::finding("a box of negative size was delivered", path);
        (void)s.contains(s.center);
      }
  });
  return 0;
}
