// SPDX-License-Identifier: BSD-3-Clause
// Writes a simulated sequence in the layout of ../shared/data (doc/FORMATS.md): velodyne/*.bin,
// labels/*.label, image_2/*.png, calib.txt, poses.txt, times.txt, objects.json.
#pragma once
#include <functional>
#include <string>

#include "cleanmap/sim/scenario.h"

namespace cleanmap::sim {

struct GenerateOptions {
  int threads = 2;
  bool images = true;  ///< render image_2/ when the scenario's sensor has a camera
};

struct GenerateSummary {
  std::size_t frames = 0, points = 0, moving_points = 0, images = 0;
};

/// Generates every frame of `sc` into `dir` (created). Each file is written atomically.
/// `progress(done, total)` after each frame.
GenerateSummary generateSequence(const Scenario& sc, const std::string& dir,
                                 const GenerateOptions& opt,
                                 const std::function<void(int, int)>& progress = {});

}  // namespace cleanmap::sim
