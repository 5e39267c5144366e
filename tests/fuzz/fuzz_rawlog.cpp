// SPDX-License-Identifier: BSD-3-Clause
// MRPT rawlogs, both formats (cleanmap::mrpt::RawlogSource): every frame is read.
#include "cleanmap/mrpt/rawlog.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace cleanmap;
  const std::string path = fuzz::writeInput("input.rawlog", data, size);
  fuzz::expectCleanError(path, [&] {
    mrpt::RawlogReadOptions opts;
    opts.allow_empty_scans = size > 0 && (data[0] & 1);
    mrpt::RawlogSource src(path, opts);
    while (auto f = src.next()) {
      fuzz::requireFinitePoints(f->scan.points, path);
      if (f->scan.has_pose && !f->scan.pose.matrix().allFinite())
        fuzz::finding("a non-finite pose was delivered", path);
      if ((f->mount && !f->mount->matrix().allFinite()) ||
          (f->odometry && !f->odometry->matrix().allFinite()))
        fuzz::finding("a non-finite mount or odometry was delivered", path);
    }
  });
  return 0;
}
