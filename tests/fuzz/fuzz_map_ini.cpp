// SPDX-License-Identifier: BSD-3-Clause
// MRPT map configurations declaring our map plugins (cleanmap::maps::parseMapConfig).
#include "cleanmap/maps/map_config.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace cleanmap;
  const std::string text(reinterpret_cast<const char*>(data), size);
  fuzz::expectCleanError("fuzz.ini", [&] {
    (void)cleanmap_maps::parseMapConfig(text, "fuzz.ini", "", size > 0 && (data[0] & 1));
  });
  return 0;
}
