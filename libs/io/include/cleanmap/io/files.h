// SPDX-License-Identifier: BSD-3-Clause
// Low-level file formats: KITTI `.bin` scans, SemanticKITTI `.label` files, atomic writes.
#pragma once
#include <functional>
#include <iosfwd>
#include <string>
#include <vector>

#include "cleanmap/core/types.h"

namespace cleanmap::io {

struct ScanReadOptions {
  bool allow_empty = false;  ///< an empty scan is an error unless allowed (then returned empty)
};

/// Reads a KITTI Velodyne `.bin` (float32 x, y, z, intensity per point, little-endian).
/// Throws cleanmap::Error on a missing file, a size that is not a multiple of 16, or an empty scan
/// (unless allowed). NaN / infinite points are dropped and counted in Scan::dropped_invalid.
Scan readKittiBin(const std::string& path, const ScanReadOptions& opts = {});

/// Writes a scan as KITTI `.bin` (valid points only), atomically.
void writeKittiBin(const std::string& path, const std::vector<PointXYZI>& points);

/// Reads a `.label` file (uint32 little-endian per point). If expected_count is given, a different
/// count is an error naming both numbers.
Labels readLabels(const std::string& path, std::optional<std::size_t> expected_count = {});

/// Writes a `.label` file atomically.
void writeLabels(const std::string& path, const Labels& labels);

/// Writes `path` through a temporary sibling and a rename, so an interrupted run never leaves a
/// half-written file. The writer gets a binary stream; any exception removes the temporary.
void writeFileAtomic(const std::string& path, const std::function<void(std::ostream&)>& writer);
/// For a file written atomically: creates `path`'s folder if needed and returns the temporary
/// sibling to write before renaming it to `path` (writeFileAtomic, io::writeBytesAtomic).
std::string atomicTemporaryFor(const std::string& path);

/// A folder written as a whole, so that an error or a signal never leaves it half-written: its
/// files go into a staging folder `.<name>.<tag>-staging-<pid>` beside it (those of killed runs
/// are removed first), and publish() moves that into place in one step, swapping it with an
/// earlier folder where the file system can (renameat2 RENAME_EXCHANGE; else two renames leave
/// the folder missing for an instant, never half-written). Destroyed unpublished, it removes the
/// staging folder and leaves the folder as it was.
class StagedFolder {
 public:
  /// Throws cleanmap::Error naming `dir` if the staging folder cannot be made.
  StagedFolder(const std::string& dir, const std::string& tag);
  ~StagedFolder();
  StagedFolder(const StagedFolder&) = delete;
  StagedFolder& operator=(const StagedFolder&) = delete;

  const std::string& path() const { return staging_; }  ///< where to write
  const std::string& dir() const { return dir_; }       ///< the folder, once published
  void publish();

 private:
  std::string dir_, staging_;
  bool published_ = false;
};

/// Before a StagedFolder replaces `dir`: returns if `dir` is absent, an empty folder, or a folder
/// `isOurs` recognises as this tool's earlier output; else throws cleanmap::Error naming `dir`
/// ("exists and is not a folder", or "is a non-empty folder that holds no <what>; choose another
/// <option><alternative>"), so that a folder a user keeps other things in is never replaced.
void requireReplaceableFolder(const std::string& dir,
                              const std::function<bool(const std::string&)>& isOurs,
                              const std::string& what, const std::string& option,
                              const std::string& alternative = "");

/// Before a folder made from `input` (a file or a folder) replaces `dir`: throws cleanmap::Error
/// naming `dir` if replacing it could delete what the run reads, whatever option asked for the
/// replacement (--force): `dir` is `input` or holds it, or `input` is a folder and `dir` a
/// non-empty folder inside it that `isOurs` does not recognise as this tool's earlier output (its
/// files may be the input's own, as velodyne/). Paths are compared as written and with their
/// symbolic links resolved. An empty `input` checks nothing.
void requireOutsideInput(const std::string& dir, const std::string& input,
                         const std::function<bool(const std::string&)>& isOurs,
                         const std::string& option);

/// An error message as the user should read it: paths inside this process's staging folder for
/// `dir` (StagedFolder with `tag`) named as they will be in `dir`, and the temporaries' suffixes
/// (".tmp.<pid>", ".part.<pid>", ".head.<pid>") dropped.
std::string messageWithoutStaging(std::string message, const std::string& dir,
                                  const std::string& tag);

/// Whole file as text; throws cleanmap::Error naming the file if it cannot be read.
std::string readTextFile(const std::string& path);

/// Throws cleanmap::Error(path, "directory does not exist") unless `path` is a directory.
void requireDirectory(const std::string& path);

}  // namespace cleanmap::io
