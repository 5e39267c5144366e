// SPDX-License-Identifier: BSD-3-Clause
// Binary little-endian PLY point clouds (x, y, z, intensity as float32), written in a stream so a
// map of any length needs no memory, and moved into place atomically at the end.
#pragma once
#include <cstdio>
#include <string>
#include <vector>

#include "cleanmap/core/types.h"

namespace cleanmap::io {

class PlyStreamWriter {
 public:
  explicit PlyStreamWriter(const std::string& path);
  ~PlyStreamWriter();  ///< without close(): removes the temporary data, leaves no file
  PlyStreamWriter(const PlyStreamWriter&) = delete;
  PlyStreamWriter& operator=(const PlyStreamWriter&) = delete;

  void append(const std::vector<PointXYZI>& points);
  /// Writes header + points to the final path through a temporary and a rename.
  void close();
  std::size_t count() const { return count_; }

 private:
  std::string path_, body_;
  std::FILE* f_ = nullptr;
  std::size_t count_ = 0;
};

/// Writes a whole cloud (atomically).
void writePly(const std::string& path, const std::vector<PointXYZI>& points);
/// Reads a binary little-endian or ASCII PLY with float x, y, z (and optional intensity);
/// throws cleanmap::Error naming the file otherwise.
std::vector<PointXYZI> readPly(const std::string& path);

}  // namespace cleanmap::io
