// SPDX-License-Identifier: BSD-3-Clause
// KITTI .bin scans: float32 x y z intensity records (cleanmap::io::readKittiBin).
#include "cleanmap/io/files.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace cleanmap;
  const std::string path = fuzz::writeInput("000000.bin", data, size);
  fuzz::expectCleanError(path, [&] {
    io::ScanReadOptions opts;
    opts.allow_empty = size > 0 && (data[0] & 1);
    const Scan s = io::readKittiBin(path, opts);
    fuzz::requireFinitePoints(s.points, path);
    if (s.original_size < s.points.size())
      fuzz::finding("original_size below the kept count", path);
  });
  return 0;
}
