// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §5: per-point moving-object segmentation measures.
#pragma once
#include <cstdint>
#include <string>

#include "cleanmap/core/types.h"

namespace cleanmap {

/// Confusion counts of the moving class over evaluated points.
struct MosCounts {
  uint64_t tp = 0, fp = 0, fn = 0, tn = 0;
  uint64_t ignored = 0;  ///< ground truth 0 / 1
  /// predicted 0 (not classified: outside the crop, invalid, the recording vehicle's own)
  uint64_t out_of_range = 0;

  MosCounts& operator+=(const MosCounts& o);
  double precision() const { return tp + fp ? double(tp) / double(tp + fp) : 0.0; }
  double recall() const { return tp + fn ? double(tp) / double(tp + fn) : 0.0; }
  double iou() const { return tp + fp + fn ? double(tp) / double(tp + fp + fn) : 0.0; }
  uint64_t evaluated() const { return tp + fp + fn + tn; }
  /// Share of evaluated points predicted moving.
  double flaggedRate() const { return evaluated() ? double(tp + fp) / double(evaluated()) : 0.0; }
};

/// Compares predicted labels (our SemanticKITTI-MOS output) with ground truth, point by point in
/// the original order. Points we did not classify (0) and ground-truth ignore (0, 1) are excluded.
/// Throws cleanmap::Error naming `what` if the sizes differ.
MosCounts compareLabels(const Labels& predicted, const Labels& truth, const std::string& what);

}  // namespace cleanmap
