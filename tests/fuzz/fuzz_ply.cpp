// SPDX-License-Identifier: BSD-3-Clause
// PLY clouds, ASCII and binary (cleanmap::io::readPly).
#include "cleanmap/io/ply.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace cleanmap;
  const std::string path = fuzz::writeInput("cloud.ply", data, size);
  // Every point delivered comes from the file: never more points than bytes.
  fuzz::expectCleanError(path, [&] {
    if (io::readPly(path).size() > size) fuzz::finding("more points than bytes", path);
  });
  return 0;
}
