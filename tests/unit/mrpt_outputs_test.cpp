// SPDX-License-Identifier: BSD-3-Clause
// The MRPT outputs (DESIGN §4a) read back with MRPT itself: the rawlogs scan by scan against the
// pipeline's labels, the streamed simplemap byte-equal to MRPT's own serialization, the scene's
// objects.
#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <tuple>

#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/maps/CColouredPointsMap.h>
#include <mrpt/maps/CSimpleMap.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CObservationRobotPose.h>
#include <mrpt/obs/CRawlog.h>
#include <mrpt/opengl/COpenGLScene.h>
#include <mrpt/opengl/CPointCloud.h>
#include <mrpt/opengl/CPointCloudColoured.h>
#include <mrpt/poses/CPose3DPDFGaussian.h>
#include <mrpt/serialization/CArchive.h>
#include <mrpt/serialization/archiveFrom_std_vector.h>

#include "cleanmap/io/files.h"
#include "cleanmap/io/kitti.h"
#include "cleanmap/io/output.h"
#include "cleanmap/io/ply.h"
#include "cleanmap/mrpt/convert.h"
#include "cleanmap/mrpt/outputs.h"
#include "cleanmap/mrpt/rawlog.h"
#include "cleanmap/pipeline/laser_pipeline.h"
#include "test_data.h"

using namespace cleanmap;
namespace fs = std::filesystem;

namespace {

struct Decided {
  std::size_t index;
  std::string stem;
  Eigen::Isometry3d pose;
  Scan scan;
  Labels labels;
  std::size_t moving = 0;
};

// The first `n` scans of a labelled set through the pipeline, written by MrptOutputWriter.
std::vector<Decided> runAndWrite(const std::string& set, std::size_t n, const fs::path& dir,
                                 const cleanmap::mrpt::MrptOutputOptions& opts) {
  auto seq = io::KittiSequence::open(test::dataDir() + "/" + set);
  std::vector<Decided> out;
  cleanmap::mrpt::MrptOutputWriter w(dir.string(), opts);
  LaserPipeline pl(PipelineParams{}, [&](ScanResult&& r) {
    out.push_back({r.index, r.stem, r.pose, r.scan, r.labels, r.moving.size()});
    w.write(std::move(r));
  });
  pl.keepScans(true);
  for (std::size_t i = 0; i < std::min(n, seq.size()); ++i) pl.push(seq.frame(i));
  pl.finish();
  w.finish();
  return out;
}

// Every observation of a rawlog, in order.
std::vector<::mrpt::obs::CObservation::Ptr> readObservations(const std::string& path) {
  cleanmap::mrpt::registerClasses();
  ::mrpt::io::CFileGZInputStream in(path);
  auto ar = ::mrpt::serialization::archiveFrom(in);
  ::mrpt::obs::CActionCollection::Ptr acts;
  ::mrpt::obs::CSensoryFrame::Ptr sf;
  ::mrpt::obs::CObservation::Ptr obs;
  std::size_t idx = 0;
  std::vector<::mrpt::obs::CObservation::Ptr> all;
  while (::mrpt::obs::CRawlog::getActionObservationPairOrObservation(ar, acts, sf, obs, idx))
    if (obs) all.push_back(obs);
  return all;
}

std::vector<uint8_t> fileBytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

}  // namespace

TEST(MrptOutputs, LabelColoursDecodeToTheirLabels) {
  for (const uint32_t l :
       {uint32_t(kMoving), uint32_t(kStatic), uint32_t(kGround), uint32_t(kUnclassified)}) {
    const auto c = cleanmap::mrpt::labelColour(l);
    EXPECT_EQ(cleanmap::mrpt::labelFromColour(c[0], c[1], c[2]), l);
  }
  EXPECT_EQ(cleanmap::mrpt::labelFromColour(0.3f, 0.3f, 0.3f), uint32_t(kOutlier));
}

// The scene's static cloud is filled in bulk (issue #16): the bytes push_back would give, every
// colour value included; colours that do not match the points are an error.
TEST(MrptOutputs, ColouredCloudInBulkIsTheOnePushBackMakes) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-80.0f, 80.0f);
  std::vector<PointXYZI> pts;
  std::vector<std::array<uint8_t, 3>> rgb;
  for (int i = 0; i < 3 * 256; ++i) {
    pts.push_back({u(rng), u(rng), 0.1f * u(rng), 0.0f});
    const auto v = static_cast<uint8_t>(i % 256);  // every value in each channel
    rgb.push_back({v, static_cast<uint8_t>(255 - v), static_cast<uint8_t>(rng() % 256)});
  }
  auto bulk = ::mrpt::opengl::CPointCloudColoured::Create();
  auto each = ::mrpt::opengl::CPointCloudColoured::Create();
  cleanmap::mrpt::setColouredCloud(*bulk, pts, rgb);
  for (std::size_t i = 0; i < pts.size(); ++i)
    each->push_back(pts[i].x, pts[i].y, pts[i].z, rgb[i][0] / 255.0f, rgb[i][1] / 255.0f,
                    rgb[i][2] / 255.0f);
  std::vector<uint8_t> a, b;
  auto ar_a = ::mrpt::serialization::archiveFrom(a);
  auto ar_b = ::mrpt::serialization::archiveFrom(b);
  ar_a << *bulk;
  ar_b << *each;
  ASSERT_EQ(bulk->size(), pts.size());
  EXPECT_TRUE(a == b) << "the bulk cloud serializes differently from push_back's";
  rgb.pop_back();
  EXPECT_THROW(cleanmap::mrpt::setColouredCloud(*bulk, pts, rgb), std::invalid_argument);
}

TEST(MrptOutputs, ScanWithoutItsPointsIsAClearError) {
  const auto dir = test::scratchDir("not_kept");
  cleanmap::mrpt::MrptOutputOptions opts;
  opts.background = false;
  cleanmap::mrpt::MrptOutputWriter w(dir.string(), opts);
  ScanResult r;
  r.source = "input.rawlog";
  r.stem = "000007";
  r.labels.assign(10, kStatic);
  test::expectError([&] { w.write(std::move(r)); }, "input.rawlog", "000007");
}

// On real scans: the cleaned rawlog holds exactly the scan minus its moving points, the labelled
// rawlog every point with its label's colour, the simplemap the cleaned scans with their poses.
TEST(MrptOutputs, ReadBackWithMrptMatchTheRun) {
  CLEANMAP_REQUIRE_DATASET("kitti_city");
  const auto dir = test::scratchDir("city");
  const auto run = runAndWrite("kitti_city", 12, dir, {});
  ASSERT_EQ(run.size(), 12u);
  std::size_t moving = 0;

  const auto cleaned = readObservations((dir / "cleaned.rawlog").string());
  const auto labelled = readObservations((dir / "labelled.rawlog").string());
  ASSERT_EQ(cleaned.size(), 2 * run.size());
  ASSERT_EQ(labelled.size(), 3 * run.size());
  for (std::size_t k = 0; k < run.size(); ++k) {
    const auto& d = run[k];
    SCOPED_TRACE("scan " + std::to_string(d.index));
    const auto pose = std::dynamic_pointer_cast<::mrpt::obs::CObservationRobotPose>(cleaned[2 * k]);
    ASSERT_TRUE(pose);
    EXPECT_TRUE(cleanmap::mrpt::toIsometry(pose->pose.mean).isApprox(d.pose, 1e-9));
    EXPECT_GT(::mrpt::Clock::toDouble(pose->timestamp), 9e8);  // never 0: MRPT's "no time"

    const auto pc =
        std::dynamic_pointer_cast<::mrpt::obs::CObservationPointCloud>(cleaned[2 * k + 1]);
    ASSERT_TRUE(pc && pc->pointcloud);
    std::vector<PointXYZI> expect;
    for (std::size_t i = 0; i < d.scan.size(); ++i)
      if (d.labels[d.scan.originalIndex(i)] != kMoving) expect.push_back(d.scan.points[i]);
    ASSERT_EQ(pc->pointcloud->size(), expect.size());
    EXPECT_EQ(expect.size() + d.moving, d.scan.size());
    const auto got = cleanmap::mrpt::scanFromObservation(*pc);
    ASSERT_TRUE(got && got->size() == expect.size());
    EXPECT_EQ(0, std::memcmp(got->points.data(), expect.data(), expect.size() * sizeof(PointXYZI)))
        << "cleaned scan differs from the scan minus its moving points";
    moving += d.moving;

    const auto lab =
        std::dynamic_pointer_cast<::mrpt::obs::CObservationPointCloud>(labelled[3 * k + 1]);
    ASSERT_TRUE(lab);
    const auto mov =
        std::dynamic_pointer_cast<::mrpt::obs::CObservationPointCloud>(labelled[3 * k + 2]);
    ASSERT_TRUE(mov && mov->pointcloud);
    EXPECT_EQ(mov->sensorLabel, "LIDAR_MOVING");
    EXPECT_EQ(mov->pointcloud->size(), d.moving);
    const auto* cm = dynamic_cast<const ::mrpt::maps::CColouredPointsMap*>(lab->pointcloud.get());
    ASSERT_TRUE(cm);
    ASSERT_EQ(cm->size(), d.scan.size());
    std::size_t wrong = 0;
    for (std::size_t i = 0; i < cm->size(); ++i) {
      float x, y, z, r, g, b;
      cm->getPointRGB(i, x, y, z, r, g, b);
      wrong += cleanmap::mrpt::labelFromColour(r, g, b) != d.labels[d.scan.originalIndex(i)] ||
               x != d.scan.points[i].x;
    }
    EXPECT_EQ(wrong, 0u) << "labelled points whose colour is not their label";
  }
  EXPECT_GT(moving, 10000u) << "city has moving cars: the test must remove some";

  // The simplemap as MRPT loads it, and its bytes equal to MRPT's serialization of what it loaded.
  ::mrpt::maps::CSimpleMap sm;
  ASSERT_TRUE(sm.loadFromFile((dir / "static_map.simplemap").string()));
  ASSERT_EQ(sm.size(), run.size());
  for (std::size_t k = 0; k < run.size(); ++k) {
    ::mrpt::poses::CPose3DPDF::Ptr pdf;
    ::mrpt::obs::CSensoryFrame::Ptr sf;
    sm.get(k, pdf, sf);
    EXPECT_TRUE(cleanmap::mrpt::toIsometry(pdf->getMeanVal()).isApprox(run[k].pose, 1e-9));
    const auto pc = sf->getObservationByClass<::mrpt::obs::CObservationPointCloud>();
    ASSERT_TRUE(pc && pc->pointcloud);
    EXPECT_EQ(pc->pointcloud->size(), run[k].scan.size() - run[k].moving);
  }
  std::vector<uint8_t> mrpt_bytes;
  auto ar = ::mrpt::serialization::archiveFrom(mrpt_bytes);
  ar << sm;
  EXPECT_TRUE(mrpt_bytes == fileBytes(dir / "static_map.simplemap"))
      << "the streamed simplemap is not MRPT's own serialization";

  // The scene: static map, moving points, trajectory.
  ::mrpt::opengl::COpenGLScene scene;
  ASSERT_TRUE(scene.loadFromFile((dir / "static_map.3Dscene").string()));
  const auto stat =
      std::dynamic_pointer_cast<::mrpt::opengl::CPointCloudColoured>(scene.getByName("static_map"));
  ASSERT_TRUE(stat);
  EXPECT_GT(stat->size(), 20000u);
  const auto mov =
      std::dynamic_pointer_cast<::mrpt::opengl::CPointCloud>(scene.getByName("moving_points"));
  ASSERT_TRUE(mov);
  EXPECT_GT(mov->size(), 1000u);
  EXPECT_LT(mov->size(), moving);  // one point per voxel
  const auto traj =
      std::dynamic_pointer_cast<::mrpt::opengl::CPointCloud>(scene.getByName("trajectory"));
  ASSERT_TRUE(traj);
  EXPECT_GE(traj->size(), run.size());  // every pose, and points between them
  EXPECT_NEAR(traj->getPoint3Df(0).x, run.front().pose.translation().x(), 1e-3);
}

// gzip-compressed outputs (two concatenated members in the simplemap) read back the same.
TEST(MrptOutputs, CompressedOutputsReadBackTheSame) {
  CLEANMAP_REQUIRE_DATASET("kitti_city");
  const auto plain = test::scratchDir("plain");
  const auto gz = test::scratchDir("gz");
  cleanmap::mrpt::MrptOutputOptions o;
  o.scene = false;
  runAndWrite("kitti_city", 3, plain, o);
  o.gzip_level = 1;
  o.background = false;
  runAndWrite("kitti_city", 3, gz, o);
  EXPECT_LT(fs::file_size(gz / "cleaned.rawlog"), fs::file_size(plain / "cleaned.rawlog"));
  ::mrpt::maps::CSimpleMap a, b;
  ASSERT_TRUE(a.loadFromFile((plain / "static_map.simplemap").string()));
  ASSERT_TRUE(b.loadFromFile((gz / "static_map.simplemap").string()));
  std::vector<uint8_t> ba, bb;
  auto aa = ::mrpt::serialization::archiveFrom(ba);
  auto ab = ::mrpt::serialization::archiveFrom(bb);
  aa << a;
  ab << b;
  EXPECT_TRUE(ba == bb);
  EXPECT_EQ(readObservations((gz / "labelled.rawlog").string()).size(), 9u);
  EXPECT_FALSE(fs::exists(gz / "static_map.3Dscene"));
}

// gzip outputs on a disk that fills up, during the writes or in the last flush (8 bytes short of
// the largest file: its gzip trailer, which MRPT's close() and `out << in.rdbuf()` do not
// report): one line naming the folder's file; no temporary left, and the files that are there
// whole (the app's staging folder removes those too).
TEST(MrptOutputs, FullDiskIsAClearErrorAndLeavesNoPartialFile) {
  CLEANMAP_REQUIRE_DATASET("kitti_city");
  const auto dir = test::scratchDir("full");
  cleanmap::mrpt::MrptOutputOptions o;
  o.scene = false;
  o.gzip_level = 1;
  o.background = false;
  runAndWrite("kitti_city", 3, dir, o);
  std::map<std::string, std::uint64_t> whole;
  for (const auto& e : fs::directory_iterator(dir))
    whole[e.path().filename().string()] = e.file_size();
  ASSERT_EQ(whole.size(), 3u);
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::uint64_t smallest = UINTMAX_MAX, largest = 0;
  for (const auto& [name, size] : whole) {
    smallest = std::min(smallest, size);
    largest = std::max(largest, size);
  }
  for (const std::uint64_t limit : {std::uint64_t{64} << 10, smallest - 8, largest - 8}) {
    {
      const test::FileSizeLimit disk(limit);
      test::expectError([&] { runAndWrite("kitti_city", 3, dir, o); }, dir.string(),
                        "write failed (disk full?)");
    }
    for (const auto& e : fs::directory_iterator(dir)) {
      const std::string name = e.path().filename().string();
      ASSERT_TRUE(whole.count(name)) << name << " left with files of at most " << limit << " bytes";
      EXPECT_EQ(e.file_size(), whole[name]) << name << " cut short at " << limit << " bytes";
    }
  }
}

// As the app writes them (map_decisions): cleaned.rawlog, the simplemap and the scene hold what
// the cleaned map holds: every scan minus the points map_labels/ calls moving (the windowed
// test's, those whose space the sequence saw empty, which are map_removed.ply's points, and the
// recording car's own returns).
TEST(MrptOutputs, WithTheMapsDecisionsTheyHoldWhatTheCleanedMapHolds) {
  CLEANMAP_REQUIRE_DATASET("kitti_city");
  const auto dir = test::scratchDir("decided");
  fs::remove_all(dir);
  auto seq = io::KittiSequence::open(test::dataDir() + "/kitti_city");
  const PipelineParams params;
  std::vector<Decided> run;
  std::size_t map_removed = 0, self = 0;
  {
    io::OutputWriter writer(dir.string(), "kitti_city", params);
    cleanmap::mrpt::MrptOutputOptions mo;
    mo.map_decisions = true;
    cleanmap::mrpt::MrptOutputWriter w(writer.staging(), mo);
    LaserPipeline pl(params, [&](ScanResult&& r) {
      run.push_back({r.index, r.stem, r.pose, r.scan, r.labels, r.moving.size()});
      self += r.self_index.size();
      writer.write(r, std::nullopt);
      w.write(std::move(r));
    });
    pl.keepScans(true);
    for (std::size_t i = 0; i < 12; ++i) pl.push(seq.frame(i));  // the car passes at 6-10
    pl.finish();
    writer.writeMaps(pl.freeSpace(), [&](const io::MapScan& m) {
      map_removed += m.removed.size();
      w.writeMapScan(m.index, m.map_labels, m.kept, m.removed);
    });
    w.finish();
    writer.finish(0.0);
  }
  ASSERT_GT(map_removed, 1000u) << "the cleaning must remove points for this test to mean much";
  EXPECT_EQ(io::readPly((dir / "map_removed.ply").string()).size(), map_removed);

  const auto cleaned = readObservations((dir / "cleaned.rawlog").string());
  ASSERT_EQ(cleaned.size(), 2 * run.size());
  ::mrpt::maps::CSimpleMap sm;
  ASSERT_TRUE(sm.loadFromFile((dir / "static_map.simplemap").string()));
  ASSERT_EQ(sm.size(), run.size());
  std::size_t windowed_kept = 0, kept = 0;
  for (std::size_t k = 0; k < run.size(); ++k) {
    const auto& d = run[k];
    SCOPED_TRACE("scan " + d.stem);
    const Labels map_labels = io::readLabels((dir / "map_labels" / (d.stem + ".label")).string());
    std::vector<PointXYZI> expect;
    for (std::size_t i = 0; i < d.scan.size(); ++i)
      if (map_labels.at(d.scan.originalIndex(i)) != kMoving) expect.push_back(d.scan.points[i]);
    windowed_kept += d.scan.size() - d.moving;
    kept += expect.size();
    const auto pc =
        std::dynamic_pointer_cast<::mrpt::obs::CObservationPointCloud>(cleaned[2 * k + 1]);
    ASSERT_TRUE(pc && pc->pointcloud);
    const auto got = cleanmap::mrpt::scanFromObservation(*pc);
    ASSERT_TRUE(got && got->size() == expect.size());
    EXPECT_EQ(0, std::memcmp(got->points.data(), expect.data(), expect.size() * sizeof(PointXYZI)))
        << "cleaned scan differs from the scan minus what the map calls moving";
    ::mrpt::poses::CPose3DPDF::Ptr pdf;
    ::mrpt::obs::CSensoryFrame::Ptr sf;
    sm.get(k, pdf, sf);
    EXPECT_TRUE(cleanmap::mrpt::toIsometry(pdf->getMeanVal()).isApprox(d.pose, 1e-9));
    const auto spc = sf->getObservationByClass<::mrpt::obs::CObservationPointCloud>();
    ASSERT_TRUE(spc && spc->pointcloud);
    EXPECT_EQ(spc->pointcloud->size(), expect.size());
  }
  // And the recording car's own returns (DESIGN §2.2, "Self returns"): its roof, in every scan.
  EXPECT_GT(self, 100u);
  EXPECT_EQ(windowed_kept - kept, map_removed + self)
      << "the cleaned scans lack exactly what the map removed and the car's own returns";

  // The scene's static map: points of static_map_full.ply, none of map_removed.ply.
  auto key = [](const PointXYZI& p) { return std::tuple(p.x, p.y, p.z); };
  std::set<std::tuple<float, float, float>> full, removed;
  for (const auto& p : io::readPly((dir / "static_map_full.ply").string())) full.insert(key(p));
  for (const auto& p : io::readPly((dir / "map_removed.ply").string())) removed.insert(key(p));
  ::mrpt::opengl::COpenGLScene scene;
  ASSERT_TRUE(scene.loadFromFile((dir / "static_map.3Dscene").string()));
  const auto stat =
      std::dynamic_pointer_cast<::mrpt::opengl::CPointCloudColoured>(scene.getByName("static_map"));
  ASSERT_TRUE(stat);
  std::size_t outside = 0, gone = 0;
  for (std::size_t i = 0; i < stat->size(); ++i) {
    const auto p = stat->getPoint3Df(i);
    PointXYZI q;
    q.x = p.x;
    q.y = p.y;
    q.z = p.z;
    outside += !full.count(key(q));
    gone += removed.count(key(q));
  }
  EXPECT_GT(stat->size(), 20000u);
  EXPECT_EQ(outside, 0u) << "scene points that are not in static_map_full.ply";
  EXPECT_EQ(gone, 0u) << "scene points the map removed";
}

// The map's decisions must match the scans written: any other order, a missing decision or a
// decision without map_decisions is a clear error naming the folder.
TEST(MrptOutputs, MapDecisionsOutOfStepAreClearErrors) {
  const auto dir = test::scratchDir("decision_errors");
  auto scan = [](std::size_t index) {
    ScanResult r;
    r.index = index;
    r.stem = "00000" + std::to_string(index);
    r.timestamp = 1.0 + double(index);
    r.scan.points.resize(4);
    for (std::size_t i = 0; i < 4; ++i) r.scan.points[i].x = 1.0f + float(i);
    r.scan.original_size = 4;
    r.labels.assign(4, kStatic);
    return r;
  };
  cleanmap::mrpt::MrptOutputOptions mo;
  mo.background = false;
  {
    cleanmap::mrpt::MrptOutputWriter w(dir.string(), mo);
    test::expectError([&] { w.writeMapScan(0, Labels(4, kStatic), {}, {}); }, dir.string(),
                      "map_decisions");
  }
  mo.map_decisions = true;
  {
    cleanmap::mrpt::MrptOutputWriter w(dir.string(), mo);
    w.write(scan(3));
    test::expectError([&] { w.writeMapScan(4, Labels(4, kStatic), {}, {}); }, dir.string(),
                      "out of order");
  }
  {
    cleanmap::mrpt::MrptOutputWriter w(dir.string(), mo);
    w.write(scan(3));
    w.write(scan(4));
    w.writeMapScan(3, Labels(4, kStatic), {}, {});
    test::expectError([&] { w.finish(); }, dir.string(), "1 of 2 scans were not decided");
  }
  {
    cleanmap::mrpt::MrptOutputWriter w(dir.string(), mo);
    test::expectError([&] { w.writeMapScan(0, Labels(4, kStatic), {}, {}); }, dir.string(),
                      "never written");
  }
  for (const auto& e : fs::directory_iterator(dir))
    EXPECT_EQ(e.path().filename().string().find(".mrpt_spool"), std::string::npos)
        << "a spool was left behind: " << e.path();
}
