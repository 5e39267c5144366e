// SPDX-License-Identifier: BSD-3-Clause
// The lidar models cleanmap knows (issue #15; doc/SIMULATOR.md): a preset gives the ring
// elevations and the azimuth step that cleanmap-sim casts.
#pragma once
#include <optional>
#include <string>
#include <vector>

#include "cleanmap/core/types.h"

namespace cleanmap {

enum class SensorModel { kAuto, kHdl64, kHdl32, kVlp16, kOs1_64, kOs1_128 };

struct SensorPreset {
  SensorModel model;
  const char* name;         ///< as in ini files: hdl64, hdl32, vlp16, os1-64, os1-128
  int rings;                ///< lasers
  double fov_lo_deg;        ///< lowest ring's elevation
  double fov_hi_deg;        ///< highest ring's elevation
  double azimuth_step_deg;  ///< between the columns of a ring, at 10 Hz
};

/// Every preset (not kAuto), in the order of SensorModel.
const std::vector<SensorPreset>& sensorPresets();
const SensorPreset& sensorPreset(SensorModel m);  ///< m != kAuto
/// The model named `name` ("auto" included); nullopt if unknown.
std::optional<SensorModel> sensorModelByName(const std::string& name);
/// "auto", "hdl64", ...
const char* sensorModelName(SensorModel m);

/// Ring elevations of a preset, radians, top to bottom: the HDL-64E's two blocks (upper +2.0 ..
/// -8.33 deg, lower -8.83 .. -24.33 deg), evenly spaced rings for the others.
std::vector<double> ringElevations(SensorModel m);
/// `rings` elevations evenly spaced from hi_deg down to lo_deg, radians (rings >= 2).
std::vector<double> evenElevations(int rings, double lo_deg, double hi_deg);

/// The angular spacing of a lidar's returns, degrees: between neighbouring rings and between
/// neighbouring returns of a ring.
struct AngularResolution {
  double vertical_deg = 0, azimuth_deg = 0;
};
/// A preset's: its field of view over rings - 1, and its azimuth step.
AngularResolution presetResolution(SensorModel m);
/// Rings closer than this (degrees) are measured only with columns coarser than
/// kCoarseColumnsDeg (measureResolution).
constexpr double kDenseRingsDeg = 0.8;
/// 1.5 times the HDL-64E's column step at 10 Hz (0.18 degrees): coarser columns are not its.
constexpr double kCoarseColumnsDeg = 0.27;
/// Measured in one scan (sensor frame) from the elevations and azimuths of its returns 5-100 m
/// away horizontally: rings are runs of 0.05-degree elevation bins with returns, separated by
/// empty bins, holding at least an eighth of a typical ring's returns; the azimuth step is the
/// median over rings of each ring's median gap. nullopt where fewer than 8 rings stand apart, or
/// they lie less than kDenseRingsDeg apart with columns no coarser than kCoarseColumnsDeg (the
/// HDL-64E, whose rings blur together, KITTI's included: the reference density). An Ouster at
/// 1024 columns (0.35 degrees) is measured. `rings_deg`, where given, receives the rings' median
/// gap wherever 8 stand apart, dense or not (the simulated HDL-64E 0.33, KITTI's blurred
/// 0.50-0.52).
std::optional<AngularResolution> measureResolution(const std::vector<PointXYZI>& points,
                                                   double* rings_deg = nullptr);
/// Returns per solid angle relative to the HDL-64E's (DESIGN §2d): what a point count tuned on it
/// (object.min_moving) is multiplied by for this sensor.
double densityScale(const AngularResolution& r);
/// An HDL-64E point count (object.min_moving, rule 7's least component) scaled by a scan's
/// densityScale, at least 1.
int scaledCount(double n, double density);

}  // namespace cleanmap
