// SPDX-License-Identifier: BSD-3-Clause
// cleanmap-kitti2rawlog: KITTI odometry / SemanticKITTI / raw folder -> MRPT rawlog or simplemap.
#include <cstring>
#include <iostream>
#include <string>

#include "../common/cli.h"
#include "cleanmap/core/error.h"
#include "cleanmap/io/kitti.h"
#include "cleanmap/mrpt/rawlog.h"

namespace {

constexpr const char* kUsage =
    R"(usage: cleanmap-kitti2rawlog INPUT_DIR OUTPUT.rawlog|OUTPUT.simplemap [--external]

Converts a KITTI folder into an MRPT rawlog (observation-only format), readable by RawLogViewer,
rawlog-edit and cleanmap. Per scan it writes a CObservationRobotPose (when poses exist), a
CObservationPointCloud (XYZI, lidar frame) and a CObservationImage (with TCamera and camera pose)
when the folder has images; all share the scan's timestamp.
An output named *.simplemap is a CSimpleMap instead, as a SLAM saves its keyframes: one keyframe
per scan at its pose (the folder must have poses), holding the point cloud and the image.
cleanmap and cleanmap-build-map read it (MRPT 2.5.8's observations2map inserts point clouds
without their keyframe's pose: use cleanmap-build-map, which takes MRPT's maps too).

INPUT_DIR     KITTI odometry / SemanticKITTI folder (velodyne/, poses.txt, calib.txt, times.txt,
              image_2/) or KITTI raw synced drive (velodyne_points/data/, oxts/data/, image_02/data/,
              calibration in the drive or date folder). See doc/FORMATS.md.
OUTPUT        written atomically (a temporary file renamed at the end). A simplemap is held in
              memory until then (embedded: about 1.8 MB per HDL-64E scan; --external: bytes).
--external    do not embed points and images: reference the .bin and .png files by absolute path
              (MRPT lazy loading, KittiBinFile format). Small output; the KITTI folder must stay.
--help        this text.
)";

}  // namespace

int main(int argc, char** argv) {
  std::string in, out;
  cleanmap::mrpt::RawlogWriteOptions wopts;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      std::cout << kUsage;
      return 0;
    } else if (a == "--external") {
      wopts.external = true;
    } else if (!a.empty() && a[0] == '-') {
      std::cerr << "cleanmap-kitti2rawlog: unknown option '" << a << "' (see --help)\n";
      return 2;
    } else if (in.empty()) {
      in = a;
    } else if (out.empty()) {
      out = a;
    } else {
      std::cerr << "cleanmap-kitti2rawlog: unexpected argument '" << a << "' (see --help)\n";
      return 2;
    }
  }
  if (in.empty() || out.empty()) {
    std::cerr << "cleanmap-kitti2rawlog: need INPUT_DIR and OUTPUT.rawlog or OUTPUT.simplemap (see "
                 "--help)\n";
    return 2;
  }
  try {
    cleanmap::io::KittiReadOptions ro;
    ro.scan.allow_empty = true;  // the rule of every app: empty scans are kept and counted
    auto seq = cleanmap::io::KittiSequence::open(in, ro);
    const bool simplemap = cleanmap::mrpt::isSimplemapName(out);
    if (simplemap && !seq.hasPoses())
      throw cleanmap::Error(in,
                            "has no poses (poses.txt, or oxts/ for a raw drive): a "
                            "simplemap's keyframes need them; write a .rawlog");
    cleanmap::mrpt::RawlogWriter writer(out, wopts);
    const auto camera = seq.camera();
    std::size_t dropped = 0, empty = 0;
    for (std::size_t i = 0; i < seq.size(); ++i) {
      const cleanmap::Frame f = seq.frame(i);
      dropped += f.scan.dropped_invalid;
      empty += f.scan.empty();
      writer.write(f, camera, seq.scanPath(i), seq.hasImages() ? seq.imagePath(i) : std::string());
    }
    writer.close();
    std::cout << "cleanmap-kitti2rawlog: " << out << ": " << writer.scans()
              << (simplemap ? " keyframes, " : " scans, ") << writer.poses() << " poses, "
              << writer.images() << " images" << (wopts.external ? " (external references)" : "");
    if (dropped) std::cout << "; dropped " << dropped << " NaN/inf points";
    if (empty) std::cout << "; " << empty << " empty scans kept (no valid point)";
    std::cout << '\n';
  } catch (const std::exception& e) {
    std::cerr << "cleanmap-kitti2rawlog: error: " << cleanmap::cli::errorLine(e) << '\n';
    return 1;
  }
  return 0;
}
