// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/io/config.h"

#include <charconv>
#include <cmath>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <sstream>

#include "cleanmap/core/error.h"
#include "cleanmap/io/files.h"
#include "cleanmap/io/ini.h"

namespace cleanmap::io {
namespace {

struct Key {
  std::function<void(double)> set;
  std::function<double()> get;
  bool integer;
  std::vector<std::string> names = {};  ///< a named choice: the value is the index of its name
  bool auto_zero = false;               ///< a number, or "auto" (stored as 0)
  bool non_negative = false;            ///< refused below 0 (the seed: an unsigned integer)
};

// Keys that moved: where they went (an old ini gets one clear error).
const std::map<std::string, std::string>& movedKeys() {
  static const std::map<std::string, std::string> m = {
      {"ground.sensor_height",
       "is now [sensor] height: metres above the ground, positive (1.73 for KITTI's HDL-64E), or "
       "auto to measure it from the scans"},
      {"registration.cone_noise",
       "is now registration.relative_error: the pose error between two scans as a fraction of the "
       "path between them (default 0.01), and it widens only the scan-conflict check"},
  };
  return m;
}

// A key's value from ini text: a number, or one of its names.
std::optional<double> parseValue(const Key& k, const std::string& text, std::string& why) {
  if (k.auto_zero && text == "auto") return 0.0;
  if (k.names.empty()) {
    auto v = parseNumber(text, k.integer, why);
    if (!v && k.auto_zero)
      why = std::string("needs ") + (k.integer ? "an integer" : "a number") + " or auto, got '" +
            text + "'";
    if (v && k.auto_zero && k.integer && *v == 0) {  // a count of 0 is not a way to say auto
      why = "needs auto or an integer >= 1, got '" + text + "'";
      return std::nullopt;
    }
    if (v && k.non_negative && *v < 0) {
      why = "needs a non-negative integer, got '" + text + "'";
      return std::nullopt;
    }
    return v;
  }
  for (std::size_t i = 0; i < k.names.size(); ++i)
    if (k.names[i] == text) return double(i);
  why = "needs one of";
  for (std::size_t i = 0; i < k.names.size(); ++i) why += (i ? ", " : " ") + k.names[i];
  why += "; got '" + text + "'";
  return std::nullopt;
}

std::string formatValue(const Key& k) {
  if (k.auto_zero && k.get() == 0) return "auto";
  if (k.names.empty()) return shortestDouble(k.get());
  return k.names.at(static_cast<std::size_t>(k.get()));
}

// The single table of ini keys: section.key -> field.
std::map<std::string, Key> table(PipelineParams& p) {
  auto d = [](double& f) { return Key{[&f](double v) { f = v; }, [&f] { return f; }, false}; };
  auto i = [](int& f) {
    return Key{[&f](double v) { f = static_cast<int>(v); }, [&f] { return double(f); }, true};
  };
  Key height = d(p.sensor.height);
  height.auto_zero = true;
  Key window_k = i(p.ds.window_k);
  window_k.auto_zero = true;
  Key window_stride = i(p.ds.window_stride);
  window_stride.auto_zero = true;
  return {
      {"sensor.height", height},
      {"sensor.model", Key{[&p](double v) { p.sensor.model = static_cast<SensorModel>(int(v)); },
                           [&p] { return double(int(p.sensor.model)); },
                           true,
                           {"auto", "hdl64", "hdl32", "vlp16", "os1-64", "os1-128"}}},
      {"sensor.deskew", Key{[&p](double v) { p.sensor.deskew = static_cast<DeskewMode>(int(v)); },
                            [&p] { return double(int(p.sensor.deskew)); },
                            true,
                            {"auto", "0", "1"}}},
      {"filter.crop_tau", d(p.filter.crop_tau)},
      {"filter.self_range", d(p.filter.self_range)},
      {"filter.dup_window", i(p.filter.dup_window)},
      {"filter.dup_distance", d(p.filter.dup_distance)},
      {"ground.cell", d(p.ground.cell)},
      {"ground.step", d(p.ground.step)},
      {"ground.point_refine", Key{[&p](double v) { p.ground.point_refine = v != 0; },
                                  [&p] { return p.ground.point_refine ? 1.0 : 0.0; }, true}},
      {"ground.max_gap_cells", i(p.ground.max_gap_cells)},
      {"ds.sigma_m", d(p.ds.sigma_m)},
      {"ds.sigma_r", d(p.ds.sigma_r)},
      {"ds.lambda_theta", d(p.ds.lambda_theta)},
      {"ds.search_lambdas", d(p.ds.search_lambdas)},
      {"ds.r_sup", d(p.ds.r_sup)},
      {"ds.r_inf", d(p.ds.r_inf)},
      {"ds.window_k", window_k},
      {"ds.window_s", d(p.ds.window_s)},
      {"ds.window_stride", window_stride},
      {"ds.scan_conflict", d(p.ds.scan_conflict)},
      {"ds.ring_vote", Key{[&p](double v) { p.ds.ring_vote = v != 0; },
                           [&p] { return p.ds.ring_vote ? 1.0 : 0.0; }, true}},
      {"ds.grazing", Key{[&p](double v) { p.ds.grazing = v != 0; },
                         [&p] { return p.ds.grazing ? 1.0 : 0.0; }, true}},
      {"ds.empty_run", d(p.ds.empty_run)},
      {"octree.leaf", d(p.octree.leaf)},
      {"octree.tau_np", i(p.octree.tau_np)},
      {"octree.fraction", d(p.octree.fraction)},
      {"object.enabled", Key{[&p](double v) { p.object.enabled = v != 0; },
                             [&p] { return p.object.enabled ? 1.0 : 0.0; }, true}},
      {"object.voxel", d(p.object.voxel)},
      {"object.moving_fraction", d(p.object.moving_fraction)},
      {"object.static_fraction", d(p.object.static_fraction)},
      {"object.min_moving", i(p.object.min_moving)},
      {"object.far_points", i(p.object.far_points)},
      {"object.max_length", d(p.object.max_length)},
      {"object.max_height", d(p.object.max_height)},
      {"object.max_width", d(p.object.max_width)},
      {"object.persist_radius", d(p.object.persist_radius)},
      {"object.foot_height", d(p.object.foot_height)},
      {"object.foot_reach", d(p.object.foot_reach)},
      {"object.feet", Key{[&p](double v) { p.object.feet = v != 0; },
                          [&p] { return p.object.feet ? 1.0 : 0.0; }, true}},
      {"object.roofs", Key{[&p](double v) { p.object.roofs = v != 0; },
                           [&p] { return p.object.roofs ? 1.0 : 0.0; }, true}},
      {"object.ring_pool", d(p.object.ring_pool)},
      {"object.wall_gap", d(p.object.wall_gap)},
      {"object.column_links", Key{[&p](double v) { p.object.column_links = v != 0; },
                                  [&p] { return p.object.column_links ? 1.0 : 0.0; }, true}},
      {"object.measure", Key{[&p](double v) { p.object.measure = v != 0; },
                             [&p] { return p.object.measure ? 1.0 : 0.0; }, true}},
      {"object.hold_start", Key{[&p](double v) { p.object.hold_start = v != 0; },
                                [&p] { return p.object.hold_start ? 1.0 : 0.0; }, true}},
      {"registration.min_range", d(p.registration.min_range)},
      {"registration.max_range", d(p.registration.max_range)},
      {"registration.voxel", d(p.registration.voxel)},
      {"registration.align_voxel", d(p.registration.align_voxel)},
      {"registration.knn", i(p.registration.knn)},
      {"registration.plane_epsilon", d(p.registration.plane_epsilon)},
      {"registration.max_correspondence", d(p.registration.max_correspondence)},
      {"registration.kernel", d(p.registration.kernel)},
      {"registration.max_iterations", i(p.registration.max_iterations)},
      {"registration.map_points_per_voxel", i(p.registration.map_points_per_voxel)},
      {"registration.map_radius", d(p.registration.map_radius)},
      {"registration.max_speed", d(p.registration.max_speed)},
      {"registration.max_turn_rate", d(p.registration.max_turn_rate)},
      {"registration.map_lag", i(p.registration.map_lag)},
      {"registration.odometry_tolerance", d(p.registration.odometry_tolerance)},
      {"registration.odometry_drift", d(p.registration.odometry_drift)},
      {"registration.odometry_window", i(p.registration.odometry_window)},
      {"registration.deskew", Key{[&p](double v) { p.registration.deskew = v != 0; },
                                  [&p] { return p.registration.deskew ? 1.0 : 0.0; }, true}},
      {"registration.relative_error", d(p.registration.relative_error)},
      {"static_map.radius", d(p.map.radius)},
      {"static_map.clean", Key{[&p](double v) { p.map.clean = v != 0; },
                               [&p] { return p.map.clean ? 1.0 : 0.0; }, true}},
      {"static_map.policy", Key{[&p](double v) { p.map.policy = static_cast<MapPolicy>(int(v)); },
                                [&p] { return double(int(p.map.policy)); },
                                true,
                                {"moving", "transient"}}},
      {"static_map.voxel", d(p.map.voxel)},
      {"static_map.min_free_scans", i(p.map.min_free_scans)},
      {"static_map.free_ratio", d(p.map.free_ratio)},
      {"static_map.vacated_scans", i(p.map.vacated_scans)},
      {"static_map.between_scans", i(p.map.between_scans)},
      {"static_map.arrived_scans", i(p.map.arrived_scans)},
      {"static_map.objects", Key{[&p](double v) { p.map.objects = v != 0; },
                                 [&p] { return p.map.objects ? 1.0 : 0.0; }, true}},
      {"static_map.object_overlap", d(p.map.object_overlap)},
      {"static_map.hit_inflate", d(p.map.hit_inflate)},
      {"static_map.margin", d(p.map.margin)},
      {"static_map.flat_slope", d(p.map.flat_slope)},
      {"static_map.graze_reach", d(p.map.graze_reach)},
      {"static_map.grazing_sides", Key{[&p](double v) { p.map.grazing_sides = v != 0; },
                                       [&p] { return p.map.grazing_sides ? 1.0 : 0.0; }, true}},
      {"static_map.min_range", d(p.map.min_range)},
      {"static_map.beam_spacing", d(p.map.beam_spacing)},
      {"image.enabled", Key{[&p](double v) { p.image.enabled = v != 0; },
                            [&p] { return p.image.enabled ? 1.0 : 0.0; }, true}},
      {"image.patch_height", d(p.image.patch_height)},
      {"image.min_patch", i(p.image.min_patch)},
      {"image.max_patch", i(p.image.max_patch)},
      {"image.search_margin", d(p.image.search_margin)},
      {"image.uniform_std", d(p.image.uniform_std)},
      {"image.ncc_threshold", d(p.image.ncc_threshold)},
      {"image.depth_threshold", d(p.image.depth_threshold)},
      {"image.dilation_radius", i(p.image.dilation_radius)},
      {"image.occlusion", d(p.image.occlusion)},
      {"image.cell", d(p.image.cell)},
      {"image.min_views", i(p.image.min_views)},
      {"image.changed_fraction", d(p.image.changed_fraction)},
      {"image.max_cells", i(p.image.max_cells)},
      {"image.max_incidence_deg", d(p.image.max_incidence_deg)},
      {"image.align", Key{[&p](double v) { p.image.align = v != 0; },
                          [&p] { return p.image.align ? 1.0 : 0.0; }, true}},
      {"image.align_max_shift", d(p.image.align_max_shift)},
      {"image.align_small_shift", d(p.image.align_small_shift)},
      {"run.seed", Key{[&p](double v) { p.seed = static_cast<uint64_t>(v); },
                       [&p] { return double(p.seed); },
                       true,
                       {},
                       false,
                       true}},
      {"run.threads", i(p.threads)},
      {"run.epoch", i(p.epoch)},
  };
}

}  // namespace

std::optional<double> parseNumber(const std::string& text, bool integer, std::string& why) {
  double v = 0;
  std::size_t used = 0;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (text.empty() || used != text.size() || !std::isfinite(v)) {
    why = "needs a number, got '" + text + "'";
    return std::nullopt;
  }
  if (integer && v != std::floor(v)) {
    why = "needs an integer, got '" + text + "'";
    return std::nullopt;
  }
  if (integer && std::abs(v) > 2147483647.0) {
    why = "needs an integer of magnitude below 2^31, got '" + text + "'";
    return std::nullopt;
  }
  return v;
}

void setParam(PipelineParams& params, const std::string& key, const std::string& value,
              const std::string& where) {
  auto keys = table(params);
  const auto it = keys.find(key);
  if (const auto m = movedKeys().find(key); m != movedKeys().end())
    throw Error(where, "'" + key + "' " + m->second);
  if (it == keys.end()) throw Error(where, "unknown key '" + key + "'");
  std::string why;
  const auto v = parseValue(it->second, trimBlanks(value), why);
  if (!v) throw Error(where, "'" + key + "' " + why);
  it->second.set(*v);
}

std::vector<std::pair<std::string, std::string>> paramValues(const PipelineParams& params) {
  PipelineParams copy = params;
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto& [name, key] : table(copy)) out.emplace_back(name, formatValue(key));
  return out;
}

std::vector<std::string> paramKeys() {
  PipelineParams p;
  std::vector<std::string> out;
  for (const auto& kv : table(p)) out.push_back(kv.first);
  return out;
}

void parseParams(const std::string& text, const std::string& name, PipelineParams& params) {
  auto keys = table(params);
  std::set<std::string> given;  // across repeated section blocks too
  IniHandlers on;
  on.section = [&](const std::string& section, int line) {
    bool known = false;
    for (const auto& kv : keys) known = known || kv.first.rfind(section + ".", 0) == 0;
    if (!known) iniError(name, line, "unknown section [" + section + "]");
  };
  on.entry = [&](const IniLine& e) {
    const std::string full = e.section + "." + e.key;
    if (const auto m = movedKeys().find(full); m != movedKeys().end())
      iniError(name, e.line, "'" + e.key + "' in [" + e.section + "] " + m->second);
    const auto it = keys.find(full);
    if (it == keys.end())
      iniError(name, e.line, "unknown key '" + e.key + "' in [" + e.section + "]");
    if (!given.insert(full).second)
      iniError(name, e.line, "'" + e.key + "' given twice in [" + e.section + "]");
    std::string why;
    const auto v = parseValue(it->second, e.value, why);
    if (!v) iniError(name, e.line, "'" + e.key + "' " + why);
    it->second.set(*v);
  };
  parseIni(text, name, on);
  validate(params, name);
}

void loadParams(const std::string& path, PipelineParams& params) {
  parseParams(readTextFile(path), path, params);
}

std::string shortestDouble(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);  // shortest form that reads back exactly
  return std::string(buf, r.ptr);
}

std::string toIni(const PipelineParams& params) {
  PipelineParams copy = params;
  std::ostringstream os;
  std::string section;
  for (const auto& [name, key] : table(copy)) {
    const auto dot = name.find('.');
    if (name.substr(0, dot) != section) {
      section = name.substr(0, dot);
      os << (os.tellp() > 0 ? "\n" : "") << "[" << section << "]\n";
    }
    os << name.substr(dot + 1) << " = " << formatValue(key) << "\n";
  }
  return os.str();
}

}  // namespace cleanmap::io
