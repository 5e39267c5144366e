// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/io/ply.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "cleanmap/core/error.h"
#include "cleanmap/io/binary_field.h"
#include "cleanmap/io/files.h"

namespace cleanmap::io {

namespace {
constexpr std::size_t kXyzi = sizeof(PointXYZI);
std::size_t recordSize(CloudColour c) {
  return kXyzi + (c == CloudColour::kNone ? 0 : 3);
}
}  // namespace

std::array<uint8_t, 3> heightColour(double dz) {
  // Samples of viridis at t = 0, 1/4, 1/2, 3/4, 1, linearly interpolated.
  static constexpr double kRamp[5][3] = {
      {68, 1, 84}, {59, 82, 139}, {33, 145, 140}, {94, 201, 98}, {253, 231, 37}};
  const double t = std::clamp((dz + 2.0) / 5.0, 0.0, 1.0) * 4.0;
  const int k = std::min(3, static_cast<int>(t));
  const double f = t - k;
  std::array<uint8_t, 3> c{};
  for (int j = 0; j < 3; ++j) {
    // lround of a value in [0, 255], without the libm call: half rounds up, as lround's.
    const double v = kRamp[k][j] + f * (kRamp[k + 1][j] - kRamp[k][j]);
    const int i = static_cast<int>(v);
    c[j] = static_cast<uint8_t>(i + (v - i >= 0.5));
  }
  return c;
}

PlyStreamWriter::PlyStreamWriter(const std::string& path, const CloudStreamOptions& opts)
    : path_(path), body_(path + ".body.tmp." + std::to_string(::getpid())), opts_(opts) {
  const auto parent = std::filesystem::path(path).parent_path();
  std::error_code ec;
  if (!parent.empty()) std::filesystem::create_directories(parent, ec);
  f_ = std::fopen(body_.c_str(), "w+b");
  if (!f_) throw Error(path, "cannot open a temporary file for writing");
}

PlyStreamWriter::~PlyStreamWriter() {
  if (f_) {
    std::fclose(f_);
    std::remove(body_.c_str());
  }
}

void PlyStreamWriter::append(const std::vector<PointXYZI>& points, double sensor_z) {
  if (points.empty()) return;
  const std::size_t rs = recordSize(opts_.colour);
  const char* data = reinterpret_cast<const char*>(points.data());
  if (opts_.colour != CloudColour::kNone) {
    rec_.resize(points.size() * rs);
    for (std::size_t i = 0; i < points.size(); ++i) {
      char* r = rec_.data() + i * rs;
      std::memcpy(r, &points[i], kXyzi);
      const auto c = opts_.colour == CloudColour::kRed
                         ? std::array<uint8_t, 3>{255, 0, 0}
                         : heightColour(static_cast<double>(points[i].z) - sensor_z);
      std::memcpy(r + kXyzi, c.data(), 3);
    }
    data = rec_.data();
  }
  if (std::fwrite(data, rs, points.size(), f_) != points.size())
    throw Error(path_, "write failed (disk full?)");
  count_ += points.size();
}

void PlyStreamWriter::close() {
  if (!f_) return;
  std::fflush(f_);
  std::rewind(f_);
  writeFileAtomic(path_, [&](std::ostream& os) {
    os << "ply\nformat binary_little_endian 1.0\ncomment cleanmap\nelement vertex " << count_
       << "\nproperty float x\nproperty float y\nproperty float z\nproperty float intensity\n";
    if (opts_.colour != CloudColour::kNone)
      os << "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    os << "end_header\n";
    std::vector<char> buf(1 << 20);
    std::size_t n;
    while ((n = std::fread(buf.data(), 1, buf.size(), f_)) > 0)
      os.write(buf.data(), static_cast<std::streamsize>(n));
  });
  if (!opts_.pcd_path.empty()) writePcd();
  std::fclose(f_);
  f_ = nullptr;
  std::remove(body_.c_str());
}

// The PCD twin, from the same body: rgb packed into a float as PCL does (0x00RRGGBB).
void PlyStreamWriter::writePcd() {
  const bool rgb = opts_.colour != CloudColour::kNone;
  const std::size_t rs = recordSize(opts_.colour);
  std::rewind(f_);
  writeFileAtomic(opts_.pcd_path, [&](std::ostream& os) {
    os << "# .PCD v0.7 - written by cleanmap\nVERSION 0.7\nFIELDS x y z intensity"
       << (rgb ? " rgb\nSIZE 4 4 4 4 4\nTYPE F F F F F\nCOUNT 1 1 1 1 1"
               : "\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1")
       << "\nWIDTH " << count_ << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << count_
       << "\nDATA binary\n";
    constexpr std::size_t kBatch = 1 << 16;
    std::vector<char> in(kBatch * rs), out(kBatch * (kXyzi + 4));
    std::size_t n;
    while ((n = std::fread(in.data(), rs, kBatch, f_)) > 0) {
      if (!rgb) {
        os.write(in.data(), static_cast<std::streamsize>(n * rs));
        continue;
      }
      for (std::size_t i = 0; i < n; ++i) {
        const auto* r = reinterpret_cast<const unsigned char*>(in.data() + i * rs);
        const uint32_t packed =
            (uint32_t(r[kXyzi]) << 16) | (uint32_t(r[kXyzi + 1]) << 8) | uint32_t(r[kXyzi + 2]);
        std::memcpy(out.data() + i * (kXyzi + 4), r, kXyzi);
        std::memcpy(out.data() + i * (kXyzi + 4) + kXyzi, &packed, 4);
      }
      os.write(out.data(), static_cast<std::streamsize>(n * (kXyzi + 4)));
    }
  });
}

void writePly(const std::string& path, const std::vector<PointXYZI>& points) {
  PlyStreamWriter w(path);
  w.append(points);
  w.close();
}

namespace {

struct PlyProperty {
  std::string name;
  FieldType type = FieldType::kF32;
  bool list = false;
};
struct PlyElement {
  std::string name;
  std::size_t count = 0;
  std::vector<PlyProperty> props;
};
struct PlyHeader {
  enum class Format { kAscii, kLittle, kBig } format = Format::kAscii;
  std::vector<PlyElement> elements;
  std::size_t data_start = 0;  // byte offset of the first element's data
};

PlyHeader readPlyHeader(const std::string& data, const std::string& path) {
  std::istringstream in(data);
  std::string line;
  if (!std::getline(in, line) || line.rfind("ply", 0) != 0) throw Error(path, "not a PLY file");
  PlyHeader h;
  bool have_format = false;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream ls(line);
    std::string w;
    ls >> w;
    if (w == "format") {
      std::string f;
      ls >> f;
      if (f == "ascii")
        h.format = PlyHeader::Format::kAscii;
      else if (f == "binary_little_endian")
        h.format = PlyHeader::Format::kLittle;
      else if (f == "binary_big_endian")
        h.format = PlyHeader::Format::kBig;
      else
        throw Error(path, "unsupported PLY format '" + f + "'");
      have_format = true;
    } else if (w == "element") {
      PlyElement e;
      if (!(ls >> e.name >> e.count))
        throw Error(path, "malformed PLY element line '" + line + "'");
      h.elements.push_back(e);
    } else if (w == "property") {
      if (h.elements.empty()) throw Error(path, "PLY property before any element");
      PlyProperty prop;
      std::string type;
      ls >> type;
      if (type == "list") {
        prop.list = true;
        std::string count_type;
        ls >> count_type >> type;
      }
      const auto t = plyFieldType(type);
      if (!t) throw Error(path, "unsupported PLY property type '" + type + "'");
      prop.type = *t;
      ls >> prop.name;
      h.elements.back().props.push_back(prop);
    } else if (w == "end_header") {
      if (!have_format) throw Error(path, "PLY header has no format line");
      const auto pos = in.tellg();
      h.data_start = pos < 0 ? data.size() : static_cast<std::size_t>(pos);
      return h;
    }
  }
  throw Error(path, "PLY header has no end_header");
}

}  // namespace

std::vector<PointXYZI> readPly(const std::string& path) {
  const std::string data = readTextFile(path);
  const PlyHeader h = readPlyHeader(data, path);
  // Elements before "vertex" are skipped: whole lines in ASCII, fixed-size records in binary.
  std::size_t skip_records = 0, skip_bytes = 0;
  const PlyElement* vertex = nullptr;
  for (const auto& e : h.elements) {
    if (e.name == "vertex") {
      vertex = &e;
      break;
    }
    // Every record takes at least a byte: a count beyond the file's size is a lie (and would
    // overflow the sums below).
    if (e.count > data.size())
      throw Error(path, "PLY element '" + e.name + "' claims " + std::to_string(e.count) +
                            " records, more than the file's bytes");
    skip_records += e.count;
    for (const auto& prop : e.props) {
      if (prop.list && h.format != PlyHeader::Format::kAscii)
        throw Error(path, "PLY element '" + e.name + "' before the vertices has list properties");
      skip_bytes += e.count * fieldSize(prop.type);
    }
  }
  if (!vertex) throw Error(path, "PLY has no vertex element");
  int ix = -1, iy = -1, iz = -1, ii = -1;
  std::vector<std::size_t> off;  // byte offset of each property within a binary record
  std::size_t stride = 0;
  for (std::size_t k = 0; k < vertex->props.size(); ++k) {
    const auto& prop = vertex->props[k];
    if (prop.list) throw Error(path, "PLY vertex property '" + prop.name + "' is a list");
    const int idx = static_cast<int>(k);
    if (prop.name == "x") ix = idx;
    if (prop.name == "y") iy = idx;
    if (prop.name == "z") iz = idx;
    if (prop.name == "intensity") ii = idx;
    off.push_back(stride);
    stride += fieldSize(prop.type);
  }
  if (ix < 0 || iy < 0 || iz < 0) throw Error(path, "PLY vertices lack x, y or z");
  const std::size_t n = vertex->count;
  const std::size_t body = data.size() - h.data_start;
  // Check the count against the file size before allocating anything.
  const std::size_t min_bytes =
      h.format == PlyHeader::Format::kAscii ? 2 * vertex->props.size() : stride;
  if (n > 0 && (body < skip_bytes || (body - skip_bytes) / min_bytes < n))
    throw Error(path, "truncated PLY: header promises " + std::to_string(n) +
                          " vertices, the file is too short");
  std::vector<PointXYZI> pts(n);
  if (h.format == PlyHeader::Format::kAscii) {
    std::istringstream in(data.substr(h.data_start));
    std::string line;
    for (std::size_t k = 0; k < skip_records; ++k) std::getline(in, line);
    std::vector<double> v(vertex->props.size());
    for (std::size_t k = 0; k < n; ++k) {
      for (auto& x : v)
        if (!(in >> x))
          throw Error(path, "truncated PLY: " + std::to_string(k) + " of " + std::to_string(n) +
                                " vertices");
      pts[k] = {float(v[std::size_t(ix)]), float(v[std::size_t(iy)]), float(v[std::size_t(iz)]),
                ii >= 0 ? float(v[std::size_t(ii)]) : 0.f};
    }
    return pts;
  }
  const bool big = h.format == PlyHeader::Format::kBig;
  const char* base = data.data() + h.data_start + skip_bytes;
  auto get = [&](std::size_t k, int prop) {
    const auto q = static_cast<std::size_t>(prop);
    return static_cast<float>(decodeField(base + k * stride + off[q], vertex->props[q].type, big));
  };
  for (std::size_t k = 0; k < n; ++k)
    pts[k] = {get(k, ix), get(k, iy), get(k, iz), ii >= 0 ? get(k, ii) : 0.f};
  return pts;
}

}  // namespace cleanmap::io
