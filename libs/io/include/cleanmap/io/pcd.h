// SPDX-License-Identifier: BSD-3-Clause
// PCL `.pcd` point clouds (the format of most dynamic-removal tools' maps: DUFOMap, Removert,
// ERASOR, OctoMap exports), read so their maps are scored like ours (DESIGN §5).
#pragma once
#include <string>
#include <vector>

#include "cleanmap/core/types.h"

namespace cleanmap::io {

/// Reads a PCD v0.7 file: DATA ascii, binary or binary_compressed (LZF); fields x, y, z as F4 or
/// F8 and an optional `intensity`; other fields are skipped; NaN points (organized clouds) are
/// dropped. Throws cleanmap::Error naming the file and what is wrong.
std::vector<PointXYZI> readPcd(const std::string& path);

/// Writes x, y, z, intensity as float32, DATA binary (or ascii), atomically.
void writePcd(const std::string& path, const std::vector<PointXYZI>& points, bool ascii = false);

/// `.ply` or `.pcd` by extension; anything else is an error.
std::vector<PointXYZI> readCloud(const std::string& path);

}  // namespace cleanmap::io
