// SPDX-License-Identifier: BSD-3-Clause
// The scene at one instant, as ray-castable primitives, and the simulated sensors: a Velodyne
// HDL-64E (64 rings, 10 Hz) and a KITTI-calibrated pinhole camera.
#pragma once
#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "cleanmap/core/frame.h"
#include "cleanmap/core/types.h"
#include "cleanmap/sim/scenario.h"

namespace cleanmap::sim {

/// What a ray hit.
/// kCurb: vertical step faces of the ground (curbs, ramp sides); neither ground nor object.
enum class Surface { kNone, kGround, kCurb, kStatic, kMover };

struct Hit {
  double t = 0;  ///< distance along the (unit) ray
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  Surface surface = Surface::kNone;
  int object = -1;           ///< index into World::objects(), -1 for ground
  Eigen::Vector2d uv{0, 0};  ///< surface coordinates, m (for textures)
};

/// One solid of the scene at time t.
struct Solid {
  enum Kind { kBox, kCylinder } kind = kBox;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();  ///< box centre; cylinder base centre
  Eigen::Vector3d half = Eigen::Vector3d::Ones();    ///< box half sizes (l, w, h)/2
  double yaw = 0, c = 1, s = 0;
  double radius = 0, height = 0;  ///< cylinder
  double bound = 0;               ///< xy bounding-circle radius
  Surface surface = Surface::kStatic;
  Texture texture = Texture::kChecker;
  Eigen::Vector3f colour{0.5f, 0.5f, 0.5f};
  int tracked_id = 0;  ///< objects.json id, 0 if not tracked
  std::string name, cls;
  /// Motion truth (movers): 1 moving, 0 static, -1 uncertain (the labelled data's rules: > 0.5 m
  /// over
  /// +-0.5 s is moving, < 0.2 m is static).
  int motion = 0;
};

class World {
 public:
  /// The scene of `sc` at time `t` seconds.
  World(const Scenario& sc, double t);
  /// Nearest hit of the ray origin + t dir (dir unit), t in (0, max_t]. `only` restricts the
  /// solids tested (indices); nullptr = all.
  bool intersect(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double max_t, Hit& hit,
                 const std::vector<int>* only = nullptr) const;
  const std::vector<Solid>& solids() const { return solids_; }
  /// Ground height at (x, y), the road's, sidewalk's or ramp's.
  double groundHeight(double x, double y) const;

 private:
  bool intersectGround(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double max_t,
                       Hit& hit) const;
  GroundSpec g_;
  std::vector<Solid> solids_;
};

/// Ground height at (x, y) for a ground description.
double groundHeight(const GroundSpec& g, double x, double y);
/// Ego sensor pose at time t (lidar frame in the world: x forward, z up, pitched with the road).
Eigen::Isometry3d egoPose(const Scenario& sc, double t);
/// The pose of frame k as a localisation system would report it: egoPose plus a random walk of
/// Scenario::ego_pose_drift per metre travelled on x and y (seeded; 0 drift = egoPose).
Eigen::Isometry3d reportedPose(const Scenario& sc, int k);
/// The wheel odometry of frame k where the scenario has it (Scenario::ego_odometry; its own
/// seeded walk, in the world frame: only its increments mean something), else nothing.
std::optional<Eigen::Isometry3d> odometryPose(const Scenario& sc, int k);
/// Position and heading (x, y, yaw) along a polyline after arc length s (clamped to its end;
/// before its start, on along the first segment).
Eigen::Vector3d alongPath(const std::vector<Eigen::Vector2d>& path, double s);
/// Arc length a mover has covered by time t (start delay and stop interval applied).
double moverArc(const MoverSpec& m, double t);

/// HDL-64E ring elevations, radians, top to bottom.
const std::vector<double>& hdl64Elevations();

struct SimScan {
  double time = 0;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  ///< lidar pose at `time` (truth)
  /// The pose written to poses.txt: `pose` plus the scenario's pose drift (reportedPose).
  Eigen::Isometry3d reported_pose = Eigen::Isometry3d::Identity();
  std::vector<PointXYZI> points;  ///< sensor frame at each point's capture time (not de-skewed)
  Labels labels;                  ///< ground truth: 9 static, 251 moving, 0 ignore (DESIGN §5)
  std::vector<Surface> surface;   ///< per point
  std::vector<int> solid;         ///< per point, index into the frame's World::solids(), -1 ground
  /// Per point with sweep_motion (else empty): its capture time in s after `time` (DESIGN §2.0).
  std::vector<float> point_time;
};

/// One lidar sweep of frame `k`. Deterministic for a given scenario (noise is a hash of the seed,
/// frame and ray), whatever `threads`.
SimScan simulateScan(const Scenario& sc, int k, int threads = 2);
/// The pipeline's input for frame `k`, as cleanmap reads what cleanmap-sim writes: the scan's
/// points (moved out of `s`), its reported pose and time, stem "%06d".
Frame frameOf(SimScan&& s, int k);

/// KITTI 2011_09_26 left colour camera (rectified P2 and velodyne-to-camera Tr), 1242 x 375.
PinholeCamera kittiCamera();
/// Renders frame k by ray casting the scene at the frame's time (BGR, 8 bit). `cull_solids`: each
/// band of columns tests only the solids its rays can reach (the same image); false tests every
/// solid for every pixel, the reference the tests compare against.
cv::Mat renderImage(const Scenario& sc, int k, const PinholeCamera& cam, int threads = 2,
                    bool cull_solids = true);

}  // namespace cleanmap::sim
