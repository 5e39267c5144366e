// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/io/calib.h"

#include <sstream>

#include "cleanmap/core/error.h"
#include "cleanmap/io/files.h"

namespace cleanmap::io {

KeyValueFile KeyValueFile::load(const std::string& path) {
  KeyValueFile kv;
  kv.path_ = path;
  std::istringstream in(readTextFile(path));
  std::string line;
  while (std::getline(in, line)) {
    const auto colon = line.find(':');
    if (colon == std::string::npos) continue;
    const std::string key = line.substr(0, colon);
    std::istringstream vs(line.substr(colon + 1));
    std::vector<double> v;
    std::string tok;
    bool numeric = true;
    while (vs >> tok) {
      try {
        std::size_t used = 0;
        v.push_back(std::stod(tok, &used));
        numeric = numeric && used == tok.size();
      } catch (const std::exception&) {
        numeric = false;
      }
    }
    kv.values_[key] = std::move(v);
    kv.numeric_[key] = numeric;
  }
  return kv;
}

const std::vector<double>& KeyValueFile::numbers(const std::string& key, std::size_t count) const {
  const auto it = values_.find(key);
  if (it == values_.end()) throw Error(path_, "missing calibration key '" + key + "'");
  if (!numeric_.at(key)) throw Error(path_, "calibration key '" + key + "' is not numeric");
  if (it->second.size() != count)
    throw Error(path_, "calibration key '" + key + "' has " + std::to_string(it->second.size()) +
                           " numbers, expected " + std::to_string(count));
  return it->second;
}

Eigen::Matrix<double, 3, 4> KeyValueFile::matrix3x4(const std::string& key) const {
  const auto& v = numbers(key, 12);
  Eigen::Matrix<double, 3, 4> m;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) m(r, c) = v[static_cast<std::size_t>(r * 4 + c)];
  return m;
}

Eigen::Isometry3d KeyValueFile::rigidRT(const std::string& r_key, const std::string& t_key) const {
  const auto& r = numbers(r_key, 9);
  const auto& t = numbers(t_key, 3);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) T.matrix()(i, j) = r[static_cast<std::size_t>(i * 3 + j)];
    T.matrix()(i, 3) = t[static_cast<std::size_t>(i)];
  }
  return T;
}

Eigen::Isometry3d isometryFrom3x4(const Eigen::Matrix<double, 3, 4>& m) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.matrix().topRows<3>() = m;
  return T;
}

Eigen::Isometry3d exactInverse(const Eigen::Isometry3d& T) {
  Eigen::Isometry3d inv;
  inv.matrix() = T.matrix().inverse();
  return inv;
}

void requireRigid(const Eigen::Isometry3d& T, const std::string& path, const std::string& what) {
  if (!T.matrix().allFinite()) throw Error(path, what + " is not finite");
  const Eigen::Matrix3d R = T.linear();
  const double off = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (off > 1e-2 || R.determinant() < 0)
    throw Error(path,
                what + " is not a rigid transform (its rotation is not orthonormal with det +1)");
}

}  // namespace cleanmap::io
