// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/scan_result.h"

#include <algorithm>

namespace cleanmap {

StageTimes& StageTimes::operator+=(const StageTimes& o) {
  registration += o.registration;
  index += o.index;
  ground += o.ground;
  duplicates += o.duplicates;
  octree += o.octree;
  classify += o.classify;
  objects += o.objects;
  free_space += o.free_space;
  images += o.images;
  total += o.total;
  return *this;
}

ScanStats& ScanStats::operator+=(const ScanStats& o) {
  points += o.points;
  invalid += o.invalid;
  in_crop += o.in_crop;
  ground += o.ground;
  duplicates += o.duplicates;
  candidates += o.candidates;
  tested += o.tested;
  moving += o.moving;
  static_points += o.static_points;
  window += o.window;
  window_k = std::max(window_k, o.window_k);
  window_stride = std::max(window_stride, o.window_stride);
  scan_rate_hz = std::max(scan_rate_hz, o.scan_rate_hz);
  map_far += o.map_far;
  self_returns += o.self_returns;
  deskewed += o.deskewed;
  deskew_max_shift = std::max(deskew_max_shift, o.deskew_max_shift);
  total_conflicts += o.total_conflicts;
  no_evidence += o.no_evidence;
  scans_visited += o.scans_visited;
  beams += o.beams;
  early_decisions += o.early_decisions;
  settled_skips += o.settled_skips;
  conflicting_scans += o.conflicting_scans;
  ring_votes += o.ring_votes;
  objects_moving += o.objects_moving;
  consensus_points += o.consensus_points;
  consensus_removed += o.consensus_removed;
  consensus_body_kept += o.consensus_body_kept;
  consensus_foot_left += o.consensus_foot_left;
  consensus_surface_left += o.consensus_surface_left;
  mover_feet += o.mover_feet;
  mover_roofs += o.mover_roofs;
  consensus_still_part_left += o.consensus_still_part_left;
  consensus_wide_left += o.consensus_wide_left;
  objects_persisted += o.objects_persisted;
  objects_left_place += o.objects_left_place;
  objects_measured += o.objects_measured;
  objects_far_kept += o.objects_far_kept;
  objects_carried_back += o.objects_carried_back;
  carried_back_points += o.carried_back_points;
  empty += o.empty;
  image_scans += o.image_scans;
  image_units += o.image_units;
  image_confirmed_colour += o.image_confirmed_colour;
  image_confirmed_depth += o.image_confirmed_depth;
  image_rejected_colour += o.image_rejected_colour;
  image_rejected_depth += o.image_rejected_depth;
  image_unseen += o.image_unseen;
  image_grazing += o.image_grazing;
  image_held += o.image_held;
  image_links += o.image_links;
  image_links_aligned += o.image_links_aligned;
  image_link_shift += o.image_link_shift;
  image_relabelled += o.image_relabelled;
  ms += o.ms;
  return *this;
}

}  // namespace cleanmap
