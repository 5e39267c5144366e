// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/io/objects.h"

#include <Eigen/Geometry>
#include <cmath>
#include <nlohmann/json.hpp>

#include "cleanmap/core/error.h"
#include "cleanmap/io/files.h"

namespace cleanmap::io {

bool ObjectState::contains(const Eigen::Vector3d& p, double margin) const {
  const Eigen::Vector3d d = p - center;
  const double c = std::cos(yaw), s = std::sin(yaw);
  const Eigen::Vector3d local(c * d.x() + s * d.y(), -s * d.x() + c * d.y(), d.z());
  const Eigen::Vector3d half = 0.5 * size + Eigen::Vector3d::Constant(margin);
  return (local.cwiseAbs().array() <= half.array()).all();
}

bool GtObject::movingAnywhere() const {
  for (const auto& kv : frames)
    if (kv.second.motion == Motion::kMoving) return true;
  return false;
}

namespace {

Eigen::Vector3d vec3(const nlohmann::json& j, const std::string& path, const std::string& what) {
  if (!j.is_array() || j.size() != 3) throw Error(path, what + " is not an array of 3 numbers");
  const Eigen::Vector3d v(j[0].get<double>(), j[1].get<double>(), j[2].get<double>());
  if (!v.allFinite()) throw Error(path, what + " is not finite");
  return v;
}

// A scan index: decimal digits only, within range (std::stoul takes "-1", " 7" and "7x").
std::size_t frameIndex(const std::string& key, const std::string& path) {
  const bool digits =
      !key.empty() && key.size() <= 9 && key.find_first_not_of("0123456789") == std::string::npos;
  if (!digits) throw Error(path, "frame key '" + key.substr(0, 20) + "' is not a scan index");
  return static_cast<std::size_t>(std::stoul(key));
}

}  // namespace

std::vector<GtObject> readObjects(const std::string& path) {
  nlohmann::json root;
  try {
    root = nlohmann::json::parse(readTextFile(path));
  } catch (const nlohmann::json::exception& e) {
    throw Error(path, std::string("invalid JSON: ") + e.what());
  }
  if (!root.is_array()) throw Error(path, "expected a JSON array of objects");
  std::vector<GtObject> objects;
  try {
    for (const auto& jo : root) {
      GtObject o;
      o.id = jo.at("id").get<int>();
      o.name = jo.value("name", std::string());
      o.cls = jo.value("class", std::string());
      for (const auto& [key, js] : jo.at("frames").items()) {
        ObjectState st;
        const std::size_t index = frameIndex(key, path);
        const std::string where = "object " + std::to_string(o.id) + " frame " + key;
        st.center = vec3(js.at("center"), path, where + " center");
        st.size = vec3(js.at("size"), path, where + " size");
        if ((st.size.array() < 0).any()) throw Error(path, where + " size is negative");
        st.yaw = js.at("yaw").get<double>();
        if (!std::isfinite(st.yaw)) throw Error(path, where + " yaw is not finite");
        const auto& m = js.at("moving");
        st.motion = m.is_boolean() ? (m.get<bool>() ? Motion::kMoving : Motion::kStatic)
                                   : Motion::kUncertain;
        st.n_points = js.value("n_points", 0);
        o.frames[index] = st;
      }
      objects.push_back(std::move(o));
    }
  } catch (const nlohmann::json::exception& e) {
    throw Error(path, std::string("bad object record: ") + e.what());
  }
  return objects;
}

}  // namespace cleanmap::io
