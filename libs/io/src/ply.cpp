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
#include "cleanmap/io/direct_file.h"
#include "cleanmap/io/files.h"

namespace cleanmap::io {

namespace {
constexpr std::size_t kXyzi = sizeof(PointXYZI);
std::size_t recordSize(CloudColour c) {
  return kXyzi + (c == CloudColour::kNone ? 0 : 3);
}
}  // namespace

namespace {
// The headers are written first with room for any count and rewritten by close() at the same
// length: a comment line takes up the difference, so no reader sees padding in a value.
constexpr std::size_t kCountRoom = 20;  // digits of the largest uint64

std::string plyHeader(CloudColour colour, std::size_t count, std::size_t length) {
  std::string tail = "\nelement vertex " + std::to_string(count) +
                     "\nproperty float x\nproperty float y\nproperty float z\nproperty float "
                     "intensity\n";
  if (colour != CloudColour::kNone)
    tail += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  tail += "end_header\n";
  std::string head = "ply\nformat binary_little_endian 1.0\ncomment cleanmap";
  if (length > head.size() + tail.size()) head.append(length - head.size() - tail.size(), ' ');
  return head + tail;
}

std::string pcdHeader(bool rgb, std::size_t count, std::size_t length) {
  const std::string n = std::to_string(count);
  std::string head = "# .PCD v0.7 - written by cleanmap";
  const std::string tail = "\nVERSION 0.7\nFIELDS x y z intensity" +
                           std::string(rgb ? " rgb\nSIZE 4 4 4 4 4\nTYPE F F F F F\nCOUNT 1 1 1 1 1"
                                           : "\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1") +
                           "\nWIDTH " + n + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + n +
                           "\nDATA binary\n";
  if (length > head.size() + tail.size()) head.append(length - head.size() - tail.size(), ' ');
  return head + tail;
}

std::string temporaryOf(const std::string& path) {
  return path + ".tmp." + std::to_string(::getpid());
}
}  // namespace

// Both files are written where they end up (under a temporary name), the points once: no body
// written, read back and copied (issue #16).
PlyStreamWriter::PlyStreamWriter(const std::string& path, const CloudStreamOptions& opts)
    : path_(path), opts_(opts) {
  const auto parent = std::filesystem::path(path).parent_path();
  std::error_code ec;
  if (!parent.empty()) std::filesystem::create_directories(parent, ec);
  const bool rgb = opts_.colour != CloudColour::kNone;
  ply_head_ = plyHeader(opts_.colour, 0, 0).size() + kCountRoom;
  ply_ = std::make_unique<DirectFile>(temporaryOf(path_));
  const std::string h = plyHeader(opts_.colour, 0, ply_head_);
  ply_->write(h.data(), h.size());
  if (!opts_.pcd_path.empty()) {
    pcd_head_ = pcdHeader(rgb, 0, 0).size() + 2 * kCountRoom;
    pcd_ = std::make_unique<DirectFile>(temporaryOf(opts_.pcd_path));
    const std::string p = pcdHeader(rgb, 0, pcd_head_);
    pcd_->write(p.data(), p.size());
  }
}

PlyStreamWriter::~PlyStreamWriter() {
  for (auto* f : {&ply_, &pcd_})
    if (*f) {
      const std::string tmp = (*f)->path();
      f->reset();
      std::remove(tmp.c_str());
    }
}

void PlyStreamWriter::append(const std::vector<PointXYZI>& points, double sensor_z) {
  if (points.empty()) return;
  if (!ply_) throw Error(path_, "append after close");
  const std::size_t rs = recordSize(opts_.colour);
  const char* data = reinterpret_cast<const char*>(points.data());
  if (opts_.colour != CloudColour::kNone) {
    rec_.resize(points.size() * rs);
    if (pcd_) pcd_rec_.resize(points.size() * (kXyzi + 4));
    for (std::size_t i = 0; i < points.size(); ++i) {
      char* r = rec_.data() + i * rs;
      std::memcpy(r, &points[i], kXyzi);
      const auto c = opts_.colour == CloudColour::kRed
                         ? std::array<uint8_t, 3>{255, 0, 0}
                         : heightColour(static_cast<double>(points[i].z) - sensor_z);
      std::memcpy(r + kXyzi, c.data(), 3);
      if (pcd_) {  // PCL's packed rgb: 0x00RRGGBB in the bytes of a float
        const uint32_t packed = (uint32_t(c[0]) << 16) | (uint32_t(c[1]) << 8) | uint32_t(c[2]);
        char* q = pcd_rec_.data() + i * (kXyzi + 4);
        std::memcpy(q, &points[i], kXyzi);
        std::memcpy(q + kXyzi, &packed, 4);
      }
    }
    data = rec_.data();
  }
  ply_->write(data, points.size() * rs);
  if (pcd_) {
    if (opts_.colour != CloudColour::kNone)
      pcd_->write(pcd_rec_.data(), pcd_rec_.size());
    else
      pcd_->write(points.data(), points.size() * kXyzi);
  }
  count_ += points.size();
}

void PlyStreamWriter::close() {
  if (!ply_) return;
  const std::string h = plyHeader(opts_.colour, count_, ply_head_);
  ply_->patchHead(0, h.data(), h.size());
  ply_->close();
  if (pcd_) {
    const std::string p = pcdHeader(opts_.colour != CloudColour::kNone, count_, pcd_head_);
    pcd_->patchHead(0, p.data(), p.size());
    pcd_->close();
  }
  for (auto [f, path] : {std::pair{&ply_, path_}, std::pair{&pcd_, opts_.pcd_path}}) {
    if (!*f) continue;
    std::error_code ec;
    std::filesystem::rename((*f)->path(), path, ec);
    if (ec) throw Error(path, "cannot move the finished file into place: " + ec.message());
    f->reset();
  }
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
