// SPDX-License-Identifier: BSD-3-Clause
#include "fuzz_support.h"

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>

namespace fs = std::filesystem;

namespace cleanmap::fuzz {
namespace {

struct Scratch {
  std::string dir;
  Scratch() {
    const char* t = std::getenv("TMPDIR");
    fs::path base = t && *t ? fs::path(t) : fs::path("/tmp");
    dir = (base / ("cleanmap-fuzz-" + std::to_string(::getpid()))).string();
    fs::create_directories(dir);
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

}  // namespace

const std::string& scratchDir() {
  static const Scratch s;
  return s.dir;
}

std::string writeInput(const std::string& name, const uint8_t* data, std::size_t size) {
  const fs::path p = fs::path(scratchDir()) / name;
  if (p.has_parent_path()) fs::create_directories(p.parent_path());
  std::ofstream f(p, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  if (!f) finding("cannot write the scratch input", p.string());
  return p.string();
}

std::string writeInput(const std::string& name, const std::string& text) {
  return writeInput(name, reinterpret_cast<const uint8_t*>(text.data()), text.size());
}

void requireFinitePoints(const std::vector<PointXYZI>& points, const std::string& path) {
  for (const auto& p : points)
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      finding("a non-finite point was delivered", path);
}

void finding(const std::string& why, const std::string& message) {
  std::fprintf(stderr, "FUZZ FINDING: %s: %s\n", why.c_str(), message.c_str());
  std::abort();
}

}  // namespace cleanmap::fuzz
