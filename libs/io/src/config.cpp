// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/io/config.h"

#include <cmath>
#include <functional>
#include <iomanip>
#include <map>
#include <sstream>

#include "cleanmap/core/error.h"
#include "cleanmap/io/files.h"

namespace cleanmap::io {
namespace {

struct Key {
  std::function<void(double)> set;
  std::function<double()> get;
  bool integer;
};

// The single table of ini keys: section.key -> field.
std::map<std::string, Key> table(PipelineParams& p) {
  auto d = [](double& f) { return Key{[&f](double v) { f = v; }, [&f] { return f; }, false}; };
  auto i = [](int& f) {
    return Key{[&f](double v) { f = static_cast<int>(v); }, [&f] { return double(f); }, true};
  };
  return {
      {"filter.crop_tau", d(p.filter.crop_tau)},
      {"filter.dup_window", i(p.filter.dup_window)},
      {"filter.dup_distance", d(p.filter.dup_distance)},
      {"ground.cell", d(p.ground.cell)},
      {"ground.step", d(p.ground.step)},
      {"ground.sensor_height", d(p.ground.sensor_height)},
      {"ground.point_refine", Key{[&p](double v) { p.ground.point_refine = v != 0; },
                                  [&p] { return p.ground.point_refine ? 1.0 : 0.0; }, true}},
      {"ground.max_gap_cells", i(p.ground.max_gap_cells)},
      {"ds.sigma_m", d(p.ds.sigma_m)},
      {"ds.sigma_r", d(p.ds.sigma_r)},
      {"ds.lambda_theta", d(p.ds.lambda_theta)},
      {"ds.search_lambdas", d(p.ds.search_lambdas)},
      {"ds.r_sup", d(p.ds.r_sup)},
      {"ds.r_inf", d(p.ds.r_inf)},
      {"ds.window_k", i(p.ds.window_k)},
      {"ds.scan_conflict", d(p.ds.scan_conflict)},
      {"octree.leaf", d(p.octree.leaf)},
      {"octree.tau_np", i(p.octree.tau_np)},
      {"octree.fraction", d(p.octree.fraction)},
      {"object.enabled", Key{[&p](double v) { p.object.enabled = v != 0; },
                             [&p] { return p.object.enabled ? 1.0 : 0.0; }, true}},
      {"object.voxel", d(p.object.voxel)},
      {"object.moving_fraction", d(p.object.moving_fraction)},
      {"object.static_fraction", d(p.object.static_fraction)},
      {"object.min_moving", i(p.object.min_moving)},
      {"object.max_length", d(p.object.max_length)},
      {"object.max_height", d(p.object.max_height)},
      {"object.persist_radius", d(p.object.persist_radius)},
      {"run.seed", Key{[&p](double v) { p.seed = static_cast<uint64_t>(v); },
                       [&p] { return double(p.seed); }, true}},
      {"run.threads", i(p.threads)},
  };
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t\r") - b + 1);
}

}  // namespace

void parseParams(const std::string& text, const std::string& name, PipelineParams& params) {
  auto keys = table(params);
  std::istringstream in(text);
  std::string line, section;
  int lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    const std::string where = name + ":" + std::to_string(lineno);
    const auto hash = line.find_first_of("#;");
    line = trim(hash == std::string::npos ? line : line.substr(0, hash));
    if (line.empty()) continue;
    if (line.front() == '[') {
      if (line.back() != ']') throw Error(where, "malformed section header '" + line + "'");
      section = trim(line.substr(1, line.size() - 2));
      bool known = false;
      for (const auto& kv : keys) known = known || kv.first.rfind(section + ".", 0) == 0;
      if (!known) throw Error(where, "unknown section [" + section + "]");
      continue;
    }
    const auto eq = line.find('=');
    if (eq == std::string::npos) throw Error(where, "expected 'key = value', got '" + line + "'");
    const std::string key = trim(line.substr(0, eq)), value = trim(line.substr(eq + 1));
    const auto it = keys.find(section + "." + key);
    if (it == keys.end())
      throw Error(where, "unknown key '" + key + "'" +
                             (section.empty() ? " outside any section" : " in [" + section + "]"));
    double v = 0;
    std::size_t used = 0;
    try {
      v = std::stod(value, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != value.size() || value.empty() || !std::isfinite(v))
      throw Error(where, "'" + key + "' needs a number, got '" + value + "'");
    if (it->second.integer && v != std::floor(v))
      throw Error(where, "'" + key + "' needs an integer, got '" + value + "'");
    it->second.set(v);
  }
  validate(params, name);
}

void loadParams(const std::string& path, PipelineParams& params) {
  parseParams(readTextFile(path), path, params);
}

std::string toIni(const PipelineParams& params) {
  PipelineParams copy = params;
  std::ostringstream os;
  os << std::setprecision(17);
  std::string section;
  for (const auto& [name, key] : table(copy)) {
    const auto dot = name.find('.');
    if (name.substr(0, dot) != section) {
      section = name.substr(0, dot);
      os << (os.tellp() > 0 ? "\n" : "") << "[" << section << "]\n";
    }
    os << name.substr(dot + 1) << " = " << key.get() << "\n";
  }
  return os.str();
}

void validate(const PipelineParams& p, const std::string& name) {
  auto require = [&](bool ok, const std::string& what) {
    if (!ok) throw Error(name, what);
  };
  require(p.filter.crop_tau > 0, "filter.crop_tau must be > 0");
  require(p.filter.dup_window >= 0, "filter.dup_window must be >= 0");
  require(p.filter.dup_distance > 0, "filter.dup_distance must be > 0");
  require(p.ground.cell > 0, "ground.cell must be > 0");
  require(p.ground.step > 0, "ground.step must be > 0");
  require(p.ds.sigma_m >= 0 && p.ds.sigma_r >= 0 && p.ds.sigma_m + p.ds.sigma_r > 0,
          "ds.sigma_m and ds.sigma_r must be >= 0, not both 0");
  require(p.ds.lambda_theta > 0 && p.ds.lambda_theta < 0.5, "ds.lambda_theta must be in (0, 0.5) rad");
  require(p.ds.search_lambdas > 0, "ds.search_lambdas must be > 0");
  require(0 <= p.ds.r_inf && p.ds.r_inf <= p.ds.r_sup && p.ds.r_sup < 1,
          "need 0 <= ds.r_inf <= ds.r_sup < 1");
  require(p.ds.window_k >= 0, "ds.window_k must be >= 0");
  require(p.ds.scan_conflict > 0 && p.ds.scan_conflict <= 1,
          "ds.scan_conflict must be in (0, 1] (1 = off)");
  require(p.octree.leaf > 0, "octree.leaf must be > 0");
  require(p.octree.tau_np >= 1, "octree.tau_np must be >= 1");
  require(p.octree.fraction > 0 && p.octree.fraction <= 1, "octree.fraction must be in (0, 1]");
  require(p.object.voxel > 0, "object.voxel must be > 0");
  require(0 <= p.object.static_fraction && p.object.static_fraction <= p.object.moving_fraction &&
              p.object.moving_fraction <= 1,
          "need 0 <= object.static_fraction <= object.moving_fraction <= 1");
  require(p.object.min_moving >= 1, "object.min_moving must be >= 1");
  require(p.object.max_length > 0 && p.object.max_height > 0, "object.max_length and max_height must be > 0");
  require(p.object.persist_radius >= 0 && p.object.persist_radius <= 10,
          "object.persist_radius must be in [0, 10] m (0 = off)");
  require(p.threads >= 1, "run.threads must be >= 1");
}

}  // namespace cleanmap::io
