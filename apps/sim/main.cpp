// SPDX-License-Identifier: BSD-3-Clause
// cleanmap-sim: synthetic HDL-64E + camera sequences with exact labels (issue #4).
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>

#include "../common/cli.h"
#include "cleanmap/core/error.h"
#include "cleanmap/io/files.h"
#include "cleanmap/io/kitti.h"
#include "cleanmap/mrpt/rawlog.h"
#include "cleanmap/sim/generate.h"
#include "cleanmap/sim/world.h"

namespace fs = std::filesystem;

namespace {

bool g_progress_shown = false;

constexpr const char* kUsage = R"(usage: cleanmap-sim [SCENARIO.ini] -o OUTDIR [options]

Generates a street scene seen by a moving Velodyne HDL-64E (64 rings, 10 Hz) and a KITTI-calibrated
colour camera, with exact per-point labels, in the layout of ../shared/data:
  velodyne/NNNNNN.bin  labels/NNNNNN.label (9 static, 251 moving, 0 ignore)  image_2/NNNNNN.png
  calib.txt (P0, P2, Tr)  poses.txt (KITTI camera-0 convention)  times.txt  objects.json
and the same sequence as an MRPT rawlog, OUTDIR/sequence.rawlog.
Without SCENARIO.ini the default scenario (datasets/scenarios/default.ini) is used.
Scenario format: doc/SIMULATOR.md; examples in datasets/scenarios/.

-o, --output DIR   output folder, written as a whole (an error leaves it as it was); an
                   earlier sequence there is replaced, another non-empty folder refused
--frames N         generate the first N frames only
--threads N        ray-casting threads (default 2; the output does not depend on it)
--no-images        skip the camera images
--no-rawlog        skip sequence.rawlog
--print-default    print the default scenario and exit
--help             this text
)";

}  // namespace

int main(int argc, char** argv) {
  std::string scenario, out;
  long frames = -1, threads = 2;
  bool images = true, rawlog = true;
  cleanmap::cli::Args args("cleanmap-sim", argc, argv);
  while (!args.done()) {
    const std::string a = args.next();
    if (a == "--help" || a == "-h") {
      std::cout << kUsage;
      return 0;
    } else if (a == "--print-default") {
      std::cout << cleanmap::sim::defaultScenarioText();
      return 0;
    } else if (a == "-o" || a == "--output")
      out = args.value(a);
    else if (a == "--frames")
      frames = args.integer(a, 1);
    else if (a == "--threads")
      threads = args.integer(a, 1);
    else if (a == "--no-images")
      images = false;
    else if (a == "--no-rawlog")
      rawlog = false;
    else if (!a.empty() && a[0] != '-' && scenario.empty())
      scenario = a;
    else
      args.unexpected(a);
  }
  if (out.empty()) args.fail("need -o OUTDIR");
  try {
    auto sc =
        scenario.empty() ? cleanmap::sim::defaultScenario() : cleanmap::sim::loadScenario(scenario);
    if (frames > 0) sc.frames = static_cast<int>(std::min<long>(frames, sc.frames));
    cleanmap::sim::GenerateOptions opt;
    opt.threads = static_cast<int>(threads);
    opt.images = images;
    // Written as a whole (a staging folder beside OUTDIR, then one rename): an error or a signal
    // leaves OUTDIR as it was. An earlier sequence is replaced; any other non-empty folder is not.
    cleanmap::io::requireReplaceableFolder(
        out, [](const std::string& d) { return fs::exists(fs::path(d) / "scenario.ini"); },
        "cleanmap-sim sequence (no scenario.ini)", "-o");
    cleanmap::io::StagedFolder staged(out, "cleanmap-sim");
    const std::string dir = staged.path();
    const auto sum = cleanmap::sim::generateSequence(sc, dir, opt, [](int d, int t) {
      g_progress_shown = true;
      std::fprintf(stderr, "\rcleanmap-sim: frame %d/%d   ", d, t);
    });
    std::fprintf(stderr, "\n");
    cleanmap::io::writeFileAtomic(dir + "/scenario.ini", [&](std::ostream& os) {
      os << (scenario.empty() ? cleanmap::sim::defaultScenarioText()
                              : cleanmap::io::readTextFile(scenario));
    });
    if (rawlog) {
      cleanmap::io::KittiReadOptions ro;
      auto seq = cleanmap::io::KittiSequence::open(dir, ro);
      cleanmap::mrpt::RawlogWriter writer(dir + "/sequence.rawlog");
      const auto camera = seq.camera();
      for (std::size_t i = 0; i < seq.size(); ++i) {
        cleanmap::Frame f = seq.frame(i);
        f.odometry = cleanmap::sim::odometryPose(sc, static_cast<int>(i));  // [ego] odometry
        writer.write(f, camera, seq.scanPath(i),
                     seq.hasImages() ? seq.imagePath(i) : std::string());
      }
      writer.close();
    }
    staged.publish();
    std::printf("cleanmap-sim: %s: %zu frames, %zu points (%zu moving), %zu images%s -> %s\n",
                sc.name.c_str(), sum.frames, sum.points, sum.moving_points, sum.images,
                rawlog ? ", sequence.rawlog" : "", out.c_str());
  } catch (const std::exception& e) {
    std::cerr << (g_progress_shown ? "\n" : "") << "cleanmap-sim: error: "
              << cleanmap::io::messageWithoutStaging(cleanmap::cli::errorLine(e), out,
                                                     "cleanmap-sim")
              << '\n';
    return 1;
  }
  return 0;
}
