// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/io/ply.h"

#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "cleanmap/core/error.h"
#include "cleanmap/io/files.h"

namespace cleanmap::io {

PlyStreamWriter::PlyStreamWriter(const std::string& path)
    : path_(path), body_(path + ".body.tmp." + std::to_string(::getpid())) {
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

void PlyStreamWriter::append(const std::vector<PointXYZI>& points) {
  if (points.empty()) return;
  if (std::fwrite(points.data(), sizeof(PointXYZI), points.size(), f_) != points.size())
    throw Error(path_, "write failed (disk full?)");
  count_ += points.size();
}

void PlyStreamWriter::close() {
  if (!f_) return;
  std::fflush(f_);
  std::rewind(f_);
  writeFileAtomic(path_, [&](std::ostream& os) {
    os << "ply\nformat binary_little_endian 1.0\ncomment cleanmap\nelement vertex " << count_
       << "\nproperty float x\nproperty float y\nproperty float z\nproperty float intensity\n"
          "end_header\n";
    std::vector<char> buf(1 << 20);
    std::size_t n;
    while ((n = std::fread(buf.data(), 1, buf.size(), f_)) > 0)
      os.write(buf.data(), static_cast<std::streamsize>(n));
  });
  std::fclose(f_);
  f_ = nullptr;
  std::remove(body_.c_str());
}

void writePly(const std::string& path, const std::vector<PointXYZI>& points) {
  PlyStreamWriter w(path);
  w.append(points);
  w.close();
}

std::vector<PointXYZI> readPly(const std::string& path) {
  const std::string data = readTextFile(path);
  std::istringstream in(data);
  std::string line;
  if (!std::getline(in, line) || line.rfind("ply", 0) != 0) throw Error(path, "not a PLY file");
  bool binary = false, ascii = false, in_vertex = false;
  std::size_t n = 0;
  std::vector<std::string> props;
  std::vector<int> sizes;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream ls(line);
    std::string w;
    ls >> w;
    if (w == "format") {
      std::string f;
      ls >> f;
      binary = f == "binary_little_endian";
      ascii = f == "ascii";
      if (!binary && !ascii) throw Error(path, "unsupported PLY format '" + f + "'");
    } else if (w == "element") {
      std::string name;
      ls >> name;
      in_vertex = name == "vertex";
      if (in_vertex) ls >> n;
    } else if (w == "property" && in_vertex) {
      std::string type, name;
      ls >> type >> name;
      const int size = (type == "float" || type == "float32" || type == "int" || type == "uint") ? 4
                       : (type == "double" || type == "float64")                              ? 8
                       : (type == "uchar" || type == "uint8" || type == "char")               ? 1
                       : (type == "short" || type == "ushort")                                ? 2
                                                                                               : 0;
      if (size == 0) throw Error(path, "unsupported vertex property type '" + type + "'");
      props.push_back(type + " " + name);
      sizes.push_back(size);
    } else if (w == "end_header") {
      break;
    }
  }
  auto find = [&](const std::string& name) {
    for (std::size_t i = 0; i < props.size(); ++i)
      if (props[i].substr(props[i].find(' ') + 1) == name) return static_cast<int>(i);
    return -1;
  };
  const int ix = find("x"), iy = find("y"), iz = find("z"), ii = find("intensity");
  if (ix < 0 || iy < 0 || iz < 0) throw Error(path, "PLY vertices lack x, y or z");
  std::vector<PointXYZI> pts(n);
  if (ascii) {
    for (std::size_t k = 0; k < n; ++k) {
      std::vector<double> v(props.size());
      for (auto& x : v)
        if (!(in >> x)) throw Error(path, "truncated PLY: " + std::to_string(k) + " of " +
                                              std::to_string(n) + " vertices");
      pts[k] = {float(v[std::size_t(ix)]), float(v[std::size_t(iy)]), float(v[std::size_t(iz)]),
                ii >= 0 ? float(v[std::size_t(ii)]) : 0.f};
    }
    return pts;
  }
  std::size_t stride = 0;
  std::vector<std::size_t> off;
  for (int s : sizes) {
    off.push_back(stride);
    stride += static_cast<std::size_t>(s);
  }
  const std::size_t start = static_cast<std::size_t>(in.tellg());
  if (data.size() < start + n * stride)
    throw Error(path, "truncated PLY: header promises " + std::to_string(n) + " vertices");
  auto get = [&](std::size_t k, int p) -> float {
    const char* b = data.data() + start + k * stride + off[std::size_t(p)];
    if (sizes[std::size_t(p)] == 8) {
      double d;
      std::memcpy(&d, b, 8);
      return static_cast<float>(d);
    }
    float f;
    std::memcpy(&f, b, 4);
    return f;
  };
  for (std::size_t k = 0; k < n; ++k)
    pts[k] = {get(k, ix), get(k, iy), get(k, iz), ii >= 0 ? get(k, ii) : 0.f};
  return pts;
}

}  // namespace cleanmap::io
