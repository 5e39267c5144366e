// SPDX-License-Identifier: BSD-3-Clause
// PCD clouds: ascii, binary and binary_compressed (cleanmap::io::readPcd).
#include "cleanmap/io/pcd.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace cleanmap;
  const std::string path = fuzz::writeInput("cloud.pcd", data, size);
  fuzz::expectCleanError(path, [&] {
    // binary_compressed may expand, but never beyond what its header's size fields allow the
    // reader to check against (a bounded ratio, see readPcd).
    (void)io::readPcd(path);
  });
  return 0;
}
