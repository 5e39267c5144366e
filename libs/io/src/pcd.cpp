// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/io/pcd.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>

#include "cleanmap/core/error.h"
#include "cleanmap/io/binary_field.h"
#include "cleanmap/io/files.h"
#include "cleanmap/io/ply.h"

namespace cleanmap::io {
namespace {

struct Field {
  std::string name;
  int size = 4, count = 1;
  char type = 'F';
  FieldType decoded = FieldType::kF32;
  std::size_t offset = 0;  // within a point record
};

// LZF as PCL writes it (liblzf format): literal runs and back references.
std::string lzfDecompress(const std::string& in, std::size_t out_size, const std::string& path) {
  std::string out;
  out.reserve(out_size);
  std::size_t ip = 0;
  while (ip < in.size()) {
    const unsigned ctrl = static_cast<unsigned char>(in[ip++]);
    if (ctrl < 32) {
      const std::size_t len = ctrl + 1;
      if (ip + len > in.size() || out.size() + len > out_size)
        throw Error(path, "corrupt binary_compressed data (literal run past the end)");
      out.append(in, ip, len);
      ip += len;
    } else {
      std::size_t len = ctrl >> 5;
      if (len == 7) {
        if (ip >= in.size()) throw Error(path, "corrupt binary_compressed data");
        len += static_cast<unsigned char>(in[ip++]);
      }
      if (ip >= in.size()) throw Error(path, "corrupt binary_compressed data");
      const std::size_t back = ((ctrl & 0x1f) << 8) + static_cast<unsigned char>(in[ip++]) + 1;
      len += 2;
      if (back > out.size() || out.size() + len > out_size)
        throw Error(path, "corrupt binary_compressed data (back reference out of range)");
      std::size_t ref = out.size() - back;
      for (std::size_t i = 0; i < len; ++i) out.push_back(out[ref + i]);  // may overlap
    }
  }
  if (out.size() != out_size)
    throw Error(path, "binary_compressed data decompress to " + std::to_string(out.size()) +
                          " bytes, header says " + std::to_string(out_size));
  return out;
}

double readValue(const char* p, const Field& f) {
  return decodeField(p, f.decoded);
}

}  // namespace

std::vector<PointXYZI> readPcd(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path, "cannot open");
  std::vector<Field> fields;
  std::size_t width = 0, height = 1, points = 0;
  bool have_points = false;
  std::string data, line;
  std::vector<int> sizes, counts;
  std::vector<char> types;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    if (key == "VERSION" || key == "VIEWPOINT") continue;
    if (key == "FIELDS") {
      for (std::string n; ls >> n;) fields.push_back({n});
    } else if (key == "SIZE") {
      for (int v; ls >> v;) sizes.push_back(v);
    } else if (key == "TYPE") {
      for (char v; ls >> v;) types.push_back(v);
    } else if (key == "COUNT") {
      for (int v; ls >> v;) counts.push_back(v);
    } else if (key == "WIDTH") {
      ls >> width;
    } else if (key == "HEIGHT") {
      ls >> height;
    } else if (key == "POINTS") {
      ls >> points;
      have_points = true;
    } else if (key == "DATA") {
      ls >> data;
      break;
    } else {
      throw Error(path, "not a PCD file (unexpected header line '" + line.substr(0, 40) + "')");
    }
  }
  if (data.empty()) throw Error(path, "not a PCD file (no DATA line)");
  if (fields.empty() || sizes.size() != fields.size() || types.size() != fields.size())
    throw Error(path, "FIELDS, SIZE and TYPE must list the same number of entries");
  if (counts.empty()) counts.assign(fields.size(), 1);
  if (counts.size() != fields.size()) throw Error(path, "COUNT must list one entry per field");
  if (!have_points) points = width * height;
  std::size_t record = 0;
  int ix = -1, iy = -1, iz = -1, ii = -1;
  for (std::size_t k = 0; k < fields.size(); ++k) {
    auto& f = fields[k];
    f.size = sizes[k];
    f.type = types[k];
    f.count = counts[k];
    const auto decoded = pcdFieldType(f.type, f.size);
    if (!decoded || f.count < 1)
      throw Error(path, "field '" + f.name + "' has an unsupported TYPE/SIZE/COUNT");
    f.decoded = *decoded;
    f.offset = record;
    record += std::size_t(f.size) * std::size_t(f.count);
    if (f.name == "x") ix = int(k);
    if (f.name == "y") iy = int(k);
    if (f.name == "z") iz = int(k);
    if (f.name == "intensity") ii = int(k);
  }
  if (ix < 0 || iy < 0 || iz < 0) throw Error(path, "PCD has no x, y, z fields");

  std::vector<PointXYZI> out;
  out.reserve(std::min<std::size_t>(points, 1u << 20));  // grows with the data, not with the header
  auto emit = [&](double x, double y, double z, double i) {
    if (std::isfinite(x) && std::isfinite(y) && std::isfinite(z))
      out.push_back({float(x), float(y), float(z), std::isfinite(i) ? float(i) : 0.f});
  };
  if (data == "ascii") {
    std::size_t values_per_point = 0;
    for (const auto& f : fields) values_per_point += std::size_t(f.count);
    std::vector<double> v(values_per_point);
    for (std::size_t n = 0; n < points; ++n) {
      for (auto& x : v) {
        std::string tok;
        if (!(in >> tok))
          throw Error(path, "ASCII data end after " + std::to_string(n) + " of " +
                                std::to_string(points) + " points");
        x = tok == "nan" || tok == "NaN" ? NAN : std::strtod(tok.c_str(), nullptr);
      }
      auto at = [&](int k) {
        std::size_t pos = 0;
        for (int j = 0; j < k; ++j) pos += std::size_t(fields[j].count);
        return v[pos];
      };
      emit(at(ix), at(iy), at(iz), ii >= 0 ? at(ii) : 0.0);
    }
    return out;
  }
  const std::string rest((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (data == "binary") {
    if (rest.size() / record < points)
      throw Error(path, "truncated: binary data hold " + std::to_string(rest.size()) + " bytes, " +
                            std::to_string(points) + " points need " +
                            std::to_string(points * record));
    for (std::size_t n = 0; n < points; ++n) {
      const char* p = rest.data() + n * record;
      emit(readValue(p + fields[ix].offset, fields[ix]),
           readValue(p + fields[iy].offset, fields[iy]),
           readValue(p + fields[iz].offset, fields[iz]),
           ii >= 0 ? readValue(p + fields[ii].offset, fields[ii]) : 0.0);
    }
    return out;
  }
  if (data == "binary_compressed") {
    if (rest.size() < 8) throw Error(path, "truncated: no binary_compressed sizes");
    uint32_t csize = 0, usize = 0;
    std::memcpy(&csize, rest.data(), 4);
    std::memcpy(&usize, rest.data() + 4, 4);
    if (rest.size() < 8 + std::size_t(csize))
      throw Error(path, "truncated: compressed data shorter than the " + std::to_string(csize) +
                            " bytes announced");
    if (record == 0 || usize / record != points || usize % record != 0)
      throw Error(path, "binary_compressed size " + std::to_string(usize) + " does not match " +
                            std::to_string(points) + " points of " + std::to_string(record) +
                            " bytes");
    const std::string raw = lzfDecompress(rest.substr(8, csize), usize, path);
    // Field-major: all values of field 0, then of field 1, ...
    auto value = [&](int k, std::size_t n) {
      const auto& f = fields[k];
      return readValue(
          raw.data() + f.offset * points + n * std::size_t(f.size) * std::size_t(f.count), f);
    };
    for (std::size_t n = 0; n < points; ++n)
      emit(value(ix, n), value(iy, n), value(iz, n), ii >= 0 ? value(ii, n) : 0.0);
    return out;
  }
  throw Error(path, "unsupported DATA '" + data + "' (ascii, binary, binary_compressed)");
}

void writePcd(const std::string& path, const std::vector<PointXYZI>& points, bool ascii) {
  writeFileAtomic(path, [&](std::ostream& os) {
    os << "# .PCD v0.7 - written by cleanmap\nVERSION 0.7\nFIELDS x y z intensity\n"
          "SIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH "
       << points.size() << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << points.size()
       << "\nDATA " << (ascii ? "ascii" : "binary") << '\n';
    if (ascii) {
      os.precision(9);
      for (const auto& p : points)
        os << p.x << ' ' << p.y << ' ' << p.z << ' ' << p.intensity << '\n';
    } else {
      os.write(reinterpret_cast<const char*>(points.data()),
               static_cast<std::streamsize>(points.size() * sizeof(PointXYZI)));
    }
  });
}

std::vector<PointXYZI> readCloud(const std::string& path) {
  auto ends = [&](const char* e) {
    const std::size_t n = std::strlen(e);
    if (path.size() < n) return false;
    std::string tail = path.substr(path.size() - n);
    for (auto& c : tail) c = char(std::tolower(static_cast<unsigned char>(c)));
    return tail == e;
  };
  if (ends(".ply")) return readPly(path);
  if (ends(".pcd")) return readPcd(path);
  throw Error(path, "unknown point-cloud format (expected .ply or .pcd)");
}

}  // namespace cleanmap::io
