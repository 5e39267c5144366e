// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §4a: the MRPT outputs of a run.
#include "cleanmap/mrpt/outputs.h"

#include <unistd.h>

#include <condition_variable>
#include <cstdio>
#include <deque>
#include <exception>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <thread>

#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/io/CFileOutputStream.h>
#include <mrpt/maps/CColouredPointsMap.h>
#include <mrpt/maps/CSimpleMap.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CObservationRobotPose.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/opengl/CCamera.h>
#include <mrpt/opengl/COpenGLScene.h>
#include <mrpt/opengl/CPointCloud.h>
#include <mrpt/opengl/CPointCloudColoured.h>
#include <mrpt/poses/CPose3DPDFGaussian.h>
#include <mrpt/serialization/CArchive.h>
#include <mrpt/serialization/archiveFrom_std_vector.h>

#include "cleanmap/core/cell_key.h"
#include "cleanmap/core/error.h"
#include "cleanmap/core/stopwatch.h"
#include "cleanmap/io/ply.h"
#include "cleanmap/mrpt/convert.h"
#include "cleanmap/mrpt/rawlog.h"

namespace fs = std::filesystem;

namespace cleanmap::mrpt {

// Palette of labelled.rawlog: binary fractions, exact in float.
std::array<float, 3> labelColour(uint32_t label) {
  switch (label) {
    case kMoving:
      return {1.0f, 0.0f, 0.0f};
    case kStatic:
      return {0.75f, 0.75f, 0.75f};
    case kGround:
      return {0.5f, 0.25f, 0.0f};
    default:  // kUnclassified: out of the crop
      return {0.0f, 0.25f, 1.0f};
  }
}

uint32_t labelFromColour(float r, float g, float b) {
  for (const uint32_t l :
       {uint32_t(kMoving), uint32_t(kStatic), uint32_t(kGround), uint32_t(kUnclassified)}) {
    const auto c = labelColour(l);
    if (c[0] == r && c[1] == g && c[2] == b) return l;
  }
  return kOutlier;
}

namespace {

// A file written under a temporary name, renamed into place by close(): gzip at `level` >= 1,
// plain at 0 (MRPT's gzip reader reads plain files too, and zlib's CRC is not free).
struct OutFile {
  std::string path, tmp;
  std::FILE* plain = nullptr;
  ::mrpt::io::CFileGZOutputStream gz;
  bool open = false;

  OutFile(std::string p, int level, const char* suffix = ".tmp.") : path(std::move(p)) {
    tmp = path + suffix + std::to_string(::getpid());
    if (level <= 0)
      plain = std::fopen(tmp.c_str(), "wb");
    else if (!gz.open(tmp, level))
      throw Error(path, "cannot open for writing");
    if (level <= 0 && !plain) throw Error(path, "cannot open for writing");
    open = true;
  }
  ~OutFile() {
    if (open) {
      finishWriting();
      std::remove(tmp.c_str());
    }
  }
  void write(const void* data, std::size_t n) {
    if (plain ? std::fwrite(data, 1, n, plain) != n : gz.Write(data, n) != n)
      throw Error(path, "write failed (disk full?)");
  }
  void finishWriting() {
    open = false;
    if (plain) {
      const bool ok = std::fclose(plain) == 0;
      plain = nullptr;
      if (!ok) throw Error(path, "write failed (disk full?)");
    } else {
      gz.close();
    }
  }
  void close() {
    if (!open) return;
    finishWriting();
    std::error_code ec;
    fs::rename(tmp, path, ec);
    if (ec) {
      std::remove(tmp.c_str());
      throw Error(path, "cannot move into place: " + ec.message());
    }
  }
};

// Serializes objects in MRPT's archive format into a reused buffer (its capacity stays).
class Encoder {
 public:
  template <class... T>
  std::pair<const void*, std::size_t> operator()(const T&... objs) {
    buf_.clear();
    auto ar = ::mrpt::serialization::archiveFrom(buf_);
    (ar << ... << objs);
    return {buf_.data(), buf_.size()};
  }

 private:
  std::vector<uint8_t> buf_;
};

// The serialized bytes of an object.
std::vector<uint8_t> serialized(const ::mrpt::serialization::CSerializable& o) {
  Encoder enc;
  const auto [p, n] = enc(o);
  return {static_cast<const uint8_t*>(p), static_cast<const uint8_t*>(p) + n};
}

// A growing set of cell keys, open addressing with linear probing: the scene's voxel filter sees
// every static point of a run, where std::unordered_set's node per key cost 3 % of the run.
class CellSet {
 public:
  CellSet() : keys_(1 << 16, kEmpty), mask_((1 << 16) - 1) {}
  /// True if the key was not in the set (and is now).
  bool insert(uint64_t key) {
    for (std::size_t i = slot(key);; i = (i + 1) & mask_) {
      if (keys_[i] == key) return false;
      if (keys_[i] == kEmpty) {
        keys_[i] = key;
        if (++size_ * 2 > keys_.size()) grow();
        return true;
      }
    }
  }

 private:
  static constexpr uint64_t kEmpty = ~uint64_t(0);  // cell keys use 63 bits (cell_key.h)
  std::size_t slot(uint64_t key) const {
    return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> 17) & mask_;
  }
  void grow() {
    std::vector<uint64_t> old(keys_.size() * 2, kEmpty);
    old.swap(keys_);
    mask_ = keys_.size() - 1;
    for (const uint64_t k : old)
      if (k != kEmpty)
        for (std::size_t i = slot(k);; i = (i + 1) & mask_)
          if (keys_[i] == kEmpty) {
            keys_[i] = k;
            break;
          }
  }
  std::vector<uint64_t> keys_;
  std::size_t mask_, size_ = 0;
};

}  // namespace

// A CSimpleMap is written as a stream: MRPT's serialization of it is the object header, a uint32
// count, the (pose, sensory frame) pairs, and an end byte 0x88. The pairs go to one gzip member as
// they come, the header with the final count to another, and the two members are concatenated
// (gzip readers, zlib's included, read concatenated members as one stream). The header is taken
// from MRPT's own serialization of an empty map, so a changed format is detected, never guessed.
struct MrptOutputWriter::Impl {
  std::string folder;
  std::unique_ptr<OutFile> cleaned, labelled, simplemap_body;
  Encoder enc;
  ::mrpt::maps::CPointsMapXYZI::Ptr kept_map = ::mrpt::maps::CPointsMapXYZI::Create();
  ::mrpt::maps::CColouredPointsMap::Ptr labelled_map = ::mrpt::maps::CColouredPointsMap::Create();
  ::mrpt::maps::CPointsMapXYZI::Ptr moving_map = ::mrpt::maps::CPointsMapXYZI::Create();
  std::size_t simplemap_count = 0;
  long simplemap_count_offset = 0;
  // The worker thread and its queue (MrptOutputOptions::background).
  std::thread worker;
  std::mutex mu;
  std::condition_variable cv;
  std::deque<ScanResult> queue;
  bool closing = false;
  std::exception_ptr error;
  // Scene: voxel-decimated points and the trajectory.
  CellSet static_cells, moving_cells;
  std::vector<PointXYZI> scene_static, scene_moving;
  std::vector<std::array<uint8_t, 3>> scene_static_rgb;
  std::vector<Eigen::Vector3d> trajectory;

  // Consecutive points of a scan (neighbours on a ring) mostly share a voxel: the last key is
  // checked first, which spares most lookups in the large set.
  void addToScene(const ScanResult& r, double inv_voxel) {
    const double z0 = r.pose.translation().z();
    uint64_t last = ~uint64_t(0);
    for (const auto& p : r.static_full) {  // the ground too: it gives the scene its shape
      const uint64_t key = cellKeyOf<double>(p.x, p.y, p.z, inv_voxel);
      if (key == last) continue;
      last = key;
      if (static_cells.insert(key)) {
        scene_static.push_back(p);
        scene_static_rgb.push_back(io::heightColour(double(p.z) - z0));
      }
    }
    last = ~uint64_t(0);
    for (const auto& p : r.moving) {
      const uint64_t key = cellKeyOf<double>(p.x, p.y, p.z, inv_voxel);
      if (key != last && moving_cells.insert(key)) scene_moving.push_back(p);
      last = key;
    }
    trajectory.push_back(r.pose.translation());
  }

  void writeScene(const std::string& path) const {
    using namespace ::mrpt::opengl;
    COpenGLScene scene;
    auto stat = CPointCloudColoured::Create();
    stat->setName("static_map");
    stat->setPointSize(2.0f);
    stat->reserve(scene_static.size());
    for (std::size_t i = 0; i < scene_static.size(); ++i) {
      const auto& p = scene_static[i];
      const auto& c = scene_static_rgb[i];
      stat->push_back(p.x, p.y, p.z, c[0] / 255.0f, c[1] / 255.0f, c[2] / 255.0f);
    }
    scene.insert(stat);
    auto mov = CPointCloud::Create();
    mov->setName("moving_points");
    mov->setPointSize(3.0f);
    mov->setColor(1.0, 0.0, 0.0);
    for (const auto& p : scene_moving) mov->insertPoint(p.x, p.y, p.z);
    scene.insert(mov);
    // The trajectory as points every 0.25 m: MRPT 2.5.8's CSetOfLines misaligns its point base
    // class (UBSan reports every member call), so no lines.
    auto traj = CPointCloud::Create();
    traj->setName("trajectory");
    traj->setPointSize(4.0f);
    traj->setColor(0.0, 0.9, 1.0);
    for (std::size_t i = 0; i < trajectory.size(); ++i) {
      const Eigen::Vector3d a = trajectory[i];
      Eigen::Vector3d d = Eigen::Vector3d::Zero();
      if (i + 1 < trajectory.size()) d = trajectory[i + 1] - a;
      const int steps = std::max(1, static_cast<int>(std::ceil(d.norm() / 0.25)));
      for (int k = 0; k < steps; ++k) {
        const Eigen::Vector3d p = a + d * (double(k) / steps);
        traj->insertPoint(float(p.x()), float(p.y()), float(p.z()));
      }
    }
    scene.insert(traj);
    // The first view: the whole drive from above and behind its start, on a dark background.
    if (!trajectory.empty()) {
      Eigen::Vector3d lo = trajectory.front(), hi = lo;
      for (const auto& p : trajectory) {
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
      }
      const Eigen::Vector3d c = 0.5 * (lo + hi);
      const Eigen::Vector3d dir = trajectory.back() - trajectory.front();
      auto cam = CCamera::Create();
      cam->setPointingAt(c.x(), c.y(), c.z());
      cam->setZoomDistance(static_cast<float>(std::max(40.0, 1.5 * (hi - lo).head<2>().norm())));
      cam->setAzimuthDegrees(dir.head<2>().norm() > 1
                                 ? static_cast<float>(std::atan2(-dir.y(), -dir.x()) * 180 / M_PI)
                                 : 180.0f);
      cam->setElevationDegrees(50.0f);
      scene.insert(cam);
    }
    scene.getViewport()->setCustomBackgroundColor({0.05f, 0.05f, 0.08f});
    const std::string tmp = path + ".tmp." + std::to_string(::getpid());
    try {  // plain, not gzip: SceneViewer3D reads both, and gzip costs seconds on a long drive
      ::mrpt::io::CFileOutputStream f(tmp);
      auto ar = ::mrpt::serialization::archiveFrom(f);
      ar << scene;
    } catch (const std::exception& e) {
      std::remove(tmp.c_str());
      throw Error(path, std::string("cannot write the scene: ") + e.what());
    }
    std::error_code ec;
    fs::rename(tmp, path, ec);
    if (ec) throw Error(path, "cannot move into place: " + ec.message());
  }

  // The header of a serialized CSimpleMap (up to its count), from MRPT's own serialization of an
  // empty map: header, uint32 count 0, end byte 0x88.
  static std::vector<uint8_t> simplemapHeader(const std::string& path) {
    auto empty = serialized(::mrpt::maps::CSimpleMap());
    const std::size_t n = empty.size();
    if (n < 5 || empty[n - 1] != 0x88 || empty[n - 2] || empty[n - 3] || empty[n - 4] ||
        empty[n - 5])
      throw Error(path, "this MRPT's CSimpleMap format is not the one cleanmap streams");
    empty.resize(n - 5);
    return empty;
  }

  void startSimplemap(const std::string& path, int level) {
    simplemap_body = std::make_unique<OutFile>(path, level);
    if (level <= 0) {  // plain: the header goes first, its count is patched at the end
      const auto head = simplemapHeader(path);
      const uint32_t zero = 0;
      simplemap_body->write(head.data(), head.size());
      simplemap_body->write(&zero, 4);
      simplemap_count_offset = static_cast<long>(head.size());
    }
  }

  void writeSimplemap(const std::string& path, int level) {
    const uint8_t end = 0x88;  // the end byte of the CSimpleMap object
    simplemap_body->write(&end, 1);
    const uint32_t count = static_cast<uint32_t>(simplemap_count);  // little endian, as MRPT
    if (level <= 0) {
      std::FILE* f = simplemap_body->plain;
      if (std::fseek(f, simplemap_count_offset, SEEK_SET) != 0 || std::fwrite(&count, 4, 1, f) != 1)
        throw Error(path, "write failed (disk full?)");
      simplemap_body->close();
      return;
    }
    // gzip: the header with the count is a gzip member of its own, put in front of the body's.
    simplemap_body->finishWriting();
    const auto head_bytes = simplemapHeader(path);
    OutFile head(path, level, ".head.");
    head.write(head_bytes.data(), head_bytes.size());
    head.write(&count, 4);
    head.finishWriting();
    const std::string tmp = path + ".part." + std::to_string(::getpid());
    {
      std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
      for (const std::string& part : {head.tmp, simplemap_body->tmp}) {
        std::ifstream in(part, std::ios::binary);
        out << in.rdbuf();
      }
      if (!out) throw Error(path, "write failed (disk full?)");
    }
    std::remove(head.tmp.c_str());
    std::remove(simplemap_body->tmp.c_str());
    std::error_code ec;
    fs::rename(tmp, path, ec);
    if (ec) throw Error(path, "cannot move into place: " + ec.message());
  }
};

MrptOutputWriter::MrptOutputWriter(const std::string& folder, const MrptOutputOptions& opts)
    : impl_(std::make_unique<Impl>()), opts_(opts) {
  registerClasses();
  impl_->folder = folder;
  if (opts_.rawlogs) {
    impl_->cleaned = std::make_unique<OutFile>(folder + "/cleaned.rawlog", opts_.gzip_level);
    impl_->labelled = std::make_unique<OutFile>(folder + "/labelled.rawlog", opts_.gzip_level);
    impl_->startSimplemap(folder + "/static_map.simplemap", opts_.gzip_level);
  }
  if (opts_.background) impl_->worker = std::thread([this] { work(); });
}

MrptOutputWriter::~MrptOutputWriter() {
  stopWorker(false);
}  // an error or a signal: stop now

std::size_t MrptOutputWriter::scenePoints() const {
  return impl_->scene_static.size() + impl_->scene_moving.size();
}

void MrptOutputWriter::write(ScanResult&& r) {
  auto& I = *impl_;
  if (!opts_.background) return writeNow(r);
  std::unique_lock<std::mutex> lock(I.mu);
  I.cv.wait(lock, [&] { return I.queue.size() < 2 || I.error; });
  if (I.error) std::rethrow_exception(I.error);
  I.queue.push_back(std::move(r));
  I.cv.notify_all();
}

void MrptOutputWriter::work() {
  auto& I = *impl_;
  for (;;) {
    ScanResult r;
    {
      std::unique_lock<std::mutex> lock(I.mu);
      I.cv.wait(lock, [&] { return !I.queue.empty() || I.closing; });
      if (I.queue.empty()) return;
      r = std::move(I.queue.front());
      I.queue.pop_front();
      I.cv.notify_all();
    }
    try {
      writeNow(r);
    } catch (...) {
      std::lock_guard<std::mutex> lock(I.mu);
      I.error = std::current_exception();
      I.queue.clear();
      I.cv.notify_all();
      return;
    }
  }
}

void MrptOutputWriter::stopWorker(bool drain) {
  auto& I = *impl_;
  if (!I.worker.joinable()) return;
  {
    std::lock_guard<std::mutex> lock(I.mu);
    if (!drain) I.queue.clear();
    I.closing = true;
    I.cv.notify_all();
  }
  I.worker.join();
}

void MrptOutputWriter::writeNow(const ScanResult& r) {
  using namespace ::mrpt::obs;
  const auto t0 = Clock::now();
  auto& I = *impl_;
  if (opts_.scene) I.addToScene(r, 1.0 / opts_.viewer_voxel);
  if (opts_.rawlogs) {
    if (r.scan.original_size == 0 && !r.labels.empty())
      throw Error(r.source, "scan " + r.stem + ": its points were not kept for the MRPT outputs");
    const auto stamp = toMrptTime(r.timestamp);
    const ::mrpt::poses::CPose3D pose = toCPose3D(r.pose);
    auto pose_obs = CObservationRobotPose::Create();
    pose_obs->sensorLabel = "POSE";
    pose_obs->timestamp = stamp;
    pose_obs->pose.mean = pose;
    pose_obs->pose.cov.setZero();

    // The maps live as long as the writer: no fresh pages per scan.
    auto& kept = *I.kept_map;
    auto& lab = *I.labelled_map;
    auto& mov = *I.moving_map;
    const std::size_t n = r.scan.size();
    std::size_t k = 0, m = 0;
    kept.resize(n);
    lab.resize(n);
    mov.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      const auto& p = r.scan.points[i];
      const uint32_t l = r.labels[r.scan.originalIndex(i)];
      if (l != kMoving)
        kept.setPointRGB(k++, p.x, p.y, p.z, p.intensity, 0, 0);
      else
        mov.setPointRGB(m++, p.x, p.y, p.z, p.intensity, 0, 0);
      const auto c = labelColour(l);
      lab.setPointRGB(i, p.x, p.y, p.z, c[0], c[1], c[2]);
    }
    kept.resize(k);
    mov.resize(m);
    kept.mark_as_modified();
    mov.mark_as_modified();
    lab.mark_as_modified();
    auto cloud = [&](const char* label, const ::mrpt::maps::CPointsMap::Ptr& map) {
      auto o = CObservationPointCloud::Create();
      o->sensorLabel = label;
      o->timestamp = stamp;
      o->pointcloud = map;
      return o;
    };
    const auto cleaned = cloud("LIDAR", I.kept_map);
    const auto labelled = cloud("LIDAR_LABELLED", I.labelled_map);
    // RawLogViewer 2.5.8 draws a point cloud without its colours (doc/MRPT.md): the moving
    // points also come as their own cloud, a LIDAR_MOVING row in its timeline.
    const auto moving = cloud("LIDAR_MOVING", I.moving_map);

    // The cleaned cloud is serialized once, for the rawlog and the simplemap.
    const auto [pb, pn] = I.enc(*pose_obs);
    I.cleaned->write(pb, pn);
    I.labelled->write(pb, pn);
    const auto [lb, ln] = I.enc(*labelled);
    I.labelled->write(lb, ln);
    const auto [mb, mn] = I.enc(*moving);
    I.labelled->write(mb, mn);
    CSensoryFrame sf;
    sf.insert(cleaned);
    const auto [cb, cn] = I.enc(*cleaned);
    I.cleaned->write(cb, cn);
    const auto [sb, sn] = I.enc(::mrpt::poses::CPose3DPDFGaussian(pose), sf);
    I.simplemap_body->write(sb, sn);
    ++I.simplemap_count;
  }
  ms_ += msSince(t0);
}

void MrptOutputWriter::finish() {
  stopWorker(true);
  auto& I = *impl_;
  if (I.error) std::rethrow_exception(I.error);
  const auto t0 = Clock::now();
  if (opts_.rawlogs) {
    I.cleaned->close();
    I.labelled->close();
    I.writeSimplemap(I.folder + "/static_map.simplemap", opts_.gzip_level);
  }
  if (opts_.scene) I.writeScene(I.folder + "/static_map.3Dscene");
  ms_ += msSince(t0);
}

}  // namespace cleanmap::mrpt
