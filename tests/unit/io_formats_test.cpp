// SPDX-License-Identifier: BSD-3-Clause
// PLY maps, the binary field decoder and ini parameters: round trips and clear errors.
#include <gtest/gtest.h>

#include <array>

#include <cstring>
#include <fstream>
#include <set>

#include "cleanmap/io/binary_field.h"
#include "cleanmap/io/config.h"
#include "cleanmap/io/files.h"
#include "cleanmap/io/ini.h"
#include "cleanmap/io/pcd.h"
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

// The coloured maps: PLY with uchar red/green/blue after the floats, PCD with a packed `rgb`;
// both read back to the same points, and the colours are where the header says.
TEST(Ply, ColouredMapAndItsPcdTwin) {
  const auto dir = test::scratchDir("ply_rgb");
  const std::vector<PointXYZI> pts{{1, 2, -1.5f, 0.25f}, {3, 4, 3.5f, 0.5f}};
  {
    io::PlyStreamWriter w(
        (dir / "m.ply").string(),
        io::CloudStreamOptions{io::CloudColour::kHeight, (dir / "m.pcd").string()});
    w.append(pts, /*sensor_z=*/0.5);
    w.close();
  }
  for (const char* f : {"m.ply", "m.pcd"}) {
    const auto back = io::readCloud((dir / f).string());
    ASSERT_EQ(back.size(), 2u) << f;
    EXPECT_EQ(0, std::memcmp(back.data(), pts.data(), sizeof(PointXYZI) * 2)) << f;
  }
  std::ifstream in(dir / "m.ply", std::ios::binary);
  const std::string data((std::istreambuf_iterator<char>(in)), {});
  ASSERT_NE(data.find("property uchar red"), std::string::npos);
  const std::size_t body = data.find("end_header\n") + 11;
  ASSERT_EQ(data.size(), body + 2 * 19);
  const auto rgb = [&](int i) {
    const auto* p = reinterpret_cast<const unsigned char*>(data.data() + body + i * 19 + 16);
    return std::array<uint8_t, 3>{p[0], p[1], p[2]};
  };
  EXPECT_EQ(rgb(0), io::heightColour(-2.0));  // 2 m below the sensor: the bottom of the ramp
  EXPECT_EQ(rgb(1), io::heightColour(3.0));   // 3 m above: the top
  EXPECT_NE(rgb(0), rgb(1));
  EXPECT_EQ(io::heightColour(-9.0), io::heightColour(-2.0));  // clamped
  for (double dz = -2; dz <= 3; dz += 0.25)
    EXPECT_LT(io::heightColour(dz)[0], 254) << dz;  // no red
  // The ramp's rounding is lround's, on a fine sweep.
  const double ramp[5][3] = {
      {68, 1, 84}, {59, 82, 139}, {33, 145, 140}, {94, 201, 98}, {253, 231, 37}};
  for (int i = 0; i <= 500000; ++i) {
    const double dz = -2.5 + 6.0 * i / 500000;
    const double t = std::clamp((dz + 2.0) / 5.0, 0.0, 1.0) * 4.0;
    const int k = std::min(3, static_cast<int>(t));
    for (int j = 0; j < 3; ++j)
      ASSERT_EQ(io::heightColour(dz)[static_cast<std::size_t>(j)],
                std::lround(ramp[k][j] + (t - k) * (ramp[k + 1][j] - ramp[k][j])))
          << dz;
  }
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
  std::ofstream(dir / "t.ply")
      << "ply\nformat binary_little_endian 1.0\nelement vertex 5\n"
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

// Issue #15: [sensor] height is metres above the ground or auto; the old key names the new one.
TEST(Config, SensorHeightAndModel) {
  PipelineParams p;
  EXPECT_EQ(p.sensor.height, 0.0);  // auto
  EXPECT_NE(io::toIni(p).find("[sensor]\ndeskew = auto\nheight = auto\n"), std::string::npos);
  io::parseParams("[sensor]\nheight = 2.2\n", "x.ini", p);
  EXPECT_DOUBLE_EQ(p.sensor.height, 2.2);
  PipelineParams q;
  io::parseParams(io::toIni(p), "roundtrip", q);
  EXPECT_DOUBLE_EQ(q.sensor.height, 2.2);
  io::parseParams("[sensor]\nheight = auto\n", "x.ini", q);
  EXPECT_EQ(q.sensor.height, 0.0);
  test::expectError([&] { io::parseParams("[sensor]\nheight = tall\n", "x.ini", p); }, "x.ini:2",
                    "'height' needs a number or auto, got 'tall'");
  test::expectError(
      [] {
        PipelineParams r;
        io::parseParams("[sensor]\nheight = -1.73\n", "x.ini", r);
      },
      "x.ini", "sensor.height must be auto or in [0.1, 10] m above the ground");
  io::parseParams("[sensor]\nmodel = vlp16\n", "x.ini", q);
  EXPECT_EQ(q.sensor.model, SensorModel::kVlp16);
  EXPECT_NE(io::toIni(q).find("model = vlp16\n"), std::string::npos);
  test::expectError([&] { io::parseParams("[sensor]\nmodel = vlp-16\n", "x.ini", p); }, "x.ini:2",
                    "needs one of auto, hdl64, hdl32, vlp16, os1-64, os1-128; got 'vlp-16'");
  // DESIGN §2.0: the de-skew is auto, 0 or 1.
  io::parseParams("[sensor]\ndeskew = 1\n", "x.ini", q);
  EXPECT_EQ(q.sensor.deskew, DeskewMode::kOn);
  EXPECT_NE(io::toIni(q).find("deskew = 1\n"), std::string::npos);
  io::parseParams("[sensor]\ndeskew = 0\n", "x.ini", q);
  EXPECT_EQ(q.sensor.deskew, DeskewMode::kOff);
  test::expectError([&] { io::parseParams("[sensor]\ndeskew = yes\n", "x.ini", p); }, "x.ini:2",
                    "'deskew' needs one of auto, 0, 1; got 'yes'");
  test::expectError([&] { io::parseParams("[ground]\nsensor_height = -1.73\n", "x.ini", p); },
                    "x.ini:2", "'sensor_height' in [ground] is now [sensor] height");
  test::expectError([&] { io::setParam(p, "ground.sensor_height", "-1.73", "[s]"); }, "[s]",
                    "'ground.sensor_height' is now [sensor] height");
}

// (config/cleanmap.ini is an MRPT map file now: tests/unit/maps_test.cpp checks it.)
TEST(Config, SetParamByKeyAndListValues) {
  PipelineParams p;
  io::setParam(p, "ds.window_k", " 4 ", "[s]");
  EXPECT_EQ(p.ds.window_k, 4);
  test::expectError([&] { io::setParam(p, "ds.window", "4", "[s]"); }, "[s]",
                    "unknown key 'ds.window'");
  test::expectError([&] { io::setParam(p, "ds.window_k", "4.5", "[s]"); }, "[s]",
                    "'ds.window_k' needs an integer or auto, got '4.5'");
  const auto values = io::paramValues(p);
  ASSERT_EQ(values.size(), io::paramKeys().size());
  bool found = false;
  for (const auto& [k, v] : values) found = found || (k == "ds.window_k" && v == "4");
  EXPECT_TRUE(found);
}

TEST(Config, BadIniIsAClearError) {
  PipelineParams p;
  test::expectError([&] { io::parseParams("[ds]\nlamda_theta = 0.004\n", "x.ini", p); }, "x.ini:2",
                    "unknown key 'lamda_theta' in [ds]");
  test::expectError([&] { io::parseParams("[dss]\n", "x.ini", p); }, "x.ini:1",
                    "unknown section [dss]");
  test::expectError([&] { io::parseParams("[ds]\nsigma_r = fast\n", "x.ini", p); }, "x.ini:2",
                    "needs a number");
  test::expectError([&] { io::parseParams("[ds]\nwindow_k = 2.5\n", "x.ini", p); }, "x.ini:2",
                    "needs an integer");
  test::expectError([&] { io::parseParams("[ds]\nr_sup = 0.5\n", "x.ini", p); }, "x.ini",
                    "r_inf <= ds.r_sup");
  // Found by fuzz_params_ini (corpus finding_negative_seed): a negative seed was cast to uint64.
  test::expectError([&] { io::parseParams("[run]\nseed = -2\n", "x.ini", p); }, "x.ini:2",
                    "needs a non-negative integer, got '-2'");
  test::expectError(
      [] {
        PipelineParams q;
        io::parseParams("[ds]\nscan_conflict = 0\n", "x.ini", q);
      },
      "x.ini", "ds.scan_conflict must be in (0, 1]");
  for (const char* bad : {"-0.1", "1.5"})
    test::expectError(
        [&] {
          PipelineParams q;
          io::parseParams(std::string("[ds]\nempty_run = ") + bad + "\n", "x.ini", q);
        },
        "x.ini", "ds.empty_run must be in [0, 1] (0 = off)");
  for (const char* bad : {"-1", "11"})  // DESIGN §2.2, self returns
    test::expectError(
        [&] {
          PipelineParams q;
          io::parseParams(std::string("[filter]\nself_range = ") + bad + "\n", "x.ini", q);
        },
        "x.ini", "filter.self_range must be in [0, 10] m (0 = off)");
  for (const char* bad : {"-0.05", "2"})  // doc/OBJECTS.md rule 1, "Beside a wall"
    test::expectError(
        [&] {
          PipelineParams q;
          io::parseParams(std::string("[object]\nwall_gap = ") + bad + "\n", "x.ini", q);
        },
        "x.ini", "object.wall_gap must be in [0, 1] m (0 = off)");
  {  // read as written; 0 turns it off
    PipelineParams q;
    EXPECT_EQ(q.object.wall_gap, 0.15);
    io::parseParams("[object]\nwall_gap = 0\n", "x.ini", q);
    EXPECT_EQ(q.object.wall_gap, 0.0);
  }
  {  // 0 turns the self returns off
    PipelineParams q;
    io::parseParams("[filter]\nself_range = 0\n", "x.ini", q);
    EXPECT_EQ(q.filter.self_range, 0.0);
  }
  {  // 0 turns the empty runs off (DESIGN §2b)
    PipelineParams q;
    io::parseParams("[ds]\nempty_run = 0\n", "x.ini", q);
    EXPECT_EQ(q.ds.empty_run, 0.0);
  }
  test::expectError(
      [] {
        PipelineParams q;
        io::parseParams("[image]\nalign_small_shift = 0\n", "x.ini", q);
      },
      "x.ini", "image.align_small_shift must be in (0, 5] m");
  {  // an ini of before the thirty-sixth session: a bound below align_small_shift still loads
    PipelineParams q;
    io::parseParams("[image]\nalign_max_shift = 0.1\n", "x.ini", q);
    EXPECT_EQ(q.image.align_max_shift, 0.1);
  }
  test::expectError([&] { io::loadParams("/nonexistent.ini", p); }, "/nonexistent.ini",
                    "does not exist");
}

namespace {

// Appends `v` as the bytes of type T, little- or big-endian.
template <class T>
void put(std::string& out, double v, bool big) {
  const T x = static_cast<T>(v);
  char b[sizeof(T)];
  std::memcpy(b, &x, sizeof(T));
  if (big) std::reverse(b, b + sizeof(T));
  out.append(b, sizeof(T));
}

void putTyped(std::string& out, const std::string& type, double v, bool big) {
  if (type == "char" || type == "int8")
    put<int8_t>(out, v, big);
  else if (type == "uchar" || type == "uint8")
    put<uint8_t>(out, v, big);
  else if (type == "short" || type == "int16")
    put<int16_t>(out, v, big);
  else if (type == "ushort" || type == "uint16")
    put<uint16_t>(out, v, big);
  else if (type == "int" || type == "int32")
    put<int32_t>(out, v, big);
  else if (type == "uint" || type == "uint32")
    put<uint32_t>(out, v, big);
  else if (type == "float" || type == "float32")
    put<float>(out, v, big);
  else
    put<double>(out, v, big);
}

}  // namespace

// Every PLY scalar type, as coordinates and as intensity, in the three formats: the values come
// back exactly (they are small integers, representable in every type), and a record narrower than
// 4 bytes is never read past (ASan checks the last vertex).
TEST(Ply, EveryPropertyTypeInEveryFormat) {
  const auto dir = test::scratchDir("ply_types");
  const std::vector<std::string> types = {"char",  "uchar",  "short",   "ushort", "int",   "uint",
                                          "float", "double", "int8",    "uint8",  "int16", "uint16",
                                          "int32", "uint32", "float32", "float64"};
  for (const auto& type : types)
    for (const std::string format : {"ascii", "binary_little_endian", "binary_big_endian"}) {
      const bool big = format == "binary_big_endian";
      const bool is_signed = type.find('u') != 0;  // uchar, ushort, uint, uint8...
      const std::vector<std::array<double, 4>> v = {{1, 2, 3, 100},
                                                    {is_signed ? -7.0 : 7.0, 5, 6, 120}};
      std::string text = "ply\nformat " + format + " 1.0\ncomment t\nelement vertex 2\n";
      for (const char* n : {"x", "y", "z", "intensity"})
        text += "property " + type + " " + n + "\n";
      text += "end_header\n";
      for (const auto& r : v)
        for (std::size_t k = 0; k < 4; ++k) {
          if (format == "ascii")
            text += std::to_string(int(r[k])) + (k == 3 ? "\n" : " ");
          else
            putTyped(text, type, r[k], big);
        }
      const auto path = (dir / (type + "_" + format + ".ply")).string();
      test::writeText(path, text);
      const auto pts = io::readPly(path);
      ASSERT_EQ(pts.size(), 2u) << path;
      for (std::size_t i = 0; i < 2; ++i) {
        EXPECT_EQ(pts[i].x, float(v[i][0])) << path;
        EXPECT_EQ(pts[i].y, float(v[i][1])) << path;
        EXPECT_EQ(pts[i].z, float(v[i][2])) << path;
        EXPECT_EQ(pts[i].intensity, float(v[i][3])) << path;  // a uchar 120 is 120, not 1.7e-43
      }
    }
}

TEST(Ply, SkipsElementsBeforeVerticesAndRefusesAbsurdHeaders) {
  const auto dir = test::scratchDir("ply_elements");
  std::string b =
      "ply\nformat binary_little_endian 1.0\nelement camera 1\nproperty float fx\nproperty uchar "
      "id\n"
      "element vertex 1\nproperty double x\nproperty double y\nproperty double z\nproperty uchar "
      "intensity\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  putTyped(b, "float", 700.0, false);
  putTyped(b, "uchar", 3, false);
  for (double x : {1.25, -2.5, 3.75}) putTyped(b, "double", x, false);
  putTyped(b, "uchar", 200, false);
  test::writeText(dir / "e.ply", b);
  const auto pts = io::readPly((dir / "e.ply").string());
  ASSERT_EQ(pts.size(), 1u);
  EXPECT_EQ(pts[0].x, 1.25f);
  EXPECT_EQ(pts[0].z, 3.75f);
  EXPECT_EQ(pts[0].intensity, 200.f);
  // A header promising 10^12 vertices: one clear error, no allocation attempt.
  test::writeText(dir / "huge.ply",
                  "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\n"
                  "property float x\nproperty float y\nproperty float z\nend_header\n0000");
  test::expectError([&] { io::readPly((dir / "huge.ply").string()); }, "huge.ply",
                    "promises 1000000000000 vertices");
  test::writeText(dir / "list.ply",
                  "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n"
                  "property float y\nproperty list uchar float z\nend_header\n");
  test::expectError([&] { io::readPly((dir / "list.ply").string()); }, "list.ply", "is a list");
  test::writeText(dir / "type.ply",
                  "ply\nformat ascii 1.0\nelement vertex 1\nproperty half x\nend_header\n");
  test::expectError([&] { io::readPly((dir / "type.ply").string()); }, "type.ply",
                    "unsupported PLY property type 'half'");
  test::writeText(dir / "nohdr.ply", "ply\nformat ascii 1.0\nelement vertex 1\n");
  test::expectError([&] { io::readPly((dir / "nohdr.ply").string()); }, "nohdr.ply",
                    "no end_header");
}

TEST(BinaryField, DecodesEveryTypeBothEndians) {
  EXPECT_EQ(io::fieldSize(*io::plyFieldType("ushort")), 2u);
  EXPECT_EQ(io::pcdFieldType('F', 2), std::nullopt);
  EXPECT_EQ(io::pcdFieldType('X', 4), std::nullopt);
  EXPECT_EQ(*io::pcdFieldType('U', 1), io::FieldType::kU8);
  EXPECT_EQ(*io::pcdFieldType('I', 8), io::FieldType::kI64);
  for (bool big : {false, true}) {
    std::string b;
    putTyped(b, "int16", -1234, big);
    EXPECT_EQ(io::decodeField(b.data(), io::FieldType::kI16, big), -1234.0);
    b.clear();
    putTyped(b, "double", 0.1, big);
    EXPECT_EQ(io::decodeField(b.data(), io::FieldType::kF64, big), 0.1);
    b.clear();
    put<uint64_t>(b, 1ull << 40, big);
    EXPECT_EQ(io::decodeField(b.data(), io::FieldType::kU64, big), double(1ull << 40));
  }
}

TEST(Ini, CommentsSectionsAndRepeatedKeys) {
  std::vector<std::string> seen;
  io::IniHandlers on;
  on.section = [&](const std::string& s, int) { seen.push_back("[" + s + "]"); };
  on.entry = [&](const io::IniLine& e) {
    seen.push_back(e.section + "." + e.key + "=" + e.value + "@" + std::to_string(e.line));
  };
  io::parseIni("# top\n[a]  ; note\nk = 1 2; 3 # tail\n\n[b]\nk = x#y\n[a]\nk = again\n", "t.ini",
               on);
  const std::vector<std::string> want = {"[a]",       "a.k=1 2; 3@3", "[b]",
                                         "b.k=x#y@6", "[a]",          "a.k=again@8"};
  EXPECT_EQ(seen, want);
  test::expectError([&] { io::parseIni("[a]\nk = 1\nk = 2\n", "t.ini", on); }, "t.ini:3",
                    "'k' given twice in [a]");
  test::expectError([&] { io::parseIni("k = 1\n", "t.ini", on); }, "t.ini:1",
                    "outside any section");
  test::expectError([&] { io::parseIni("[a]\nk =\n", "t.ini", on); }, "t.ini:2", "empty value");
  test::expectError([&] { io::parseIni("[a\n", "t.ini", on); }, "t.ini:1",
                    "malformed section header");
  test::expectError([&] { io::parseIni("[a]\njust text\n", "t.ini", on); }, "t.ini:2",
                    "expected 'key = value'");
}

TEST(Config, RepeatedKeysAndEmptyWindowAreErrors) {
  PipelineParams p;
  test::expectError([&] { io::parseParams("[ds]\nsigma_r = 0.2\nsigma_r = 0.3\n", "x.ini", p); },
                    "x.ini:3", "'sigma_r' given twice in [ds]");
  test::expectError(
      [&] {
        io::parseParams("[ds]\nsigma_r = 0.2\n[filter]\ncrop_tau = 20\n[ds]\nsigma_r = 0.3\n",
                        "x.ini", p);
      },
      "x.ini:6", "'sigma_r' given twice in [ds]");
  test::expectError([&] { io::parseParams("[ds]\nwindow_k = 0\n", "x.ini", p); }, "x.ini:2",
                    "'window_k' needs auto or an integer >= 1, got '0'");
  test::expectError([&] { io::parseParams("[ds]\nwindow_k = 51\n", "x.ini", p); }, "x.ini",
                    "ds.window_k must be auto or in [1, 50] scans");
}

TEST(Config, PrintsTheShortestExactForm) {
  EXPECT_EQ(io::shortestDouble(0.15), "0.15");
  EXPECT_EQ(io::shortestDouble(30), "30");
  EXPECT_EQ(io::shortestDouble(-1.73), "-1.73");
  EXPECT_EQ(io::shortestDouble(1.0 / 6.0), "0.16666666666666666");
  EXPECT_NE(io::toIni(PipelineParams{}).find("sigma_r = 0.15\n"), std::string::npos);
  for (double v : {0.1, 1.0 / 3.0, 6.02e23, 2.2250738585072014e-308, 0.0035})
    EXPECT_EQ(std::stod(io::shortestDouble(v)), v);
}
