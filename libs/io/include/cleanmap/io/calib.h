// SPDX-License-Identifier: BSD-3-Clause
// "key: numbers" text files as KITTI writes them (calib.txt, calib_*_to_*.txt).
#pragma once
#include <Eigen/Geometry>
#include <map>
#include <string>
#include <vector>

namespace cleanmap::io {

class KeyValueFile {
 public:
  /// Parses `path`. Lines whose value is not all numbers (e.g. "calib_time: ...") are kept as
  /// non-numeric and only fail when asked for.
  static KeyValueFile load(const std::string& path);

  bool has(const std::string& key) const { return values_.count(key) > 0; }
  /// The numbers under `key`; throws cleanmap::Error naming the file and key if it is missing,
  /// non-numeric or does not hold exactly `count` numbers.
  const std::vector<double>& numbers(const std::string& key, std::size_t count) const;
  const std::string& path() const { return path_; }

  /// 3x4 row-major matrix under `key` as an affine 4x4 (KITTI "Tr", "P2").
  Eigen::Matrix<double, 3, 4> matrix3x4(const std::string& key) const;
  /// Rigid transform from "R" (9, row-major) and "T" (3) keys (KITTI raw calib_*_to_*.txt).
  Eigen::Isometry3d rigidRT(const std::string& r_key = "R", const std::string& t_key = "T") const;

 private:
  std::string path_;
  std::map<std::string, std::vector<double>> values_;
  std::map<std::string, bool> numeric_;
};

/// Isometry from a 3x4 [R|t]; the rotation is taken as given (KITTI matrices are orthonormal to
/// ~1e-9).
Eigen::Isometry3d isometryFrom3x4(const Eigen::Matrix<double, 3, 4>& m);

/// Inverse by the full 4x4 matrix (as the KITTI devkit's inv()), not by transposing the rotation:
/// exact also for calibration rotations that are orthonormal to a few digits only.
Eigen::Isometry3d exactInverse(const Eigen::Isometry3d& T);

/// Throws Error(path, "<what> is not a rigid transform ...") unless T is finite with a rotation
/// block orthonormal within 1e-2 (rounded hand-typed values pass, garbage does not) and det +1.
void requireRigid(const Eigen::Isometry3d& T, const std::string& path, const std::string& what);

}  // namespace cleanmap::io
