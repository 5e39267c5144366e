// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/sim/generate.h"

#include <cstdio>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "cleanmap/core/error.h"
#include "cleanmap/io/files.h"
#include "cleanmap/io/kitti.h"
#include "cleanmap/sim/world.h"

namespace fs = std::filesystem;

namespace cleanmap::sim {
namespace {

std::string row3x4(const Eigen::Matrix<double, 3, 4>& m) {
  std::ostringstream os;
  os.precision(12);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) os << (r || c ? " " : "") << m(r, c);
  return os.str();
}

}  // namespace

GenerateSummary generateSequence(const Scenario& sc, const std::string& dir,
                                 const GenerateOptions& opt,
                                 const std::function<void(int, int)>& progress) {
  std::error_code ec;
  for (const char* sub : {"velodyne", "labels", "image_2"}) {
    if (std::string(sub) == "image_2" && !(opt.images && sc.sensor.camera)) continue;
    fs::create_directories(fs::path(dir) / sub, ec);
    if (ec) throw Error(dir, "cannot create the output folder: " + ec.message());
  }
  const PinholeCamera cam = kittiCamera();
  // KITTI odometry convention: poses.txt holds camera-0 poses, T_world_velo = Tr^-1 P Tr.
  Eigen::Isometry3d Tr = Eigen::Isometry3d::Identity();
  Eigen::Matrix<double, 3, 4> P0 = cam.P;
  P0.col(3).setZero();
  Tr = cam.T_cam_lidar;
  GenerateSummary sum;
  std::vector<Eigen::Isometry3d> cam_poses;
  std::string times;
  nlohmann::json objects = nlohmann::json::array();
  std::map<int, std::size_t> object_row;  // tracked id -> index in `objects`
  for (int k = 0; k < sc.frames; ++k) {
    char stem[16];
    std::snprintf(stem, sizeof stem, "%06d", k);
    const SimScan s = simulateScan(sc, k, opt.threads);
    io::writeKittiBin(dir + "/velodyne/" + stem + ".bin", s.points);
    io::writeLabels(dir + "/labels/" + stem + ".label", s.labels);
    cam_poses.push_back(Tr * s.reported_pose * Tr.inverse());
    char t[32];
    std::snprintf(t, sizeof t, "%.6e\n", s.time);
    times += t;
    sum.points += s.points.size();
    for (uint32_t l : s.labels) sum.moving_points += l == 251;
    if (opt.images && sc.sensor.camera) {
      const cv::Mat img = renderImage(sc, k, cam, opt.threads);
      std::vector<uchar> png;
      if (!cv::imencode(".png", img, png)) throw Error(dir, "PNG encoding failed");
      io::writeFileAtomic(dir + "/image_2/" + stem + ".png", [&](std::ostream& os) {
        os.write(reinterpret_cast<const char*>(png.data()),
                 static_cast<std::streamsize>(png.size()));
      });
      ++sum.images;
    }
    // objects.json: tracked solids (vehicles, movers) in this scan's lidar frame.
    const World w(sc, s.time);
    std::map<int, int> hits;
    for (std::size_t i = 0; i < s.solid.size(); ++i)
      if (s.solid[i] >= 0) ++hits[s.solid[i]];
    const Eigen::Isometry3d inv = s.pose.inverse();
    const double ego_yaw = std::atan2(s.pose.linear()(1, 0), s.pose.linear()(0, 0));
    for (int i = 0; i < static_cast<int>(w.solids().size()); ++i) {
      const Solid& o = w.solids()[i];
      if (!o.tracked_id || !hits.count(i)) continue;
      if (!object_row.count(o.tracked_id)) {
        object_row[o.tracked_id] = objects.size();
        objects.push_back({{"id", o.tracked_id},
                           {"name", o.name},
                           {"class", o.cls},
                           {"frames", nlohmann::json::object()}});
      }
      const Eigen::Vector3d c = inv * o.center;
      nlohmann::json f = {{"center", {c.x(), c.y(), c.z()}},
                          {"size", {2 * o.half.x(), 2 * o.half.y(), 2 * o.half.z()}},
                          {"yaw", std::remainder(o.yaw - ego_yaw, 2 * M_PI)},
                          {"n_points", hits[i]}};
      f["moving"] = o.motion < 0 ? nlohmann::json(nullptr) : nlohmann::json(o.motion > 0);
      objects[object_row[o.tracked_id]]["frames"][std::to_string(k)] = f;
    }
    ++sum.frames;
    if (progress) progress(k + 1, sc.frames);
  }
  io::writePosesFile(dir + "/poses.txt", cam_poses);
  io::writeFileAtomic(dir + "/times.txt", [&](std::ostream& os) { os << times; });
  io::writeFileAtomic(dir + "/calib.txt", [&](std::ostream& os) {
    os << "P0: " << row3x4(P0) << "\nP2: " << row3x4(cam.P)
       << "\nTr: " << row3x4(Tr.matrix().topRows<3>()) << '\n';
  });
  io::writeFileAtomic(dir + "/objects.json",
                      [&](std::ostream& os) { os << objects.dump(1) << '\n'; });
  return sum;
}

}  // namespace cleanmap::sim
