// SPDX-License-Identifier: BSD-3-Clause
// cleanmap's flat parameter file (-c file.ini, a run's params.ini): parse, then validate.
#include "cleanmap/io/config.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace cleanmap;
  const std::string text(reinterpret_cast<const char*>(data), size);
  fuzz::expectCleanError("fuzz.ini", [&] {
    PipelineParams p;
    io::parseParams(text, "fuzz.ini", p);
    validate(p, "fuzz.ini");
    // What was accepted writes back and reads back to the same values.
    PipelineParams q;
    io::parseParams(io::toIni(p), "fuzz.ini", q);
    if (io::paramValues(p) != io::paramValues(q)) fuzz::finding("ini round trip differs", text);
  });
  return 0;
}
