// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/maps/map_config.h"

#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/core/initializer.h>
#include <mrpt/maps/TMetricMapTypesRegistry.h>
#include <mrpt/rtti/CObject.h>

#include <algorithm>
#include <cctype>
#include <map>
#include <regex>
#include <sstream>

#include "cleanmap/core/error.h"
#include "cleanmap/io/config.h"
#include "cleanmap/io/files.h"
#include "cleanmap/maps/ground_model_map.h"
#include "cleanmap/maps/moving_objects_map.h"
#include "cleanmap/mrpt/convert.h"
#include "map_options.h"

namespace cleanmap_maps {

void registerMaps() {
  static const bool once = [] {
    mrpt::rtti::registerClass(CLASS_ID(CGroundModelMap));
    mrpt::rtti::registerClass(CLASS_ID(CMovingObjectsMap));
    return true;
  }();
  (void)once;
}

// Loaded as a plugin (RawLogViewer -l, SceneViewer3D -l, rawlog-edit --plugins), the library
// registers itself; MAP_DEFINITION_REGISTER already did the map factory.
MRPT_INITIALIZER(cleanmap_maps_register) {
  registerMaps();
}

namespace {

bool endsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

bool isMovingMap(const std::string& map_name) {
  return map_name == "cleanmap_moving" || map_name == "cleanmap_maps::CMovingObjectsMap";
}
bool isGroundMap(const std::string& map_name) {
  return map_name == "cleanmap_ground" || map_name == "cleanmap_maps::CGroundModelMap";
}
bool isOurs(const std::string& map_name) {
  return isMovingMap(map_name) || isGroundMap(map_name);
}

}  // namespace

namespace {

MapConfig parseChecked(const std::string& text, const std::string& name, const std::string& section,
                       bool require_moving) {
  mrpt::config::CConfigFileMemory cfg(text);
  std::vector<std::string> sections;
  cfg.getAllSections(sections);
  const auto& registry =
      mrpt::maps::internal::TMetricMapTypesRegistry::Instance().getAllRegistered();
  std::vector<std::string> names;
  for (const auto& kv : registry) names.push_back(kv.first);

  auto declares = [&](const std::string& s) {
    std::vector<std::string> keys;
    cfg.getAllKeys(s, keys);
    return std::any_of(keys.begin(), keys.end(),
                       [](const auto& k) { return endsWith(k, "_count"); });
  };
  MapConfig mc;
  if (!section.empty()) {
    if (!cfg.sectionExists(section))
      throw cleanmap::Error(name, "no section [" + section + "] (the map list)");
    mc.section = section;
  } else {
    for (const char* s : kMapSections)
      if (cfg.sectionExists(s) && declares(s)) {
        mc.section = s;
        break;
      }
    for (const char* s : kMapSections)  // else the first list section, checked below
      if (mc.section.empty() && cfg.sectionExists(s)) mc.section = s;
    if (mc.section.empty())
      throw cleanmap::Error(
          name,
          "declares no maps: expected a [MappingApplication] (or [map], "
          "[MetricMap]) section with <map>_count keys (cleanmap_moving_count = 1)");
  }
  const std::string& S = mc.section;

  // The list: every <map>_count names a registered map (MRPT would ignore a misspelled one).
  std::map<std::string, uint64_t> counts;
  std::vector<std::string> keys;
  cfg.getAllKeys(S, keys);
  for (const auto& k : keys) {
    if (endsWith(k, "_count")) {
      const std::string map_name = k.substr(0, k.size() - 6);
      if (!registry.count(map_name))
        throw cleanmap::Error(name, "[" + S + "]: unknown map '" + map_name + "' in '" + k + "'" +
                                        suggestion(map_name, names));
      const std::string v = cfg.read_string(S, k, "", true);
      if (v.empty() ||
          !std::all_of(v.begin(), v.end(), [](unsigned char c) { return std::isdigit(c); }))
        throw cleanmap::Error(name, "[" + S + "]: '" + k + "' needs a count, got '" + v + "'");
      // MRPT numbers map sections with two digits: more than 100 maps cannot be configured.
      if (v.size() > 3 || std::stoul(v) > 100)
        throw cleanmap::Error(name, "[" + S + "]: '" + k + "' = " + v.substr(0, 20) +
                                        " maps: at most 100 can be configured");
      counts[map_name] = std::stoull(v);
    } else if (k.rfind("cleanmap", 0) == 0) {
      std::vector<std::string> count_keys;
      for (const auto& n : names) count_keys.push_back(n + "_count");
      throw cleanmap::Error(name,
                            "[" + S + "]: unknown key '" + k + "'" + suggestion(k, count_keys));
    }
  }
  if (require_moving && std::none_of(counts.begin(), counts.end(),
                                     [](const auto& kv) { return isMovingMap(kv.first); }))
    throw cleanmap::Error(
        name, "[" + S + "] declares no cleanmap_moving map (cleanmap_moving_count = 1)");

  // Every section of the form <S>_<map>_<NN>_<suffix> belongs to a declared map instance.
  const std::regex tail("_([0-9]{2})_([A-Za-z]+)$");
  for (const auto& sec : sections) {
    if (sec.rfind(S + "_", 0) != 0) continue;
    const std::string rest = sec.substr(S.size() + 1);
    std::smatch m;
    if (!std::regex_search(rest, m, tail))
      throw cleanmap::Error(name, "[" + sec + "]: not a map section (<list>_<map>_<NN>_<options>)");
    const std::string map_name = rest.substr(0, static_cast<std::size_t>(m.position(0)));
    if (!registry.count(map_name))
      throw cleanmap::Error(
          name, "[" + sec + "]: unknown map '" + map_name + "'" + suggestion(map_name, names));
    const uint64_t nn = std::stoull(m[1].str());
    if (!counts.count(map_name) || nn >= counts[map_name])
      throw cleanmap::Error(
          name, "[" + sec + "]: [" + S + "] declares " +
                    std::to_string(counts.count(map_name) ? counts[map_name] : 0) + " " + map_name +
                    " map(s), so this section would be ignored");
    const std::string suffix = m[2].str();
    if (isOurs(map_name) && suffix != "creationOpts" && suffix != "insertOpts" &&
        suffix != "likelihoodOpts")
      throw cleanmap::Error(name, "[" + sec + "]: unknown options section '" + suffix +
                                      "' (creationOpts or insertOpts)");
  }

  // Our maps' options, checked by their own loaders before MRPT's (which would wrap the error).
  for (const auto& [map_name, n] : counts) {
    if (!isOurs(map_name)) continue;
    for (uint64_t i = 0; i < n; ++i) {
      char idx[8];
      std::snprintf(idx, sizeof idx, "%02u", static_cast<unsigned>(i));
      const std::string prefix = S + "_" + map_name + "_" + idx;
      try {
        if (isMovingMap(map_name)) {
          CMovingObjectsMap::TMapDefinition d;
          d.loadFromConfigFile(cfg, prefix);
        } else {
          CGroundModelMap::TMapDefinition d;
          d.loadFromConfigFile(cfg, prefix);
        }
      } catch (const cleanmap::Error& e) {
        throw cleanmap::Error(name, e.what());
      }
    }
  }
  mc.maps.loadFromConfigFile(cfg, S);
  return mc;
}

}  // namespace

MapConfig parseMapConfig(const std::string& text, const std::string& name,
                         const std::string& section, bool require_moving) {
  registerMaps();
  try {
    return parseChecked(text, name, section, require_moving);
  } catch (const cleanmap::Error&) {
    throw;
  } catch (const std::exception& e) {  // MRPT's ini parser ($eval{...}, @include) and loaders
    throw cleanmap::Error(name, "MRPT cannot read it: " + cleanmap::mrpt::briefMessage(e));
  }
}

MapConfig loadMapConfig(const std::string& path, const std::string& section) {
  return parseMapConfig(cleanmap::io::readTextFile(path), path, section);
}

cleanmap::PipelineParams loadPipelineParams(const std::string& path) {
  const std::string text = cleanmap::io::readTextFile(path);
  cleanmap::PipelineParams p;
  if (!isMapConfig(text)) {
    cleanmap::io::parseParams(text, path, p);
    return p;
  }
  const auto mc = parseMapConfig(text, path);
  for (const auto& def : mc.maps)
    if (const auto* d = dynamic_cast<const CMovingObjectsMap::TMapDefinition*>(def.get()))
      return d->params;
  throw cleanmap::Error(path, "declares no cleanmap_moving map");
}

bool isMapConfig(const std::string& text) {
  // A map list section or a map's options section; cleanmap's flat files have neither.
  static const std::regex decl(
      R"((^|\n)[ \t]*\[[ \t]*(MappingApplication|map|MetricMap)([ \t]*\]|_[^\]]*_[0-9]{2}_))");
  return std::regex_search(text, decl);
}

std::string mapConfigText(const cleanmap::PipelineParams& params, const std::string& section,
                          double map_voxel, double ground_extent) {
  std::ostringstream os;
  os << "[" << section << "]\ncleanmap_moving_count = 1\ncleanmap_ground_count = 1\n\n";
  os << "[" << section << "_cleanmap_moving_00_creationOpts]\n";
  for (const auto& [k, v] : cleanmap::io::paramValues(params)) os << k << " = " << v << "\n";
  os << "map_voxel = " << cleanmap::io::shortestDouble(map_voxel) << "\n";
  os << "map_object_scans = " << CMovingObjectsMap::kDefaultObjectScans << "\n\n";
  os << "[" << section
     << "_cleanmap_moving_00_insertOpts]\nuse_pose_observations = 0\nsensor_label = auto\n\n";
  os << "[" << section << "_cleanmap_ground_00_creationOpts]\ncell = "
     << cleanmap::io::shortestDouble(params.ground.cell) << "\n\n";
  os << "[" << section << "_cleanmap_ground_00_insertOpts]\n"
     << "step = " << cleanmap::io::shortestDouble(params.ground.step) << "\n"
     << "height = "
     << (params.sensor.height > 0 ? cleanmap::io::shortestDouble(params.sensor.height) : "auto")
     << "\n"
     << "point_refine = " << (params.ground.point_refine ? 1 : 0) << "\n"
     << "max_gap_cells = " << params.ground.max_gap_cells << "\n"
     << "extent = " << cleanmap::io::shortestDouble(ground_extent) << "\n"
     << "use_pose_observations = 0\n";
  return os.str();
}

}  // namespace cleanmap_maps
