// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/io/grouping_spool.h"

#include <cstdint>
#include <cstring>

#include "cleanmap/core/cell_key.h"
#include "cleanmap/core/error.h"

namespace cleanmap::io {
namespace {

struct GroupingHeader {
  double side;
  uint64_t points, voxels;
  uint8_t pooled, piece, pad[6];
};

template <class T>
void put(const std::vector<T>& v, std::vector<unsigned char>& out) {
  if (v.empty()) return;  // its data() may be null
  const auto* p = reinterpret_cast<const unsigned char*>(v.data());
  out.insert(out.end(), p, p + v.size() * sizeof(T));
}

}  // namespace

void appendGrouping(const ObjectComponents& cc, std::vector<unsigned char>& out) {
  GroupingHeader h{};
  h.side = cc.side;
  h.points = cc.point_voxel.size();
  h.voxels = cc.voxels.size();
  h.pooled = !cc.pooled.empty();
  h.piece = !cc.piece.empty();
  const auto* p = reinterpret_cast<const unsigned char*>(&h);
  out.insert(out.end(), p, p + sizeof h);
  put(cc.point_voxel, out);
  put(cc.voxels, out);
  put(cc.root_of, out);
  put(cc.pooled, out);
  put(cc.piece, out);
}

void readGrouping(const unsigned char* bytes, std::size_t n, std::size_t points,
                  const RingReach& reach, const std::string& source, ObjectComponents& out) {
  GroupingHeader h{};
  if (n < sizeof h) throw Error(source, "a grouping of " + std::to_string(n) + " bytes (short)");
  std::memcpy(&h, bytes, sizeof h);
  if (h.points != points)
    throw Error(source, "a grouping of " + std::to_string(h.points) + " points for a scan of " +
                            std::to_string(points));
  const uint64_t nv = h.voxels;
  const uint64_t want =
      sizeof h + 4 * h.points + (12 + 4) * nv + (h.pooled ? nv : 0) + (h.piece ? nv : 0);
  if (nv > h.points || n != want)
    throw Error(source, "a grouping of " + std::to_string(n) + " bytes where its counts need " +
                            std::to_string(want));
  std::size_t at = sizeof h;
  const auto get = [&](auto& v, std::size_t count) {
    v.resize(count);
    if (count == 0) return;  // an empty vector's data() may be null
    std::memcpy(static_cast<void*>(v.data()), bytes + at, count * sizeof(v[0]));
    at += count * sizeof(v[0]);
  };
  out.side = h.side;
  out.reach = reach;
  get(out.point_voxel, h.points);
  get(out.voxels, nv);
  get(out.root_of, nv);
  get(out.pooled, h.pooled ? nv : 0);
  get(out.piece, h.piece ? nv : 0);
  for (const uint32_t v : out.point_voxel)
    if (v != UINT32_MAX && v >= nv)
      throw Error(source, "a grouping with a point's voxel past its voxels");
  for (const uint32_t r : out.root_of)
    if (r >= nv) throw Error(source, "a grouping with a root past its voxels");
  out.voxel_of.clear();
  out.voxel_of.reserve(nv);
  for (uint32_t v = 0; v < nv; ++v) {
    const Eigen::Vector3i& c = out.voxels[v];
    out.voxel_of[cellKey(c.x(), c.y(), c.z())] = v;
  }
}

}  // namespace cleanmap::io
