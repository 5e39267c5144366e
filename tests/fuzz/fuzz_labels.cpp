// SPDX-License-Identifier: BSD-3-Clause
// SemanticKITTI-style .label files: one uint32 per point (cleanmap::io::readLabels).
#include "cleanmap/io/files.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace cleanmap;
  const std::string path = fuzz::writeInput("000000.label", data, size);
  fuzz::expectCleanError(path, [&] {
    // With and without the scan's point count (the first byte picks one).
    const std::optional<std::size_t> expected =
        size > 0 && (data[0] & 1) ? std::optional<std::size_t>(size / 4) : std::nullopt;
    const Labels l = io::readLabels(path, expected);
    if (l.size() != size / 4) fuzz::finding("label count differs from the file size / 4", path);
  });
  return 0;
}
