// SPDX-License-Identifier: BSD-3-Clause
#include "map_options.h"

#include <algorithm>
#include <cmath>

#include "cleanmap/core/error.h"
#include "cleanmap/io/config.h"
#include "cleanmap/io/ini.h"

namespace cleanmap_maps {
namespace {

double number(const std::string& text, bool integer, const std::string& key,
              const std::string& where) {
  std::string why;
  const auto v = cleanmap::io::parseNumber(cleanmap::io::trimBlanks(text), integer, why);
  if (!v) throw cleanmap::Error(where, "'" + key + "' " + why);
  return *v;
}

}  // namespace

std::size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diag = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] != b[j - 1])});
      diag = up;
    }
  }
  return row[b.size()];
}

std::string suggestion(const std::string& key, const std::vector<std::string>& known) {
  std::string best;
  std::size_t bd = std::max<std::size_t>(3, key.size() / 3) + 1;
  for (const auto& k : known)
    if (const std::size_t d = editDistance(key, k); d < bd) {
      bd = d;
      best = k;
    }
  return best.empty() ? "" : "; did you mean '" + best + "'?";
}

const std::vector<std::string>& genericMapKeys() {
  static const std::vector<std::string> k = {"enableSaveAs3DObject", "enableObservationLikelihood",
                                             "enableObservationInsertion"};
  return k;
}

void OptionTable::real(const std::string& key, double& v) {
  keys_[key] = [&v, key](const std::string& s, const std::string& w) {
    v = number(s, false, key, w);
  };
}

void OptionTable::integer(const std::string& key, int& v) {
  keys_[key] = [&v, key](const std::string& s, const std::string& w) {
    v = static_cast<int>(number(s, true, key, w));
  };
}

void OptionTable::flag(const std::string& key, bool& v) {
  keys_[key] = [&v, key](const std::string& s, const std::string& w) {
    const std::string t = cleanmap::io::trimBlanks(s);
    if (t == "true" || t == "1")
      v = true;
    else if (t == "false" || t == "0")
      v = false;
    else
      throw cleanmap::Error(w, "'" + key + "' needs 0, 1, true or false, got '" + t + "'");
  };
}

void OptionTable::load(const mrpt::config::CConfigFileBase& source, const std::string& section,
                       bool generic) const {
  if (!source.sectionExists(section)) return;
  const std::string where = "[" + section + "]";
  std::vector<std::string> present;
  source.getAllKeys(section, present);
  const auto& gk = genericMapKeys();
  for (const auto& key : present) {
    const auto it = keys_.find(key);
    if (it != keys_.end()) {
      // MRPT strips `//` comments; a `#` or `;` after a blank starts one too (as in our ini).
      std::string v = source.read_string(section, key, "", true);
      for (std::size_t i = 1; i < v.size(); ++i)
        if ((v[i] == '#' || v[i] == ';') && (v[i - 1] == ' ' || v[i - 1] == '\t')) {
          v.resize(i);
          break;
        }
      it->second(v, where);
      continue;
    }
    if (generic && std::find(gk.begin(), gk.end(), key) != gk.end()) continue;
    std::vector<std::string> known;
    for (const auto& kv : keys_) known.push_back(kv.first);
    throw cleanmap::Error(where, "unknown key '" + key + "'" + suggestion(key, known));
  }
}

void checkMapVoxel(double map_voxel, const std::string& where) {
  if (!(map_voxel == 0 || (map_voxel >= 1e-3 && map_voxel <= 1e3)))
    throw cleanmap::Error(where, "map_voxel must be 0 or in [0.001, 1000] m");
}

}  // namespace cleanmap_maps
