// SPDX-License-Identifier: BSD-3-Clause
// doc/OBJECTS.md rule 7, "Measured": how far a rigid object moved between two scans, from its
// outline seen from above. The windowed test (DESIGN §2b) sees a vehicle moving only where its
// space empties; one sliding along its own side at walking pace (a queue creeping past, a car
// pulling away beside the sensor) keeps its side occupied, and its ends move less than the beam
// model's margin in a few scans. Its outline, matched against another scan's, shows the shift
// where its ends are in view: across the shift, or a side's trailing end along it.
#pragma once
#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace cleanmap {

struct ShiftParams {
  double cell = 0.15;   ///< m; the outline's grid (a point covers its cell and the 8 around)
  double reach = 1.5;   ///< m; the largest shift searched along each axis
  int coarse_step = 3;  ///< cells; the first search's step, refined +-2 cells around its best
  /// m; a cell is on the outline where its points span this much height: a vertical face
  /// stacks its rings in the same cells, a roof seen at a grazing angle holds one ring's stripe,
  /// and the stripes fall elsewhere from another place of the sensor.
  double min_span = 0.25;
};

/// The outline of an object matched against a target's: of its `cells` (grid cells on its
/// vertical faces, ShiftParams::min_span), `at_rest` lie within a cell of a target point as they
/// are and `at_shift` once moved by `shift` (world x, y), the shift within `reach` that matches
/// most (the nearest to zero among ties). Where the outline's cells match depends on what each scan
/// saw: a side seen over another stretch matches best shifted along itself. Only the cells *facing*
/// the shift tell it: those on a stretch of outline across it (within 45 degrees; a line over the 5
/// x 5 cells around the cell, its spread across under a fifth of that along). Of them,
/// `facing_at_rest` and `facing_at_shift` match. `evidence`: the object's points in facing cells
/// that match only shifted (indices into the object): where the object stood in one scan and not in
/// the other, which that other scan should see empty (a static object it did not see there matches
/// the same way, only shifted onto its neighbour). The other cells on a line lie *along* the
/// shift (a side sliding along itself): `along`, `along_at_rest`, `along_at_shift`, and
/// `end_evidence`, the object's points in those that match only shifted at its trailing end
/// (within the shift and a cell of its rearmost outline cell, going along the shift): where a side
/// that slid on stood, or the end of a side the target saw over another stretch (not empty there).
/// `old_evidence`, the other half of `evidence` (indices into the target): the target's points
/// in the outline cells the evidence cells match shifted, where no cell of the object matches in
/// place. Where the object stood in the target's scan alone, which the object's scan should see
/// empty (a vehicle driving away hides its new place behind its old one from the target's scan).
struct OutlineShift {
  Eigen::Vector2f shift = Eigen::Vector2f::Zero();
  std::size_t cells = 0, at_rest = 0, at_shift = 0;
  std::size_t facing = 0, facing_at_rest = 0, facing_at_shift = 0;
  std::vector<uint32_t> evidence, old_evidence;
  std::size_t along = 0, along_at_rest = 0, along_at_shift = 0;
  std::vector<uint32_t> end_evidence;
  /// A side's ends, found whatever the shift (doc/OBJECTS.md rule 7, "A side's ends"): where the
  /// object's outline cells lie on one straight line (spread across it at most a cell), `side` is
  /// its direction (unit; zero otherwise). Per end (0 the lower along `side`, 1 the upper):
  /// `end_shift`, how far along `side` the target's stretch of that line (its outline within two
  /// cells of it, unbroken by gaps over three cells) ends beyond the object's (m, signed; NaN
  /// where the target has none of it or its stretch runs on past `reach`), and the points one
  /// holds beyond the other's end by more than a cell: `end_object` (indices into the object) or
  /// `end_target` (into the target). Where one scan saw the side and the other did not; a side
  /// that slid along itself left the other scan's view of that place empty.
  Eigen::Vector2f side = Eigen::Vector2f::Zero();
  float end_shift[2] = {std::numeric_limits<float>::quiet_NaN(),
                        std::numeric_limits<float>::quiet_NaN()};
  std::vector<uint32_t> end_object[2], end_target[2];
};

/// Matches the outline of `object` (its points, any frame with z up) against that of `target`
/// (the same frame; points farther than `reach` from the object's box are not read). Grids the
/// object's box grown by `reach`: O(points + cells x (searched shifts)). Deterministic.
OutlineShift outlineShift(const std::vector<Eigen::Vector3f>& object,
                          const std::vector<Eigen::Vector3f>& target, const ShiftParams& p = {});

}  // namespace cleanmap
