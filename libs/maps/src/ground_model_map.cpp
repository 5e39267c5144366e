// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/maps/ground_model_map.h"

#include <mrpt/config/CConfigFileBase.h>
#include <mrpt/obs/CObservation.h>
#include <mrpt/opengl/CPointCloudColoured.h>
#include <mrpt/opengl/CSetOfObjects.h>
#include <mrpt/serialization/CArchive.h>
#include <mrpt/version.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include "cleanmap/core/error.h"
#include "cleanmap/core/ground.h"
#include "cleanmap/core/median.h"
#include "cleanmap/io/config.h"
#include "cleanmap/io/files.h"
#include "cleanmap/io/ini.h"
#include "cleanmap/io/ply.h"
#include "cleanmap/mrpt/convert.h"
#include "map_options.h"
#include "pose_observations.h"

namespace cleanmap_maps {

IMPLEMENTS_SERIALIZABLE(CGroundModelMap, CMetricMap, cleanmap_maps)
MAP_DEFINITION_REGISTER("cleanmap_maps::CGroundModelMap,cleanmap_ground",
                        cleanmap_maps::CGroundModelMap)

namespace {

uint64_t key2(int64_t ix, int64_t iy) {
  return (static_cast<uint64_t>(static_cast<uint32_t>(ix)) << 32) | static_cast<uint32_t>(iy);
}
int32_t keyX(uint64_t k) {
  return static_cast<int32_t>(static_cast<uint32_t>(k >> 32));
}
int32_t keyY(uint64_t k) {
  return static_cast<int32_t>(static_cast<uint32_t>(k));
}

// The map's option table: creationOpts `cell`; insertOpts the segmentation of SPEC §2a.
void insertOptionKeys(OptionTable& t, CGroundModelMap::TInsertionOptions& o) {
  t.real("step", o.step);
  t.custom("height", [&o](const std::string& v, const std::string& where) {
    const std::string text = cleanmap::io::trimBlanks(v);
    if (text == "auto") {
      o.height = 0;
      return;
    }
    std::string why;
    const auto x = cleanmap::io::parseNumber(text, false, why);
    if (!x) throw cleanmap::Error(where, "'height' needs a number or auto, got '" + text + "'");
    o.height = *x;
  });
  t.custom("sensor_height", [](const std::string&, const std::string& where) {
    throw cleanmap::Error(where,
                          "'sensor_height' is now 'height': metres above the ground, positive "
                          "(1.73 for KITTI's HDL-64E), or auto to measure it from the scans");
  });
  t.flag("point_refine", o.point_refine);
  t.integer("max_gap_cells", o.max_gap_cells);
  t.real("extent", o.extent);
  t.flag("use_pose_observations", o.use_pose_observations);
}

void checkOptions(double cell, const CGroundModelMap::TInsertionOptions& o,
                  const std::string& where) {
  auto bad = [&](const std::string& what) { throw cleanmap::Error(where, what); };
  if (!(cell >= 0.05 && cell <= 10)) bad("cell must be in [0.05, 10] m");
  if (!(o.step > 0)) bad("step must be > 0");
  if (!(o.extent > 0 && o.extent <= 1000)) bad("extent must be in (0, 1000] m");
  // The grid segmented per scan (params.h).
  if (const auto excess = cleanmap::groundGridExcess(o.extent, cell); !excess.empty())
    bad("cell is too small for the grid: extent / cell = " + excess);
  if (o.max_gap_cells < 1) bad("max_gap_cells must be >= 1");
  if (!(o.height == 0 || (o.height >= 0.1 && o.height <= 10)))
    bad("height must be auto or in [0.1, 10] m above the ground");
}

}  // namespace

CGroundModelMap::CGroundModelMap(double cell) : cell_(cell) {
  if (!(cell >= 0.05 && cell <= 10))
    throw cleanmap::Error("cleanmap_ground", "cell must be in [0.05, 10] m");
}

cleanmap::GroundParams CGroundModelMap::groundParams() const {
  cleanmap::GroundParams g;
  g.cell = cell_;
  g.step = insertionOptions.step;
  g.point_refine = insertionOptions.point_refine;
  g.max_gap_cells = insertionOptions.max_gap_cells;
  return g;
}

std::optional<double> CGroundModelMap::height(double x, double y) const {
  const auto it = cells_.find(key2(static_cast<int64_t>(std::floor(x / cell_)),
                                   static_cast<int64_t>(std::floor(y / cell_))));
  if (it == cells_.end()) return std::nullopt;
  return it->second.height();
}

std::vector<std::pair<std::pair<int32_t, int32_t>, CGroundModelMap::Cell>>
CGroundModelMap::sortedCells() const {
  std::vector<std::pair<std::pair<int32_t, int32_t>, Cell>> out;
  out.reserve(cells_.size());
  for (const auto& [k, c] : cells_) out.push_back({{keyX(k), keyY(k)}, c});
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  return out;
}

// As the pipeline (DESIGN §2a): a configured height, else the median of this scan's and the 10
// previous scans' measurements.
double CGroundModelMap::groundBelowSensor(const cleanmap::Scan& scan) {
  const auto measured = cleanmap::estimateGroundHeight(scan.points);
  if (insertionOptions.height > 0) return -insertionOptions.height;
  if (measured) {
    recent_ground_.push_back(*measured);
    if (recent_ground_.size() > 11) recent_ground_.pop_front();
  }
  if (recent_ground_.empty()) return -cleanmap::kDefaultSensorHeight;
  return cleanmap::median(std::vector<double>(recent_ground_.begin(), recent_ground_.end()));
}

void CGroundModelMap::insertGround(const cleanmap::Scan& scan, const std::vector<uint8_t>& ground) {
  const double inv = 1.0 / cell_;
  // Consecutive points of a ring mostly share a cell: the last one is kept (the map's nodes stay
  // where they are), so most points skip the hash lookup (issue #16).
  Cell* last = nullptr;
  uint64_t last_key = 0;
  for (std::size_t i = 0; i < scan.points.size() && i < ground.size(); ++i) {
    if (!ground[i]) continue;
    const Eigen::Vector3d w = scan.pose * scan.points[i].xyz().cast<double>();
    const uint64_t k = key2(static_cast<int64_t>(std::floor(w.x() * inv)),
                            static_cast<int64_t>(std::floor(w.y() * inv)));
    if (!last || k != last_key) {
      last = &cells_[k];
      last_key = k;
    }
    last->sum_z += w.z();
    ++last->count;
  }
  ++scans_;
}

const std::vector<uint8_t>& CGroundModelMap::insertScan(const cleanmap::Scan& scan) {
  last_flags_ = cleanmap::segmentGround(scan.points, groundParams(), insertionOptions.extent,
                                        groundBelowSensor(scan));
  for (auto& f : last_flags_) f = f != 0;  // 1 = ground, whichever kind (lastGroundFlags)
  insertGround(scan, last_flags_);
  return last_flags_;
}

void CGroundModelMap::merge(const CGroundModelMap& other) {
  if (other.cell_ != cell_)
    throw cleanmap::Error("cleanmap_ground", "cannot merge maps of different cell sizes");
  for (const auto& [k, c] : other.cells_) {
    Cell& d = cells_[k];
    d.sum_z += c.sum_z;
    d.count += c.count;
  }
  scans_ += other.scans_;
}

void CGroundModelMap::internal_clear() {
  cells_.clear();
  scans_ = 0;
  last_flags_.clear();
}

bool CGroundModelMap::internal_insertObservation(
    const mrpt::obs::CObservation& obs,
    const std::optional<const mrpt::poses::CPose3D>& robotPose) {
  auto posed = posedScanOf(obs, robotPose, insertionOptions.use_pose_observations, pose_obs_);
  if (posed.consumed) return true;
  if (!posed.scan) return false;  // not a lidar observation
  insertScan(*posed.scan);
  return true;
}

void CGroundModelMap::saveMetricMapRepresentationToFile(const std::string& prefix) const {
  const auto cells = sortedCells();
  std::vector<cleanmap::PointXYZI> pts;
  double lo = 1e300, hi = -1e300;
  for (const auto& [ij, c] : cells) {
    const double h = c.height();
    pts.push_back({static_cast<float>((ij.first + 0.5) * cell_),
                   static_cast<float>((ij.second + 0.5) * cell_), static_cast<float>(h),
                   static_cast<float>(c.count)});
    lo = std::min(lo, h);
    hi = std::max(hi, h);
  }
  cleanmap::io::CloudStreamOptions opts;
  opts.colour = cleanmap::io::CloudColour::kHeight;
  cleanmap::io::PlyStreamWriter ply(prefix + ".ply", opts);
  ply.append(pts, cells.empty() ? 0.0 : lo + 2.0);  // the lowest cell at the ramp's start
  ply.close();
  cleanmap::io::writeFileAtomic(prefix + ".txt", [&](std::ostream& os) {
    os << "# cleanmap ground model: cell " << cell_
       << " m; ix iy x y height count (x, y: cell centre, world frame, m)\n";
    os.precision(9);
    for (const auto& [ij, c] : cells)
      os << ij.first << ' ' << ij.second << ' ' << (ij.first + 0.5) * cell_ << ' '
         << (ij.second + 0.5) * cell_ << ' ' << c.height() << ' ' << c.count << '\n';
  });
}

void CGroundModelMap::getVisualizationInto(mrpt::opengl::CSetOfObjects& o) const {
  if (!genericMapParams.enableSaveAs3DObject) return;
  const auto cells = sortedCells();
  double lo = 1e300;
  for (const auto& kv : cells) lo = std::min(lo, kv.second.height());
  auto cloud = mrpt::opengl::CPointCloudColoured::Create();
  cloud->setName("cleanmap_ground");
  cloud->setPointSize(4.0f);
  for (const auto& [ij, c] : cells) {
    const double h = c.height();
    const auto rgb = cleanmap::io::heightColour(h - (lo + 2.0));
    cloud->push_back(static_cast<float>((ij.first + 0.5) * cell_),
                     static_cast<float>((ij.second + 0.5) * cell_), static_cast<float>(h),
                     rgb[0] / 255.0f, rgb[1] / 255.0f, rgb[2] / 255.0f);
  }
  o.insert(cloud);
}

std::string CGroundModelMap::asString() const {
  std::ostringstream os;
  os << "cleanmap ground model: " << cells_.size() << " cells of " << cell_ << " m from " << scans_
     << " scans";
  return os.str();
}

// Version 1: insertOpts `height` (above the ground, 0 = auto) replaced version 0's
// `sensor_height` (the ground below the sensor, negative).
uint8_t CGroundModelMap::serializeGetVersion() const {
  return 1;
}

void CGroundModelMap::serializeTo(mrpt::serialization::CArchive& out) const {
  out << genericMapParams;
  out << cell_ << insertionOptions.step << insertionOptions.height << insertionOptions.point_refine
      << static_cast<int32_t>(insertionOptions.max_gap_cells) << insertionOptions.extent
      << insertionOptions.use_pose_observations << static_cast<uint64_t>(scans_);
  const auto cells = sortedCells();  // sorted: equal maps serialize to equal bytes
  out << static_cast<uint64_t>(cells.size());
  for (const auto& [ij, c] : cells) out << ij.first << ij.second << c.sum_z << c.count;
}

void CGroundModelMap::serializeFrom(mrpt::serialization::CArchive& in, uint8_t version) {
  if (version > 1) MRPT_THROW_UNKNOWN_SERIALIZATION_VERSION(version);
  in >> genericMapParams;
  int32_t gap = 0;
  uint64_t scans = 0, n = 0;
  in >> cell_ >> insertionOptions.step >> insertionOptions.height >>
      insertionOptions.point_refine >> gap >> insertionOptions.extent >>
      insertionOptions.use_pose_observations >> scans;
  insertionOptions.max_gap_cells = gap;
  if (version == 0) insertionOptions.height = -insertionOptions.height;  // was sensor_height
  scans_ = scans;
  // A saved map is input like any file: its options as an ini would have to give them, and its
  // counts not trusted to size anything (a corrupt one would ask for 2^64 cells: the cells are
  // read until the data runs out).
  checkOptions(cell_, insertionOptions, "serialized cleanmap_ground");
  in >> n;
  cells_.clear();
  cells_.reserve(std::min<uint64_t>(n, kReserveAtMost));
  for (uint64_t i = 0; i < n; ++i) {
    int32_t ix = 0, iy = 0;
    Cell c;
    in >> ix >> iy >> c.sum_z >> c.count;
    if (c.count == 0 || !std::isfinite(c.sum_z))
      throw cleanmap::Error("serialized cleanmap_ground", "cell " + std::to_string(i) +
                                                              " has no height (a count of 0 or a "
                                                              "non-finite sum)");
    cells_[key2(ix, iy)] = c;
  }
  last_flags_.clear();
}

// ---- map definition (ini) ----

CGroundModelMap::TMapDefinition::TMapDefinition() = default;

void CGroundModelMap::TMapDefinition::loadFromConfigFile_map_specific(
    const mrpt::config::CConfigFileBase& source, const std::string& prefix) {
  const std::string creation = prefix + "_creationOpts", insert = prefix + "_insertOpts";
  OptionTable c;
  c.real("cell", cell);
  c.load(source, creation, /*generic=*/true);
  OptionTable t;
  insertOptionKeys(t, insertionOpts);
  t.load(source, insert, /*generic=*/false);
  checkOptions(cell, insertionOpts, "[" + prefix + "]");
}

void CGroundModelMap::TMapDefinition::dumpToTextStream_map_specific(std::ostream& out) const {
  out << "cell = " << cell << "\nstep = " << insertionOpts.step << "\nheight = "
      << (insertionOpts.height > 0 ? cleanmap::io::shortestDouble(insertionOpts.height) : "auto")
      << "\npoint_refine = " << insertionOpts.point_refine
      << "\nmax_gap_cells = " << insertionOpts.max_gap_cells
      << "\nextent = " << insertionOpts.extent
      << "\nuse_pose_observations = " << insertionOpts.use_pose_observations << "\n";
}

#if MRPT_VERSION >= 0x20b03
std::shared_ptr<mrpt::maps::CMetricMap>
#else
mrpt::maps::CMetricMap*
#endif
CGroundModelMap::internal_CreateFromMapDefinition(const mrpt::maps::TMetricMapInitializer& def_) {
  const auto& def = dynamic_cast<const CGroundModelMap::TMapDefinition&>(def_);
#if MRPT_VERSION >= 0x20b03
  auto m = std::make_shared<CGroundModelMap>(def.cell);
#else
  auto* m = new CGroundModelMap(def.cell);
#endif
  m->insertionOptions = def.insertionOpts;
  return m;
}

}  // namespace cleanmap_maps
