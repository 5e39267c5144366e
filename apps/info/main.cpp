// SPDX-License-Identifier: BSD-3-Clause
// cleanmap-info: what a KITTI folder or rawlog holds, as cleanmap reads it.
#include <algorithm>
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include "../common/cli.h"
#include "cleanmap/core/error.h"
#include "cleanmap/core/params.h"
#include "cleanmap/io/kitti.h"
#include "cleanmap/mrpt/input.h"
#include "cleanmap/mrpt/rawlog.h"

namespace {

constexpr const char* kUsage = R"(usage: cleanmap-info INPUT

Summarises a KITTI folder (odometry, SemanticKITTI or raw) or an MRPT rawlog as cleanmap reads
it: scans and points per scan, invalid points dropped, poses and trajectory length, images and
camera, a rawlog's sensors and the scans timed earlier than the scan before, and, for labelled
folders, the share of moving points.
)";

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2 || std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h") {
    std::cout << kUsage;
    return argc == 2 ? 0 : 2;
  }
  const std::string input = argv[1];
  try {
    cleanmap::mrpt::InputOptions opts;
    opts.allow_empty_scans = true;
    auto src = cleanmap::mrpt::openInput(input, opts);
    const auto* kitti = dynamic_cast<const cleanmap::io::KittiSequence*>(src.get());
    const auto* rawlog = dynamic_cast<const cleanmap::mrpt::RawlogSource*>(src.get());
    std::vector<std::size_t> sizes;
    std::size_t dropped = 0, posed = 0, images = 0, empty = 0, moving = 0, labelled = 0,
                odometry = 0, timed = 0;
    std::vector<double> spans;  // each timed scan's first to last point time (s)
    double length = 0, t0 = 0, t1 = 0;
    std::optional<Eigen::Vector3d> last;
    std::vector<double> times;
    std::vector<Eigen::Vector3d> positions;  // while every scan has a pose
    bool all_posed = true;
    while (auto f = src->next()) {
      const auto& s = f->scan;
      if (sizes.empty()) t0 = s.timestamp;
      times.push_back(s.timestamp);
      all_posed = all_posed && s.has_pose;
      if (all_posed) positions.push_back(s.pose.translation());
      t1 = s.timestamp;
      sizes.push_back(s.size());
      dropped += s.dropped_invalid;
      empty += s.empty();
      images += f->image.has_value();
      odometry += f->odometry.has_value();
      if (!s.point_time.empty()) {
        ++timed;
        const auto [lo, hi] = std::minmax_element(s.point_time.begin(), s.point_time.end());
        spans.push_back(double(*hi) - double(*lo));
      }
      if (s.has_pose) {
        ++posed;
        if (last) length += (s.pose.translation() - *last).norm();
        last = s.pose.translation();
      }
      if (kitti && kitti->hasLabels()) {
        for (uint32_t l : kitti->loadLabels(f->index, s.original_size)) {
          labelled += 1;
          moving += cleanmap::gtClass(l) == cleanmap::GtClass::kMoving;
        }
      }
    }
    std::vector<std::size_t> sorted = sizes;
    std::sort(sorted.begin(), sorted.end());
    std::printf("input:   %s (%s)\n", input.c_str(),
                kitti ? (kitti->layout() == cleanmap::io::KittiLayout::kRaw ? "KITTI raw"
                                                                            : "KITTI odometry")
                      : (rawlog && rawlog->isSimplemap() ? "MRPT simplemap" : "MRPT rawlog"));
    std::printf("scans:   %zu over %.2f s; points per scan min %zu / median %zu / max %zu\n",
                sizes.size(), t1 - t0, sorted.front(), sorted[sorted.size() / 2], sorted.back());
    std::printf("invalid: %zu NaN/inf points dropped, %zu empty scans\n", dropped, empty);
    std::printf("poses:   %zu of %zu scans; trajectory %.2f m\n", posed, sizes.size(), length);
    // DESIGN §2b: the window compares neighbouring sweeps; a SLAM's keyframes may be far apart.
    if (!all_posed) positions.clear();
    if (const auto gap = cleanmap::scanSpacing(times, positions)) {
      if (const auto w = cleanmap::sparseScansWarning(gap->seconds, gap->metres); !w.empty())
        std::printf("spacing: %s\n", w.c_str());
      else if (all_posed)
        std::printf("spacing: %.2f s and %.2f m between scans (median)\n", gap->seconds,
                    gap->metres);
      else
        std::printf("spacing: %.2f s between scans (median)\n", gap->seconds);
    }
    // DESIGN §2.0: scans whose points carry their times are de-skewed (sensor.deskew auto)
    if (timed) {
      std::sort(spans.begin(), spans.end());
      std::printf("point times: %zu of %zu scans, sweep %.1f ms (median): de-skewed by default\n",
                  timed, sizes.size(), 1000.0 * spans[spans.size() / 2]);
    } else {
      std::printf("point times: none: not de-skewed unless sensor.deskew = 1\n");
    }
    if (odometry)  // rawlog odometry: GICP's guess with --poses gicp (DESIGN §2.1)
      std::printf("odometry: %zu of %zu scans\n", odometry, sizes.size());
    if (const auto cam = src->camera())
      std::printf("images:  %zu; camera %s %dx%d, focal %.1f px\n", images, cam->name.c_str(),
                  cam->width, cam->height, cam->focal());
    else
      std::printf("images:  %zu\n", images);
    if (const auto* r = rawlog) {
      // "lidar 'X'" and the other sensors of that kind the reader skipped, with the option.
      const auto sensor = [](const char* kind, const std::string& label, const auto& others) {
        std::string line = std::string(kind) + " '" + label + "'";
        if (!others.empty())
          line += std::string("; other ") + kind +
                  "s, skipped: " + cleanmap::mrpt::labelCounts(others) + "; cleanmap --" + kind +
                  " LABEL chooses";
        return line;
      };
      std::string line = "sensors: " + sensor("lidar", r->lidarLabel(), r->otherLidars());
      if (!r->cameraLabel().empty())
        line += "; " + sensor("camera", r->cameraLabel(), r->otherCameras());
      std::printf("%s\n", line.c_str());
      if (const auto w = cleanmap::mrpt::timedBackWarning(*r); !w.empty())
        std::printf("times:   %s\n", w.c_str());
    }
    if (labelled)
      std::printf("labels:  %zu points, %zu moving (%.2f %%)\n", labelled, moving,
                  100.0 * static_cast<double>(moving) / static_cast<double>(labelled));
  } catch (const std::exception& e) {
    std::cerr << "cleanmap-info: error: " << cleanmap::cli::errorLine(e) << '\n';
    return 1;
  }
  return 0;
}
