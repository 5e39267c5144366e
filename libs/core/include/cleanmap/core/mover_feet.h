// SPDX-License-Identifier: BSD-3-Clause
// doc/OBJECTS.md rule 6, a mover's feet: the returns of a moving object within `ground.step` of
// the road (a car's lowest face and tyres, a walker's shoes) are ground for DESIGN §2a's point
// refinement and would stay in every map. Those standing under the mover, raised above the road
// around them, go with it.
#pragma once
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "cleanmap/core/ground.h"
#include "cleanmap/core/object_consensus.h"
#include "cleanmap/core/types.h"

namespace cleanmap {

struct MoverFeetParams {
  /// m; a foot's nearest return above lies within this horizontal distance: the surface it
  /// continues down to the road, with the range noise of a return and a bumper's slant.
  double radius = 0.15;
  /// m; the least rise over the road around it, the median of the scan's other ground returns
  /// in the 3 x 3 ground cells (`cell`) around the foot (where fewer than 5, in the cells out to
  /// where the next ring down, `ring_gap`, meets a flat road, at most 6 m); three times their
  /// scatter (1.4826 MAD) where that is larger, so a rough or noisy road's own returns are not
  /// raised.
  double rise = 0.03;
  double cell = 0.4;  ///< m; the ground grid's cell (GroundParams::cell)
  /// rad; the lidar's angle between rings: that return must lie within two ring steps at the
  /// foot's range above it (at least 0.3 m), the next ring up on the same surface.
  double ring_gap = 0.4 * 3.14159265358979323846 / 180.0;
};

/// Indices of the feet among `points` (sensor frame): points refined to ground (`ground` ==
/// kGroundRefined) in the crop (`in_crop`) whose nearest return above (horizontally, within
/// `radius`, and two ring steps up at most, at least 0.3 m; non-ground, in the crop) is moving
/// (`moving`), and that lie more than `rise` over the road around them. A static surface
/// straight above one (a wall's foot behind a walker's legs) keeps it. `pose` (sensor to world,
/// z up) gives the heights and horizontal distances. Every other ground point (any flag) is the
/// road's sample. Ascending order. `world` (optional): pose * point, as computed in double,
/// already known for the non-ground points in the crop (the pipeline's candidates); the others
/// are computed here.
std::vector<uint32_t> moverFeet(const std::vector<PointXYZI>& points, const Eigen::Isometry3d& pose,
                                const std::vector<uint8_t>& ground,
                                const std::vector<uint8_t>& moving,
                                const std::vector<uint8_t>& in_crop, const MoverFeetParams& p,
                                const std::vector<Eigen::Vector3d>* world = nullptr);

/// doc/OBJECTS.md rule 6, a sparse lidar's roofs. The ring just above a vehicle's near face
/// passes over its top and lands on its roof, metres further on (a car followed 7.7 m back by a
/// VLP-16: its front face's top ring at 1.33 m, the next one 4.3 m further on its roof's rear
/// edge): a one-ring stripe, not joined to the face in the grouping's voxels. With the face
/// moving, the stripe stays static and behind, a trail of roofs in the map. A dense lidar's
/// roofs below the sensor fall apart so too (an HDL-64E's rings 1.3 and 4.3 m apart on a car's
/// roof 8-12 m off).
struct MoverRoofParams {
  double ring_gap = 0;  ///< rad between the lidar's rings (0: none taken)
  /// A dense lidar (rings under kDenseRingsDeg apart, DESIGN §2b): its roofs alone. Its lowest
  /// ring does not fall apart from a face (rule 6's feet take what it leaves), nor its slices.
  bool dense = false;
  double voxel = 0.3;   ///< m; the grouping's voxel (ObjectParams::voxel): the margins
  double length = 6.0;  ///< m; how far beyond its near face a roof below the sensor may reach
  /// m; a mover at most this wide (its returns' horizontal diagonal) on two rings or more (a
  /// walker) has no roof beyond its faces, only slices on them (ObjectParams::ring_pool; 0: every
  /// mover may)
  double narrow = 0;
  /// A slice under the vehicle with this share of it flagged moving is one of its slices however
  /// high over the road, and slices so flagged stack (ObjectParams::moving_fraction, rule 2's).
  double flagged = 0.2;
  double max_length = 25.0;  ///< m; a stack is vehicle-sized (ObjectParams::max_length)
  double max_height = 5.0;   ///< m (ObjectParams::max_height)
};

/// Indices of roof stripes among `points` (sensor frame; `pose` gives heights): the static points
/// of the components of `cc` not moving in every point that lie on one ring (elevations within
/// half a ring step), at least 3 of them, all within the shadow of a moving vehicle, a component
/// moving whole (`whole` and `moving` for nine in ten of its points): within its azimuths (and a
/// voxel), no nearer than a voxel before its nearest return (a ring grazing its face's top edge)
/// and at most `length` beyond its farthest (a voxel for a mover at most `narrow` across and as
/// high), and at most a voxel below its top and 1.25 ring steps (at its farthest return) above it,
/// under the next ring over its top; or, its lowest ring's slice, on its faces (at most a voxel
/// beyond its farthest return), under its lowest return by at most those 1.25 ring steps and within
/// them of the road (the median height of the `ground` returns before it and under it, at least 5)
/// unless `flagged` of it is moving. A stripe
/// taken on its faces extends the vehicle for the next one. And the static points of stacks: two
/// or more one-ring slices, each with `flagged` of it moving (not all), one over another (within
/// 1.25 ring steps, over half of the narrower one's azimuths, ranges within a voxel), vehicle-sized
/// together. At a dense lidar (`p.dense`) only the roofs, each return behind the faces on the
/// ring over the vehicle's top in its 0.5-degree bin of azimuth (within half a ring step).
/// Ascending order; empty where `p.ring_gap` is 0.
std::vector<uint32_t> moverRoofs(const std::vector<PointXYZI>& points,
                                 const Eigen::Isometry3d& pose, const ObjectComponents& cc,
                                 const std::vector<uint8_t>& moving,
                                 const std::vector<uint8_t>& whole,
                                 const std::vector<uint8_t>& ground, const MoverRoofParams& p);

}  // namespace cleanmap
