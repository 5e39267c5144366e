// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2e, grazing beams: per return of a scan, the stretch of its beam that runs within
// `margin` of a flat surface (the road, a sidewalk, a roof), found from that scan alone. The
// clean map's free space marks nothing there; the moving-point test's beams vote nothing there
// (DESIGN §2b, "Grazing beams").
#pragma once
#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "cleanmap/core/types.h"

namespace cleanmap {

class GrazingStretches {
 public:
  /// `points` in the sensor frame, `R` the sensor-to-world rotation (the world's z is up),
  /// `azimuth` per point (fast::atan2(y, x)). flat_slope: the largest rise of a flat surface;
  /// margin: how near the surface a beam runs; reach: how far beyond its last return a surface a
  /// beam passes over is taken to go on (all as MapParams). column_step (rad between the lidar's
  /// columns, e.g. freeSpaceAzimuthBin) and hit_inflate, where both are positive: side() too;
  /// column_step and `links`: links() too.
  void compute(const std::vector<PointXYZI>& points, const Eigen::Matrix3f& R,
               const std::vector<float>& azimuth, double flat_slope, double margin, double reach,
               double column_step = 0, double hit_inflate = 0, bool links = false);
  /// Per point, metres along its beam from the sensor: the stretch [from, to] that grazes a flat
  /// surface; to < from where there is none.
  const std::vector<float>& from() const { return skip_a_; }
  const std::vector<float>& to() const { return skip_b_; }
  /// Per point, metres along its beam: where it ends on an upright surface met at a grazing angle
  /// whose returns lie farther apart than 2 hit_inflate, the clean map's free space marks nothing
  /// from there to its end (DESIGN §2e, "Grazing sides"); +infinity elsewhere. The moving-point
  /// test does not use it. Empty where compute() had no column_step.
  const std::vector<float>& side() const { return side_; }
  /// Pairs (n, q), flat: returns of one upright surface in neighbouring columns (of column_step
  /// where it is finer than the cells'), q at most kMaxLink away (horizontally) and at most 2.5
  /// times the spacing of the columns before them, each on the line through its own two
  /// neighbours (as side()) with the two lines parallel and one (the returns beyond each end
  /// within 0.05 m + 0.5 % of range of the line through the other end), or q the line's last
  /// return before nothing or something over kMaxLink farther (doc/OBJECTS.md rule 1, "Coarse
  /// columns"); empty unless compute() had column_step and links.
  const std::vector<uint32_t>& links() const { return links_; }
  static constexpr float kMaxLink = 1.0f;  // m
  /// Whether links() were found in the lidar's own columns (column_step finer than the cells'
  /// 0.69 degrees: a dense lidar), not in the cells'.
  bool fineLinks() const { return fine_links_; }
  /// Whether point n lies on a flat surface (its rise from its lower neighbour in its column is
  /// at most flat_slope).
  bool flat(std::size_t n) const { return n < slope_.size() && !std::isnan(slope_[n]); }
  /// flat(n), and no return rises steeply from it (it is its upper neighbour's lower one): not
  /// the foot of an upright surface, a walker's shoe or a car's sill whose lower neighbour is the
  /// road a ring step nearer (the moving-point test's kFlatSurface, DESIGN §2b).
  bool flatTop(std::size_t n) const {
    return flat(n) && !upright_above_[static_cast<std::size_t>(cell_[n])];
  }

 private:
  void sides(const std::vector<PointXYZI>& points, const std::vector<float>& azimuth, int naz,
             float m, float step, float hit_inflate, bool links, float flat_slope);
  // n's rise from l below it where at most flat_slope (l nearer horizontally), else NaN.
  float flatRise(std::size_t n, uint32_t l, double flat_slope) const {
    if (!(rho_[n] > rho_[l] + 1e-3f)) return std::numeric_limits<float>::quiet_NaN();
    const float rise = (zw_[n] - zw_[l]) / (rho_[n] - rho_[l]);
    return std::abs(rise) <= flat_slope ? rise : std::numeric_limits<float>::quiet_NaN();
  }
  static constexpr float kAzBin = 0.012f;  // rad: the cells' azimuth
  static constexpr int kElBands = 747;     // the cells' bands of elevation
  static constexpr int kMaxDown = 45;      // bands: 4.4 degrees down near the horizon
  // The returns' cells of azimuth x elevation, each return's cell, lower neighbour, rise to it
  // where flat, horizontal range and height from the sensor (world frame); kept between scans.
  std::vector<uint32_t> grid_;  // UINT32_MAX between calls
  std::vector<int> cell_, flat_below_;
  std::vector<uint16_t> band_;  // each return's band of elevation
  std::vector<uint32_t> lower_;
  std::vector<uint8_t> upright_above_;  // per cell: a return rises steeply from its return
  std::vector<float> slope_, rho_, zw_, xw_, yw_, skip_a_, skip_b_, side_;
  std::vector<float> dir_x_, dir_y_;
  std::vector<uint32_t> next_a_, next_b_, links_;
  // The links' cells where the lidar's columns are finer than kAzBin (UINT32_MAX between calls).
  std::vector<uint32_t> fine_grid_;
  std::vector<int> fine_cell_;
  bool fine_links_ = false;
  static constexpr uint8_t kLinkFlat = 1, kLinkRoad = 2;
  std::vector<uint8_t> link_kind_;  // per return, in the links' columns: kLinkFlat | kLinkRoad
};

}  // namespace cleanmap
