// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/io/kitti.h"

#include <algorithm>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>

#include <opencv2/imgcodecs.hpp>

#include "cleanmap/core/deskew.h"
#include "cleanmap/core/error.h"
#include "cleanmap/core/params.h"
#include "cleanmap/io/calib.h"
#include "cleanmap/io/config.h"
#include "cleanmap/io/image.h"

namespace fs = std::filesystem;

namespace cleanmap::io {
namespace {

bool isDir(const fs::path& p) {
  std::error_code ec;
  return fs::is_directory(p, ec);
}
bool isFile(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec);
}

std::vector<std::string> stemsOf(const std::vector<std::string>& files) {
  std::vector<std::string> s;
  s.reserve(files.size());
  for (const auto& f : files) s.push_back(fs::path(f).stem().string());
  return s;
}

void requireCount(const std::string& path, const std::string& what, std::size_t n,
                  std::size_t scans) {
  if (n != scans)
    throw Error(path, "has " + std::to_string(n) + " " + what + " but the sequence has " +
                          std::to_string(scans) + " scans");
}

// The scans' times may repeat (placeholders) but never go back: the window in seconds (DESIGN
// §2b), the sweeps' motion (§2.0) and the camera's depth correction (§3) read differences of them.
void requireTimeOrder(const std::string& path, const std::vector<double>& t,
                      const std::vector<std::string>& stems) {
  for (std::size_t i = 1; i < t.size() && i < stems.size(); ++i)
    if (t[i] < t[i - 1])
      throw Error(path, "the time of scan " + stems[i] + " (" + shortestDouble(t[i]) +
                            ") is earlier than that of the scan before (" +
                            shortestDouble(t[i - 1]) + "); the scans must be in time order");
}

// Lines of numbers, one value per line (times.txt).
std::vector<double> readNumberLines(const std::string& path) {
  std::istringstream in(readTextFile(path));
  std::vector<double> v;
  std::string line;
  std::size_t lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    std::istringstream ls(line);
    double x = 0;
    std::string rest;
    if (!(ls >> x) || (ls >> rest) || !std::isfinite(x))
      throw Error(path, "line " + std::to_string(lineno) + " is not a finite number");
    v.push_back(x);
  }
  return v;
}

std::vector<double> readTimestampLines(const std::string& path) {
  std::istringstream in(readTextFile(path));
  std::vector<double> v;
  std::string line;
  while (std::getline(in, line))
    if (line.find_first_not_of(" \t\r") != std::string::npos)
      v.push_back(parseKittiTimestamp(line, path));
  return v;
}

// A rectified camera's 3x4 projection: finite, with a positive focal length.
void requireProjection(const Eigen::Matrix<double, 3, 4>& P, const std::string& path,
                       const std::string& key) {
  if (!P.allFinite() || !(P(0, 0) > 0) || !(P(1, 1) > 0) || P(2, 2) != 1)
    throw Error(path, key + " is not a camera projection (finite, fx, fy > 0, P(3,3) = 1)");
}

}  // namespace

std::vector<std::string> listFiles(const std::string& dir, const std::string& ext) {
  std::vector<std::string> files;
  if (!isDir(dir)) return files;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.is_regular_file() && e.path().extension() == ext) files.push_back(e.path().string());
  std::sort(files.begin(), files.end());
  return files;
}

std::vector<Eigen::Isometry3d> readPosesFile(const std::string& path) {
  std::istringstream in(readTextFile(path));
  std::vector<Eigen::Isometry3d> poses;
  std::string line;
  std::size_t lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    std::istringstream ls(line);
    Eigen::Matrix<double, 3, 4> m;
    for (int k = 0; k < 12; ++k) {
      if (!(ls >> m(k / 4, k % 4)))
        throw Error(path, "line " + std::to_string(lineno) + " does not hold 12 numbers");
    }
    std::string rest;
    if (ls >> rest)
      throw Error(path, "line " + std::to_string(lineno) + " holds more than 12 numbers");
    poses.push_back(isometryFrom3x4(m));
    requireRigid(poses.back(), path, "pose on line " + std::to_string(lineno));
  }
  return poses;
}

void writePosesFile(const std::string& path, const std::vector<Eigen::Isometry3d>& poses) {
  writeFileAtomic(path, [&](std::ostream& os) {
    os << std::scientific << std::setprecision(12);
    for (const auto& T : poses) {
      for (int k = 0; k < 12; ++k) os << (k ? " " : "") << T.matrix()(k / 4, k % 4);
      os << '\n';
    }
  });
}

Eigen::Isometry3d oxtsToMercatorPose(double lat, double lon, double alt, double roll, double pitch,
                                     double yaw, double scale) {
  constexpr double kEarthRadius = 6378137.0;  // WGS-84 equatorial radius, as in the KITTI devkit
  const double tx = scale * lon * M_PI * kEarthRadius / 180.0;
  const double ty = scale * kEarthRadius * std::log(std::tan((90.0 + lat) * M_PI / 360.0));
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(tx, ty, alt);
  return T;
}

double parseKittiTimestamp(const std::string& text, const std::string& file) {
  std::tm tm{};
  std::istringstream in(text);
  in >> std::get_time(&tm, "%Y-%m-%d %H:%M:%S");
  if (in.fail()) throw Error(file, "bad timestamp '" + text + "'");
  double frac = 0.0;
  std::string rest;
  in >> rest;
  if (!rest.empty()) {  // the fraction of a second: '.' and up to 12 digits
    if (rest[0] != '.' || rest.size() > 13 ||
        rest.find_first_not_of("0123456789", 1) != std::string::npos)
      throw Error(file, "bad timestamp '" + text + "'");
    frac = std::stod("0" + rest);
  }
  std::string extra;
  if (in >> extra) throw Error(file, "bad timestamp '" + text + "'");
  return static_cast<double>(timegm(&tm)) + frac;
}

KittiSequence KittiSequence::open(const std::string& dir, const KittiReadOptions& opts) {
  requireDirectory(dir);
  KittiSequence seq;
  seq.dir_ = dir;
  seq.opts_ = opts;
  const fs::path d(dir);
  if (isDir(d / "velodyne")) {
    seq.layout_ = KittiLayout::kOdometry;
    seq.openOdometry();
  } else if (isDir(d / "velodyne_points" / "data")) {
    seq.layout_ = KittiLayout::kRaw;
    seq.openRaw();
  } else {
    throw Error(dir, "not a KITTI folder: neither velodyne/ nor velodyne_points/data/ found");
  }
  seq.listLabels();
  return seq;
}

void KittiSequence::openOdometry() {
  const fs::path d(dir_);
  scan_files_ = listFiles((d / "velodyne").string(), ".bin");
  if (scan_files_.empty()) throw Error((d / "velodyne").string(), "holds no .bin scans");
  stems_ = stemsOf(scan_files_);
  const std::size_t n = scan_files_.size();

  const bool has_images = isDir(d / "image_2") && opts_.load_images;
  const bool has_poses = isFile(d / "poses.txt");
  std::optional<KeyValueFile> calib;
  if (isFile(d / "calib.txt")) calib = KeyValueFile::load((d / "calib.txt").string());
  if ((has_images || has_poses) && !calib)
    throw Error((d / "calib.txt").string(),
                "file does not exist (needed for the lidar-camera transform Tr)");

  if (has_poses) {
    // poses.txt is in the camera-0 frame: T_world_velo = Tr^-1 * P_i * Tr.
    const Eigen::Isometry3d Tr = isometryFrom3x4(calib->matrix3x4("Tr"));
    requireRigid(Tr, calib->path(), "Tr");
    const std::string path = (d / "poses.txt").string();
    const auto cam_poses = readPosesFile(path);
    requireCount(path, "poses", cam_poses.size(), n);
    poses_.reserve(n);
    const Eigen::Isometry3d Tr_inv = exactInverse(Tr);
    for (const auto& P : cam_poses) poses_.push_back(Tr_inv * P * Tr);
  }

  if (isFile(d / "times.txt")) {
    const std::string path = (d / "times.txt").string();
    times_ = readNumberLines(path);
    requireCount(path, "timestamps", times_.size(), n);
    requireTimeOrder(path, times_, stems_);
  } else {
    for (std::size_t i = 0; i < n; ++i) times_.push_back(0.1 * static_cast<double>(i));
  }

  if (has_images) {
    const std::string img_dir = (d / "image_2").string();
    image_files_ = listFiles(img_dir, ".png");
    requireCount(img_dir, "images", image_files_.size(), n);
    PinholeCamera cam;
    cam.name = "image_2";
    cam.P = calib->matrix3x4("P2");
    cam.T_cam_lidar = isometryFrom3x4(calib->matrix3x4("Tr"));
    requireRigid(cam.T_cam_lidar, calib->path(), "Tr");
    requireProjection(cam.P, calib->path(), "P2");
    std::tie(cam.width, cam.height) = imageSize(image_files_.front());
    camera_ = cam;
  }
}

void KittiSequence::openRaw() {
  const fs::path d(dir_);
  const fs::path velo = d / "velodyne_points";
  scan_files_ = listFiles((velo / "data").string(), ".bin");
  if (scan_files_.empty()) throw Error((velo / "data").string(), "holds no .bin scans");
  stems_ = stemsOf(scan_files_);
  const std::size_t n = scan_files_.size();

  // Calibration files live in the date folder above the drive (or beside the data).
  auto findCalib = [&](const std::string& name) -> std::string {
    for (const fs::path& c : {d / name, d.parent_path() / name})
      if (isFile(c)) return c.string();
    throw Error((d / name).string(), "file does not exist (nor in the parent folder)");
  };

  if (isFile(velo / "timestamps.txt")) {
    const std::string path = (velo / "timestamps.txt").string();
    times_ = readTimestampLines(path);
    requireCount(path, "timestamps", times_.size(), n);
    requireTimeOrder(path, times_, stems_);
  } else {
    for (std::size_t i = 0; i < n; ++i) times_.push_back(0.1 * static_cast<double>(i));
  }
  // DESIGN §2.0: a raw drive's scans are not de-skewed (KITTI's readme: "untwist" them). Each
  // sweep lasts from timestamps_start to timestamps_end (timestamps.txt: facing forward), else
  // the scan period.
  const double period = scanPeriod(times_);
  sweeps_.assign(n, period > 0 ? period : 0.1);
  if (isFile(velo / "timestamps_start.txt") && isFile(velo / "timestamps_end.txt")) {
    const std::string ps = (velo / "timestamps_start.txt").string();
    const std::string pe = (velo / "timestamps_end.txt").string();
    const auto start = readTimestampLines(ps), end = readTimestampLines(pe);
    requireCount(ps, "timestamps", start.size(), n);
    requireCount(pe, "timestamps", end.size(), n);
    for (std::size_t i = 0; i < n; ++i)
      if (end[i] - start[i] > 1e-3 && end[i] - start[i] <= 1.0) sweeps_[i] = end[i] - start[i];
  }

  const fs::path oxts = d / "oxts" / "data";
  if (isDir(oxts)) {
    const auto files = listFiles(oxts.string(), ".txt");
    requireCount(oxts.string(), "OXTS records", files.size(), n);
    const auto imu_calib = KeyValueFile::load(findCalib("calib_imu_to_velo.txt"));
    const auto imu_to_velo = imu_calib.rigidRT();
    requireRigid(imu_to_velo, imu_calib.path(), "R, T");
    const Eigen::Isometry3d velo_to_imu = exactInverse(imu_to_velo);
    double scale = 0.0;
    Eigen::Isometry3d first_inv = Eigen::Isometry3d::Identity();
    for (std::size_t i = 0; i < n; ++i) {
      std::istringstream in(readTextFile(files[i]));
      double v[6];
      for (double& x : v)
        if (!(in >> x) || !std::isfinite(x))
          throw Error(files[i], "OXTS record does not start with 6 finite numbers");
      if (std::abs(v[0]) >= 85 || std::abs(v[1]) > 180)
        throw Error(files[i], "OXTS latitude / longitude out of range (|lat| < 85, |lon| <= 180)");
      if (i == 0) scale = std::cos(v[0] * M_PI / 180.0);
      const Eigen::Isometry3d T_imu = oxtsToMercatorPose(v[0], v[1], v[2], v[3], v[4], v[5], scale);
      if (i == 0) first_inv = exactInverse(T_imu);
      // Lidar pose with the first lidar frame as world origin.
      poses_.push_back(imu_to_velo * first_inv * T_imu * velo_to_imu);
      requireRigid(poses_.back(), files[i], "the OXTS pose");
    }
  }

  const fs::path img = d / "image_02" / "data";
  if (isDir(img) && opts_.load_images) {
    image_files_ = listFiles(img.string(), ".png");
    requireCount(img.string(), "images", image_files_.size(), n);
    const auto v2c = KeyValueFile::load(findCalib("calib_velo_to_cam.txt"));
    const auto c2c = KeyValueFile::load(findCalib("calib_cam_to_cam.txt"));
    PinholeCamera cam;
    cam.name = "image_02";
    cam.P = c2c.matrix3x4("P_rect_02");
    requireProjection(cam.P, c2c.path(), "P_rect_02");
    Eigen::Isometry3d R_rect = Eigen::Isometry3d::Identity();
    const auto& r = c2c.numbers("R_rect_00", 9);
    for (int i = 0; i < 9; ++i) R_rect.matrix()(i / 3, i % 3) = r[static_cast<std::size_t>(i)];
    requireRigid(R_rect, c2c.path(), "R_rect_00");
    requireRigid(v2c.rigidRT(), v2c.path(), "R, T");
    cam.T_cam_lidar = R_rect * v2c.rigidRT();
    const auto& s = c2c.numbers("S_rect_02", 2);
    for (const double x : s)
      if (!(x >= 1 && x <= 100000 && x == std::floor(x)))
        throw Error(c2c.path(), "S_rect_02 must be two whole pixel counts in [1, 100000]");
    cam.width = static_cast<int>(s[0]);
    cam.height = static_cast<int>(s[1]);
    camera_ = cam;
  }
}

void KittiSequence::listLabels() {
  const std::string dir = (fs::path(dir_) / "labels").string();
  label_files_ = listFiles(dir, ".label");
  if (!label_files_.empty()) requireCount(dir, "label files", label_files_.size(), size());
}

std::optional<std::string> KittiSequence::objectsPath() const {
  const fs::path p = fs::path(dir_) / "objects.json";
  if (isFile(p)) return p.string();
  return std::nullopt;
}

Scan KittiSequence::loadScan(std::size_t i) const {
  Scan s = readKittiBin(scan_files_.at(i), opts_.scan);
  s.timestamp = times_.at(i);
  if (!sweeps_.empty() && opts_.point_times)  // a raw drive
    s.point_time = azimuthTimes(s.points, sweeps_[i]);
  if (hasPoses()) {
    s.pose = poses_[i];
    s.has_pose = true;
  }
  return s;
}

std::optional<Image> KittiSequence::loadImage(std::size_t i) const {
  if (!hasImages()) return std::nullopt;
  Image img;
  img.bgr = readImage(image_files_.at(i), cv::IMREAD_COLOR);
  img.timestamp = times_.at(i);
  return img;
}

Labels KittiSequence::loadLabels(std::size_t i, std::optional<std::size_t> expected_count) const {
  if (!hasLabels()) throw Error(dir_, "has no labels/ folder");
  return readLabels(label_files_.at(i), expected_count);
}

Frame KittiSequence::frame(std::size_t i) const {
  Frame f;
  f.index = i;
  f.stem = stems_.at(i);
  f.source = scanPath(i);
  f.scan = loadScan(i);
  f.image = loadImage(i);
  return f;
}

std::optional<Frame> KittiSequence::next() {
  if (cursor_ >= size()) return std::nullopt;
  return frame(cursor_++);
}

}  // namespace cleanmap::io
