// SPDX-License-Identifier: BSD-3-Clause
// Our map layers as a SLAM or cleanmap-build-map saves them (maps.bin): the plugins'
// serializeFrom, through MRPT's reader. The first byte picks the layer (CMovingObjectsMap or
// CGroundModelMap), the rest is the stream. Any exception is a clean outcome here (MRPT's reader
// wraps what a serializeFrom throws); a crash, undefined behaviour, a leak or an allocation over
// the limit is a finding. A layer read is written again, as a SLAM saving its map would.
#include <mrpt/serialization/CArchive.h>
#include <mrpt/serialization/archiveFrom_std_vector.h>

#include "cleanmap/maps/ground_model_map.h"
#include "cleanmap/maps/map_config.h"
#include "cleanmap/maps/moving_objects_map.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  cleanmap_maps::registerMaps();
  std::vector<uint8_t> in(data + 1, data + size), out;
  cleanmap_maps::CMovingObjectsMap moving;
  cleanmap_maps::CGroundModelMap ground;
  mrpt::serialization::CSerializable& layer =
      data[0] & 1 ? static_cast<mrpt::serialization::CSerializable&>(ground) : moving;
  try {
    auto ar = mrpt::serialization::archiveFrom(in);
    ar.ReadObject(&layer);
  } catch (const std::exception&) {
    return 0;
  }
  auto ar = mrpt::serialization::archiveFrom(out);
  ar << layer;
  return 0;
}
