// SPDX-License-Identifier: BSD-3-Clause
// Binary little-endian PLY point clouds (x, y, z, intensity as float32, optionally red, green,
// blue as uint8), written in a stream so a map of any length needs no memory, and moved into place
// atomically at the end; optionally the same cloud as a PCL `.pcd` (packed `rgb`).
#pragma once
#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "cleanmap/core/types.h"
#include "cleanmap/io/direct_file.h"

namespace cleanmap::io {

/// How a streamed cloud is coloured (DESIGN §4): not at all, by height above the sensor (the map:
/// blue → green → yellow from 2 m below to 3 m above, no red), or red (the moving points).
enum class CloudColour { kNone, kHeight, kRed };

/// RGB of a point `dz` metres above the sensor, for CloudColour::kHeight (viridis-like ramp).
/// Inline: it runs once per map point, and an exported function is called through the PLT.
inline std::array<uint8_t, 3> heightColour(double dz) {
  // Samples of viridis at t = 0, 1/4, 1/2, 3/4, 1, linearly interpolated.
  static constexpr double kRamp[5][3] = {
      {68, 1, 84}, {59, 82, 139}, {33, 145, 140}, {94, 201, 98}, {253, 231, 37}};
  const double t = std::clamp((dz + 2.0) / 5.0, 0.0, 1.0) * 4.0;
  const int k = std::min(3, static_cast<int>(t));
  const double f = t - k;
  std::array<uint8_t, 3> c{};
  for (int j = 0; j < 3; ++j) {
    // lround of a value in [0, 255], without the libm call: half rounds up, as lround's.
    const double v = kRamp[k][j] + f * (kRamp[k + 1][j] - kRamp[k][j]);
    const int i = static_cast<int>(v);
    c[j] = static_cast<uint8_t>(i + (v - i >= 0.5));
  }
  return c;
}

struct CloudStreamOptions {
  CloudColour colour = CloudColour::kNone;
  std::string pcd_path;  ///< also write the cloud as binary PCD (x y z intensity [rgb]) here
};

class PlyStreamWriter {
 public:
  explicit PlyStreamWriter(const std::string& path, const CloudStreamOptions& opts = {});
  ~PlyStreamWriter();  ///< without close(): removes the temporaries, leaves no file
  PlyStreamWriter(const PlyStreamWriter&) = delete;
  PlyStreamWriter& operator=(const PlyStreamWriter&) = delete;

  /// `sensor_z`: world height of the sensor that saw the points (reference of kHeight colours).
  void append(const std::vector<PointXYZI>& points, double sensor_z = 0);
  /// Sets the headers' counts and moves the files (written under temporary names) into place.
  void close();
  std::size_t count() const { return count_; }

 private:
  std::string path_;
  CloudStreamOptions opts_;
  std::vector<char> rec_, pcd_rec_;  // append()'s record buffers
  std::unique_ptr<DirectFile> ply_, pcd_;
  std::size_t ply_head_ = 0, pcd_head_ = 0;  // header lengths, fixed at the start
  std::size_t count_ = 0;
};

/// Writes a whole cloud (atomically).
void writePly(const std::string& path, const std::vector<PointXYZI>& points);
/// Reads a binary little-endian or ASCII PLY with float x, y, z (and optional intensity);
/// throws cleanmap::Error naming the file otherwise.
std::vector<PointXYZI> readPly(const std::string& path);

}  // namespace cleanmap::io
