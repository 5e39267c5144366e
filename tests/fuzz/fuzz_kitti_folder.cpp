// SPDX-License-Identifier: BSD-3-Clause
// The text files of a KITTI folder (cleanmap::io::KittiSequence::open, then every frame): a valid
// two-scan folder of each layout is written, and the fuzzer's bytes replace one of its files,
// picked by the first byte: odometry calib.txt, poses.txt, times.txt; raw timestamps.txt, an OXTS
// record, calib_imu_to_velo.txt, calib_velo_to_cam.txt, calib_cam_to_cam.txt.
#include <cmath>
#include <filesystem>

#include <opencv2/imgcodecs.hpp>

#include "cleanmap/io/files.h"
#include "cleanmap/io/kitti.h"
#include "fuzz_support.h"

namespace {

struct File {
  const char* path;  // relative to the folder of its layout
  const char* text;  // the valid content
};
const char* const kOdometry = "odometry";
const char* const kRaw = "raw/2011_09_26_drive_0001_sync";

const File kFiles[] = {
    {"odometry/calib.txt",
     "P2: 700 0 600 0 0 700 180 0 0 0 1 0\nTr: 0 -1 0 0 0 0 -1 -0.08 1 0 0 -0.27\n"},
    {"odometry/poses.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 1.2\n"},
    {"odometry/times.txt", "0.000000e+00\n1.036000e-01\n"},
    {"raw/2011_09_26_drive_0001_sync/velodyne_points/timestamps.txt",
     "2011-09-26 13:02:25.964389445\n2011-09-26 13:02:26.068252325\n"},
    {"raw/2011_09_26_drive_0001_sync/oxts/data/0000000000.txt",
     "49.015 8.434 116.4 0.03 -0.01 1.2 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0\n"},
    {"raw/calib_imu_to_velo.txt",
     "calib_time: 25-May-2012 16:47:16\nR: 1 0 0 0 1 0 0 0 1\nT: -0.81 0.32 -0.8\n"},
    {"raw/calib_velo_to_cam.txt", "R: 0 -1 0 0 0 -1 1 0 0\nT: 0 -0.08 -0.27\n"},
    {"raw/calib_cam_to_cam.txt",
     "S_rect_02: 8 4\nR_rect_00: 1 0 0 0 1 0 0 0 1\nP_rect_02: 700 0 600 0 0 700 180 0 0 0 1 0\n"},
};
const File kOther[] = {
    {"raw/2011_09_26_drive_0001_sync/oxts/data/0000000001.txt",
     "49.016 8.435 116.4 0.03 -0.01 1.2 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0\n"},
};

void writeTemplate() {
  using namespace cleanmap;
  for (const auto& f : kFiles) fuzz::writeInput(f.path, f.text);
  for (const auto& f : kOther) fuzz::writeInput(f.path, f.text);
  const std::vector<PointXYZI> pts = {{5, 0, -1.7f, 0.1f}, {0, 8, -1.7f, 0.2f}, {3, 3, 0.5f, 0.3f}};
  const cv::Mat img(4, 8, CV_8UC3, cv::Scalar(40, 80, 120));
  namespace fs = std::filesystem;
  const fs::path root(fuzz::scratchDir());
  for (const char* name : {"000000", "000001"}) {
    fs::create_directories(root / kOdometry / "velodyne");
    fs::create_directories(root / kOdometry / "image_2");
    io::writeKittiBin((root / kOdometry / "velodyne" / name).string() + ".bin", pts);
    cv::imwrite((root / kOdometry / "image_2" / name).string() + ".png", img);
  }
  for (const char* name : {"0000000000", "0000000001"}) {
    fs::create_directories(root / kRaw / "velodyne_points" / "data");
    fs::create_directories(root / kRaw / "image_02" / "data");
    io::writeKittiBin((root / kRaw / "velodyne_points" / "data" / name).string() + ".bin", pts);
    cv::imwrite((root / kRaw / "image_02" / "data" / name).string() + ".png", img);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace cleanmap;
  if (size == 0) return 0;
  static const bool written = (writeTemplate(), true);
  (void)written;
  constexpr std::size_t kCount = sizeof(kFiles) / sizeof(kFiles[0]);
  const std::size_t which = data[0] % kCount;
  const std::string path = fuzz::writeInput(kFiles[which].path, data + 1, size - 1);
  const std::string dir = fuzz::scratchDir() + "/" + (which < 3 ? kOdometry : kRaw);
  fuzz::expectCleanError(fuzz::scratchDir(), [&] {
    io::KittiReadOptions opts;
    auto seq = io::KittiSequence::open(dir, opts);
    for (std::size_t i = 0; i < seq.size(); ++i) {
      const Frame f = seq.frame(i);
      if (!std::isfinite(f.scan.timestamp)) fuzz::finding("a non-finite timestamp", path);
      if (f.scan.has_pose && !f.scan.pose.matrix().allFinite())
        fuzz::finding("a non-finite pose", path);
    }
    if (const auto cam = seq.camera()) {
      if (!cam->P.allFinite() || !cam->T_cam_lidar.matrix().allFinite())
        fuzz::finding("a non-finite camera calibration", path);
      if (cam->width <= 0 || cam->height <= 0) fuzz::finding("a camera of no size", path);
    }
  });
  fuzz::writeInput(kFiles[which].path, kFiles[which].text);  // restore for the next input
  return 0;
}
