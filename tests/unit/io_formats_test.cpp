// SPDX-License-Identifier: BSD-3-Clause
// PLY maps and ini parameters: round trips and clear errors.
#include <gtest/gtest.h>

#include <fstream>

#include "cleanmap/io/config.h"
#include "cleanmap/io/files.h"
#include "cleanmap/io/ply.h"
#include "test_data.h"

using namespace cleanmap;

TEST(Ply, BinaryRoundTripIsExact) {
  const auto dir = test::scratchDir("ply");
  std::vector<PointXYZI> pts = {{1.5f, -2.f, 3.25f, 0.5f}, {1e6f, -1e-6f, 0.f, 1.f}};
  io::writePly((dir / "m.ply").string(), pts);
  const auto back = io::readPly((dir / "m.ply").string());
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(0, std::memcmp(back.data(), pts.data(), sizeof(PointXYZI) * 2));
}

TEST(Ply, StreamedMapAndForeignAsciiPly) {
  const auto dir = test::scratchDir("ply_stream");
  {
    io::PlyStreamWriter w((dir / "s.ply").string());
    for (int k = 0; k < 3; ++k) w.append({{float(k), 0, 0, 0}, {0, float(k), 0, 0}});
    w.close();
  }
  EXPECT_EQ(io::readPly((dir / "s.ply").string()).size(), 6u);
  {
    io::PlyStreamWriter w((dir / "gone.ply").string());
    w.append({{1, 2, 3, 4}});
  }  // not closed: nothing left behind
  EXPECT_FALSE(std::filesystem::exists(dir / "gone.ply"));
  std::size_t files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) files += e.is_regular_file();
  EXPECT_EQ(files, 1u);
  std::ofstream(dir / "a.ply") << "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
                                  "property float y\nproperty float z\nend_header\n1 2 3\n4 5 6\n";
  const auto a = io::readPly((dir / "a.ply").string());
  ASSERT_EQ(a.size(), 2u);
  EXPECT_FLOAT_EQ(a[1].z, 6.f);
  std::ofstream(dir / "t.ply") << "ply\nformat binary_little_endian 1.0\nelement vertex 5\n"
                                  "property float x\nproperty float y\nproperty float z\nend_header\n";
  test::expectError([&] { io::readPly((dir / "t.ply").string()); }, "t.ply", "truncated PLY");
}

TEST(Config, IniRoundTripRestoresEveryParameter) {
  PipelineParams p;
  p.ds.lambda_theta = 0.0071;
  p.filter.crop_tau = 45;
  p.seed = 123456789;
  p.ground.point_refine = false;
  PipelineParams q;
  io::parseParams(io::toIni(p), "roundtrip", q);
  EXPECT_EQ(io::toIni(q), io::toIni(p));
  EXPECT_DOUBLE_EQ(q.ds.lambda_theta, 0.0071);
  EXPECT_EQ(q.seed, 123456789u);
  EXPECT_FALSE(q.ground.point_refine);
}

TEST(Config, ShippedIniHoldsTheDefaults) {
  PipelineParams p;
  io::loadParams(CLEANMAP_SOURCE_DIR "/config/cleanmap.ini", p);
  EXPECT_EQ(io::toIni(p), io::toIni(PipelineParams{}));
}

TEST(Config, BadIniIsAClearError) {
  PipelineParams p;
  test::expectError([&] { io::parseParams("[ds]\nlamda_theta = 0.004\n", "x.ini", p); },
                    "x.ini:2", "unknown key 'lamda_theta' in [ds]");
  test::expectError([&] { io::parseParams("[dss]\n", "x.ini", p); }, "x.ini:1",
                    "unknown section [dss]");
  test::expectError([&] { io::parseParams("[ds]\nsigma_r = fast\n", "x.ini", p); }, "x.ini:2",
                    "needs a number");
  test::expectError([&] { io::parseParams("[ds]\nwindow_k = 2.5\n", "x.ini", p); }, "x.ini:2",
                    "needs an integer");
  test::expectError([&] { io::parseParams("[ds]\nr_sup = 0.5\n", "x.ini", p); }, "x.ini",
                    "r_inf <= ds.r_sup");
  test::expectError([] { PipelineParams q; io::parseParams("[ds]\nscan_conflict = 0\n", "x.ini", q); }, "x.ini",
                    "ds.scan_conflict must be in (0, 1]");
  test::expectError([&] { io::loadParams("/nonexistent.ini", p); }, "/nonexistent.ini",
                    "does not exist");
}
