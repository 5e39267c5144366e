// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/registration/odometry.h"

#include "cleanmap/core/cell_key.h"
#include "cleanmap/core/cell_map.h"
#include "cleanmap/core/deskew.h"
#include "cleanmap/core/stopwatch.h"

#include <cmath>

namespace cleanmap::reg {

struct Odometry::Scratch {
  CellMap<uint8_t> voxels;  // the voxels that have their point, reused scan after scan
};

Odometry::~Odometry() = default;

Odometry::Odometry(const Odometry& o)
    : p_(o.p_),
      gicp_(o.gicp_),
      threads_(o.threads_),
      forward_(o.forward_),
      map_(o.map_),
      last_(o.last_),
      prev_(o.prev_),
      odometry_path_(o.odometry_path_),
      marks_(o.marks_),
      no_overlap_(o.no_overlap_),
      accepted_(o.accepted_),
      scratch_(std::make_unique<Scratch>()) {}

Odometry::Odometry(const RegistrationParams& p, int threads)
    : p_(p),
      threads_(threads),
      map_(p.max_correspondence, p.map_points_per_voxel),
      scratch_(std::make_unique<Scratch>()) {
  gicp_.max_correspondence = p.max_correspondence;
  gicp_.kernel = p.kernel;
  gicp_.max_iterations = p.max_iterations;
}

// Constant velocity: the relative motion between the last two accepted scans, scaled to the time
// since the previous scan and applied to its pose (accepted, or itself a guess). Through a run of
// refused scans (a corridor, a lidar dropout) the sensor so keeps that velocity; extrapolating
// from the last accepted scan stopped it 5 scans in (the cap, meant for gaps in time). The
// velocity is not taken from a guess: a refused stretch's accumulated error, corrected by the
// next accepted scan, is not a motion (DESIGN §2.1 step 4).
Eigen::Isometry3d Odometry::predict(double t) const {
  if (!prev_) return Eigen::Isometry3d::Identity();
  if (last_.size() < 2) return prev_->second;
  const auto& [t0, T0] = last_[0];
  const auto& [t1, T1] = last_[1];
  const Eigen::Isometry3d delta = T0.inverse() * T1;
  const double dt_prev = t1 - t0, dt = t - prev_->first;
  double s = (dt_prev > 1e-6 && dt > 0) ? dt / dt_prev : 1.0;
  s = std::min(s, 5.0);  // a long gap: do not extrapolate wildly
  const Eigen::AngleAxisd aa(delta.linear());
  Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
  step.linear() = Eigen::AngleAxisd(aa.angle() * s, aa.axis()).toRotationMatrix();
  step.translation() = delta.translation() * s;
  return prev_->second * step;
}

OdometryStep Odometry::track(const std::vector<PointXYZI>& points_in, double t, int64_t scan,
                             const std::optional<Eigen::Isometry3d>& prior, Prior kind,
                             const std::vector<float>* times) {
  auto t0 = Clock::now();
  OdometryStep step;
  // The points to align: within [min_range, max_range], one per voxel, in one pass over the
  // scan (the first point of each voxel, in scan order).
  const double r0 = p_.min_range * p_.min_range, r1 = p_.max_range * p_.max_range;
  // De-skew (DESIGN §2.0): each point moved to the frame of the scan's timestamp under the motion
  // of the last two poses. Without given times (registration.deskew alone), a 0.1 s sweep
  // clockwise from the rear, the timestamp's frame at its middle (azimuth 0).
  std::vector<PointXYZI> deskewed;
  if ((times || p_.deskew) && last_.size() == 2) {
    const SweepMotion motion =
        SweepMotion::between(last_[0].second, last_[0].first, last_[1].second, last_[1].first);
    deskewed = points_in;
    deskewPoints(deskewed, times ? *times : azimuthTimes(points_in, 0.1), motion);
  }
  const std::vector<PointXYZI>& points = deskewed.empty() ? points_in : deskewed;
  CovCloud cloud;
  CellMap<uint8_t>& voxels = scratch_->voxels;
  voxels.clear();  // keeps its slots: it grows (at half full) only while scans get denser
  voxels.reserve(points.size() / 8);
  const double inv = 1.0 / p_.voxel;
  uint64_t last = ~uint64_t(0);  // neighbours along a ring mostly share a voxel: no lookup then
  for (uint32_t i = 0; i < points.size(); ++i) {
    Eigen::Vector3d q = points[i].xyz().cast<double>();
    const double d2 = q.squaredNorm();
    if (d2 < r0 || d2 > r1) continue;
    const uint64_t key = cellKeyOf(q.x(), q.y(), q.z(), inv);
    if (key == last) continue;  // the voxel of the point before: already taken
    last = key;
    if (!voxels.insert(key)) continue;
    cloud.points.push_back(q);
    cloud.source.push_back(i);
  }
  step.ms_downsample = msSince(t0);
  t0 = Clock::now();
  cloud.covs = planeCovariances(cloud.points, p_.knn, 2.0 * p_.voxel, p_.plane_epsilon, threads_);
  CovCloud align;  // a sparser subset is aligned; the map gets the whole downsampled cloud
  for (const uint32_t k : voxelDownsample(cloud.points, p_.align_voxel)) {
    align.points.push_back(cloud.points[k]);
    align.covs.push_back(cloud.covs[k]);
  }
  step.ms_covariances = msSince(t0);
  t0 = Clock::now();
  const Eigen::Isometry3d guess = prior ? *prior : predict(t);
  // The input odometry's own chain of poses: its increment since the previous scan (the guess
  // is the previous estimate moved by it) on its pose there; a scan without it breaks the chain.
  std::optional<Eigen::Isometry3d> odometry;
  double path = 0;
  if (prior && kind == Prior::kOdometry) {
    if (!prev_) {
      marks_.clear();
      odometry = guess;
    } else {
      // The chain starts at the previous scan where that one had no odometry.
      if (marks_.empty()) marks_.push_back({prev_->second, prev_->second, 0.0});
      const Eigen::Isometry3d inc = prev_->second.inverse() * guess;
      odometry = marks_.back().odometry * inc;
      path = marks_.back().path + inc.translation().norm();
    }
  } else
    marks_.clear();
  if (map_.empty()) {
    accepted_.clear();  // the map starts again with this scan
    step.pose = guess;
    step.accepted = cloud.size() >= static_cast<std::size_t>(gicp_.min_correspondences);
    step.status = step.accepted
                      ? "first"
                      : "too few points to start the map (" + std::to_string(cloud.size()) + ")";
    if (!step.accepted) step.reason = "too few points to start the map";
  } else {
    // DESIGN §2.1, "Traffic that moves with the sensor": the entries of the last map_lag accepted
    // scans are left out (until map_lag + 1 are accepted, only the first scan's are aligned to).
    const int64_t newest = accepted_.empty() ? INT64_MAX : accepted_.front();
    auto attempt = [&](const Eigen::Isometry3d& from, OdometryStep& st, const GicpParams& gp) {
      st.gicp = alignGicp(align, map_, from, gp, threads_, newest);
      st.pose = st.gicp.T;
      st.status = st.gicp.failure.empty() ? "ok" : st.gicp.failure;
      st.reason = st.gicp.reason;
      if (st.gicp.failure.empty() && !last_.empty()) {  // a jump beyond what the motion allows
        const Eigen::Isometry3d rel = last_.back().second.inverse() * st.pose;
        const double dt = std::max(t - last_.back().first, 0.1);
        const double turn = Eigen::AngleAxisd(rel.linear()).angle();
        if (rel.translation().norm() > p_.max_speed * dt + 0.5 ||
            turn > p_.max_turn_rate * dt + 0.05) {
          st.status = "jump of " + std::to_string(rel.translation().norm()) + " m / " +
                      std::to_string(turn) + " rad in " + std::to_string(dt) + " s";
          st.reason = "a jump beyond max_speed / max_turn_rate";
        }
      }
    };
    attempt(guess, step, gicp_);
    // DESIGN §2.1 "Starting at speed": no velocity yet (no two accepted scans) and no prior, the
    // guess is a standstill, a scan period's travel off for a car already driving (1.4 m at
    // 14 m/s, beyond the correspondences' reach: a street's corridor then holds it, degenerate).
    // Refused, it is tried again from guesses along the vehicle's forward axis (forward_), both
    // ways, every half correspondence distance up to max_speed; the best accepted fitness wins.
    // Accepted, it may still be a standstill that a street's facades and road hold (sampled alike
    // by the same beams at every step, they fit it best: at 10 m/s its fitness and RMSE win). The
    // surfaces that face the forward axis say where along the street the sensor is: where the
    // scan has kFacingPoints of them and the standstill fits fewer than half of them
    // (facingScore < 0.5), the guesses run, scored on those surfaces, and the best replaces the
    // standstill if it fits most of them (> 0.5; a mover's face alone, a minority, does not).
    constexpr std::size_t kFacingPoints = 20;
    constexpr int kScreenIterations = 8;  // a guess's GICP iterations before it is scored
    const bool starting = !prior && last_.size() < 2 && prev_;
    std::optional<double> still_facing;
    if (starting && step.status == "ok")
      still_facing =
          facingScore(cloud, map_, step.pose, forward_, gicp_, threads_, kFacingPoints, newest);
    if (starting && (step.status != "ok" || (still_facing && *still_facing < 0.5))) {
      const double reach = p_.max_speed * std::clamp(t - prev_->first, 0.0, 1.0);
      const double pace = 0.5 * p_.max_correspondence;
      // Each guess is screened with a few iterations (most that land near the motion are then
      // within centimetres of their end) and scored there; only the best runs on to convergence
      // (issue #16: 20 guesses ran 300-470 iterations on the three KITTI sets).
      GicpParams screen = gicp_;
      screen.max_iterations = std::min(gicp_.max_iterations, kScreenIterations);
      std::optional<OdometryStep> best;
      double best_score = -1;
      for (int i = 1; i * pace <= reach + 1e-9; ++i)
        for (const double d : {i * pace, -i * pace}) {
          Eigen::Isometry3d from = guess;
          from.translation() += guess.linear() * (d * forward_);
          OdometryStep st;
          attempt(from, st, screen);
          ++step.start_guesses;
          step.guess_iterations += st.gicp.iterations;
          if (st.status != "ok") continue;
          const double score = still_facing ? facingScore(cloud, map_, st.pose, forward_, gicp_,
                                                          threads_, kFacingPoints, newest)
                                                  .value_or(-1.0)
                                            : st.gicp.fitness;
          if (!best || score > best_score) best = st, best_score = score;
        }
      if (still_facing && best_score <= 0.5) best.reset();
      if (best) {  // on from where the screen left it, with the full iterations
        OdometryStep fin;
        attempt(best->pose, fin, gicp_);
        step.guess_iterations += fin.gicp.iterations;
        if (fin.status == "ok") best = fin;  // else the screened pose, which passed the same checks
      }
      if (best) {
        step.gicp = best->gicp;
        step.pose = best->pose;
        step.status = best->status;
        step.reason = best->reason;
      }
    }
    // DESIGN §2.1 step 4: GICP moved the pose farther from the input odometry than that
    // odometry errs, between this scan and any of the last odometry_window scans (per scan,
    // plus its drift over the path between them and what it alone has covered since the last
    // accepted scan): traffic moving with the sensor or a corridor holds the alignment.
    if (step.status == "ok" && odometry && p_.odometry_tolerance > 0) {
      for (auto j = marks_.rbegin(); j != marks_.rend(); ++j) {
        const Eigen::Vector3d est = (j->pose.inverse() * step.pose).translation();
        const Eigen::Vector3d odo = (j->odometry.inverse() * *odometry).translation();
        const double moved = (est - odo).norm();
        const double allowed =
            p_.odometry_tolerance + p_.odometry_drift * (path - j->path + odometry_path_);
        if (moved <= allowed) continue;
        const auto back = j - marks_.rbegin() + 1;  // scans before this one
        step.status = "disagrees with the odometry (" + std::to_string(moved) + " m from it over " +
                      std::to_string(back) + (back == 1 ? " scan, " : " scans, ") +
                      std::to_string(allowed) + " allowed)";
        step.reason = "disagrees with the odometry";
        break;
      }
    }
    step.accepted = step.status == "ok";
    if (!step.accepted) step.pose = guess;
    // The map is out of the scans' reach (a long gap, a stretch that was never added): after two
    // such refusals since the last accepted scan (one odd scan, fog or a blocked view, keeps the
    // map) it starts again at the next scan, from the motion model's guess (or the given pose),
    // instead of every later scan being refused against it.
    if (step.gicp.no_overlap && ++no_overlap_ >= 2) {
      map_ = VoxelMap(p_.max_correspondence, p_.map_points_per_voxel);
      step.status += "; the map starts again at the next scan";
      step.map_restarts = true;
    }
  }
  step.ms_align = msSince(t0);
  t0 = Clock::now();
  if (step.accepted) {
    CovCloud world = cloud;
    const Eigen::Matrix3d R = step.pose.linear();
    for (std::size_t i = 0; i < world.size(); ++i) {
      world.points[i] = step.pose * world.points[i];
      world.covs[i] = R * world.covs[i] * R.transpose();
    }
    map_.insert(world, scan);
    map_.prune(step.pose.translation(), p_.map_radius);
    last_.emplace_back(t, step.pose);
    if (last_.size() > 2) last_.erase(last_.begin());
    accepted_.push_back(scan);
    if (accepted_.size() > static_cast<std::size_t>(p_.map_lag) + 1) accepted_.pop_front();
  }
  // The path odometry alone moved the pose (a refused scan with an odometry guess), since the
  // last accepted scan.
  if (step.accepted) {
    odometry_path_ = 0;
    no_overlap_ = 0;
  } else if (prior && kind == Prior::kOdometry && prev_)
    odometry_path_ += (step.pose.translation() - prev_->second.translation()).norm();
  prev_.emplace(t, step.pose);
  if (odometry) {
    marks_.push_back({*odometry, step.pose, path});
    if (marks_.size() > static_cast<std::size_t>(p_.odometry_window)) marks_.pop_front();
  }
  step.ms_map = msSince(t0);
  return step;
}

}  // namespace cleanmap::reg
