// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/maps/moving_objects_map.h"

#include <mrpt/config/CConfigFileBase.h>
#include <mrpt/obs/CObservation.h>
#include <mrpt/opengl/CPointCloud.h>
#include <mrpt/opengl/CPointCloudColoured.h>
#include <mrpt/opengl/CSetOfObjects.h>
#include <mrpt/serialization/CArchive.h>
#include <mrpt/version.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <set>
#include <sstream>

#include "cleanmap/core/cell_key.h"
#include "cleanmap/core/error.h"
#include "cleanmap/core/free_space.h"
#include "cleanmap/core/object_consensus.h"
#include "cleanmap/io/config.h"
#include "cleanmap/io/files.h"
#include "cleanmap/io/ply.h"
#include "cleanmap/mrpt/convert.h"
#include "cleanmap/pipeline/laser_pipeline.h"
#include "map_options.h"
#include "pose_observations.h"

namespace cleanmap_maps {

IMPLEMENTS_SERIALIZABLE(CMovingObjectsMap, CMetricMap, cleanmap_maps)
MAP_DEFINITION_REGISTER("cleanmap_maps::CMovingObjectsMap,cleanmap_moving",
                        cleanmap_maps::CMovingObjectsMap)

namespace {

std::vector<cleanmap::PointXYZI> sortedPoints(
    const std::unordered_map<uint64_t, cleanmap::PointXYZI>& m) {
  std::vector<std::pair<uint64_t, cleanmap::PointXYZI>> v(m.begin(), m.end());
  std::sort(v.begin(), v.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<cleanmap::PointXYZI> out;
  out.reserve(v.size());
  for (const auto& kv : v) out.push_back(kv.second);
  return out;
}

// The voxel of a point; with map_voxel 0 every point is its own entry (keyed by arrival). Calls
// added(key, i) for each point i that took a new entry.
template <class F>
void addPoints(std::unordered_map<uint64_t, cleanmap::PointXYZI>& m,
               const std::vector<cleanmap::PointXYZI>& pts, double voxel, F&& added) {
  const float inv = voxel > 0 ? static_cast<float>(1.0 / voxel) : 0.f;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const auto& p = pts[i];
    const uint64_t key = voxel > 0 ? cleanmap::cellKeyOf(p.x, p.y, p.z, inv) : m.size();
    if (m.emplace(key, p).second) added(key, i);
  }
}
void addPoints(std::unordered_map<uint64_t, cleanmap::PointXYZI>& m,
               const std::vector<cleanmap::PointXYZI>& pts, double voxel) {
  addPoints(m, pts, voxel, [](uint64_t, std::size_t) {});
}

void writePoints(mrpt::serialization::CArchive& out, const std::vector<cleanmap::PointXYZI>& v) {
  out << static_cast<uint64_t>(v.size());
  for (const auto& p : v) out << p.x << p.y << p.z << p.intensity;
}

// A saved string (MRPT's format: a uint32 length, the bytes) of at most at_most bytes: MRPT's own
// reader allocates whatever length it reads (up to 4 GiB; found by fuzzing).
std::string readString(mrpt::serialization::CArchive& in, uint32_t at_most, const char* what) {
  uint32_t n = 0;
  in >> n;
  if (n > at_most)
    throw cleanmap::Error("serialized cleanmap_moving", std::string(what) + " claims " +
                                                            std::to_string(n) + " bytes (at most " +
                                                            std::to_string(at_most) + ")");
  std::string text(n, '\0');
  if (n > 0 && in.ReadBuffer(text.data(), n) != n)
    throw cleanmap::Error("serialized cleanmap_moving", std::string(what) + " is cut short");
  return text;
}

// A saved map's count sizes nothing (a corrupt one would ask for 2^64 points): the points are
// read until the data runs out. Each must be finite and within kMaxCoordinate of the origin (its
// voxel key is an integer).
std::vector<cleanmap::PointXYZI> readPoints(mrpt::serialization::CArchive& in) {
  constexpr float kMaxCoordinate = 1e7f;
  uint64_t n = 0;
  in >> n;
  std::vector<cleanmap::PointXYZI> v;
  v.reserve(std::min<uint64_t>(n, kReserveAtMost));
  for (uint64_t i = 0; i < n; ++i) {
    cleanmap::PointXYZI p;
    in >> p.x >> p.y >> p.z >> p.intensity;
    if (!(std::abs(p.x) <= kMaxCoordinate && std::abs(p.y) <= kMaxCoordinate &&
          std::abs(p.z) <= kMaxCoordinate && std::isfinite(p.intensity)))
      throw cleanmap::Error("serialized cleanmap_moving",
                            "point " + std::to_string(i) + " is not finite or over 10,000 km away");
    v.push_back(p);
  }
  return v;
}

// The creationOpts table: every key of cleanmap's parameter table ("section.key") + map_voxel.
OptionTable creationOptions(cleanmap::PipelineParams& params, double& map_voxel,
                            int& map_object_scans) {
  OptionTable t;
  for (const auto& key : cleanmap::io::paramKeys())
    t.custom(key, [&params, key](const std::string& v, const std::string& where) {
      cleanmap::io::setParam(params, key, v, where);
    });
  t.real("map_voxel", map_voxel);
  t.integer("map_object_scans", map_object_scans);
  return t;
}

}  // namespace

// The layers alive in the process (freeSpaceBytesOfAll()).
namespace {
std::mutex g_layers_mutex;
std::set<const CMovingObjectsMap*>& liveLayers() {
  static std::set<const CMovingObjectsMap*> layers;
  return layers;
}
void enter(const CMovingObjectsMap* m) {
  std::lock_guard<std::mutex> lock(g_layers_mutex);
  liveLayers().insert(m);
}
}  // namespace

std::size_t CMovingObjectsMap::freeSpaceBytesOfAll() {
  std::lock_guard<std::mutex> lock(g_layers_mutex);
  std::size_t sum = 0;
  for (const auto* m : liveLayers()) sum += m->freeSpaceBytes();
  return sum;
}

CMovingObjectsMap::CMovingObjectsMap() {
  enter(this);
}

CMovingObjectsMap::CMovingObjectsMap(const cleanmap::PipelineParams& params, double map_voxel)
    : params_(params), map_voxel_(map_voxel) {
  cleanmap::validate(params_, "cleanmap_moving");
  checkMapVoxel(map_voxel, "cleanmap_moving");
  enter(this);
}

CMovingObjectsMap::CMovingObjectsMap(const CMovingObjectsMap& o) : CMetricMap(o) {
  copyFrom(o);
  enter(this);
}

CMovingObjectsMap& CMovingObjectsMap::operator=(const CMovingObjectsMap& o) {
  if (this != &o) {
    CMetricMap::operator=(o);
    copyFrom(o);
  }
  return *this;
}

CMovingObjectsMap::~CMovingObjectsMap() {
  std::lock_guard<std::mutex> lock(g_layers_mutex);
  liveLayers().erase(this);
}

void CMovingObjectsMap::copyFrom(const CMovingObjectsMap& o) {
  params_ = o.params_;
  map_voxel_ = o.map_voxel_;
  insertionOptions = o.insertionOptions;
  pose_obs_ = o.pose_obs_;
  pipe_ = o.pipe_ ? o.pipe_->clone([this](cleanmap::ScanResult&& r) { onDecided(std::move(r)); })
                  : nullptr;
  sink_ = nullptr;  // the copy's results are its own
  store_points_ = o.store_points_;
  keep_scans_ = o.keep_scans_;
  overlays_ = o.overlays_;
  register_ahead_ = o.register_ahead_;
  camera_ = o.camera_;
  next_index_ = o.next_index_;
  lidar_label_ = o.lidar_label_;
  static_ = o.static_;
  static_scan_ = o.static_scan_;
  object_scans_ = o.object_scans_;
  object_scans_max_ = o.object_scans_max_;
  frozen_ = o.frozen_;
  frozen_consensus_ = o.frozen_consensus_;
  ++version_;  // the decisions cached are the other map's
  moving_ = o.moving_;
  trajectory_ = o.trajectory_;
  totals_ = o.totals_;
}

void CMovingObjectsMap::setParams(const cleanmap::PipelineParams& params) {
  if (pending() > 0)
    throw cleanmap::Error("cleanmap_moving", "parameters cannot change while scans are pending");
  cleanmap::validate(params, "cleanmap_moving");
  params_ = params;
  ++version_;
  pipe_.reset();
}

void CMovingObjectsMap::setKeepScans(bool on) {
  keep_scans_ = on;
  if (pipe_) pipe_->keepScans(on);
}

void CMovingObjectsMap::setCamera(std::optional<cleanmap::PinholeCamera> camera) {
  camera_ = std::move(camera);
  if (pipe_) pipe_->setCamera(camera_);
}

void CMovingObjectsMap::setSaveOverlays(bool on) {
  overlays_ = on;
  if (pipe_) pipe_->saveOverlays(on);
}

void CMovingObjectsMap::setRegisterAhead(bool on) {
  register_ahead_ = on;
  if (pipe_) pipe_->registerAhead(on);
}

std::size_t CMovingObjectsMap::pending() const {
  return pipe_ ? pipe_->pending() : 0;
}

void CMovingObjectsMap::ensurePipeline() {
  if (pipe_) return;
  pipe_ = std::make_unique<cleanmap::LaserPipeline>(
      params_, [this](cleanmap::ScanResult&& r) { onDecided(std::move(r)); });
  pipe_->keepScans(keep_scans_);
  pipe_->setCamera(camera_);
  pipe_->saveOverlays(overlays_);
  pipe_->registerAhead(register_ahead_);
}

void CMovingObjectsMap::insertFrame(cleanmap::Frame&& frame) {
  ensurePipeline();
  ++version_;  // the free space may take the frame now
  next_index_ = std::max(next_index_, frame.index + 1);
  pipe_->push(std::move(frame));
}

const cleanmap::FreeSpaceMap* CMovingObjectsMap::freeSpace() const {
  return pipe_ ? pipe_->freeSpace() : nullptr;
}

std::size_t CMovingObjectsMap::freeSpaceBytes() const {
  return pipe_ ? pipe_->freeSpaceBytes() : 0;
}

void CMovingObjectsMap::flush() {
  if (pipe_) pipe_->finish();
}

bool CMovingObjectsMap::byObjects() const {
  return params_.map.clean && params_.map.objects && params_.object.enabled;
}

void CMovingObjectsMap::onDecided(cleanmap::ScanResult&& r) {
  ++version_;
  trajectory_.push_back({r.index, r.timestamp, r.pose});
  totals_ += r.stats;
  if (store_points_) {
    // Non-ground points remember their scan: the free space may remove them (DESIGN §2e).
    const bool kinds = r.static_full_kind.size() == r.static_full.size();
    // With map_voxel 0 every point is its own entry, keyed by arrival: the objects keep the keys.
    std::vector<uint64_t> entry(map_voxel_ == 0 && byObjects() && kinds ? r.static_full.size() : 0);
    addPoints(static_, r.static_full, map_voxel_, [&](uint64_t key, std::size_t i) {
      if (!entry.empty()) entry[i] = key;
      if (kinds && !cleanmap::isGroundKind(r.static_full_kind[i]))
        static_scan_[key] = static_cast<int64_t>(r.index);
    });
    addPoints(moving_, r.moving, map_voxel_);
    if (byObjects() && kinds) {
      // The scan's map points, then its moving points, as the app's objects take them (§2e);
      // only the vehicle-sized objects' are kept.
      std::vector<cleanmap::PointXYZI> pts = r.static_full;
      pts.insert(pts.end(), r.moving.begin(), r.moving.end());
      std::vector<uint8_t> member(pts.size(), 1);
      for (std::size_t i = 0; i < r.static_full.size(); ++i)
        member[i] = !cleanmap::isGroundKind(r.static_full_kind[i]);
      const cleanmap::RingReach reach =
          cleanmap::ringReach(params_.object, r.ring_gap, r.pose.translation().head<2>());
      const std::vector<uint8_t> in =
          cleanmap::inVehicleSizedObject(pts, member, params_.object, reach);
      ObjectScan os;
      os.index = static_cast<int64_t>(r.index);
      os.density = r.density;
      os.reach = reach;
      os.points.reserve(static_cast<std::size_t>(std::count(in.begin(), in.end(), uint8_t{1})));
      for (std::size_t i = 0; i < r.static_full.size(); ++i)
        if (in[i]) {
          os.points.push_back(pts[i].xyz());
          if (!entry.empty()) os.keys.push_back(entry[i]);
        }
      os.fixed_from = os.points.size();
      for (std::size_t i = r.static_full.size(); i < pts.size(); ++i)
        if (in[i]) os.points.push_back(pts[i].xyz());
      object_scans_.push_back(std::move(os));  // also with no object: rule 4 forgets then
      while (object_scans_max_ > 0 && object_scans_.size() > object_scans_max_) freezeOldest();
    }
  }
  if (sink_) sink_(std::move(r));
}

std::size_t CMovingObjectsMap::objectPoints() const {
  std::size_t n = 0;
  for (const auto& os : object_scans_) n += os.points.size();
  return n;
}

namespace {
std::vector<cleanmap::PointXYZI> asPoints(const std::vector<Eigen::Vector3f>& points) {
  std::vector<cleanmap::PointXYZI> pts(points.size());
  for (std::size_t i = 0; i < pts.size(); ++i)
    pts[i] = {points[i].x(), points[i].y(), points[i].z(), 0.f};
  return pts;
}
}  // namespace

void CMovingObjectsMap::decideScan(cleanmap::MapObjectConsensus& consensus,
                                   const cleanmap::FreeSpaceMap& fs, const ObjectScan& os,
                                   std::vector<uint8_t>& gone) const {
  const std::vector<cleanmap::PointXYZI> pts = asPoints(os.points);
  const std::vector<uint8_t> member(pts.size(), 1);
  gone.assign(pts.size(), 1);
  for (std::size_t i = 0; i < os.fixed_from; ++i)
    gone[i] = fs.removed(os.points[i], os.index, params_.map);
  consensus.decide(os.index, os.density, os.reach, pts, member, gone, os.fixed_from);
}

void CMovingObjectsMap::addDecisions(const ObjectScan& os, const std::vector<uint8_t>& gone,
                                     std::unordered_map<uint64_t, uint8_t>& by_object) const {
  const float inv = map_voxel_ > 0 ? static_cast<float>(1.0 / map_voxel_) : 0.f;
  for (std::size_t i = 0; i < os.fixed_from; ++i) {
    const Eigen::Vector3f& p = os.points[i];
    const uint64_t key =
        map_voxel_ > 0 ? cleanmap::cellKeyOf(p.x(), p.y(), p.z(), inv) : os.keys[i];
    const auto [it, fresh] = by_object.try_emplace(key, gone[i]);
    if (!fresh && !gone[i]) it->second = kObjectKept;
  }
}

void CMovingObjectsMap::setObjectScans(std::size_t n) {
  object_scans_max_ = n;
  ++version_;
  while (object_scans_max_ > 0 && object_scans_.size() > object_scans_max_) freezeOldest();
}

// The oldest kept scan leaves: decided now, with rule 4's memory of the scans frozen before it.
void CMovingObjectsMap::freezeOldest() {
  const cleanmap::FreeSpaceMap* fs = freeSpace();
  if (fs) {
    if (!frozen_consensus_)
      frozen_consensus_.emplace(params_.object, params_.epoch,
                                cleanmap::mapObjectOverlap(params_.map));
    std::vector<uint8_t> gone;
    decideScan(*frozen_consensus_, *fs, object_scans_.front(), gone);
    addDecisions(object_scans_.front(), gone, frozen_);
  }
  object_scans_.pop_front();
}

std::shared_ptr<const std::unordered_map<uint64_t, uint8_t>> CMovingObjectsMap::objectDecisions()
    const {
  const cleanmap::FreeSpaceMap* fs = freeSpace();
  if (!fs || !byObjects()) return nullptr;
  std::lock_guard<std::mutex> lock(objects_mutex_);
  if (by_object_ && by_object_version_ == version_) return by_object_;
  // DESIGN §2e "Objects": the kept scans' objects decided in order, as the app decides its maps;
  // a voxel holding their points is removed if all of them are (the app's map is the union of
  // the points kept). A voxel a frozen scan's objects kept is left to the free space (later
  // scans may have seen it empty: a car parked for minutes that left); one they removed stays so.
  auto by_object = std::make_shared<std::unordered_map<uint64_t, uint8_t>>();
  by_object->reserve(frozen_.size());
  for (const auto& [key, gone] : frozen_) by_object->emplace(key, gone ? kObjectGone : kFreeSpace);
  cleanmap::MapObjectConsensus consensus =
      frozen_consensus_ ? *frozen_consensus_
                        : cleanmap::MapObjectConsensus(params_.object, params_.epoch,
                                                       cleanmap::mapObjectOverlap(params_.map));
  std::vector<std::vector<uint8_t>> gone(object_scans_.size());
  for (std::size_t k = 0; k < object_scans_.size(); ++k)
    decideScan(consensus, *fs, object_scans_[k], gone[k]);
  // Rules 4 and 5 both ways, as the app's maps: the kept scans from the last to the first.
  for (std::size_t k = object_scans_.size(); k-- > 0;) {
    const ObjectScan& os = object_scans_[k];
    const std::vector<uint8_t> member(os.points.size(), 1);
    consensus.decideBackward(os.index, os.density, os.reach, asPoints(os.points), member, gone[k],
                             os.fixed_from);
  }
  for (std::size_t k = 0; k < object_scans_.size(); ++k)
    addDecisions(object_scans_[k], gone[k], *by_object);
  by_object_ = by_object;
  by_object_version_ = version_;
  return by_object;
}

std::vector<cleanmap::PointXYZI> CMovingObjectsMap::cleanedStatic(bool removed) const {
  const cleanmap::FreeSpaceMap* fs = freeSpace();
  const auto by_object = objectDecisions();
  std::unordered_map<uint64_t, cleanmap::PointXYZI> out;
  for (const auto& [key, p] : static_) {
    const auto it = static_scan_.find(key);  // a non-ground first point
    bool gone = false;
    if (fs && it != static_scan_.end()) {
      uint8_t ob = kFreeSpace;
      if (by_object)
        if (const auto f = by_object->find(key); f != by_object->end()) ob = f->second;
      gone = ob == kFreeSpace ? fs->removed(p.xyz(), it->second, params_.map) : ob == kObjectGone;
    }
    if (gone == removed) out.emplace(key, p);
  }
  return sortedPoints(out);
}
std::vector<cleanmap::PointXYZI> CMovingObjectsMap::staticPoints() const {
  return cleanedStatic(false);
}
std::vector<cleanmap::PointXYZI> CMovingObjectsMap::removedPoints() const {
  return cleanedStatic(true);
}
std::vector<cleanmap::PointXYZI> CMovingObjectsMap::movingPoints() const {
  return sortedPoints(moving_);
}

bool CMovingObjectsMap::isEmpty() const {
  return trajectory_.empty() && pending() == 0;
}

void CMovingObjectsMap::internal_clear() {
  ++version_;
  pipe_.reset();
  next_index_ = 0;
  lidar_label_.clear();
  static_.clear();
  static_scan_.clear();
  object_scans_.clear();
  frozen_.clear();
  frozen_consensus_.reset();
  moving_.clear();
  trajectory_.clear();
  totals_ = {};
}

bool CMovingObjectsMap::internal_insertObservation(
    const mrpt::obs::CObservation& obs,
    const std::optional<const mrpt::poses::CPose3D>& robotPose) {
  // One lidar per layer (insertOpts sensor_label, else the first one inserted); another lidar's
  // observations are not decoded.
  const std::string& want =
      insertionOptions.sensor_label.empty() ? lidar_label_ : insertionOptions.sensor_label;
  if (!want.empty() && obs.sensorLabel != want && cleanmap::mrpt::isLidarObservation(obs))
    return false;
  auto posed = posedScanOf(obs, robotPose, insertionOptions.use_pose_observations, pose_obs_);
  if (posed.consumed) return true;
  if (!posed.scan) return false;  // not a lidar observation
  lidar_label_ = obs.sensorLabel;
  cleanmap::Frame f;
  f.index = next_index_;
  char stem[32];
  std::snprintf(stem, sizeof stem, "%06zu", f.index);
  f.stem = stem;
  f.source = std::string(obs.GetRuntimeClass()->className) + " #" + stem;
  f.scan = std::move(*posed.scan);
  insertFrame(std::move(f));
  return true;
}

void CMovingObjectsMap::saveMetricMapRepresentationToFile(const std::string& prefix) const {
  if (pending() > 0) {  // what a finished run holds: the window decided, in a copy
    CMovingObjectsMap flushed(*this);
    flushed.flush();
    flushed.saveMetricMapRepresentationToFile(prefix);
    return;
  }
  double z0 = 0;
  for (const auto& t : trajectory_) z0 += t.pose.translation().z();
  if (!trajectory_.empty()) z0 /= static_cast<double>(trajectory_.size());
  cleanmap::io::CloudStreamOptions so;
  so.colour = cleanmap::io::CloudColour::kHeight;
  cleanmap::io::PlyStreamWriter st(prefix + "_static.ply", so);
  st.append(staticPoints(), z0);
  st.close();
  cleanmap::io::CloudStreamOptions mo;
  mo.colour = cleanmap::io::CloudColour::kRed;
  cleanmap::io::PlyStreamWriter mv(prefix + "_moving.ply", mo);
  mv.append(movingPoints());
  mv.close();
  cleanmap::io::writeFileAtomic(prefix + "_trajectory.txt", [&](std::ostream& os) {
    os.precision(17);
    os << "# index timestamp r00 r01 r02 tx r10 r11 r12 ty r20 r21 r22 tz (sensor in world)\n";
    for (const auto& t : trajectory_) {
      os << t.index << ' ' << t.timestamp;
      const Eigen::Matrix<double, 3, 4> m = t.pose.matrix().topRows<3>();
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) os << ' ' << m(r, c);
      os << '\n';
    }
  });
}

void CMovingObjectsMap::getVisualizationInto(mrpt::opengl::CSetOfObjects& o) const {
  if (!genericMapParams.enableSaveAs3DObject) return;
  double z0 = 0;
  for (const auto& t : trajectory_) z0 += t.pose.translation().z();
  if (!trajectory_.empty()) z0 /= static_cast<double>(trajectory_.size());
  auto st = mrpt::opengl::CPointCloudColoured::Create();
  st->setName("cleanmap_static");
  st->setPointSize(2.0f);
  for (const auto& p : staticPoints()) {
    const auto c = cleanmap::io::heightColour(double(p.z) - z0);
    st->push_back(p.x, p.y, p.z, c[0] / 255.0f, c[1] / 255.0f, c[2] / 255.0f);
  }
  o.insert(st);
  auto mv = mrpt::opengl::CPointCloud::Create();
  mv->setName("cleanmap_moving");
  mv->setPointSize(3.0f);
  mv->setColor(1.0, 0.0, 0.0);
  for (const auto& p : movingPoints()) mv->insertPoint(p.x, p.y, p.z);
  o.insert(mv);
}

std::string CMovingObjectsMap::asString() const {
  std::ostringstream os;
  os << "cleanmap moving-objects map: " << trajectory_.size() << " scans decided, " << pending()
     << " pending (K = "
     << (pipe_ && pipe_->windowK() ? std::to_string(pipe_->windowK())
         : params_.ds.window_k > 0 ? std::to_string(params_.ds.window_k)
                                   : std::string("auto"))
     << "); " << static_.size() << " static and " << moving_.size() << " moving points (voxel "
     << map_voxel_ << " m)";
  if (!object_scans_.empty()) os << "; " << objectPoints() << " points of objects kept";
  return os.str();
}

// ---- serialization: the content as if flushed (see the header) ----

uint8_t CMovingObjectsMap::serializeGetVersion() const {
  return 1;  // 1: the lidar's sensorLabel (insertOpts sensor_label and the one inserted)
}

void CMovingObjectsMap::serializeTo(mrpt::serialization::CArchive& out) const {
  if (pending() > 0) {  // decide the window in a copy, and store that
    CMovingObjectsMap flushed(*this);
    flushed.flush();
    flushed.serializeTo(out);
    return;
  }
  out << genericMapParams;
  out << cleanmap::io::toIni(params_) << map_voxel_ << store_points_
      << static_cast<uint64_t>(next_index_) << insertionOptions.use_pose_observations;
  out << insertionOptions.sensor_label << lidar_label_;
  out << static_cast<uint64_t>(trajectory_.size());
  for (const auto& t : trajectory_) {
    out << static_cast<uint64_t>(t.index) << t.timestamp;
    const Eigen::Matrix4d m = t.pose.matrix();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) out << m(r, c);
  }
  writePoints(out, staticPoints());
  writePoints(out, movingPoints());
  const auto& s = totals_;
  for (const std::size_t v : {s.points, s.invalid, s.in_crop, s.ground, s.duplicates, s.candidates,
                              s.tested, s.moving, s.static_points})
    out << static_cast<uint64_t>(v);
}

void CMovingObjectsMap::serializeFrom(mrpt::serialization::CArchive& in, uint8_t version) {
  if (version > 1) MRPT_THROW_UNKNOWN_SERIALIZATION_VERSION(version);
  internal_clear();
  in >> genericMapParams;
  uint64_t next = 0, n = 0;
  const std::string ini = readString(in, 1 << 20, "its parameters");
  in >> map_voxel_ >> store_points_ >> next >> insertionOptions.use_pose_observations;
  insertionOptions.sensor_label.clear();
  if (version >= 1) {
    insertionOptions.sensor_label = readString(in, 4096, "its sensor label");
    lidar_label_ = readString(in, 4096, "its lidar label");
  }
  params_ = cleanmap::PipelineParams{};
  cleanmap::io::parseParams(ini, "serialized cleanmap_moving", params_);
  checkMapVoxel(map_voxel_, "serialized cleanmap_moving");
  next_index_ = next;
  in >> n;
  trajectory_.clear();
  trajectory_.reserve(std::min<uint64_t>(n, kReserveAtMost));
  for (uint64_t i = 0; i < n; ++i) {
    TrajectoryPoint t;
    uint64_t idx = 0;
    in >> idx >> t.timestamp;
    t.index = idx;
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) in >> m(r, c);
    if (!m.allFinite())
      throw cleanmap::Error("serialized cleanmap_moving",
                            "trajectory pose " + std::to_string(i) + " is not finite");
    t.pose.matrix() = m;
    trajectory_.push_back(t);
  }
  // Points come back keyed by voxel again (or by arrival with map_voxel 0).
  addPoints(static_, readPoints(in), map_voxel_);
  addPoints(moving_, readPoints(in), map_voxel_);
  auto& s = totals_;
  for (std::size_t* v : {&s.points, &s.invalid, &s.in_crop, &s.ground, &s.duplicates, &s.candidates,
                         &s.tested, &s.moving, &s.static_points}) {
    uint64_t x = 0;
    in >> x;
    *v = x;
  }
}

// ---- map definition (ini) ----

CMovingObjectsMap::TMapDefinition::TMapDefinition() = default;

void CMovingObjectsMap::TMapDefinition::loadFromConfigFile_map_specific(
    const mrpt::config::CConfigFileBase& source, const std::string& prefix) {
  const std::string creation = prefix + "_creationOpts";
  creationOptions(params, map_voxel, map_object_scans).load(source, creation, /*generic=*/true);
  cleanmap::validate(params, "[" + creation + "]");
  checkMapVoxel(map_voxel, "[" + creation + "]");
  if (map_object_scans < 0)
    throw cleanmap::Error("[" + creation + "]", "map_object_scans must be >= 0 (0: all)");
  OptionTable insert;
  insert.flag("use_pose_observations", insertionOpts.use_pose_observations);
  insert.custom("sensor_label", [this](const std::string& v, const std::string&) {
    insertionOpts.sensor_label = v == "auto" ? "" : v;
  });
  insert.load(source, prefix + "_insertOpts", /*generic=*/false);
  if (source.sectionExists(prefix + "_likelihoodOpts"))
    throw cleanmap::Error("[" + prefix + "_likelihoodOpts]",
                          "cleanmap_moving computes no likelihood: it has no such options");
}

void CMovingObjectsMap::TMapDefinition::dumpToTextStream_map_specific(std::ostream& out) const {
  out << cleanmap::io::toIni(params) << "map_voxel = " << map_voxel
      << "\nmap_object_scans = " << map_object_scans
      << "\nuse_pose_observations = " << insertionOpts.use_pose_observations << "\nsensor_label = "
      << (insertionOpts.sensor_label.empty() ? "auto" : insertionOpts.sensor_label) << "\n";
}

#if MRPT_VERSION >= 0x20b03
std::shared_ptr<mrpt::maps::CMetricMap>
#else
mrpt::maps::CMetricMap*
#endif
CMovingObjectsMap::internal_CreateFromMapDefinition(const mrpt::maps::TMetricMapInitializer& def_) {
  const auto& def = dynamic_cast<const CMovingObjectsMap::TMapDefinition&>(def_);
#if MRPT_VERSION >= 0x20b03
  auto m = std::make_shared<CMovingObjectsMap>(def.params, def.map_voxel);
#else
  auto* m = new CMovingObjectsMap(def.params, def.map_voxel);
#endif
  m->insertionOptions = def.insertionOpts;
  m->setObjectScans(static_cast<std::size_t>(def.map_object_scans));
  return m;
}

}  // namespace cleanmap_maps
