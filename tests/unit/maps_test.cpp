// SPDX-License-Identifier: BSD-3-Clause
// The MRPT map plugins (DESIGN §4b): created by name from ini text through MRPT's own factory,
// ini mistakes refused, posed observations inserted through a CMultiMetricMap decided exactly as
// the pipeline decides the frames, deep copies, serialization round trips, the ground model.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <random>
#include <set>
#include <sstream>
#include <tuple>

#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/maps/CColouredPointsMap.h>
#include <mrpt/maps/CMultiMetricMap.h>
#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/obs/CObservation3DRangeScan.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CObservationRotatingScan.h>
#include <mrpt/obs/CRawlog.h>
#include <mrpt/opengl/CPointCloud.h>
#include <mrpt/opengl/CPointCloudColoured.h>
#include <mrpt/opengl/CSetOfObjects.h>
#include <mrpt/serialization/CArchive.h>
#include <mrpt/serialization/archiveFrom_std_vector.h>

#include "cleanmap/io/config.h"
#include "cleanmap/io/files.h"

#include "cleanmap/io/ini.h"
#include "cleanmap/io/kitti.h"
#include "cleanmap/maps/ground_model_map.h"
#include "cleanmap/maps/map_config.h"
#include "cleanmap/maps/moving_objects_map.h"
#include "cleanmap/mrpt/convert.h"
#include "cleanmap/mrpt/rawlog.h"
#include "cleanmap/pipeline/laser_pipeline.h"
#include "test_data.h"

using namespace cleanmap;
using cleanmap_maps::CGroundModelMap;
using cleanmap_maps::CMovingObjectsMap;

namespace {

std::vector<uint8_t> serialize(const ::mrpt::serialization::CSerializable& o) {
  std::vector<uint8_t> buf;
  auto ar = ::mrpt::serialization::archiveFrom(buf);
  ar << o;
  return buf;
}

template <class T>
std::shared_ptr<T> deserialize(const std::vector<uint8_t>& buf) {
  auto copy = buf;
  auto ar = ::mrpt::serialization::archiveFrom(copy);
  auto obj = ar.ReadObject();
  return std::dynamic_pointer_cast<T>(obj);
}

::mrpt::maps::CMultiMetricMap mapsFrom(const std::string& text) {
  const auto mc = cleanmap_maps::parseMapConfig(text, "test.ini");
  ::mrpt::maps::CMultiMetricMap mm;
  mm.setListOfMaps(mc.maps);
  return mm;
}

// A lidar observation of `frame` as a robot would log it: the sensor mounted at `sensor` on the
// robot, so the robot's pose is the scan's world pose (-) the mounting.
::mrpt::obs::CObservationPointCloud::Ptr observation(const Frame& f,
                                                     const ::mrpt::poses::CPose3D& sensor,
                                                     ::mrpt::poses::CPose3D& robot) {
  auto o = ::mrpt::obs::CObservationPointCloud::Create();
  o->pointcloud = cleanmap::mrpt::toPointsMap(f.scan.points);
  o->sensorPose = sensor;
  o->timestamp = cleanmap::mrpt::toMrptTime(f.scan.timestamp);
  robot = cleanmap::mrpt::toCPose3D(f.scan.pose) + (-sensor);
  return o;
}

const char* kMinimal =
    "[map]\ncleanmap_moving_count = 1\n[map_cleanmap_moving_00_creationOpts]\n"
    "ds.window_k = 3\nmap_voxel = 0.2\n";

}  // namespace

TEST(MapConfig, DefaultIniCreatesBothMapsWithTheDefaults) {
  const std::string path = CLEANMAP_SOURCE_DIR "/config/cleanmap.ini";
  const std::string text = io::readTextFile(path);
  auto mm = mapsFrom(text);
  const auto moving = mm.mapByClass<CMovingObjectsMap>();
  const auto ground = mm.mapByClass<CGroundModelMap>();
  ASSERT_TRUE(moving && ground);
  EXPECT_EQ(io::toIni(moving->params()), io::toIni(PipelineParams{}));
  EXPECT_DOUBLE_EQ(moving->mapVoxel(), 0.1);
  EXPECT_DOUBLE_EQ(ground->cellSize(), PipelineParams{}.ground.cell);
  EXPECT_DOUBLE_EQ(ground->insertionOptions.height, PipelineParams{}.sensor.height);
  // Every parameter of the table is written out in the file (nothing left to a hidden default).
  std::set<std::string> in_file;
  io::IniHandlers on;
  on.entry = [&](const io::IniLine& e) {
    if (e.section == "MappingApplication_cleanmap_moving_00_creationOpts") in_file.insert(e.key);
  };
  io::parseIni(text, path, on);
  std::set<std::string> keys{"map_voxel", "map_object_scans"};
  for (const auto& k : io::paramKeys()) keys.insert(k);
  EXPECT_EQ(in_file, keys);
  // The generated text is equivalent.
  auto mm2 = mapsFrom(cleanmap_maps::mapConfigText(PipelineParams{}));
  EXPECT_EQ(io::toIni(mm2.mapByClass<CMovingObjectsMap>()->params()), io::toIni(PipelineParams{}));
}

TEST(MapConfig, MrptFactoryCreatesOurMapByName) {
  cleanmap_maps::registerMaps();
  // MRPT's own loader, no cleanmap code in between: the alias and the class name both work.
  for (const char* name : {"cleanmap_moving", "cleanmap_maps::CMovingObjectsMap"}) {
    const std::string text = std::string("[map]\n") + name + "_count = 1\n[map_" + name +
                             "_00_creationOpts]\nds.window_k = 3\n";
    ::mrpt::config::CConfigFileMemory cfg(text);
    ::mrpt::maps::TSetOfMetricMapInitializers inits;
    inits.loadFromConfigFile(cfg, "map");
    ::mrpt::maps::CMultiMetricMap mm;
    mm.setListOfMaps(inits);
    const auto m = mm.mapByClass<CMovingObjectsMap>();
    ASSERT_TRUE(m) << name;
    EXPECT_EQ(m->params().ds.window_k, 3) << name;
  }
  auto mm = mapsFrom(kMinimal);
  EXPECT_DOUBLE_EQ(mm.mapByClass<CMovingObjectsMap>()->mapVoxel(), 0.2);
  EXPECT_FALSE(mm.mapByClass<CGroundModelMap>());
}

TEST(MapConfig, MistakesAreOneLineErrors) {
  auto expect = [](const std::string& text, const std::string& what) {
    test::expectError([&] { cleanmap_maps::parseMapConfig(text, "my.ini"); }, "my.ini", what);
  };
  // A misspelled map name: MRPT 2.5.8 would create nothing and say nothing.
  expect("[MappingApplication]\ncleanmap_movin_count = 1\n",
         "unknown map 'cleanmap_movin' in 'cleanmap_movin_count'; did you mean 'cleanmap_moving'?");
  expect("[map]\ncleanmap_moving_cont = 1\n", "unknown key 'cleanmap_moving_cont'");
  expect("[map]\npointsMap_count = 1\n", "declares no cleanmap_moving map");
  expect("[nothing]\na = 1\n", "declares no maps");
  // Options: unknown key (with the nearest known one), bad value, failed validation.
  expect(std::string(kMinimal) + "filter.crop_ta = 20\n",
         "[map_cleanmap_moving_00_creationOpts]: unknown key 'filter.crop_ta'; did you mean "
         "'filter.crop_tau'?");
  expect(std::string(kMinimal) + "ds.sigma_r = fast\n", "'ds.sigma_r' needs a number, got 'fast'");
  expect(std::string(kMinimal) + "ds.r_sup = 0.5\n", "r_inf");
  expect(std::string(kMinimal) + "[map_cleanmap_moving_00_insertOpts]\nx = 1\n",
         "[map_cleanmap_moving_00_insertOpts]: unknown key 'x'");
  expect(std::string(kMinimal) + "[map_cleanmap_moving_00_likelihoodOpts]\nx = 1\n",
         "cleanmap_moving computes no likelihood");
  // Sections MRPT would silently ignore.
  expect(std::string(kMinimal) + "[map_cleanmap_moving_01_creationOpts]\nds.window_k = 2\n",
         "declares 1 cleanmap_moving map(s), so this section would be ignored");
  expect(std::string(kMinimal) + "[map_cleanmap_movng_00_creationOpts]\nds.window_k = 2\n",
         "unknown map 'cleanmap_movng'");
  expect(
      "[map]\ncleanmap_moving_count = 1\ncleanmap_ground_count = 1\n"
      "[map_cleanmap_ground_00_insertOpts]\nstepp = 0.1\n",
      "unknown key 'stepp'; did you mean 'step'?");
  // A voxel the layer's saved form would refuse (its keys overflow): the ini refuses it too.
  expect(std::string(kMinimal) + "map_voxel = 1e-6\n",
         "[map_cleanmap_moving_00_creationOpts]: map_voxel must be 0 or in [0.001, 1000] m");
  expect(std::string(kMinimal) + "map_voxel = -1\n", "map_voxel must be 0 or in [0.001, 1000] m");
  // The ground map's grid: a cell far below the lidar's noise, or one too small for its extent.
  const std::string ground = "[map]\ncleanmap_moving_count = 1\ncleanmap_ground_count = 1\n";
  expect(ground + "[map_cleanmap_ground_00_creationOpts]\ncell = 1e-7\n",
         "cell must be in [0.05, 10] m");
  expect(ground + "[map_cleanmap_ground_00_insertOpts]\nextent = 1e9\n",
         "extent must be in (0, 1000] m");
  expect(ground + "[map_cleanmap_ground_00_creationOpts]\ncell = 0.05\n" +
             "[map_cleanmap_ground_00_insertOpts]\nextent = 400\n",
         "cell is too small for the grid: extent / cell = 8000 cells each side, at most 2500");
  test::expectError([] { cleanmap_maps::loadMapConfig("/nonexistent/x.ini"); },
                    "/nonexistent/x.ini", "");
  EXPECT_TRUE(cleanmap_maps::isMapConfig(kMinimal));
  EXPECT_FALSE(cleanmap_maps::isMapConfig(io::toIni(PipelineParams{})));
}

// Posed CObservationPointCloud through CMultiMetricMap::insertObservation (robot pose (+) sensor
// pose) gives exactly the labels of the pipeline run on the frames.
TEST(MovingObjectsMap, InsertedObservationsDecidedAsThePipelineDecides) {
  CLEANMAP_REQUIRE_DATASET("kitti_city");
  auto seq = io::KittiSequence::open(test::dataDir() + "/kitti_city");
  const std::size_t n = std::min<std::size_t>(12, seq.size());
  std::vector<Frame> frames;
  for (std::size_t i = 0; i < n; ++i) frames.push_back(seq.frame(i));

  std::vector<Labels> direct;
  {
    LaserPipeline pl(PipelineParams{}, [&](ScanResult&& r) { direct.push_back(r.labels); });
    for (auto f : frames) pl.push(std::move(f));
    pl.finish();
  }

  auto mm = mapsFrom(cleanmap_maps::mapConfigText(PipelineParams{}));
  auto moving = mm.mapByClass<CMovingObjectsMap>();
  std::vector<Labels> via_mrpt;
  moving->setScanSink([&](ScanResult&& r) { via_mrpt.push_back(r.labels); });
  const ::mrpt::poses::CPose3D sensor(0.27, 0.0, 1.73, 0.0, 0.0, 0.0);  // a roof mount
  for (const auto& f : frames) {
    ::mrpt::poses::CPose3D robot;
    const auto obs = observation(f, sensor, robot);
    EXPECT_TRUE(mm.insertObservation(*obs, robot));
  }
  // Auto K: 1 s of the 10 Hz scans. Scans 0-1 are decided, and held with the last ceil(K / 2) + 2
  // decided (rule 4 backwards, doc/OBJECTS.md): all 12 pending.
  ASSERT_EQ(n, std::size_t(kDefaultWindowK) + 2);
  EXPECT_EQ(moving->pending(), n);
  moving->flush();
  ASSERT_EQ(via_mrpt.size(), direct.size());
  std::size_t differ = 0, total = 0, moving_points = 0;
  for (std::size_t i = 0; i < direct.size(); ++i) {
    ASSERT_EQ(via_mrpt[i].size(), direct[i].size());
    for (std::size_t j = 0; j < direct[i].size(); ++j) {
      differ += via_mrpt[i][j] != direct[i][j];
      moving_points += direct[i][j] == kMoving;
    }
    total += direct[i].size();
  }
  EXPECT_GT(moving_points, 1000u);  // the city scans have moving cars
  // Composing the poses in MRPT rounds differently in the last bit: allow 1 point in 10^5.
  EXPECT_LE(differ, total / 100000) << differ << " of " << total << " labels differ";
  EXPECT_FALSE(moving->staticPoints().empty());
  EXPECT_FALSE(moving->movingPoints().empty());
  EXPECT_EQ(moving->trajectory().size(), n);
  EXPECT_NEAR(
      (moving->trajectory().back().pose.translation() - frames.back().scan.pose.translation())
          .norm(),
      0.0, 1e-9);

  // The ground model, fed by MRPT too, holds the road: its cells 4 m beside the first pose lie
  // about 1.73 m (the HDL-64E's height) below the sensor.
  auto ground = mm.mapByClass<CGroundModelMap>();
  ASSERT_TRUE(ground);
  EXPECT_EQ(ground->scansInserted(), n);
  const Eigen::Vector3d o = frames[0].scan.pose.translation();
  std::size_t near_cells = 0;
  for (double dx = -6; dx <= 6; dx += 0.4)
    if (const auto h = ground->height(o.x() + dx, o.y() + 4.0)) {
      ++near_cells;
      // 1.73 m mount; the street's camber and slope and KITTI's tilted world frame put it
      // 1.6-2.0 m below the sensor here: allow 0.45 m.
      EXPECT_NEAR(*h - o.z(), -1.73, 0.45) << "cell at dx " << dx;
    }
  EXPECT_GT(near_cells, 10u);

  // Visualisation: static points coloured by height and moving points in red.
  ::mrpt::opengl::CSetOfObjects scene;
  moving->getVisualizationInto(scene);
  const auto red =
      std::dynamic_pointer_cast<::mrpt::opengl::CPointCloud>(scene.getByName("cleanmap_moving"));
  ASSERT_TRUE(red);
  EXPECT_EQ(red->size(), moving->movingPoints().size());
  EXPECT_EQ(red->getColor_u8().R, 255);
  EXPECT_TRUE(scene.getByName("cleanmap_static"));
}

// RawLogViewer's "Map from odometry" (MRPT 2.5.8, CFormRawMap) on an external-storage rawlog from
// cleanmap-kitti2rawlog --external: every observation inserted in order at the odometry pose
// (none here: the origin). With use_pose_observations our layer takes the logged 3D poses and
// loads the lazy clouds, and decides as the pipeline does.
// DESIGN §2e in the layer: a box 8 m ahead stands in scans 0-9 and is gone in 10-19, a round wall
// at 20 m stays. The windowed test (K = 3) calls the box static in scans 0-6; the free space of
// the scans after it left removes those points from staticPoints() (policy transient), and only
// them: with static_map.clean off they stay.
TEST(MovingObjectsMap, StaticPointsAreCleanedWithTheFreeSpace) {
  auto scan = [](bool box) {
    std::vector<PointXYZI> pts;
    for (int e = 0; e < 16; ++e)
      for (int a = 0; a < 2094; ++a) {  // 0.003 rad apart, static_map.beam_spacing
        const double az = 2 * M_PI * a / 2094, el = (-8.0 + e) * M_PI / 180;
        const Eigen::Vector3d d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                                std::sin(el));
        double r = 20.0 / std::cos(el);
        if (box && d.x() > 0) {  // the box's face x = 8, |y| <= 0.6, z in [-1, 0.4]
          const double t = 8.0 / d.x();
          const Eigen::Vector3d q = t * d;
          if (std::abs(q.y()) <= 0.6 && q.z() >= -1.0 && q.z() <= 0.4) r = t;
        }
        const Eigen::Vector3d q = r * d;
        pts.push_back({float(q.x()), float(q.y()), float(q.z()), 0.5f});
      }
    return pts;
  };
  auto run = [&](bool clean) {
    PipelineParams p;
    p.ds.window_k = 3;
    p.map.clean = clean;
    CMovingObjectsMap m(p, 0.1);
    for (int k = 0; k < 20; ++k) {
      Frame f;
      f.index = static_cast<std::size_t>(k);
      f.stem = std::to_string(k);
      f.scan.points = scan(k < 10);
      f.scan.original_size = f.scan.points.size();
      f.scan.pose = Eigen::Isometry3d::Identity();
      f.scan.has_pose = true;
      f.scan.timestamp = 0.1 * k;
      m.insertFrame(std::move(f));
    }
    m.flush();
    // What the apps' memory warning reads (DESIGN §2e): this layer's free space, the only layer
    // alive here; none without the cleaning.
    const std::size_t held = m.freeSpace() ? m.freeSpace()->bytes() : 0;
    EXPECT_EQ(clean, held > 0);
    EXPECT_EQ(m.freeSpaceBytes(), held);
    EXPECT_EQ(CMovingObjectsMap::freeSpaceBytesOfAll(), held);
    {
      const CMovingObjectsMap copy(m);  // a copy is a layer too
      EXPECT_EQ(CMovingObjectsMap::freeSpaceBytesOfAll(), 2 * held);
    }
    EXPECT_EQ(CMovingObjectsMap::freeSpaceBytesOfAll(), held);
    std::size_t box = 0, wall = 0;
    for (const auto& q : m.staticPoints()) (q.xyz().norm() < 12 ? box : wall) += 1;
    std::size_t removed_box = 0;
    for (const auto& q : m.removedPoints()) removed_box += q.xyz().norm() < 12;
    return std::tuple(box, wall, removed_box, m.removedPoints().size());
  };
  const auto [box0, wall0, rb0, r0] = run(false);
  const auto [box1, wall1, rb1, r1] = run(true);
  EXPECT_EQ(CMovingObjectsMap::freeSpaceBytesOfAll(), 0u);  // both layers gone
  EXPECT_GT(box0, 100u);  // the windowed test keeps the box it saw standing
  EXPECT_EQ(r0, 0u);
  EXPECT_EQ(box1, 0u);  // the free space removes all of it ...
  EXPECT_EQ(rb1, box0);
  EXPECT_EQ(wall1, wall0);  // ... and nothing else
  EXPECT_EQ(r1, rb1);
}

TEST(MovingObjectsMap, RawLogViewerMapFromOdometryOnAnExternalRawlog) {
  CLEANMAP_REQUIRE_DATASET("kitti_city");
  auto seq = io::KittiSequence::open(test::dataDir() + "/kitti_city");
  const auto dir = test::scratchDir("external");
  const std::string rawlog = (dir / "city_external.rawlog").string();
  const std::size_t n = 12;
  std::vector<Labels> direct;
  {
    cleanmap::mrpt::RawlogWriteOptions wo;
    wo.external = true;
    cleanmap::mrpt::RawlogWriter w(rawlog, wo);
    LaserPipeline pl(PipelineParams{}, [&](ScanResult&& r) { direct.push_back(r.labels); });
    for (std::size_t i = 0; i < n; ++i) {
      Frame f = seq.frame(i);
      w.write(f, std::nullopt, f.source);
      pl.push(std::move(f));
    }
    w.close();
    pl.finish();
  }
  auto mm = mapsFrom(std::string(kMinimal) +
                     "[map_cleanmap_moving_00_insertOpts]\nuse_pose_observations = 1\n");
  auto moving = mm.mapByClass<CMovingObjectsMap>();
  moving->setParams(PipelineParams{});  // kMinimal's K = 3 back to the default
  std::vector<Labels> via_viewer;
  moving->setScanSink([&](ScanResult&& r) { via_viewer.push_back(r.labels); });
  cleanmap::mrpt::registerClasses();
  ::mrpt::io::CFileGZInputStream in(rawlog);
  auto ar = ::mrpt::serialization::archiveFrom(in);
  ::mrpt::obs::CActionCollection::Ptr acts;
  ::mrpt::obs::CSensoryFrame::Ptr sf;
  ::mrpt::obs::CObservation::Ptr obs;
  std::size_t idx = 0;
  const ::mrpt::poses::CPose3D odometry;  // the viewer's pose without odometry entries
  while (::mrpt::obs::CRawlog::getActionObservationPairOrObservation(ar, acts, sf, obs, idx))
    if (obs) mm.insertObservation(*obs, odometry);
  moving->flush();
  ASSERT_EQ(via_viewer.size(), direct.size());
  std::size_t differ = 0, total = 0;
  for (std::size_t i = 0; i < direct.size(); ++i) {
    ASSERT_EQ(via_viewer[i].size(), direct[i].size());
    for (std::size_t j = 0; j < direct[i].size(); ++j) differ += via_viewer[i][j] != direct[i][j];
    total += direct[i].size();
  }
  EXPECT_LE(differ, total / 100000) << differ << " of " << total << " labels differ";

  // Without the option, a scan without a logged pose is an error only with it on: a rawlog
  // without poses gives a clear line.
  auto strict = mapsFrom(std::string(kMinimal) +
                         "[map_cleanmap_moving_00_insertOpts]\nuse_pose_observations = 1\n");
  ::mrpt::poses::CPose3D robot;
  const auto pc = observation(seq.frame(0), ::mrpt::poses::CPose3D(), robot);
  test::expectError([&] { strict.insertObservation(*pc, robot); }, "CObservationPointCloud",
                    "no CObservationRobotPose within 10 ms");
}

// A copy taken mid-window, fed the same remaining scans, decides them as the original does; a
// serialized CMultiMetricMap holding both maps reads back equal (content as if flushed).
TEST(MovingObjectsMap, CopiesAndSerializedMultiMapsAreEqual) {
  CLEANMAP_REQUIRE_DATASET("kitti_city");
  auto seq = io::KittiSequence::open(test::dataDir() + "/kitti_city");
  PipelineParams p;
  p.ds.window_k = 3;
  auto mm = mapsFrom(cleanmap_maps::mapConfigText(p));
  auto moving = mm.mapByClass<CMovingObjectsMap>();
  const ::mrpt::poses::CPose3D sensor;
  auto insert = [&](::mrpt::maps::CMultiMetricMap& m, std::size_t i) {
    ::mrpt::poses::CPose3D robot;
    const auto obs = observation(seq.frame(i), sensor, robot);
    m.insertObservation(*obs, robot);
  };
  // K = 3: scans 0-2 are decided and held (rule 4 backwards holds the last ceil(K / 2) + 2).
  for (std::size_t i = 0; i < 6; ++i) insert(mm, i);
  ASSERT_EQ(moving->pending(), 6u);

  // Serialized now: the copy is flushed, the original keeps its window.
  const auto bytes = serialize(mm);
  EXPECT_EQ(moving->pending(), 6u);
  const auto back = deserialize<::mrpt::maps::CMultiMetricMap>(bytes);
  ASSERT_TRUE(back);
  ASSERT_TRUE(back->mapByClass<CMovingObjectsMap>() && back->mapByClass<CGroundModelMap>());
  EXPECT_EQ(back->mapByClass<CMovingObjectsMap>()->decided(), 6u);
  EXPECT_EQ(back->mapByClass<CMovingObjectsMap>()->pending(), 0u);
  EXPECT_EQ(serialize(*back), bytes);
  EXPECT_EQ(back->mapByClass<CGroundModelMap>()->cellCount(),
            mm.mapByClass<CGroundModelMap>()->cellCount());

  // MRPT 2.5.8 copies a CMultiMetricMap through serialization: its copy of our map is the
  // flushed content, equal to the map read back.
  const ::mrpt::maps::CMultiMetricMap mm_copy(mm);
  EXPECT_EQ(mm_copy.mapByClass<CMovingObjectsMap>()->pending(), 0u);
  EXPECT_EQ(serialize(*mm_copy.mapByClass<CMovingObjectsMap>()),
            serialize(*back->mapByClass<CMovingObjectsMap>()));

  // The map's own clone() is deep, window included: both continue identically.
  std::unique_ptr<CMovingObjectsMap> cm(dynamic_cast<CMovingObjectsMap*>(moving->clone()));
  ASSERT_TRUE(cm);
  EXPECT_EQ(cm->pending(), 6u);
  EXPECT_EQ(cm->decided(), 0u);  // decided scans are added once handed on
  for (std::size_t i = 6; i < 9; ++i) {
    insert(mm, i);
    ::mrpt::poses::CPose3D robot;
    const auto obs = observation(seq.frame(i), sensor, robot);
    cm->insertObservation(*obs, robot);
  }
  EXPECT_EQ(cm->decided(), moving->decided());
  moving->flush();
  cm->flush();
  EXPECT_EQ(cm->asString(), moving->asString());
  EXPECT_EQ(serialize(*cm), serialize(*moving));
  EXPECT_GT(moving->movingPoints().size(), 0u);
  // A flushed original serializes as its flushed copy did: equal maps, equal bytes.
  EXPECT_EQ(serialize(*deserialize<CMovingObjectsMap>(serialize(*moving))), serialize(*moving));
}

// A car logging two lidars ("ROOF" and "FRONT") into one multi-map: the layer takes one (its
// windowed test compares scans of one sensor): the first inserted, or the one insertOpts
// sensor_label names; the other's observations are not inserted. The choice survives
// serialization.
TEST(MovingObjectsMap, TakesTheObservationsOfOneLidar) {
  CLEANMAP_REQUIRE_DATASET("kitti_city");
  auto seq = io::KittiSequence::open(test::dataDir() + "/kitti_city");
  auto run = [&](const std::string& label_line) {
    std::string ini = kMinimal;
    ini += "[map_cleanmap_moving_00_insertOpts]\n" + label_line;
    auto mm = mapsFrom(ini);
    auto moving = mm.mapByClass<CMovingObjectsMap>();
    std::vector<std::string> inserted;
    for (std::size_t i = 0; i < 4; ++i)
      for (const char* label : {"ROOF", "FRONT"}) {
        ::mrpt::poses::CPose3D robot;
        const auto obs = observation(seq.frame(i), ::mrpt::poses::CPose3D(), robot);
        obs->sensorLabel = label;
        if (moving->insertObservation(*obs, robot)) inserted.push_back(label);
      }
    EXPECT_EQ(moving->pending() + moving->decided(), inserted.size());
    ::mrpt::obs::CObservationRotatingScan rot;  // a third lidar, of a model cleanmap cannot decode:
    rot.sensorLabel = "OUSTER";                 // not this layer's, so not decoded, no error
    rot.lidarModel = "OS1-64";
    rot.rowCount = 64;
    rot.columnCount = 4;
    rot.rangeImage.setZero(64, 4);
    rot.rangeResolution = 0.01;
    EXPECT_FALSE(moving->insertObservation(rot, ::mrpt::poses::CPose3D()));
    const auto back = deserialize<CMovingObjectsMap>(serialize(*moving));
    EXPECT_EQ(back->lidarLabel(), moving->lidarLabel());
    EXPECT_EQ(back->insertionOptions.sensor_label, moving->insertionOptions.sensor_label);
    return inserted;
  };
  const std::vector<std::string> roof(4, "ROOF"), front(4, "FRONT");
  EXPECT_EQ(run(""), roof);
  EXPECT_EQ(run("sensor_label = auto\n"), roof);
  EXPECT_EQ(run("sensor_label = FRONT\n"), front);
}

// The ground model on a synthetic scene: a plane 1.73 m below the sensor and a box on it.
TEST(GroundModelMap, FlatRoadHeightsAndMergeCommutes) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-20.f, 20.f);
  Scan scan;
  for (int i = 0; i < 40000; ++i) scan.points.push_back({u(rng), u(rng), -1.73f, 0.f});
  for (int i = 0; i < 3000; ++i)  // a 2 x 2 x 1.5 m box centred at (8, 0)
    scan.points.push_back({7.f + std::fabs(u(rng)) / 10.f, -1.f + std::fabs(u(rng)) / 10.f,
                           -1.73f + std::fabs(u(rng)) / 13.3f, 0.f});
  scan.pose = Eigen::Isometry3d(Eigen::Translation3d(100.0, 50.0, 10.0));
  scan.has_pose = true;
  CGroundModelMap a(0.4), b(0.4);
  const auto& flags = a.insertScan(scan);
  std::size_t box_ground = 0;
  for (std::size_t i = 40000; i < scan.points.size(); ++i)
    box_ground += flags[i] && scan.points[i].z > -1.73f + 0.3f;
  EXPECT_EQ(box_ground, 0u) << "box points above 0.3 m labelled ground";
  // The flags are 1 = ground whatever its kind: the box's cells' lowest returns, refined to
  // ground (DESIGN §2a), too.
  std::size_t refined = 0;
  for (std::size_t i = 40000; i < scan.points.size(); ++i) {
    ASSERT_LE(flags[i], 1) << "point " << i;
    refined += flags[i];
  }
  EXPECT_GT(refined, 0u);
  const auto h = a.height(100.0 - 10.0, 50.0 + 5.0);
  ASSERT_TRUE(h);
  EXPECT_NEAR(*h, 10.0 - 1.73, 1e-5);
  EXPECT_FALSE(a.height(0.0, 0.0));

  Scan shifted = scan;
  shifted.pose = Eigen::Isometry3d(Eigen::Translation3d(130.0, 50.0, 10.5));
  b.insertScan(shifted);
  CGroundModelMap ab = a, ba = b;
  ab.merge(b);
  ba.merge(a);
  EXPECT_EQ(serialize(ab), serialize(ba));  // sums commute: chunked runs merge in any order
  EXPECT_GT(ab.cellCount(), a.cellCount());
  const auto back = deserialize<CGroundModelMap>(serialize(ab));
  ASSERT_TRUE(back);
  EXPECT_EQ(serialize(*back), serialize(ab));
  EXPECT_NE(ab.asString().find("cells"), std::string::npos);

  const auto dir = test::scratchDir("ground");
  ab.saveMetricMapRepresentationToFile((dir / "ground").string());
  EXPECT_TRUE(std::filesystem::exists(dir / "ground.ply"));
  std::ifstream txt(dir / "ground.txt");
  std::string header;
  std::getline(txt, header);
  std::size_t rows = 0;
  for (std::string line; std::getline(txt, line);) ++rows;
  EXPECT_EQ(rows, ab.cellCount());
}
// The MRPT 2.5.8 trap cleanmap-icp-slam and cleanmap-build-map work around: a points map drops
// the robot pose of a CObservationPointCloud, not of a points-only CObservation3DRangeScan. When
// an MRPT upgrade fixes it (2.11.3 did), this test fails and the workarounds can go.
TEST(MrptTrap, PointCloudInsertionDropsTheRobotPose) {
  auto pc = ::mrpt::obs::CObservationPointCloud::Create();
  pc->pointcloud = cleanmap::mrpt::toPointsMap({{1.f, 0.f, 0.f, 0.f}});
  pc->sensorPose = ::mrpt::poses::CPose3D(0, 0, 2, 0, 0, 0);
  const ::mrpt::poses::CPose3D robot(10, 0, 0, 0, 0, 0);
  ::mrpt::maps::CSimplePointsMap a;
  a.insertObservation(*pc, robot);
  ASSERT_EQ(a.size(), 1u);
  EXPECT_FLOAT_EQ(a.getPointsBufferRef_x()[0], 1.f);  // should be 11
  auto rs = ::mrpt::obs::CObservation3DRangeScan::Create();
  rs->hasPoints3D = true;
  rs->points3D_x = {1.f};
  rs->points3D_y = {0.f};
  rs->points3D_z = {0.f};
  rs->points3D_idxs_x = {0};
  rs->points3D_idxs_y = {0};
  rs->sensorPose = pc->sensorPose;
  ::mrpt::maps::CSimplePointsMap b;
  b.insertObservation(*rs, robot);
  ASSERT_EQ(b.size(), 1u);
  EXPECT_FLOAT_EQ(b.getPointsBufferRef_x()[0], 11.f);
  EXPECT_FLOAT_EQ(b.getPointsBufferRef_z()[0], 2.f);
  // ... and our maps read the points-only range scan (sensor frame) like the point cloud.
  const auto scan = cleanmap::mrpt::scanFromObservation(*rs);
  ASSERT_TRUE(scan);
  ASSERT_EQ(scan->points.size(), 1u);
  EXPECT_FLOAT_EQ(scan->points[0].x, 1.f);
}

// The ICP-SLAM example carries cleanmap's layers exactly as config/cleanmap.ini declares them.
TEST(MapConfig, IcpSlamIniCarriesTheSameLayers) {
  const auto a = cleanmap_maps::parseMapConfig(
      io::readTextFile(CLEANMAP_SOURCE_DIR "/config/cleanmap.ini"), "cleanmap.ini");
  const auto b = cleanmap_maps::parseMapConfig(
      io::readTextFile(CLEANMAP_SOURCE_DIR "/config/icp_slam_kitti.ini"), "icp_slam_kitti.ini");
  auto dump = [](const cleanmap_maps::MapConfig& mc) {
    std::ostringstream os;
    for (const auto& def : mc.maps)
      if (def->getMetricMapClassType()->className ==
              std::string("cleanmap_maps::CMovingObjectsMap") ||
          def->getMetricMapClassType()->className == std::string("cleanmap_maps::CGroundModelMap"))
        def->dumpToTextStream(os);
    return os.str();
  };
  EXPECT_FALSE(dump(a).empty());
  EXPECT_EQ(dump(a), dump(b));
  EXPECT_EQ(b.maps.size(), 3u);  // + the points map ICP aligns against
}
// Why labelled.rawlog carries a LIDAR_MOVING cloud: RawLogViewer 2.5.8 draws a point-cloud
// observation through the CPointsMap base pointer, and that path drops the colours (all black).
// When this test fails, MRPT renders the labels' colours and doc/MRPT.md can say so.
TEST(MrptTrap, ViewerDropsColoursOfCloudsSeenThroughTheBase) {
  auto m = ::mrpt::maps::CColouredPointsMap::Create();
  m->insertPoint(1, 2, 3);
  m->setPointColor(0, 1.0f, 0.0f, 0.0f);
  ::mrpt::maps::CPointsMap::Ptr base = m;
  ::mrpt::opengl::CPointCloudColoured through_base, direct;
  through_base.loadFromPointsMap(base.get());
  direct.loadFromPointsMap(m.get());
  EXPECT_EQ(through_base.getPointColor(0).R, 0);
  EXPECT_EQ(direct.getPointColor(0).R, 255);
}

namespace {

// The serialization of one of our layers, written field by field (serializeTo's order, version 1)
// so that a test can put in what no map would: `fields` writes the fields after the class header.
template <class F>
std::vector<uint8_t> layerBytes(const std::string& cls, F&& fields) {
  std::vector<uint8_t> buf;
  auto ar = ::mrpt::serialization::archiveFrom(buf);
  const uint8_t len = static_cast<uint8_t>(0x80 | cls.size()), version = 1;
  ar.WriteBuffer(&len, 1);
  ar.WriteBuffer(cls.data(), cls.size());
  ar.WriteBuffer(&version, 1);
  fields(ar);
  const uint8_t end = 0x88;  // MRPT's end of an object
  ar.WriteBuffer(&end, 1);
  return buf;
}

std::string readError(const std::vector<uint8_t>& bytes,
                      ::mrpt::serialization::CSerializable& into) {
  auto copy = bytes;
  auto ar = ::mrpt::serialization::archiveFrom(copy);
  try {
    ar.ReadObject(&into);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

long peakRssMiB() {
  rusage u{};
  ::getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss / 1024;
}

}  // namespace

// A saved layer is input like any file (found by fuzzing maps.bin): its counts size nothing (the
// elements are read until the data runs out: 2^25 trajectory poses or 2^28 ground cells claimed
// by a few bytes ask for no memory), its options are those an ini must give, and its points,
// poses and cells are finite. Each is an error MRPT's reader passes on, naming what is wrong.
TEST(MapLayers, ASavedLayerIsCheckedAsItIsRead) {
  cleanmap_maps::registerMaps();
  const ::mrpt::maps::TMapGenericParams generic;
  const std::string ini = cleanmap::io::toIni(cleanmap::PipelineParams{});
  const auto moving = [&](double voxel, uint64_t poses, bool nan_point) {
    return layerBytes("cleanmap_maps::CMovingObjectsMap", [&](auto& ar) {
      ar << generic << ini << voxel << true << uint64_t{0} << false << std::string()
         << std::string() << poses;
      if (poses > 0) return;
      for (int block = 0; block < 2; ++block)  // the static points, then the moving ones
        ar << uint64_t{1} << (nan_point ? NAN : 1.f) << 2.f << 3.f << 0.f;
      for (int total = 0; total < 9; ++total) ar << uint64_t{0};
    });
  };
  const long before = peakRssMiB();
  CMovingObjectsMap m;
  EXPECT_NE(readError(moving(0.2, uint64_t{1} << 25, false), m), "");
  CGroundModelMap g;
  const auto ground = [&](double cell, uint64_t cells, uint64_t count) {
    return layerBytes("cleanmap_maps::CGroundModelMap", [&](auto& ar) {
      ar << generic << cell << 1.0 << 0.0 << true << int32_t{3} << 40.0 << false << uint64_t{0}
         << cells;
      if (cells == 1) ar << int32_t{0} << int32_t{0} << -1.7 << count;
    });
  };
  EXPECT_NE(readError(ground(0.5, uint64_t{1} << 28, 1), g), "");
  EXPECT_LT(peakRssMiB() - before, 200) << "a claimed count sized a list";

  const auto says = [](const std::string& error, const std::string& what) {
    EXPECT_NE(error.find(what), std::string::npos) << error;
  };
  says(readError(moving(1e-30, 0, false), m), "map_voxel must be 0 or in [0.001, 1000] m");
  says(readError(moving(0.2, 0, true), m), "point 0 is not finite");
  says(readError(ground(0.0, 0, 1), g), "cell must be in [0.05, 10] m");
  says(readError(ground(0.5, 1, 0), g), "cell 0 has no height");
  // What a map writes, it reads: the fields above as serializeTo orders them.
  EXPECT_EQ(readError(moving(0.2, 0, false), m), "");
  EXPECT_EQ(readError(ground(0.5, 1, 2), g), "");
}
