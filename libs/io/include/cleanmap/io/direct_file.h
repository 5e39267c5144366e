// SPDX-License-Identifier: BSD-3-Clause
// Large files written front to back and read back once, past the page cache (issue #16).
//
// A run writes about 9.5 MB of outputs per scan (rawlogs, simplemap, maps, labels) and spools
// part of it for the map's final decision. Through the page cache each byte is copied into a
// fresh cache page; on the machines we measure on that costs ~1.6 ms per MB of kernel time (a
// fresh page is a host fault), 19 % of a long run's CPU (doc/BENCHMARK.md, twenty-first session).
// O_DIRECT moves the bytes from one reused, aligned buffer to the device instead. Where the file
// system refuses O_DIRECT (tmpfs before Linux 6.6, some network file systems), or with
// CLEANMAP_DIRECT_IO=0 in the environment, the same calls go through the page cache: the bytes
// on disk are the same either way.
#pragma once
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <string>

namespace cleanmap::io {

/// A file written sequentially (created or truncated). Full buffers are written by one I/O thread
/// shared by the process while the caller fills the other of two; close() waits for them, writes
/// the last, padded block and cuts the file to its exact size.
/// Destroyed without close() (an error, a signal), it closes the descriptor and leaves the file
/// as far as it got: callers write under a temporary name and rename when done.
class DirectFile {
 public:
  /// Opens `path` for writing; throws cleanmap::Error naming it if it cannot. `buffer`: bytes
  /// kept before a write to disk (rounded up to the 4 KiB alignment). `direct` false: through
  /// the page cache (as where the file system refuses O_DIRECT).
  explicit DirectFile(std::string path, std::size_t buffer = std::size_t(512) << 10,
                      bool direct = true);
  ~DirectFile();
  DirectFile(const DirectFile&) = delete;
  DirectFile& operator=(const DirectFile&) = delete;

  /// Appends n bytes; throws cleanmap::Error("write failed (disk full?)") on failure.
  void write(const void* data, std::size_t n);
  /// Overwrites n bytes at `offset`, which must already be written and lie in the file's first
  /// 4 KiB (a header's count, patched at the end); throws cleanmap::Error otherwise.
  void patchHead(std::size_t offset, const void* data, std::size_t n);
  /// Writes what is buffered, sets the exact size and closes; throws cleanmap::Error on failure.
  void close();

  std::uint64_t size() const { return on_disk_ + used_; }  ///< bytes written so far
  bool direct() const { return direct_; }  ///< false where the file system refused O_DIRECT
  const std::string& path() const { return path_; }

  static constexpr std::size_t kAlign = 4096;

 private:
  friend class IoThread;
  void flushFull();         // hands the full buffer to the I/O thread
  void waitIdle(int slot);  // until that buffer's write (-1: both) is done; rethrows its error
  void writeAt(const unsigned char* data, std::size_t n, std::uint64_t offset);

  std::string path_;
  int fd_ = -1;
  std::atomic<bool> direct_{false};  // dropped by a write the file system refuses
  unsigned char* bufs_[2] = {};      // aligned, cap_ bytes each: one filled, one being written
  bool busy_[2] = {false, false};    // in the I/O thread's hands (its mutex guards these)
  std::exception_ptr error_;         // of a write on the I/O thread (same mutex)
  int cur_ = 0;
  unsigned char* head_ = nullptr;  // aligned copy of block 0 once it left the buffer
  bool head_dirty_ = false;
  std::size_t cap_ = 0, used_ = 0;
  std::uint64_t on_disk_ = 0;  // bytes handed to the device (whole buffers)
};

/// A file read front to back (a spool written by DirectFile), O_DIRECT where allowed.
class DirectReader {
 public:
  explicit DirectReader(std::string path, std::size_t buffer = std::size_t(512) << 10,
                        bool direct = true);
  ~DirectReader();
  DirectReader(const DirectReader&) = delete;
  DirectReader& operator=(const DirectReader&) = delete;
  /// Reads exactly n bytes; throws cleanmap::Error(path, "truncated") at the end of the file.
  void read(void* data, std::size_t n);

 private:
  void fill();

  std::string path_;
  int fd_ = -1;
  bool direct_ = false;
  unsigned char* buf_ = nullptr;
  std::size_t cap_ = 0, pos_ = 0, end_ = 0;
  std::uint64_t offset_ = 0;
  bool eof_ = false;
};

/// A file read, and patched, at given offsets (pread / pwrite): the map's pass over its spool
/// from the last scan to the first (DESIGN §2e, "Objects"). Read-only, past the page cache where
/// allowed (as DirectReader); writable, through it.
class PositionalFile {
 public:
  /// Opens `path` (for reading, and writing where `writable`); throws cleanmap::Error naming it.
  PositionalFile(std::string path, bool writable);
  ~PositionalFile();
  PositionalFile(const PositionalFile&) = delete;
  PositionalFile& operator=(const PositionalFile&) = delete;
  /// Reads exactly n bytes at `offset`; throws cleanmap::Error(path, "truncated") past the end.
  void readAt(std::uint64_t offset, void* data, std::size_t n);
  /// Writes n bytes at `offset`; throws cleanmap::Error on failure.
  void writeAt(std::uint64_t offset, const void* data, std::size_t n);

 private:
  std::string path_;
  int fd_ = -1;
  bool direct_ = false;
  unsigned char* buf_ = nullptr;  // aligned, for O_DIRECT reads
  std::size_t cap_ = 0;
};

/// Writes `path` with these bytes through a temporary sibling and a rename (as writeFileAtomic),
/// past the page cache where allowed: the per-scan label files.
void writeBytesAtomic(const std::string& path, const void* data, std::size_t n);

}  // namespace cleanmap::io
