// SPDX-License-Identifier: BSD-3-Clause
// The objects' grouping of one scan as bytes (DESIGN §2e, "Objects"): the map's forward pass
// spools the grouping it decided each scan with, and the backward pass reads it back instead of
// grouping the same points again (issue #16).
#pragma once
#include <cstddef>
#include <string>
#include <vector>

#include "cleanmap/core/object_consensus.h"

namespace cleanmap::io {

/// Appends `cc` to `out`: its voxel side, its voxels, each point's voxel, the components' roots,
/// the pooled and piece flags. The rings' reach is not stored (the scan's header gives it).
void appendGrouping(const ObjectComponents& cc, std::vector<unsigned char>& out);

/// Fills `out` (its buffers reused) with the grouping appendGrouping wrote as these n bytes, for
/// `points` points and the rings' `reach`; the voxel index is rebuilt. Throws cleanmap::Error
/// naming `source` where the bytes are short, too many, or of another number of points.
void readGrouping(const unsigned char* bytes, std::size_t n, std::size_t points,
                  const RingReach& reach, const std::string& source, ObjectComponents& out);

}  // namespace cleanmap::io
