// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/io/files.h"

#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "cleanmap/core/error.h"
#include "cleanmap/io/direct_file.h"

namespace fs = std::filesystem;

namespace cleanmap::io {
namespace {

std::vector<char> readBinary(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw Error(path, "file does not exist");
  if (fs::is_directory(path, ec)) throw Error(path, "is a directory, expected a file");
  std::ifstream f(path, std::ios::binary | std::ios::ate);
  if (!f) throw Error(path, "cannot open for reading");
  const auto end = f.tellg();
  if (end < 0) throw Error(path, "cannot tell its size (not a regular file?)");
  const auto size = static_cast<std::size_t>(end);
  std::vector<char> bytes(size);
  f.seekg(0);
  if (size > 0 && !f.read(bytes.data(), static_cast<std::streamsize>(size)))
    throw Error(path, "read error");
  return bytes;
}

}  // namespace

Scan readKittiBin(const std::string& path, const ScanReadOptions& opts) {
  const std::vector<char> bytes = readBinary(path);
  if (bytes.size() % sizeof(PointXYZI) != 0)
    throw Error(path, "truncated scan: " + std::to_string(bytes.size()) +
                          " bytes is not a multiple of 16 (float32 x, y, z, intensity)");
  Scan scan;
  scan.points.resize(bytes.size() / sizeof(PointXYZI));
  if (!bytes.empty()) std::memcpy(scan.points.data(), bytes.data(), bytes.size());
  scan.original_size = scan.points.size();
  dropInvalidPoints(scan);
  if (scan.points.empty() && !opts.allow_empty)
    throw Error(path, scan.original_size == 0
                          ? "empty scan (0 points)"
                          : "empty scan: all " + std::to_string(scan.original_size) +
                                " points are NaN or infinite");
  return scan;
}

void writeKittiBin(const std::string& path, const std::vector<PointXYZI>& points) {
  writeFileAtomic(path, [&](std::ostream& os) {
    os.write(reinterpret_cast<const char*>(points.data()),
             static_cast<std::streamsize>(points.size() * sizeof(PointXYZI)));
  });
}

Labels readLabels(const std::string& path, std::optional<std::size_t> expected_count) {
  const std::vector<char> bytes = readBinary(path);
  if (bytes.size() % sizeof(uint32_t) != 0)
    throw Error(path, "truncated label file: " + std::to_string(bytes.size()) +
                          " bytes is not a multiple of 4 (uint32 per point)");
  Labels labels(bytes.size() / sizeof(uint32_t));
  if (!bytes.empty()) std::memcpy(labels.data(), bytes.data(), bytes.size());
  if (expected_count && labels.size() != *expected_count)
    throw Error(path, "has " + std::to_string(labels.size()) + " labels but the scan has " +
                          std::to_string(*expected_count) + " points");
  return labels;
}

void writeLabels(const std::string& path, const Labels& labels) {
  writeBytesAtomic(path, labels.data(), labels.size() * sizeof(uint32_t));  // past the page cache
}

std::string atomicTemporaryFor(const std::string& path) {
  const fs::path target(path);
  if (target.has_parent_path()) {
    std::error_code ec;
    fs::create_directories(target.parent_path(), ec);
    if (ec) throw Error(target.parent_path().string(), "cannot create directory: " + ec.message());
  }
  return path + ".tmp." + std::to_string(::getpid());
}

void writeFileAtomic(const std::string& path, const std::function<void(std::ostream&)>& writer) {
  const fs::path target(path);
  const std::string tmp = atomicTemporaryFor(path);
  try {
    {
      std::ofstream os(tmp, std::ios::binary | std::ios::trunc);
      if (!os) throw Error(path, "cannot open for writing");
      writer(os);
      os.flush();
      if (!os) throw Error(path, "write failed (disk full?)");
    }
    std::error_code ec;
    fs::rename(tmp, target, ec);
    if (ec) throw Error(path, "cannot move the finished file into place: " + ec.message());
  } catch (...) {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    throw;
  }
}

std::string readTextFile(const std::string& path) {
  const std::vector<char> bytes = readBinary(path);
  return std::string(bytes.begin(), bytes.end());
}

void requireDirectory(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw Error(path, "directory does not exist");
  if (!fs::is_directory(path, ec)) throw Error(path, "is not a directory");
}

namespace {

// Staging folders of runs that were killed (SIGKILL, power loss) are removed by the next run.
void removeStaleStaging(const fs::path& parent, const std::string& prefix) {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(parent.empty() ? "." : parent, ec)) {
    const std::string n = e.path().filename().string();
    if (n.rfind(prefix, 0) != 0) continue;
    const long pid = std::atol(n.c_str() + prefix.size());
    if (pid > 0 && ::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH)
      fs::remove_all(e.path(), ec);
  }
}

std::string trimmedFolder(std::string dir) {
  while (dir.size() > 1 && dir.back() == '/') dir.pop_back();
  return dir;
}

std::string stagingPrefix(const std::string& dir, const std::string& tag) {
  return "." + fs::path(dir).filename().string() + "." + tag + "-staging-";
}

std::string stagingPath(const std::string& dir, const std::string& tag) {
  return (fs::path(dir).parent_path() / (stagingPrefix(dir, tag) + std::to_string(::getpid())))
      .string();
}

}  // namespace

std::string messageWithoutStaging(std::string message, const std::string& dir,
                                  const std::string& tag) {
  const std::string d = trimmedFolder(dir);
  auto replaceAll = [&](const std::string& from, const std::string& to) {
    for (std::size_t at = message.find(from); at != std::string::npos;
         at = message.find(from, at + to.size()))
      message.replace(at, from.size(), to);
  };
  replaceAll(stagingPath(d, tag), d);
  const std::string pid = std::to_string(::getpid());
  for (const char* suffix : {".tmp.", ".part.", ".head."}) replaceAll(suffix + pid, "");
  return message;
}

void requireReplaceableFolder(const std::string& dir,
                              const std::function<bool(const std::string&)>& isOurs,
                              const std::string& what, const std::string& option,
                              const std::string& alternative) {
  std::error_code ec;
  const auto st = fs::status(dir, ec);
  if (!fs::exists(st)) return;
  if (!fs::is_directory(st))
    throw Error(dir, "exists and is not a folder; choose another " + option);
  if (fs::is_empty(dir, ec) || isOurs(dir)) return;
  throw Error(dir, "is a non-empty folder that holds no " + what + "; choose another " + option +
                       alternative);
}

namespace {

// `p` absolute and normal, without a trailing separator; with `resolve`, its symbolic links
// resolved as far as it exists.
fs::path comparablePath(const std::string& p, bool resolve) {
  std::error_code ec;
  fs::path a = resolve ? fs::weakly_canonical(p, ec) : fs::path();
  if (!resolve || ec) a = fs::absolute(p, ec).lexically_normal();
  while (a.has_relative_path() && a.filename().empty()) a = a.parent_path();
  return a;
}

// True if `inner` is `outer` or lies below it (whole components).
bool isWithin(const fs::path& inner, const fs::path& outer) {
  auto i = inner.begin();
  for (auto o = outer.begin(); o != outer.end(); ++o, ++i)
    if (i == inner.end() || *i != *o) return false;
  return true;
}

}  // namespace

void requireOutsideInput(const std::string& dir, const std::string& input,
                         const std::function<bool(const std::string&)>& isOurs,
                         const std::string& option) {
  if (input.empty()) return;
  std::error_code ec;
  const bool input_is_folder = fs::is_directory(input, ec);
  for (const bool resolve : {false, true}) {
    const fs::path d = comparablePath(dir, resolve), in = comparablePath(input, resolve);
    if (d == in)
      throw Error(dir, std::string("the output folder is the input ") +
                           (input_is_folder ? "folder" : "file") + "; choose another " + option);
    if (isWithin(in, d))
      throw Error(dir, "holds the input " + input + ", which replacing it would delete; " +
                           "choose another " + option);
    if (input_is_folder && isWithin(d, in) && fs::is_directory(dir, ec) && !fs::is_empty(dir, ec) &&
        !isOurs(dir))
      throw Error(dir, "lies inside the input folder " + input + " and holds files that may be " +
                           "the input's; choose another " + option + " (no option replaces it)");
  }
}

StagedFolder::StagedFolder(const std::string& dir, const std::string& tag)
    : dir_(trimmedFolder(dir)) {
  const fs::path out(dir_);
  std::error_code ec;
  if (!out.parent_path().empty()) fs::create_directories(out.parent_path(), ec);
  if (ec) throw Error(dir_, "cannot create the parent folder: " + ec.message());
  removeStaleStaging(out.parent_path(), stagingPrefix(dir_, tag));
  staging_ = stagingPath(dir_, tag);
  fs::remove_all(staging_, ec);
  fs::create_directories(staging_, ec);
  if (ec) throw Error(dir_, "cannot create the staging folder " + staging_ + ": " + ec.message());
}

StagedFolder::~StagedFolder() {
  if (published_) return;
  std::error_code ec;
  fs::remove_all(staging_, ec);
}

void StagedFolder::publish() {
  std::error_code ec;
  if (!fs::exists(dir_, ec)) {
    fs::rename(staging_, dir_, ec);
    if (ec) throw Error(dir_, "cannot move the finished folder into place: " + ec.message());
  } else if (::renameat2(AT_FDCWD, staging_.c_str(), AT_FDCWD, dir_.c_str(), RENAME_EXCHANGE) !=
             0) {
    const std::string old = staging_ + ".old";
    fs::rename(dir_, old, ec);
    if (!ec) fs::rename(staging_, dir_, ec);
    if (ec) throw Error(dir_, "cannot replace the earlier folder: " + ec.message());
    fs::remove_all(old, ec);
    published_ = true;
    return;
  }
  published_ = true;
  fs::remove_all(staging_, ec);  // after a swap: the earlier folder
}

}  // namespace cleanmap::io
