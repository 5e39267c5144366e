// SPDX-License-Identifier: BSD-3-Clause
// The simulator's scenario files (cleanmap::sim::parseScenario).
#include "cleanmap/sim/scenario.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace cleanmap;
  const std::string text(reinterpret_cast<const char*>(data), size);
  fuzz::expectCleanError("fuzz.scenario", [&] { (void)sim::parseScenario(text, "fuzz.scenario"); });
  return 0;
}
