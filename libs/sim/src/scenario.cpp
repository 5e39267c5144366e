// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/sim/scenario.h"

#include <cmath>
#include <functional>
#include <map>
#include <sstream>

#include "cleanmap/core/error.h"
#include "cleanmap/io/config.h"
#include "cleanmap/io/files.h"
#include "cleanmap/io/ini.h"

namespace cleanmap::sim {
namespace {

struct Reader {
  std::string file;
  int line = 0;
  [[noreturn]] void fail(const std::string& what) const {
    throw Error(file + ":" + std::to_string(line), what);
  }
  std::vector<double> numbers(const std::string& key, const std::string& v, std::size_t n_min,
                              std::size_t n_max) const {
    std::vector<double> out;
    std::string s = v;
    for (char& c : s)
      if (c == ';' || c == ',') c = ' ';
    std::istringstream is(s);
    std::string tok;
    while (is >> tok) {
      char* end = nullptr;
      const double x = std::strtod(tok.c_str(), &end);
      if (end == tok.c_str() || *end != '\0' || !std::isfinite(x))
        fail(key + ": '" + tok + "' is not a number");
      out.push_back(x);
    }
    if (out.size() < n_min || out.size() > n_max)
      fail(key + ": expected " +
           (n_min == n_max ? std::to_string(n_min)
                           : std::to_string(n_min) + ".." + std::to_string(n_max)) +
           " numbers, got " + std::to_string(out.size()));
    return out;
  }
  double number(const std::string& key, const std::string& v, double lo, double hi) const {
    const double x = numbers(key, v, 1, 1)[0];
    if (x < lo || x > hi)
      fail(key + " = " + v + " is outside [" + io::shortestDouble(lo) + ", " +
           io::shortestDouble(hi) + "]");
    return x;
  }
  bool boolean(const std::string& key, const std::string& v) const {
    if (v == "true" || v == "1" || v == "yes") return true;
    if (v == "false" || v == "0" || v == "no") return false;
    fail(key + ": expected true or false, got '" + v + "'");
  }
  std::vector<Eigen::Vector2d> path(const std::string& key, const std::string& v) const {
    const auto n = numbers(key, v, 4, 2000);
    if (n.size() % 2) fail(key + ": expected x y pairs");
    std::vector<Eigen::Vector2d> p;
    for (std::size_t i = 0; i < n.size(); i += 2) p.emplace_back(n[i], n[i + 1]);
    for (std::size_t i = 1; i < p.size(); ++i)
      if ((p[i] - p[i - 1]).norm() < 1e-6) fail(key + ": repeated waypoint");
    return p;
  }
  Texture texture(const std::string& key, const std::string& v) const {
    if (v == "checker") return Texture::kChecker;
    if (v == "flat") return Texture::kFlat;
    fail(key + ": expected checker or flat, got '" + v + "'");
  }
  Eigen::Vector3f colour(const std::string& key, const std::string& v) const {
    const auto c = numbers(key, v, 3, 3);
    for (double x : c)
      if (x < 0 || x > 1) fail(key + ": colour components are in [0, 1]");
    return Eigen::Vector3d(c[0], c[1], c[2]).cast<float>();
  }
};

}  // namespace

Scenario parseScenario(const std::string& text, const std::string& name) {
  Scenario sc;
  sc.source = name;
  Reader r{name};
  std::string section;
  // Handlers per section; a new [box] / [cylinder] / [mover] starts a new element.
  using Handler = std::function<bool(const std::string&, const std::string&)>;
  std::map<std::string, Handler> handlers;
  handlers["scenario"] = [&](const std::string& k, const std::string& v) {
    if (k == "name")
      sc.name = v;
    else if (k == "frames")
      sc.frames = static_cast<int>(r.number(k, v, 1, 100000));
    else if (k == "rate_hz")
      sc.rate_hz = r.number(k, v, 1, 100);
    else if (k == "seed")
      sc.seed = static_cast<uint64_t>(r.number(k, v, 0, 1e15));
    else
      return false;
    return true;
  };
  // The lidar's rings, resolved after the file is read (the keys come in any order).
  std::optional<SensorModel> model;
  std::optional<int> rings;
  std::optional<std::vector<double>> fov;
  bool azimuth_given = false;
  handlers["sensor"] = [&](const std::string& k, const std::string& v) {
    auto& s = sc.sensor;
    if (k == "azimuth_step_deg") {
      s.azimuth_step_deg = r.number(k, v, 0.05, 5);
      azimuth_given = true;
    } else if (k == "model") {
      model = sensorModelByName(v);
      if (!model || *model == SensorModel::kAuto) {
        std::string names;
        for (const auto& p : sensorPresets())
          names += std::string(names.empty() ? "" : ", ") + p.name;
        r.fail("model: expected one of " + names + ", got '" + v + "'");
      }
    } else if (k == "rings") {
      const double x = r.number(k, v, 2, 256);
      if (x != std::floor(x)) r.fail("rings: expected an integer, got '" + v + "'");
      rings = static_cast<int>(x);
    } else if (k == "vertical_fov_deg") {
      fov = r.numbers(k, v, 2, 2);
      if (!((*fov)[0] < (*fov)[1]) || (*fov)[0] < -90 || (*fov)[1] > 90)
        r.fail("vertical_fov_deg: expected lo hi with -90 <= lo < hi <= 90 (degrees)");
    } else if (k == "range_noise")
      s.range_noise = r.number(k, v, 0, 1);
    else if (k == "dropout")
      s.dropout = r.number(k, v, 0, 0.99);
    else if (k == "min_range")
      s.min_range = r.number(k, v, 0, 50);
    else if (k == "max_range")
      s.max_range = r.number(k, v, 1, 1000);
    else if (k == "height")
      s.height = r.number(k, v, 0.1, 10);
    else if (k == "sweep_motion")
      s.sweep_motion = r.boolean(k, v);
    else if (k == "camera")
      s.camera = r.boolean(k, v);
    else
      return false;
    return true;
  };
  handlers["ego"] = [&](const std::string& k, const std::string& v) {
    if (k == "path")
      sc.ego_path = r.path(k, v);
    else if (k == "speed")
      sc.ego_speed = r.number(k, v, 0, 60);
    else if (k == "pose_drift")
      sc.ego_pose_drift = r.number(k, v, 0, 0.1);
    else if (k == "odometry")
      sc.ego_odometry = r.number(k, v, 0, 0.1);
    else
      return false;
    return true;
  };
  handlers["ground"] = [&](const std::string& k, const std::string& v) {
    auto& g = sc.ground;
    if (k == "slope")
      g.slope = r.number(k, v, -0.3, 0.3);
    else if (k == "road_half_width")
      g.road_half_width = r.number(k, v, 1, 100);
    else if (k == "curb_height")
      g.curb_height = r.number(k, v, 0, 0.5);
    else if (k == "ramp") {
      const auto n = r.numbers(k, v, 6, 6);
      if (!(n[0] < n[1] && n[1] <= n[2] && n[3] < n[4] && n[5] > 0 && n[5] < 3))
        r.fail("ramp: expected x0 < x1 <= x2, y0 < y1 and 0 < height < 3");
      g.ramp = std::array<double, 6>{n[0], n[1], n[2], n[3], n[4], n[5]};
    } else
      return false;
    return true;
  };
  handlers["box"] = [&](const std::string& k, const std::string& v) {
    auto& b = sc.boxes.back();
    if (k == "name")
      b.name = v;
    else if (k == "class")
      b.cls = v;
    else if (k == "center") {
      const auto n = r.numbers(k, v, 2, 2);
      b.center = {n[0], n[1]};
    } else if (k == "size") {
      const auto n = r.numbers(k, v, 3, 3);
      if (n[0] <= 0 || n[1] <= 0 || n[2] <= 0) r.fail("size: l w h must be > 0");
      b.size = {n[0], n[1], n[2]};
    } else if (k == "yaw_deg")
      b.yaw = r.number(k, v, -360, 360) * M_PI / 180;
    else if (k == "lift")
      b.lift = r.number(k, v, 0, 100);
    else if (k == "texture")
      b.texture = r.texture(k, v);
    else if (k == "colour")
      b.colour = r.colour(k, v);
    else if (k == "tracked")
      b.tracked = r.boolean(k, v);
    else
      return false;
    return true;
  };
  handlers["cylinder"] = [&](const std::string& k, const std::string& v) {
    auto& c = sc.cylinders.back();
    if (k == "name")
      c.name = v;
    else if (k == "class")
      c.cls = v;
    else if (k == "center") {
      const auto n = r.numbers(k, v, 2, 2);
      c.center = {n[0], n[1]};
    } else if (k == "radius")
      c.radius = r.number(k, v, 0.01, 10);
    else if (k == "height")
      c.height = r.number(k, v, 0.1, 100);
    else if (k == "colour")
      c.colour = r.colour(k, v);
    else
      return false;
    return true;
  };
  handlers["mover"] = [&](const std::string& k, const std::string& v) {
    auto& m = sc.movers.back();
    if (k == "name")
      m.name = v;
    else if (k == "class")
      m.cls = v;
    else if (k == "size") {
      const auto n = r.numbers(k, v, 3, 3);
      if (n[0] <= 0 || n[1] <= 0 || n[2] <= 0) r.fail("size: l w h must be > 0");
      m.size = {n[0], n[1], n[2]};
    } else if (k == "path")
      m.path = r.path(k, v);
    else if (k == "speed")
      m.speed = r.number(k, v, 0, 60);
    else if (k == "start")
      m.start = r.number(k, v, 0, 1e6);
    else if (k == "accel")
      m.accel = r.number(k, v, 0, 20);
    else if (k == "stop") {
      const auto n = r.numbers(k, v, 2, 2);
      if (!(n[0] >= 0 && n[1] > n[0])) r.fail("stop: expected t0 < t1, seconds");
      m.stop = std::make_pair(n[0], n[1]);
    } else if (k == "texture")
      m.texture = r.texture(k, v);
    else if (k == "colour")
      m.colour = r.colour(k, v);
    else
      return false;
    return true;
  };
  io::IniHandlers on;
  on.section = [&](const std::string& sec, int line) {
    r.line = line;
    section = sec;
    if (!handlers.count(section))
      r.fail("unknown section [" + section +
             "] (scenario, sensor, ego, ground, box, cylinder, mover)");
    if (section == "box")
      sc.boxes.emplace_back(), sc.boxes.back().name = "box" + std::to_string(sc.boxes.size());
    if (section == "cylinder")
      sc.cylinders.emplace_back(),
          sc.cylinders.back().name = "cylinder" + std::to_string(sc.cylinders.size());
    if (section == "mover")
      sc.movers.emplace_back(), sc.movers.back().name = "mover" + std::to_string(sc.movers.size());
  };
  on.entry = [&](const io::IniLine& e) {
    r.line = e.line;
    if (!handlers[e.section](e.key, e.value))
      r.fail("unknown key '" + e.key + "' in [" + e.section + "]");
  };
  io::parseIni(text, name, on);
  r.line = 0;
  const SensorPreset& preset = sensorPreset(model.value_or(SensorModel::kHdl64));
  sc.sensor.model = preset.model;
  if (rings || fov) {
    const double lo = fov ? (*fov)[0] : preset.fov_lo_deg, hi = fov ? (*fov)[1] : preset.fov_hi_deg;
    sc.sensor.elevations = evenElevations(rings.value_or(preset.rings), lo, hi);
  } else {
    sc.sensor.elevations = ringElevations(preset.model);
  }
  if (!azimuth_given) sc.sensor.azimuth_step_deg = preset.azimuth_step_deg;
  for (const auto& m : sc.movers)
    if (m.path.size() < 2)
      throw Error(name, "mover '" + m.name + "' has no path (at least two waypoints)");
  if (sc.sensor.min_range >= sc.sensor.max_range)
    throw Error(name, "sensor min_range must be < max_range");
  return sc;
}

Scenario loadScenario(const std::string& path) {
  return parseScenario(io::readTextFile(path), path);
}

Scenario defaultScenario() {
  return parseScenario(defaultScenarioText(), "default scenario");
}

}  // namespace cleanmap::sim
