// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2.1: scan-to-local-map GICP odometry. The map starts with the first scan; each new scan
// is aligned from a constant-velocity guess (or a given prior), checked (too few points,
// degenerate scene, a jump beyond max_speed / max_turn_rate) and, if accepted, added to the map.
// Points the pipeline later decides moving are taken out of the map (dropPoints). A scan is not
// aligned against the entries of the last `map_lag` accepted scans (traffic moving with the
// sensor sits in them; DESIGN §2.1).
#pragma once
#include <Eigen/Geometry>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cleanmap/core/params.h"
#include "cleanmap/core/types.h"
#include "cleanmap/registration/gicp.h"
#include "cleanmap/registration/voxel_map.h"

namespace cleanmap::reg {

struct OdometryStep {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  ///< sensor pose in the world
  GicpResult gicp;        ///< the alignment (iterations 0 for the first scan)
  bool accepted = false;  ///< false: `pose` is the prediction, the scan was not added to the map
  std::string status;     ///< "first", "ok", or why the alignment was refused
  std::string reason;     ///< a refusal's reason without its figures ("" when accepted)
  bool map_restarts = false;  ///< refused for want of overlap: the map starts again next scan
  int start_guesses = 0;      ///< guesses tried after a standstill's was refused (DESIGN §2.1)
  int guess_iterations = 0;   ///< their GICP iterations, the best one's run on included
  /// Wall time of each step, ms: range crop + downsampling (and de-skew), covariances, GICP,
  /// map update.
  double ms_downsample = 0, ms_covariances = 0, ms_align = 0, ms_map = 0;
};

/// Where track()'s `prior` comes from: given poses (refine, the first scan) only start GICP;
/// input odometry also bounds how far GICP may move from it
/// (RegistrationParams::odometry_tolerance).
enum class Prior { kGiven, kOdometry };

class Odometry {
 public:
  Odometry(const RegistrationParams& p, int threads);
  Odometry(const Odometry& o);  ///< copies the map and the motion model (not the scratch tables)
  Odometry& operator=(const Odometry&) = delete;
  ~Odometry();

  /// The pose of a scan (sensor-frame points) taken at `timestamp` (s). `prior` replaces the
  /// constant-velocity guess (--poses refine, rawlog odometry: `kind`). With `times` (each
  /// point's time after `timestamp`, DESIGN §2.0) the points are aligned de-skewed by the motion
  /// of the last two poses; without, only where registration.deskew is on (azimuth times).
  OdometryStep track(const std::vector<PointXYZI>& points, double timestamp, int64_t scan,
                     const std::optional<Eigen::Isometry3d>& prior = std::nullopt,
                     Prior kind = Prior::kGiven, const std::vector<float>* times = nullptr);
  /// The vehicle's forward axis in the sensor's frame (default x): the start's search along it
  /// (DESIGN §2.1 "Starting at speed"). A lidar mounted yawed on the vehicle: its mount's inverse
  /// rotation of the vehicle's x.
  void setForwardAxis(const Eigen::Vector3d& axis) { forward_ = axis.normalized(); }
  /// Takes the points of `scan` flagged in `drop` (indexed like the scan's points) out of the map.
  void dropPoints(int64_t scan, const std::vector<uint8_t>& drop) { map_.remove(scan, drop); }

  const VoxelMap& map() const { return map_; }

 private:
  Eigen::Isometry3d predict(double timestamp) const;

  RegistrationParams p_;
  GicpParams gicp_;
  int threads_;
  Eigen::Vector3d forward_ = Eigen::Vector3d::UnitX();
  VoxelMap map_;
  std::vector<std::pair<double, Eigen::Isometry3d>> last_;    // the last two accepted (time, pose)
  std::optional<std::pair<double, Eigen::Isometry3d>> prev_;  // the previous scan, even refused
  double odometry_path_ = 0;  // m odometry alone has moved the pose since the last accepted scan
  // The last odometry_window scans with input odometry: the odometry's own chain of poses (its
  // increments, anchored at the first estimate), the estimate, and the odometry's path so far.
  struct OdometryMark {
    Eigen::Isometry3d odometry, pose;
    double path;
  };
  std::deque<OdometryMark> marks_;
  int no_overlap_ = 0;            // refusals for want of overlap with the map since then
  std::deque<int64_t> accepted_;  // the last map_lag + 1 accepted scans; the oldest is aligned to
  struct Scratch;                 // per-scan tables, reused
  std::unique_ptr<Scratch> scratch_;
};

}  // namespace cleanmap::reg
