// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/io/output.h"

#include <sys/resource.h>
#include <unistd.h>

#include <cstdlib>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <future>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <optional>

#include "cleanmap/core/error.h"
#include "cleanmap/core/median.h"
#include "cleanmap/core/object_consensus.h"
#include "cleanmap/io/background_files.h"
#include "cleanmap/io/config.h"
#include "cleanmap/io/direct_file.h"
#include "cleanmap/io/files.h"
#include "cleanmap/io/grouping_spool.h"
#include "cleanmap/io/kitti.h"
#include "cleanmap/io/ply.h"

namespace cleanmap::io {
namespace fs = std::filesystem;
namespace {

struct Spread {
  double median = 0, p95 = 0, mean = 0;
};
Spread spread(std::vector<double> v) {
  Spread s;
  if (v.empty()) return s;
  std::sort(v.begin(), v.end());
  s.median = v[v.size() / 2];
  s.p95 = v[std::min(v.size() - 1, static_cast<std::size_t>(0.95 * static_cast<double>(v.size())))];
  for (double x : v) s.mean += x / static_cast<double>(v.size());
  return s;
}

nlohmann::json countsJson(const MosCounts& c) {
  return {{"precision", c.precision()},
          {"recall", c.recall()},
          {"iou", c.iou()},
          {"tp", c.tp},
          {"fp", c.fp},
          {"fn", c.fn},
          {"tn", c.tn},
          {"flagged_rate", c.flaggedRate()},
          {"ignored", c.ignored},
          {"out_of_range", c.out_of_range}};
}

}  // namespace

double peakRssMiB() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return static_cast<double>(ru.ru_maxrss) / 1024.0;
}

std::optional<double> processAgeSeconds() {
#if defined(__linux__)
  // Field 22 of /proc/self/stat, the start in clock ticks since boot; the fields are counted
  // after the command's name, which is in parentheses and may hold spaces or parentheses.
  std::FILE* f = std::fopen("/proc/self/stat", "r");
  if (!f) return std::nullopt;
  char buf[1024];
  const std::size_t n = std::fread(buf, 1, sizeof buf - 1, f);
  std::fclose(f);
  buf[n] = '\0';
  const char* p = std::strrchr(buf, ')');
  if (!p) return std::nullopt;
  ++p;
  for (int field = 3; field <= 22; ++field) {  // p: before the space ahead of `field`
    while (*p == ' ') ++p;
    if (*p == '\0') return std::nullopt;
    if (field == 22) break;
    while (*p != ' ' && *p != '\0') ++p;
  }
  char* end = nullptr;
  const unsigned long long ticks = std::strtoull(p, &end, 10);
  const long hz = sysconf(_SC_CLK_TCK);
  timespec now{};
  if (end == p || hz <= 0 || clock_gettime(CLOCK_BOOTTIME, &now) != 0) return std::nullopt;
  const double age = static_cast<double>(now.tv_sec) + 1e-9 * static_cast<double>(now.tv_nsec) -
                     static_cast<double>(ticks) / static_cast<double>(hz);
  return age >= 0 ? std::optional<double>(age) : std::nullopt;
#else
  return std::nullopt;
#endif
}

double processCpuSeconds() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  const auto sec = [](const timeval& t) {
    return static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_usec);
  };
  return sec(ru.ru_utime) + sec(ru.ru_stime);
}

bool isCleanmapRun(const std::string& dir) {
  const fs::path report = fs::path(dir) / "report.json";
  std::error_code ec;
  if (!fs::is_regular_file(report, ec)) return false;
  try {
    const auto j = nlohmann::json::parse(readTextFile(report.string()));
    return j.is_object() && (j.value("generator", "") == "cleanmap" || j.contains("params_ini"));
  } catch (const std::exception&) {
    return false;
  }
}

void checkOutputFolder(const std::string& outdir, const OutputOptions& opts) {
  requireReplaceableFolder(
      outdir, [&](const std::string& d) { return opts.force || isCleanmapRun(d); },
      "cleanmap run (no cleanmap report.json)", "-o",
      ", or pass --force to replace it and everything in it");
}

OutputWriter::OutputWriter(const std::string& outdir, const std::string& input,
                           const PipelineParams& params, const OutputOptions& opts)
    : dir_(outdir), input_(input), params_(params), started_s_(processAgeSeconds()) {
  while (dir_.size() > 1 && dir_.back() == '/') dir_.pop_back();
  checkOutputFolder(dir_, opts);
  staged_ = std::make_unique<StagedFolder>(dir_, "cleanmap");
  staging_ = staged_->path();
  files_ = std::make_unique<BackgroundFiles>();
  std::error_code ec;
  fs::create_directories(fs::path(staging_) / "labels", ec);
  if (ec) throw Error(staging_, "cannot create labels/: " + ec.message());
  // DESIGN §4: the maps in RGB (static by height above the sensor, moving in red), the compact
  // map and the moving points also as PCD.
  const CloudStreamOptions height{CloudColour::kHeight, {}};
  compact_ = std::make_unique<PlyStreamWriter>(
      staging_ + "/static_map.ply",
      CloudStreamOptions{CloudColour::kHeight, staging_ + "/static_map.pcd"});
  full_ = std::make_unique<PlyStreamWriter>(staging_ + "/static_map_full.ply", height);
  removed_ = std::make_unique<PlyStreamWriter>(staging_ + "/map_removed.ply",
                                               CloudStreamOptions{CloudColour::kRed, {}});
  fs::create_directories(fs::path(staging_) / "map_labels", ec);
  if (ec) throw Error(staging_, "cannot create map_labels/: " + ec.message());
  spool_path_ = staging_ + "/.map_spool";
  // One scan's spool (24 bytes a point: ~3 MB) fits a buffer, so the pipeline's thread hands it
  // over and goes on while it is written, instead of waiting for the device buffer by buffer
  // (1.4-3.0 ms a scan with 512 KiB buffers, 0.4-0.6 ms with these; issue #16).
  spool_ = std::make_unique<DirectFile>(spool_path_, std::size_t(4) << 20);
  moving_ = std::make_unique<PlyStreamWriter>(
      staging_ + "/dynamic.ply", CloudStreamOptions{CloudColour::kRed, staging_ + "/dynamic.pcd"});
}

OutputWriter::~OutputWriter() {
  files_.reset();    // the queued files are done before their folder goes
  compact_.reset();  // closes and removes the temporaries first
  full_.reset();
  moving_.reset();
  removed_.reset();
  spool_.reset();
  staged_.reset();  // unpublished: removes the staging folder
}

namespace {
// A refused alignment's reason (its status without the figures); where GICP's map started again
// after it (DESIGN §2.1 step 4), that is said too.
std::string refusalReason(const PoseInfo& p) {
  const std::string reason = p.reason.empty() ? p.status.substr(0, p.status.find(" (")) : p.reason;
  return p.map_restarts ? reason + ", the map started again" : reason;
}
}  // namespace

std::vector<std::pair<std::string, std::size_t>> OutputWriter::refusedAlignments() const {
  std::map<std::string, std::size_t> by_reason;
  for (const PoseInfo& p : pose_info_)
    if (!p.accepted && p.source != "given") ++by_reason[refusalReason(p)];
  std::vector<std::pair<std::string, std::size_t>> out(by_reason.begin(), by_reason.end());
  std::stable_sort(out.begin(), out.end(),
                   [](const auto& a, const auto& b) { return a.second > b.second; });
  return out;
}

bool OutputWriter::givenPosesArePlanar() const {
  if (poses_.size() < 3) return false;
  for (std::size_t i = 0; i < poses_.size(); ++i) {
    const Eigen::Matrix3d& R = poses_[i].linear();
    // R's third row is (-sin pitch, cos pitch sin roll, cos pitch cos roll) in ZYX angles.
    if (pose_info_[i].source != "given" || std::abs(R(2, 0)) > 1e-6 || std::abs(R(2, 1)) > 1e-6 ||
        std::abs(poses_[i].translation().z() - poses_[0].translation().z()) > 1e-6)
      return false;
  }
  return true;
}

std::optional<ScanSpacing> OutputWriter::scanSpacing() const {
  std::vector<Eigen::Vector3d> at;
  at.reserve(poses_.size());
  for (const auto& p : poses_) at.push_back(p.translation());
  return cleanmap::scanSpacing(times_, at);
}

std::optional<double> OutputWriter::measuredSensorHeight() const {
  std::vector<double> m;
  for (const double g : ground_measured_)
    if (std::isfinite(g)) m.push_back(-g);
  if (m.empty()) return std::nullopt;
  return median(std::move(m));
}

void OutputWriter::write(const ScanResult& r, const std::optional<MosCounts>& eval) {
  decided_at_.push_back(r.decided_at.time_since_epoch().count() != 0
                            ? r.decided_at
                            : std::chrono::steady_clock::now());
  files_->writeLabels(staging_ + "/labels/" + r.stem + ".label", r.labels);
  if (!r.overlay.empty()) {  // --save-overlays (DESIGN §3)
    std::vector<uchar> png;
    if (!cv::imencode(".png", r.overlay, png))
      throw Error(staging_ + "/overlays/" + r.stem + ".png", "cannot encode the overlay image");
    std::error_code ec;
    fs::create_directories(staging_ + "/overlays", ec);
    writeFileAtomic(staging_ + "/overlays/" + r.stem + ".png", [&](std::ostream& os) {
      os.write(reinterpret_cast<const char*>(png.data()), std::streamsize(png.size()));
    });
  }
  const double z = r.pose.translation().z();
  moving_->append(r.moving, z);
  spoolScan(r);
  poses_.push_back(r.pose);
  times_.push_back(r.timestamp);
  pose_info_.push_back(r.pose_info);
  ground_measured_.push_back(r.ground_measured);
  ground_z_.push_back(r.ground_z);
  density_.push_back(r.density);
  stats_.push_back(r.stats);
  stems_.push_back(r.stem);
  if (eval) {
    has_eval_ = true;
    eval_ += *eval;
    scan_eval_.push_back(*eval);
  }
}

// The spool of the map points (DESIGN §2e): per scan a header, then its full-map points with their
// original index and kind, then its moving points with theirs (they belong to the map's objects).
// Read back by writeMaps().
namespace {
struct SpoolHeader {
  int64_t index;
  double x, y, z;  // the sensor's position
  double density, ring_gap;
  uint64_t points, full, moving, self;
};
struct SpoolPoint {
  PointXYZI p;
  uint32_t orig;
  uint32_t kind;  // MapKind
};

}  // namespace

void OutputWriter::spoolScan(const ScanResult& r) {
  // A result made without the pipeline may lack the indices and kinds: its points are then
  // static, outside the compact map and map_labels/.
  const bool indexed = r.static_full_index.size() == r.static_full.size() &&
                       r.static_full_kind.size() == r.static_full.size();
  if (!indexed && !r.static_compact.empty())
    throw Error(staging_, "scan " + r.stem +
                              ": a compact map without static_full_kind (which points are in it)");
  const Eigen::Vector3d t = r.pose.translation();
  const SpoolHeader h{static_cast<int64_t>(r.index),
                      t.x(),
                      t.y(),
                      t.z(),
                      r.density,
                      r.ring_gap,
                      r.labels.size(),
                      r.static_full.size(),
                      r.moving.size(),
                      r.self_index.size()};
  spool_offsets_.push_back(spool_->size());
  spool_->write(&h, sizeof h);
  std::vector<SpoolPoint> pts(r.static_full.size());
  for (std::size_t i = 0; i < pts.size(); ++i)
    pts[i] = {r.static_full[i], indexed ? r.static_full_index[i] : ~uint32_t(0),
              indexed ? uint32_t{r.static_full_kind[i]} : uint32_t{kMapDuplicate}};
  spool_->write(pts.data(), pts.size() * sizeof(SpoolPoint));
  const bool moving_indexed = r.moving_index.size() == r.moving.size();
  pts.resize(r.moving.size());
  for (std::size_t i = 0; i < pts.size(); ++i)
    pts[i] = {r.moving[i], moving_indexed ? r.moving_index[i] : ~uint32_t(0), 0};
  spool_->write(pts.data(), pts.size() * sizeof(SpoolPoint));
  if (!r.self_index.empty())
    spool_->write(r.self_index.data(), r.self_index.size() * sizeof(uint32_t));
}

// DESIGN §2e: every spooled point is decided with the whole sequence's free space: the ground
// stays, a point whose voxel the policy calls empty goes to map_removed.ply, the others to the
// maps; map_labels/<stem>.label says what the map did with each original point.
void OutputWriter::writeMaps(const FreeSpaceMap* free_space, const MapScanSink& sink) {
  if (maps_written_) throw Error(staging_, "the maps were already written (writeMaps twice)");
  maps_written_ = true;
  const auto t0 = std::chrono::steady_clock::now();
  const auto elapsedMs = [](std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
  };
  spool_->close();
  std::vector<PointXYZI> full, compact, removed;
  const bool by_objects = free_space && params_.map.clean && params_.map.objects;
  std::optional<FreeSpaceMap::Lookup> lookup;
  if (free_space) lookup.emplace(*free_space);
  // One scan of the spool with the free space's decision per point, and for its objects (DESIGN
  // §2e) the scan's map points, then its moving points (in the objects too).
  struct Spooled {
    SpoolHeader h;
    std::vector<SpoolPoint> pts, moving;
    std::vector<uint32_t> self;  // the recording vehicle's own returns (DESIGN §2.2), removed
    std::vector<PointXYZI> objects;
    std::vector<uint8_t> member, gone;
    ObjectComponents groups;           // the objects' grouping, spooled by the forward pass
    std::vector<unsigned char> bytes;  // its bytes in the spool
  };
  // Rules 4 and 5 both ways (DESIGN §2e "Objects"): a first pass decides the objects and keeps
  // its decisions per point (.map_decisions, a byte each); a second goes from the last scan to
  // the first, reading the scans whose objects the backward rules can reach and adding their
  // removals to the decisions; the third reads the points and their decisions and writes.
  const bool both_ways = by_objects && params_.object.enabled &&
                         (params_.object.persist_radius > 0 || mapObjectOverlap(params_.map) > 0);
  bool decide = true;  // the pass reading looks the free space up (the first, or the only one)
  // The objects' input: the map points (ground not a member), then the moving points, removed.
  const auto assemble = [](Spooled& b) {
    b.objects.clear();
    b.member.clear();
    for (const auto& q : b.pts) {
      b.objects.push_back(q.p);
      b.member.push_back(!isGroundKind(static_cast<uint8_t>(q.kind)));
    }
    for (const auto& q : b.moving) b.objects.push_back(q.p);
    b.member.resize(b.objects.size(), 1);
    b.gone.resize(b.objects.size(), 1);
  };
  // The free space's decision per point (then the moving points, removed, for the objects).
  const auto lookUp = [&](Spooled& b) {
    b.gone.clear();
    for (const auto& q : b.pts) {
      const bool ground = isGroundKind(static_cast<uint8_t>(q.kind));
      b.gone.push_back(free_space && !ground && lookup->removed(q.p.xyz(), b.h.index, params_.map));
    }
    if (by_objects) b.gone.resize(b.objects.size(), 1);
  };
  const auto read = [&](DirectReader& spool, Spooled& b) {
    spool.read(&b.h, sizeof b.h);
    b.pts.resize(b.h.full);
    b.moving.resize(b.h.moving);
    spool.read(b.pts.data(), b.pts.size() * sizeof(SpoolPoint));
    spool.read(b.moving.data(), b.moving.size() * sizeof(SpoolPoint));
    b.self.resize(b.h.self);
    if (!b.self.empty()) spool.read(b.self.data(), b.self.size() * sizeof(uint32_t));
    if (!decide) return;
    if (by_objects) assemble(b);
    if (!both_ways)
      lookUp(b);  // else the forward pass's work does, beside the next scan's grouping
  };
  // The spool's scans in order. With two threads the next scan is read (looked up where read()
  // does so, and given `prepare`, which must not touch what `work` does) beside this one's work
  // (issue #16); the reader and the lookup are only ever used by one of them at a time.
  const auto forEachScan = [&](const std::function<void(std::size_t, Spooled&)>& work,
                               const std::function<void(Spooled&)>& prepare = nullptr) {
    DirectReader spool(spool_path_);
    const auto load = [&](Spooled& b) {
      read(spool, b);
      if (prepare) prepare(b);
    };
    Spooled cur, next;
    if (!stems_.empty()) load(cur);
    for (std::size_t s = 0; s < stems_.size(); ++s) {
      std::future<void> ahead;
      const bool more = s + 1 < stems_.size();
      if (more && params_.threads > 1) ahead = std::async(std::launch::async, load, std::ref(next));
      work(s, cur);
      if (ahead.valid())
        ahead.get();
      else if (more)
        load(next);
      std::swap(cur, next);
    }
  };
  MapObjectConsensus consensus(params_.object, params_.epoch, mapObjectOverlap(params_.map));
  const auto reachOf = [&](const SpoolHeader& h) {  // its lidar's rings (doc/OBJECTS.md rule 1)
    return ringReach(params_.object, h.ring_gap, Eigen::Vector2d(h.x, h.y));
  };
  const auto decideObjects = [&](Spooled& b, const ObjectComponents* grouped) {
    const auto st = consensus.decide(b.h.index, b.h.density, reachOf(b.h), b.objects, b.member,
                                     b.gone, b.pts.size(), grouped);
    map_object_points_ += st.points_added;
    map_object_kept_ += st.points_removed;
    map_objects_ += st.moving_objects;
  };
  const std::string decisions_path = staging_ + "/.map_decisions";
  const std::string groupings_path = staging_ + "/.map_groupings";
  if (both_ways) {
    std::vector<uint8_t> had_whole(stems_.size(), 0);
    std::vector<std::uint64_t> decided_at(stems_.size() + 1, 0);  // offsets in .map_decisions
    std::vector<std::uint64_t> grouped_at(stems_.size() + 1, 0);  // and in .map_groupings
    std::vector<int64_t> scan_index(stems_.size(), 0);
    {
      // Each scan's grouping is spooled for the backward pass, which would otherwise group the
      // same points again (issue #16; about 0.6 MB a scan of kitti_highway, deleted at the end).
      DirectFile decisions(decisions_path, std::size_t(1) << 20),
          groupings(groupings_path, std::size_t(1) << 20);
      std::vector<unsigned char> bytes;
      // A scan's grouping reads only the parameters: the next scan's is made with its read beside
      // this one's lookup and decision, which holds the objects' memory (issue #16; the three
      // take about a third of the pass each, the read a fifth).
      const auto group = [&](Spooled& b) {
        consensus.group(b.objects, b.member, reachOf(b.h), b.groups);
      };
      forEachScan(
          [&](std::size_t s, Spooled& b) {
            lookUp(b);
            decideObjects(b, &b.groups);
            decisions.write(b.gone.data(), b.pts.size());
            bytes.clear();
            appendGrouping(b.groups, bytes);
            groupings.write(bytes.data(), bytes.size());
            had_whole[s] = consensus.hadWholeObjects();
            decided_at[s + 1] = decided_at[s] + b.pts.size();
            grouped_at[s + 1] = grouped_at[s] + bytes.size();
            scan_index[s] = b.h.index;
          },
          group);
      decisions.close();
      groupings.close();
    }
    map_forward_ms_ = elapsedMs(t0);
    const auto t_back = std::chrono::steady_clock::now();
    // From the last scan to the first: a scan without whole objects, after one without either,
    // has nothing the backward rules could change or pass on. With two threads the scan before
    // is read beside this one's decision (issue #16), and dropped if not needed; the files are
    // only ever used by one thread at a time.
    PositionalFile spool(spool_path_, false), decisions_rw(decisions_path, true),
        groupings_in(groupings_path, false);
    const auto load = [&](std::size_t s, Spooled& b) {
      spool.readAt(spool_offsets_[s], &b.h, sizeof b.h);
      b.pts.resize(b.h.full);
      b.moving.resize(b.h.moving);
      const std::uint64_t at = spool_offsets_[s] + sizeof b.h;
      spool.readAt(at, b.pts.data(), b.pts.size() * sizeof(SpoolPoint));
      spool.readAt(at + b.pts.size() * sizeof(SpoolPoint), b.moving.data(),
                   b.moving.size() * sizeof(SpoolPoint));
      b.gone.resize(b.pts.size());
      decisions_rw.readAt(decided_at[s], b.gone.data(), b.gone.size());
      assemble(b);
      b.bytes.resize(grouped_at[s + 1] - grouped_at[s]);
      groupings_in.readAt(grouped_at[s], b.bytes.data(), b.bytes.size());
      readGrouping(b.bytes.data(), b.bytes.size(), b.objects.size(), reachOf(b.h), groupings_path,
                   b.groups);
    };
    Spooled cur, next;
    bool loaded = false;  // cur holds scan s
    for (std::size_t s = stems_.size(); s-- > 0;) {
      if (!had_whole[s] && !consensus.backwardMemory()) {
        consensus.skipBackward(scan_index[s]);
        loaded = false;
        continue;
      }
      if (!loaded) load(s, cur);
      const bool read_ahead = s > 0 && params_.threads > 1;
      std::future<void> ahead;
      if (read_ahead) ahead = std::async(std::launch::async, load, s - 1, std::ref(next));
      const auto st =
          consensus.decideBackward(cur.h.index, cur.h.density, reachOf(cur.h), cur.objects,
                                   cur.member, cur.gone, cur.pts.size(), &cur.groups);
      if (read_ahead) ahead.get();
      map_object_points_ += st.points_added;
      map_objects_ += st.moving_objects;
      if (st.points_added > 0) decisions_rw.writeAt(decided_at[s], cur.gone.data(), cur.pts.size());
      loaded = read_ahead;
      if (loaded) std::swap(cur, next);
    }
    decide = false;
    map_backward_ms_ = elapsedMs(t_back);
  }
  const auto t_write = std::chrono::steady_clock::now();
  std::optional<DirectReader> decisions;
  if (both_ways) decisions.emplace(decisions_path);
  forEachScan([&](std::size_t s, Spooled& cur) {
    const SpoolHeader& h = cur.h;
    const auto& pts = cur.pts;
    auto& gone = cur.gone;
    Labels map_labels(h.points, kUnclassified);
    full.clear();
    compact.clear();
    removed.clear();
    if (both_ways) {
      gone.resize(pts.size());
      decisions->read(gone.data(), gone.size());
    } else if (by_objects) {
      decideObjects(cur, nullptr);
    }
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const auto& q = pts[i];
      const auto kind = static_cast<uint8_t>(q.kind);
      if (q.orig < map_labels.size())
        map_labels[q.orig] = gone[i] ? kMoving : isGroundKind(kind) ? kGround : kStatic;
      if (gone[i]) {
        removed.push_back(q.p);
        continue;
      }
      full.push_back(q.p);
      if (kind == kMapStatic) compact.push_back(q.p);
      map_far_kept_ += kind == kMapFar || kind == kMapFarGround;
    }
    for (const auto& q : cur.moving)
      if (q.orig < map_labels.size()) map_labels[q.orig] = kMoving;
    for (const uint32_t o : cur.self)
      if (o < map_labels.size()) map_labels[o] = kMoving;
    map_removed_ += removed.size();
    full_->append(full, h.z);
    compact_->append(compact, h.z);
    removed_->append(removed, h.z);
    files_->writeLabels(staging_ + "/map_labels/" + stems_[s] + ".label", map_labels);
    if (sink) sink(MapScan{h.index, stems_[s], map_labels, full, removed});
  });
  spool_.reset();
  decisions.reset();
  files_->remove(spool_path_);  // hundreds of MB: the file system frees them beside what follows
  if (both_ways) {
    files_->remove(decisions_path);
    files_->remove(groupings_path);
  }
  map_write_ms_ = elapsedMs(t_write);
  map_ms_ = elapsedMs(t0);
}

void OutputWriter::publish() {
  files_->wait();
  staged_->publish();
}

void OutputWriter::finish(double wall_s, const FreeSpaceMap* free_space) {
  if (!maps_written_) writeMaps(free_space);
  files_->wait();  // a label file's error before the report
  compact_->close();
  full_->close();
  moving_->close();
  removed_->close();
  writePosesFile(staging_ + "/poses.txt", poses_);
  writeFileAtomic(staging_ + "/poses_tum.txt", [&](std::ostream& os) {  // TUM: t x y z qx qy qz qw
    char buf[256];
    for (std::size_t i = 0; i < poses_.size(); ++i) {
      const Eigen::Quaterniond q(poses_[i].linear());
      const Eigen::Vector3d t = poses_[i].translation();
      std::snprintf(buf, sizeof buf, "%.6f %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n", times_[i], t.x(),
                    t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
      os << buf;
    }
  });
  writeFileAtomic(staging_ + "/params.ini", [&](std::ostream& os) { os << toIni(params_); });

  ScanStats total;
  std::vector<double> t_total, t_reg, t_index, t_ground, t_dup, t_oct, t_cls, t_obj, t_free, t_img;
  std::vector<double> t_interval;  // between two decisions while the input flowed (inputEnded)
  for (std::size_t i = 1; i < decided_at_.size() && decided_at_[i] <= input_ended_; ++i)
    t_interval.push_back(
        std::chrono::duration<double, std::milli>(decided_at_[i] - decided_at_[i - 1]).count());
  for (const auto& s : stats_) {
    total += s;
    t_total.push_back(s.ms.total);
    t_reg.push_back(s.ms.registration);
    t_index.push_back(s.ms.index);
    t_ground.push_back(s.ms.ground);
    t_dup.push_back(s.ms.duplicates);
    t_oct.push_back(s.ms.octree);
    t_cls.push_back(s.ms.classify);
    t_obj.push_back(s.ms.objects);
    t_free.push_back(s.ms.free_space);
    if (s.image_scans) t_img.push_back(s.ms.images);
  }
  const std::size_t empty = total.empty;
  nlohmann::json j;
  j["generator"] = "cleanmap";
  j["input"] = input_;
  j["scans"] = stats_.size();
  j["counts"] = {{"points", total.points},
                 {"invalid_dropped", total.invalid},
                 {"empty_scans", empty},
                 {"in_crop", total.in_crop},
                 {"self_returns", total.self_returns},
                 {"ground", total.ground},
                 {"duplicates", total.duplicates},
                 {"candidates", total.candidates},
                 {"tested", total.tested},
                 {"moving", total.moving},
                 {"static", total.static_points},
                 {"total_conflicts", total.total_conflicts},
                 {"conflicting_scan_votes", total.conflicting_scans},
                 {"ring_votes", total.ring_votes},
                 {"objects_turned_moving", total.objects_moving},
                 {"objects_kept_moving_by_hysteresis", total.objects_persisted},
                 {"objects_kept_moving_leaving", total.objects_left_place},
                 {"objects_measured_moving", total.objects_measured},
                 {"objects_far_kept_moving", total.objects_far_kept},
                 {"objects_carried_back", total.objects_carried_back},
                 {"carried_back_points", total.carried_back_points},
                 {"consensus_points_added", total.consensus_points},
                 {"consensus_points_removed", total.consensus_removed},
                 {"consensus_body_points_kept", total.consensus_body_kept},
                 {"consensus_foot_points_left", total.consensus_foot_left},
                 {"consensus_surface_points_left", total.consensus_surface_left},
                 {"consensus_still_part_points_left", total.consensus_still_part_left},
                 {"consensus_wide_objects_left", total.consensus_wide_left},
                 {"mover_feet_points", total.mover_feet},
                 {"mover_roof_points", total.mover_roofs},
                 {"no_evidence_points", total.no_evidence},
                 {"test_scans_visited", total.scans_visited},
                 {"test_beams_evaluated", total.beams},
                 {"test_early_decisions", total.early_decisions},
                 {"test_skipped_settled_leaves", total.settled_skips},
                 {"static_map_points", compact_->count()},
                 {"static_map_full_points", full_->count()},
                 {"dynamic_points", moving_->count()},
                 {"map_far_points", total.map_far},
                 {"map_far_points_kept", map_far_kept_},
                 {"map_removed_points", map_removed_}};
  {
    const auto& m = params_.map;
    j["map"] = {
        {"radius_m", m.radius},
        {"clean", m.clean && free_space != nullptr},
        {"policy", m.policy == MapPolicy::kMoving ? "moving" : "transient"},
        {"removed_points", map_removed_},
        // DESIGN §2e, "Objects": of those, the points removed with their objects
        {"objects", m.clean && m.objects && free_space != nullptr},
        {"object_points", map_object_points_},
        {"object_points_kept", map_object_kept_},
        {"objects_removed", map_objects_},
        {"clean_ms", map_ms_},
        // its passes (DESIGN §2e, "Objects"): forwards and backwards deciding the objects
        // (0 where they are decided in the writing pass, one way), then the writing one
        {"clean_passes_ms",
         {{"forward", map_forward_ms_}, {"backward", map_backward_ms_}, {"write", map_write_ms_}}},
        {"free_space_mib", free_space ? double(free_space->bytes()) / (1 << 20) : 0.0},
        // DESIGN §2e: the walk's azimuth bins, the lidar's own step where it is wider
        {"free_space_azimuth_bin_rad",
         {{"min", free_space ? free_space->azimuthBinMin() : 0.0},
          {"max", free_space ? free_space->azimuthBinMax() : 0.0}}}};
  }
  // DESIGN §2.0: the de-skew
  j["deskew"] = {{"mode", params_.sensor.deskew == DeskewMode::kAuto ? "auto"
                          : params_.sensor.deskew == DeskewMode::kOn ? "1"
                                                                     : "0"},
                 {"scans", total.deskewed},
                 {"max_shift_m", total.deskew_max_shift}};
  // DESIGN §2b: the window's K, set or from the scan rate (auto)
  j["window"] = {{"k", total.window_k},
                 {"window_k", params_.ds.window_k > 0 ? nlohmann::json(params_.ds.window_k)
                                                      : nlohmann::json("auto")},
                 {"window_s", params_.ds.window_s},
                 {"stride", total.window_stride},
                 {"scan_rate_hz", total.scan_rate_hz}};
  // DESIGN §2b: how far apart the scans are (a SLAM's keyframes may be sparser than sweeps)
  if (const auto gap = scanSpacing())
    j["window"]["scan_spacing"] = {
        {"seconds", gap->seconds},
        {"metres", gap->metres},
        {"sparser_than_sweeps", !sparseScansWarning(gap->seconds, gap->metres).empty()}};
  else
    j["window"]["scan_spacing"] = nullptr;
  {  // DESIGN §3: the camera check
    const auto& im = params_.image;
    j["images"] = {
        {"enabled", im.enabled && total.image_scans > 0},
        {"scans_with_image", total.image_scans},
        {"units_tested", total.image_units},
        {"unit", "object (cells of " + shortestDouble(im.cell) + " m)"},
        {"confirmed_by_colour", total.image_confirmed_colour},
        {"confirmed_by_depth", total.image_confirmed_depth},
        {"rejected_by_colour", total.image_rejected_colour},
        {"rejected_with_depth", total.image_rejected_depth},
        {"unseen", total.image_unseen},
        {"comparisons_skipped_grazing", total.image_grazing},
        {"points_held_not_compared", total.image_held},
        {"pose_links", total.image_links},
        {"pose_links_aligned", total.image_links_aligned},
        {"pose_link_mean_shift_m", total.image_links_aligned > 0
                                       ? total.image_link_shift / double(total.image_links_aligned)
                                       : 0.0},
        {"points_relabelled_static", total.image_relabelled}};
    if (has_relabel_truth_) {
      j["images"]["relabelled_truly_static"] = relabelled_static_;
      j["images"]["relabelled_truly_moving"] = relabelled_moving_;
    }
  }
  nlohmann::json timing;
  const std::pair<const char*, std::vector<double>*> stages[] = {
      {"total", &t_total},        {"registration", &t_reg}, {"beam_index", &t_index},
      {"crop_ground", &t_ground}, {"duplicates", &t_dup},   {"octree", &t_oct},
      {"classify", &t_cls},       {"objects", &t_obj},      {"free_space", &t_free},
      {"images", &t_img},         {"interval", &t_interval}};
  for (const auto& [name, v] : stages) {
    const Spread s = spread(*v);
    timing[name] = {{"median_ms", s.median}, {"p95_ms", s.p95}, {"mean_ms", s.mean}};
  }
  j["timing_per_scan"] = timing;
  {  // DESIGN §2.1: the pose source of each scan, and the alignment's figures
    nlohmann::json per = nlohmann::json::array();
    std::map<std::string, std::size_t> by_status;
    for (std::size_t i = 0; i < pose_info_.size(); ++i) {
      const PoseInfo& p = pose_info_[i];
      ++by_status[p.status];
      per.push_back({{"scan", stems_[i]},
                     {"source", p.source},
                     {"status", p.status},
                     {"accepted", p.accepted},
                     {"iterations", p.iterations},
                     {"fitness", p.fitness},
                     {"rmse_m", p.rmse}});
      if (p.start_guesses > 0) {
        per.back()["start_guesses"] = p.start_guesses;
        per.back()["guess_iterations"] = p.guess_iterations;
      }
    }
    std::vector<double> down, cov, align, map;
    for (const PoseInfo& p : pose_info_)
      if (p.source != "given")
        down.push_back(p.ms_downsample), cov.push_back(p.ms_covariances),
            align.push_back(p.ms_align), map.push_back(p.ms_map);
    nlohmann::json steps;
    for (const auto& [name, v] : {std::pair<const char*, std::vector<double>*>{"downsample", &down},
                                  {"covariances", &cov},
                                  {"align", &align},
                                  {"map", &map}}) {
      const Spread sp = spread(*v);
      steps[name] = {{"median_ms", sp.median}, {"p95_ms", sp.p95}};
    }
    j["registration"] = {{"source", pose_info_.empty() ? "given" : pose_info_.front().source},
                         {"status_counts", by_status},
                         {"timing_per_step", steps},
                         {"per_scan", per}};
  }
  {  // DESIGN §2a: the ground below the sensor, configured or measured
    std::vector<double> measured;
    for (const double g : ground_measured_)
      if (std::isfinite(g)) measured.push_back(-g);
    std::vector<double> used;
    for (const double g : ground_z_) used.push_back(-g);
    const auto range = [](std::vector<double> v) {
      nlohmann::json o;
      if (v.empty()) return o;
      std::sort(v.begin(), v.end());
      o = {{"median", v[v.size() / 2]}, {"min", v.front()}, {"max", v.back()}};
      return o;
    };
    j["sensor"] = {{"height", params_.sensor.height > 0 ? nlohmann::json(params_.sensor.height)
                                                        : nlohmann::json("auto")},
                   {"model", sensorModelName(params_.sensor.model)},
                   {"density_scale", range(density_)},
                   {"height_measured_m", range(measured)},
                   {"height_used_m", range(used)},
                   {"scans_not_measured", ground_measured_.size() - measured.size()}};
  }
  if (sensors_)
    j["rawlog_sensors"] = {{"lidar", sensors_->lidar},
                           {"camera", sensors_->camera},
                           {"other_lidars", sensors_->other_lidars},
                           {"other_cameras", sensors_->other_cameras},
                           {"scans_timed_back", sensors_->scans_timed_back}};
  j["wall_s"] = wall_s;
  if (!output_ms_.empty()) j["output_ms"] = output_ms_;
  j["threads"] = params_.threads;
  j["peak_rss_mib"] = peakRssMiB();
  // The whole process up to this report, as a user times the command (issue #16's bars): wall_s
  // above is the scans' alone, without the start-up before them (libraries, configuration, the
  // input opened) and the map's final decision and files after them.
  process_.cpu_s = processCpuSeconds();
  process_.wall_s = processAgeSeconds();
  if (process_.wall_s && started_s_)
    process_.end_s = std::max(0.0, *process_.wall_s - *started_s_ - wall_s);
  const double cpu_s = process_.cpu_s;
  const std::optional<double> age_s = process_.wall_s;
  const double n_scans = static_cast<double>(std::max<std::size_t>(stats_.size(), 1));
  j["process"] = {{"cpu_s", cpu_s}, {"cpu_per_scan_ms", 1000 * cpu_s / n_scans}};
  if (age_s) {
    j["process"]["wall_s"] = *age_s;
    j["process"]["wall_per_scan_ms"] = 1000 * *age_s / n_scans;
    if (process_.end_s) {
      j["process"]["start_s"] = *started_s_;
      j["process"]["end_s"] = *process_.end_s;
    }
  }
  j["params_ini"] = toIni(params_);
  if (has_eval_) {
    j["evaluation"] = countsJson(eval_);
    nlohmann::json per;
    for (std::size_t i = 0; i < scan_eval_.size() && i < stems_.size(); ++i)
      per[stems_[i]] = countsJson(scan_eval_[i]);
    j["evaluation_per_scan"] = per;
  }

  writeFileAtomic(staging_ + "/report.md", [&](std::ostream& os) {
    char buf[512];
    os << "# cleanmap run report\n\nInput: `" << input_ << "`, " << stats_.size() << " scans, "
       << params_.threads << " threads, wall " << wall_s << " s";
    if (age_s) os << " (the scans; " << *age_s << " s in all)";
    os << ", CPU " << cpu_s << " s, peak RSS " << peakRssMiB()
       << " MiB.\n\n## Counts\n| points | in crop | ground | duplicates | tested | moving | static "
          "| empty scans | total conflicts | conflicting scan votes | no evidence |\n"
          "|---|---|---|---|---|---|---|---|---|---|---|\n";
    std::snprintf(buf, sizeof buf,
                  "| %zu | %zu | %zu | %zu | %zu | %zu | %zu | %zu | %zu | %zu | %zu |\n",
                  total.points, total.in_crop, total.ground, total.duplicates, total.tested,
                  total.moving, total.static_points, empty, total.total_conflicts,
                  total.conflicting_scans, total.no_evidence);
    os << buf << "\n## Time per scan (ms)\n| stage | median | p95 |\n|---|---|---|\n";
    for (const auto& [name, v] : stages) {
      const Spread s = spread(*v);
      std::snprintf(buf, sizeof buf, "| %s | %.1f | %.1f |\n", name, s.median, s.p95);
      os << buf;
    }
    // DESIGN §2.1: estimated poses, and the scans whose alignment was refused.
    if (!pose_info_.empty() && pose_info_.front().source != "given") {
      std::size_t refused = 0;
      const auto reasons = refusedAlignments();
      for (const auto& [reason, n] : reasons) refused += n;
      os << "\n## Registration (" << pose_info_.front().source << ")\n"
         << pose_info_.size() - refused << " of " << pose_info_.size()
         << " scans aligned or first; a refused scan keeps the guess (the motion model's, or the "
            "input odometry's).\n";
      if (!reasons.empty()) {
        os << "\n| refused: reason | scans |\n|---|---|\n";
        for (const auto& [reason, n] : reasons) os << "| " << reason << " | " << n << " |\n";
      }
    }
    if (has_eval_) {
      std::snprintf(buf, sizeof buf,
                    "\n## Moving-object segmentation (in-crop points, ignore labels excluded)\n"
                    "| precision | recall | IoU | TP | FP | FN |\n|---|---|---|---|---|---|\n"
                    "| %.3f | %.3f | %.3f | %llu | %llu | %llu |\n",
                    eval_.precision(), eval_.recall(), eval_.iou(), (unsigned long long)eval_.tp,
                    (unsigned long long)eval_.fp, (unsigned long long)eval_.fn);
      os << buf;
    }
  });
  // Last: report.json marks a finished run (cleanmap-eval refuses a folder without it).
  writeFileAtomic(staging_ + "/report.json", [&](std::ostream& os) { os << j.dump(1) << '\n'; });
  publish();
}

}  // namespace cleanmap::io