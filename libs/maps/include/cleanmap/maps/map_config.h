// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §4b: our maps in MRPT ini files (config/cleanmap.ini), checked. MRPT 2.5.8 silently
// ignores a misspelled `<map>_count` key, a section of a map that was not declared and any
// unknown option; here each is a one-line error naming the file, the section and the key.
#pragma once
#include <mrpt/maps/TMetricMapInitializer.h>

#include <string>

#include "cleanmap/core/params.h"

namespace cleanmap_maps {

/// Registers both map classes with MRPT (map factory and deserialization). Idempotent. Call it
/// from any program that links the library: Debian links with --as-needed, and a library whose
/// functions are never called is dropped together with its registrations.
void registerMaps();

/// The section names MRPT applications read their map list from, in the order searched.
inline constexpr const char* kMapSections[] = {"MappingApplication", "map", "MetricMap"};

struct MapConfig {
  std::string section;  ///< the list section used
  mrpt::maps::TSetOfMetricMapInitializers maps;
};

/// Reads the map list of an MRPT ini text from `section` (empty: the first of kMapSections that
/// declares a map) and checks it: every `<name>_count` names a registered map; every section
/// `<section>_<name>_<NN>_<suffix>` belongs to a declared map; our maps' sections hold only
/// known keys with valid values (cleanmap::validate); with `require_moving`, a cleanmap_moving
/// map is declared. Throws cleanmap::Error(name, ...).
MapConfig parseMapConfig(const std::string& text, const std::string& name,
                         const std::string& section = "", bool require_moving = true);
MapConfig loadMapConfig(const std::string& path, const std::string& section = "");

/// True if `text` is an MRPT map configuration (has a map list section of kMapSections or a map
/// options section), false if it is cleanmap's flat parameter file ([filter], [ds], ... as in a
/// run's params.ini).
bool isMapConfig(const std::string& text);

/// The classifier's parameters from either kind of file: the cleanmap_moving map's creationOpts
/// of an MRPT map configuration (checked as parseMapConfig does), or a flat params.ini.
cleanmap::PipelineParams loadPipelineParams(const std::string& path);

/// The ini text declaring both maps with `params` under `section` (config/cleanmap.ini is this
/// text for the defaults, with comments).
std::string mapConfigText(const cleanmap::PipelineParams& params,
                          const std::string& section = "MappingApplication", double map_voxel = 0.1,
                          double ground_extent = 30.0);

}  // namespace cleanmap_maps
