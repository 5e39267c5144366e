// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/mrpt/input.h"

#include <filesystem>

#include "cleanmap/core/error.h"
#include "cleanmap/io/kitti.h"
#include "cleanmap/mrpt/rawlog.h"

namespace cleanmap::mrpt {

std::unique_ptr<FrameSource> openInput(const std::string& path, const InputOptions& opts) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    if (!opts.lidar_label.empty() || !opts.camera_label.empty())
      throw Error(path,
                  "is a KITTI folder: a lidar or camera label selects the sensors of a rawlog "
                  "(a KITTI folder has one lidar and one camera)");
    io::KittiReadOptions k;
    k.scan.allow_empty = opts.allow_empty_scans;
    k.load_images = opts.load_images;
    k.point_times = opts.point_times;
    return std::make_unique<io::KittiSequence>(io::KittiSequence::open(path, k));
  }
  if (!std::filesystem::exists(path, ec))
    throw Error(path, "does not exist (expected a KITTI folder or a .rawlog file)");
  RawlogReadOptions r;
  r.allow_empty_scans = opts.allow_empty_scans;
  r.lidar_label = opts.lidar_label;
  r.camera_label = opts.camera_label;
  r.load_images = opts.load_images;
  return std::make_unique<RawlogSource>(path, r);
}

}  // namespace cleanmap::mrpt
