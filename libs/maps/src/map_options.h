// SPDX-License-Identifier: BSD-3-Clause
// A map's ini options read strictly from an MRPT config: every key of the section must be known,
// every value must parse. MRPT 2.5.8's MRPT_LOAD_CONFIG_VAR ignores unknown keys and reads
// "fast" as 0; our maps refuse both with one line naming the section and the key.
#pragma once
#include <mrpt/config/CConfigFileBase.h>

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

namespace cleanmap_maps {

class OptionTable {
 public:
  using Setter = std::function<void(const std::string& value, const std::string& where)>;
  void custom(const std::string& key, Setter set) { keys_[key] = std::move(set); }
  void real(const std::string& key, double& v);
  void integer(const std::string& key, int& v);
  void flag(const std::string& key, bool& v);

  /// Applies every key present in `section`; throws cleanmap::Error("[section]", ...) on an
  /// unknown key (MRPT's common map keys allowed where `generic`) or a bad value.
  void load(const mrpt::config::CConfigFileBase& source, const std::string& section,
            bool generic) const;

 private:
  std::map<std::string, Setter> keys_;
};

/// Levenshtein distance, and "; did you mean 'k'?" for the nearest of `known` (or "").
std::size_t editDistance(const std::string& a, const std::string& b);
std::string suggestion(const std::string& key, const std::vector<std::string>& known);

/// The keys every MRPT map accepts in its creationOpts (TMapGenericParams).
const std::vector<std::string>& genericMapKeys();

/// The most elements a saved map's count reserves ahead of reading them (serializeFrom): a
/// corrupt count sizes nothing.
constexpr uint64_t kReserveAtMost = 1 << 16;

/// cleanmap_moving's map_voxel: 0 (every point its own entry) or in [0.001, 1000] m, the same in
/// its ini and its saved form (a smaller voxel's keys overflow). Throws cleanmap::Error(where).
void checkMapVoxel(double map_voxel, const std::string& where);

}  // namespace cleanmap_maps
