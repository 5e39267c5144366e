// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §4a: the MRPT outputs of a run.
#include "cleanmap/mrpt/outputs.h"

#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/io/CStream.h>
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
#include "cleanmap/core/cell_map.h"
#include "cleanmap/core/error.h"
#include "cleanmap/core/serial_worker.h"
#include "cleanmap/core/stopwatch.h"
#include "cleanmap/io/direct_file.h"
#include "cleanmap/io/ply.h"
#include "cleanmap/mrpt/convert.h"
#include "cleanmap/mrpt/rawlog.h"
#include "gz_file.h"

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
// plain at 0 (MRPT's gzip reader reads plain files too, and zlib's CRC is not free). Plain files
// go past the page cache (io::DirectFile, issue #16).
struct OutFile {
  std::string path, tmp;
  std::unique_ptr<io::DirectFile> plain;
  ::mrpt::io::CFileGZOutputStream gz;
  bool open = false;

  OutFile(std::string p, int level, const char* suffix = ".tmp.") : path(std::move(p)) {
    tmp = path + suffix + std::to_string(::getpid());
    if (level <= 0)
      plain = std::make_unique<io::DirectFile>(tmp);
    else if (!gz.open(tmp, level))
      throw Error(path, "cannot open for writing");
    open = true;
  }
  ~OutFile() {
    if (open) {
      if (plain)
        plain.reset();
      else
        gz.close();
      std::remove(tmp.c_str());
    }
  }
  void write(const void* data, std::size_t n) {
    if (plain)
      plain->write(data, n);
    else if (gz.Write(data, n) != n)
      throw Error(path, "write failed (disk full?)");
  }
  // Closed and checked; the temporary stays until close() moves it or the destructor removes it.
  void finishWriting() {
    if (plain)
      plain->close();
    else
      closeGzChecked(gz, tmp, path);
  }
  void close() {
    if (!open) return;
    finishWriting();
    std::error_code ec;
    fs::rename(tmp, path, ec);
    if (ec) throw Error(path, "cannot move into place: " + ec.message());
    open = false;
  }
};

// An MRPT stream into an OutFile, write-only: MRPT serializes a scene a float at a time, and
// each goes into DirectFile's buffer (CFileOutputStream took each through std::ofstream).
class OutFileStream : public ::mrpt::io::CStream {
 public:
  explicit OutFileStream(OutFile& f) : f_(f) {}
  size_t Read(void*, size_t) override { throw std::logic_error("OutFileStream: write-only"); }
  size_t Write(const void* data, size_t n) override {
    f_.write(data, n);
    pos_ += n;
    return n;
  }
  uint64_t Seek(int64_t, TSeekOrigin) override {
    throw std::logic_error("OutFileStream: cannot seek");
  }
  uint64_t getTotalBytesCount() const override { return pos_; }
  uint64_t getPosition() const override { return pos_; }

 private:
  OutFile& f_;
  uint64_t pos_ = 0;
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

}  // namespace

// A queued piece of work of the writer thread: a decided scan, or the map's decision of one.
struct MrptOutputWriter::Job {
  bool map = false;
  ScanResult scan;
  int64_t index = 0;
  Labels map_labels;
  std::vector<PointXYZI> kept, removed;
};

namespace {
// The spool of a scan awaiting the map's decision: header, points (sensor frame), their original
// indices.
struct SpoolHeader {
  int64_t index;
  double timestamp;
  double pose[16];  // column-major 4x4
  uint64_t points;
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
  std::size_t simplemap_count_offset = 0;
  // map_decisions: the scans wait in a spool until the map decides them (writeMapScan).
  std::unique_ptr<io::DirectFile> spool;
  std::unique_ptr<io::DirectReader> spool_in;  // from the map's first decision on
  std::string spool_path;
  std::size_t spooled = 0, decided = 0;
  // Scene: voxel-decimated points and the trajectory.
  CellSet static_cells, moving_cells;  // the scene's voxel filter
  std::vector<PointXYZI> scene_static, scene_moving;
  std::vector<std::array<uint8_t, 3>> scene_static_rgb;
  std::vector<Eigen::Vector3d> trajectory;

  // A point joins the scene if its voxel has none yet (CellSet: consecutive points of a scan
  // mostly share a block of voxels, so the test stays in cache).
  void addStatic(const std::vector<PointXYZI>& pts, double z0, double inv_voxel) {
    for (const auto& p : pts)  // the ground too: it gives the scene its shape
      if (static_cells.insertPoint<double>(p.x, p.y, p.z, inv_voxel)) {
        scene_static.push_back(p);
        scene_static_rgb.push_back(io::heightColour(double(p.z) - z0));
      }
  }
  void addMoving(const std::vector<PointXYZI>& pts, double inv_voxel) {
    for (const auto& p : pts)
      if (moving_cells.insertPoint<double>(p.x, p.y, p.z, inv_voxel)) scene_moving.push_back(p);
  }

  // The cleaned cloud of a scan (every point `keep` says) into cleaned.rawlog and the simplemap.
  template <class Keep>
  void writeCleaned(const std::vector<PointXYZI>& pts, const Eigen::Isometry3d& pose,
                    double timestamp, Keep&& keep) {
    using namespace ::mrpt::obs;
    auto& kept = *kept_map;
    kept.resize(pts.size());
    std::size_t k = 0;
    // The _fast setters: setPointRGB would lock the map's k-d tree mutex once per point (issue
    // #16); the map is marked modified once, below.
    for (std::size_t i = 0; i < pts.size(); ++i)
      if (keep(i)) {
        kept.setPointFast(k, pts[i].x, pts[i].y, pts[i].z);
        kept.setPointColor_fast(k++, pts[i].intensity, 0, 0);
      }
    kept.resize(k);
    kept.mark_as_modified();
    const auto [pb, pn] = enc(*poseObservation(pose, timestamp));
    cleaned->write(pb, pn);
    auto o = CObservationPointCloud::Create();
    o->sensorLabel = "LIDAR";
    o->timestamp = toMrptTime(timestamp);
    o->pointcloud = kept_map;
    CSensoryFrame sf;
    sf.insert(o);
    // The cleaned cloud is serialized once, for the rawlog and the simplemap.
    const auto [cb, cn] = enc(*o);
    cleaned->write(cb, cn);
    const auto [sb, sn] = enc(::mrpt::poses::CPose3DPDFGaussian(toCPose3D(pose)), sf);
    simplemap_body->write(sb, sn);
    ++simplemap_count;
  }

  static ::mrpt::obs::CObservationRobotPose::Ptr poseObservation(const Eigen::Isometry3d& pose,
                                                                 double timestamp) {
    auto o = ::mrpt::obs::CObservationRobotPose::Create();
    o->sensorLabel = "POSE";
    o->timestamp = toMrptTime(timestamp);
    o->pose.mean = toCPose3D(pose);
    o->pose.cov.setZero();
    return o;
  }

  void closeSpool() {
    if (!spool && !spool_in) return;
    spool.reset();
    spool_in.reset();
    std::remove(spool_path.c_str());
  }
  void spoolWrite(const void* data, std::size_t bytes) { spool->write(data, bytes); }
  void spoolRead(void* data, std::size_t bytes) { spool_in->read(data, bytes); }

  void writeScene(const std::string& path) const {
    using namespace ::mrpt::opengl;
    COpenGLScene scene;
    auto stat = CPointCloudColoured::Create();
    stat->setName("static_map");
    stat->setPointSize(2.0f);
    setColouredCloud(*stat, scene_static, scene_static_rgb);  // one lock, not one per point
    scene.insert(stat);
    auto mov = CPointCloud::Create();
    mov->setName("moving_points");
    mov->setPointSize(3.0f);
    mov->setColor(1.0, 0.0, 0.0);
    for (const auto& p : scene_moving) mov->insertPoint(p.x, p.y, p.z);  // few: voxels of movers
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
    // Plain, not gzip: SceneViewer3D reads both, and gzip costs seconds on a long drive.
    OutFile f(path, 0);
    OutFileStream stream(f);
    try {
      auto ar = ::mrpt::serialization::archiveFrom(stream);
      ar << scene;
    } catch (const Error&) {
      throw;
    } catch (const std::exception& e) {
      throw Error(path, std::string("cannot write the scene: ") + e.what());
    }
    f.close();
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
      simplemap_count_offset = head.size();
    }
  }

  void writeSimplemap(const std::string& path, int level) {
    const uint8_t end = 0x88;  // the end byte of the CSimpleMap object
    simplemap_body->write(&end, 1);
    const uint32_t count = static_cast<uint32_t>(simplemap_count);  // little endian, as MRPT
    if (level <= 0) {
      simplemap_body->plain->patchHead(simplemap_count_offset, &count, 4);
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
      // read / write, not `out << in.rdbuf()`: that reports no error once a byte went through
      std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
      std::vector<char> buf(1 << 20);
      for (const std::string& part : {head.tmp, simplemap_body->tmp}) {
        std::ifstream in(part, std::ios::binary);
        while (in && out) {
          in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
          out.write(buf.data(), in.gcount());
        }
        if (!in.eof()) out.setstate(std::ios::badbit);  // a part that could not be read
      }
      out.close();
      if (!out) {
        std::remove(tmp.c_str());
        throw Error(path, "write failed (disk full?)");
      }
    }
    simplemap_body.reset();  // removes its temporary (the head's goes with `head`)
    std::error_code ec;
    fs::rename(tmp, path, ec);
    if (ec) {
      std::remove(tmp.c_str());
      throw Error(path, "cannot move into place: " + ec.message());
    }
  }

  // MrptOutputOptions::background: the jobs run on a thread of their own, at most two queued
  // besides the one running. Last, so its thread stops before the members its jobs use go.
  std::unique_ptr<SerialWorker<Job>> worker;
};

MrptOutputWriter::MrptOutputWriter(const std::string& folder, const MrptOutputOptions& opts)
    : impl_(std::make_unique<Impl>()), opts_(opts) {
  registerClasses();
  impl_->folder = folder;
  if (opts_.rawlogs) {
    impl_->cleaned = std::make_unique<OutFile>(folder + "/cleaned.rawlog", opts_.gzip_level);
    impl_->labelled = std::make_unique<OutFile>(folder + "/labelled.rawlog", opts_.gzip_level);
    impl_->startSimplemap(folder + "/static_map.simplemap", opts_.gzip_level);
    if (opts_.map_decisions) {
      impl_->spool_path = folder + "/.mrpt_spool." + std::to_string(::getpid());
      impl_->spool = std::make_unique<io::DirectFile>(impl_->spool_path);
    }
  }
  if (opts_.background)
    impl_->worker = std::make_unique<SerialWorker<Job>>([this](Job& j) { run(j); }, 3);
}

MrptOutputWriter::~MrptOutputWriter() {
  impl_->worker.reset();  // an error or a signal: the queued jobs are dropped
  impl_->closeSpool();
}

std::size_t MrptOutputWriter::scenePoints() const {
  return impl_->scene_static.size() + impl_->scene_moving.size();
}

void MrptOutputWriter::write(ScanResult&& r) {
  Job j;
  j.scan = std::move(r);
  enqueue(std::move(j));
}

void MrptOutputWriter::run(const Job& j) {
  if (j.map)
    writeMapNow(j);
  else
    writeNow(j.scan);
}

void MrptOutputWriter::enqueue(Job&& j) {
  if (!opts_.background) return run(j);
  impl_->worker->push(std::move(j));  // rethrows an earlier job's error
}

void MrptOutputWriter::writeNow(const ScanResult& r) {
  const auto t0 = Clock::now();
  auto& I = *impl_;
  const double inv_voxel = 1.0 / opts_.viewer_voxel;
  if (opts_.scene) {
    if (!opts_.map_decisions) I.addStatic(r.static_full, r.pose.translation().z(), inv_voxel);
    I.addMoving(r.moving, inv_voxel);
    I.trajectory.push_back(r.pose.translation());
  }
  if (opts_.rawlogs) {
    if (r.scan.original_size == 0 && !r.labels.empty())
      throw Error(r.source, "scan " + r.stem + ": its points were not kept for the MRPT outputs");
    // The maps live as long as the writer: no fresh pages per scan.
    auto& lab = *I.labelled_map;
    auto& mov = *I.moving_map;
    const std::size_t n = r.scan.size();
    std::size_t m = 0;
    lab.resize(n);
    mov.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      const auto& p = r.scan.points[i];
      const uint32_t l = r.labels[r.scan.originalIndex(i)];
      if (l == kMoving) {  // the _fast setters, as in writeCleaned
        mov.setPointFast(m, p.x, p.y, p.z);
        mov.setPointColor_fast(m++, p.intensity, 0, 0);
      }
      const auto c = labelColour(l);
      lab.setPointFast(i, p.x, p.y, p.z);
      lab.setPointColor_fast(i, c[0], c[1], c[2]);
    }
    mov.resize(m);
    mov.mark_as_modified();
    lab.mark_as_modified();
    auto cloud = [&](const char* label, const ::mrpt::maps::CPointsMap::Ptr& map) {
      auto o = ::mrpt::obs::CObservationPointCloud::Create();
      o->sensorLabel = label;
      o->timestamp = toMrptTime(r.timestamp);
      o->pointcloud = map;
      return o;
    };
    const auto [pb, pn] = I.enc(*Impl::poseObservation(r.pose, r.timestamp));
    I.labelled->write(pb, pn);
    const auto [lb, ln] = I.enc(*cloud("LIDAR_LABELLED", I.labelled_map));
    I.labelled->write(lb, ln);
    // RawLogViewer 2.5.8 draws a point cloud without its colours (doc/MRPT.md): the moving
    // points also come as their own cloud, a LIDAR_MOVING row in its timeline.
    const auto [mb, mn] = I.enc(*cloud("LIDAR_MOVING", I.moving_map));
    I.labelled->write(mb, mn);
    if (!opts_.map_decisions) {
      I.writeCleaned(r.scan.points, r.pose, r.timestamp,
                     [&](std::size_t i) { return r.labels[r.scan.originalIndex(i)] != kMoving; });
    } else {  // the cleaned scan waits for the map's decision (writeMapScan)
      SpoolHeader h{static_cast<int64_t>(r.index), r.timestamp, {}, n};
      std::copy(r.pose.matrix().data(), r.pose.matrix().data() + 16, h.pose);
      I.spoolWrite(&h, sizeof h);
      I.spoolWrite(r.scan.points.data(), n * sizeof(PointXYZI));
      std::vector<uint32_t> orig(n);
      for (std::size_t i = 0; i < n; ++i) orig[i] = static_cast<uint32_t>(r.scan.originalIndex(i));
      I.spoolWrite(orig.data(), n * sizeof(uint32_t));
    }
  }
  if (opts_.map_decisions) ++I.spooled;
  ms_ += msSince(t0);
}

// The map's decision of the next spooled scan (DESIGN §4a): its cleaned cloud holds the points
// the cleaned map keeps (map_labels other than moving: the windowed test's moving points and those
// whose space the sequence saw empty), the scene the map's points.
void MrptOutputWriter::writeMapNow(const Job& j) {
  const auto t0 = Clock::now();
  auto& I = *impl_;
  if (I.decided >= I.spooled)
    throw Error(I.folder, "the map decided scan " + std::to_string(j.index) +
                              ", which was never written (writeMapScan before write)");
  ++I.decided;
  if (opts_.scene) {
    const double inv_voxel = 1.0 / opts_.viewer_voxel;
    const double z0 = I.trajectory[I.decided - 1].z();
    I.addStatic(j.kept, z0, inv_voxel);
    I.addMoving(j.removed, inv_voxel);
  }
  if (opts_.rawlogs) {
    if (!I.spool_in) {  // every scan is spooled before the map decides the first
      I.spool->close();
      I.spool_in = std::make_unique<io::DirectReader>(I.spool_path);
    }
    SpoolHeader h;
    I.spoolRead(&h, sizeof h);
    if (h.index != j.index)
      throw Error(I.folder, "the map decided scan " + std::to_string(j.index) + " where scan " +
                                std::to_string(h.index) + " was written (out of order)");
    std::vector<PointXYZI> pts(h.points);
    std::vector<uint32_t> orig(h.points);
    I.spoolRead(pts.data(), pts.size() * sizeof(PointXYZI));
    I.spoolRead(orig.data(), orig.size() * sizeof(uint32_t));
    Eigen::Isometry3d pose;
    std::copy(h.pose, h.pose + 16, pose.matrix().data());
    I.writeCleaned(pts, pose, h.timestamp, [&](std::size_t i) {
      return orig[i] >= j.map_labels.size() || j.map_labels[orig[i]] != kMoving;
    });
  }
  ms_ += msSince(t0);
}

void MrptOutputWriter::writeMapScan(int64_t index, const Labels& map_labels,
                                    const std::vector<PointXYZI>& kept,
                                    const std::vector<PointXYZI>& removed) {
  if (!opts_.map_decisions)
    throw Error(impl_->folder, "writeMapScan needs MrptOutputOptions::map_decisions");
  Job j;
  j.map = true;
  j.index = index;
  j.map_labels = map_labels;
  j.kept = kept;
  j.removed = removed;
  enqueue(std::move(j));
}

void MrptOutputWriter::finish() {
  auto& I = *impl_;
  if (I.worker) {
    I.worker->wait();  // rethrows a job's error
    I.worker.reset();
  }
  if (I.decided < I.spooled)
    throw Error(I.folder, std::to_string(I.spooled - I.decided) + " of " +
                              std::to_string(I.spooled) +
                              " scans were not decided by the map (writeMapScan)");
  I.closeSpool();
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
