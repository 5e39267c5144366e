// SPDX-License-Identifier: BSD-3-Clause
// Scenario files of cleanmap-sim (datasets/scenarios/*.ini, format in doc/SIMULATOR.md): a street
// scene, the ego path, the sensor, and the movers, all in one world frame (x along the road,
// z up). Everything is deterministic given the file.
#pragma once
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cleanmap/core/sensor.h"

namespace cleanmap::sim {

enum class Texture { kChecker, kFlat };

struct SensorSpec {
  double azimuth_step_deg = 0.18;  ///< 2000 columns per turn x 64 rings = 128k rays
  double range_noise = 0.01;       ///< m, Gaussian sigma
  double dropout = 0.01;           ///< probability that a ray returns nothing
  double min_range = 2.0, max_range = 120.0;
  double height = 1.73;  ///< above the ground under the ego
  /// Ego and movers move during the 0.1 s sweep; each point's time rides with the frame
  /// (SimScan::point_time), not in the KITTI folder's files (DESIGN §2.0).
  bool sweep_motion = false;
  bool camera = true;  ///< render image_2/ (KITTI size and calibration)
  /// Lidar model (issue #15): `model` (a preset of cleanmap/core/sensor.h: its rings and
  /// azimuth step), or `rings` evenly spaced over `vertical_fov_deg`. Default: the HDL-64E.
  SensorModel model = SensorModel::kHdl64;
  std::vector<double> elevations = ringElevations(SensorModel::kHdl64);  ///< rad, top to bottom
};

struct GroundSpec {
  double slope = 0.0;            ///< grade along x (0.2 = 20 %)
  double road_half_width = 6.0;  ///< |y| <= this is road; beyond, sidewalk raised by curb_height
  double curb_height = 0.0;
  /// Optional ramp on the road: rises linearly over x in [x0, x1] to `height`, plateau to x2,
  /// for y in [y0, y1].
  std::optional<std::array<double, 6>> ramp;  ///< x0 x1 x2 y0 y1 height
};

/// A box standing on the ground (buildings, walls, parked vehicles).
struct BoxSpec {
  std::string name, cls = "building";
  Eigen::Vector2d center = Eigen::Vector2d::Zero();
  Eigen::Vector3d size = Eigen::Vector3d::Ones();  ///< l (along yaw), w, h
  double yaw = 0.0, lift = 0.0;                    ///< rad; lift: base above the ground, m
  Texture texture = Texture::kChecker;
  Eigen::Vector3f colour{0.6f, 0.6f, 0.6f};
  bool tracked = false;  ///< listed in objects.json (vehicles)
};

/// A vertical cylinder standing on the ground (poles, tree trunks).
struct CylinderSpec {
  std::string name, cls = "pole";
  Eigen::Vector2d center = Eigen::Vector2d::Zero();
  double radius = 0.15, height = 4.0;
  Eigen::Vector3f colour{0.5f, 0.45f, 0.4f};
};

/// A box moving along a polyline at `speed`, optionally waiting before `start` and standing
/// still during [stop_from, stop_to]. With `accel` > 0 it pulls away from rest and brakes to a
/// stop at that rate (m/s2) instead of changing speed at once.
struct MoverSpec {
  std::string name, cls = "car";
  Eigen::Vector3d size{4.5, 1.8, 1.5};
  std::vector<Eigen::Vector2d> path;
  double speed = 5.0, start = 0.0;
  double accel = 0.0;  ///< m/s2; 0 = speed changes at once
  std::optional<std::pair<double, double>> stop;
  Texture texture = Texture::kChecker;
  Eigen::Vector3f colour{0.7f, 0.1f, 0.1f};
};

struct Scenario {
  std::string name = "scenario", source;
  int frames = 40;
  double rate_hz = 10.0;
  uint64_t seed = 1;
  SensorSpec sensor;
  GroundSpec ground;
  std::vector<Eigen::Vector2d> ego_path{{0, 0}, {100, 0}};
  double ego_speed = 5.0;
  /// Pose error of the written poses (the scans are cast from the true pose): a seeded random
  /// walk, per horizontal axis, of this standard deviation per metre travelled (0.01 = 1 %).
  double ego_pose_drift = 0.0;
  /// Wheel odometry written to sequence.rawlog (CObservationOdometry): the true pose plus a seeded
  /// random walk of this standard deviation per metre, like pose drift; -1 = no odometry.
  double ego_odometry = -1.0;
  std::vector<BoxSpec> boxes;
  std::vector<CylinderSpec> cylinders;
  std::vector<MoverSpec> movers;
};

/// Parses scenario text; `name` names it in errors ("file:line: what"). Unknown sections or keys,
/// bad numbers and impossible values are errors.
Scenario parseScenario(const std::string& text, const std::string& name);
/// Reads a scenario file.
Scenario loadScenario(const std::string& path);
/// The default scenario (datasets/scenarios/default.ini, compiled in).
Scenario defaultScenario();
const std::string& defaultScenarioText();

}  // namespace cleanmap::sim
