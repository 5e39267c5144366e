// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/io/direct_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <exception>
#include <filesystem>
#include <mutex>
#include <thread>

#include "cleanmap/core/error.h"
#include "cleanmap/io/files.h"

namespace cleanmap::io {

namespace {

constexpr std::size_t kAlign = DirectFile::kAlign;

std::size_t roundUp(std::size_t n) {
  return (n + kAlign - 1) / kAlign * kAlign;
}

unsigned char* alignedBuffer(std::size_t n, const std::string& path) {
  void* p = std::aligned_alloc(kAlign, roundUp(std::max<std::size_t>(n, 1)));
  if (!p) throw Error(path, "cannot allocate an I/O buffer of " + std::to_string(n) + " bytes");
  return static_cast<unsigned char*>(p);
}

// Opens with O_DIRECT if `direct` and the file system allows it (EINVAL: it does not), plainly
// otherwise; `direct` says which.
int openMaybeDirect(const std::string& path, int flags, bool& direct) {
#ifdef O_DIRECT
  static const bool allowed = [] {  // CLEANMAP_DIRECT_IO=0: always through the page cache
    const char* v = std::getenv("CLEANMAP_DIRECT_IO");
    return !(v && std::string(v) == "0");
  }();
  int fd = -1;
  if (direct && allowed) {
    do fd = ::open(path.c_str(), flags | O_DIRECT | O_CLOEXEC, 0644);
    while (fd < 0 && errno == EINTR);
    if (fd >= 0) return fd;
    if (errno != EINVAL) return -1;
  }
#endif
  direct = false;
  int fd2;
  do fd2 = ::open(path.c_str(), flags | O_CLOEXEC, 0644);
  while (fd2 < 0 && errno == EINTR);
  return fd2;
}

// A file system may open with O_DIRECT yet refuse a transfer (EINVAL): the descriptor goes on
// without it.
template <class Flag>
bool dropDirect(int fd, Flag& direct) {
#ifdef O_DIRECT
  if (!direct || errno != EINVAL) return false;
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags < 0 || ::fcntl(fd, F_SETFL, flags & ~O_DIRECT) != 0) return false;
  direct = false;
  return true;
#else
  (void)fd;
  (void)direct;
  return false;
#endif
}

}  // namespace

// The writes of whole buffers, for every DirectFile of the process, on one thread: a writer
// fills its other buffer meanwhile instead of waiting for the device (O_DIRECT transfers are
// synchronous).
class IoThread {
 public:
  struct Job {
    DirectFile* file;
    int slot;
    std::uint64_t offset;
  };
  static IoThread& get() {
    static IoThread t;
    return t;
  }
  ~IoThread() {
    {
      std::lock_guard<std::mutex> lock(mu);
      closing = true;
    }
    cv.notify_all();
    if (worker.joinable()) worker.join();
  }
  void submit(const Job& j) {
    {
      std::lock_guard<std::mutex> lock(mu);
      if (!worker.joinable()) worker = std::thread([this] { run(); });
      jobs.push_back(j);
    }
    cv.notify_all();
  }
  std::mutex mu;
  std::condition_variable cv;  // a job queued, a job done, closing

 private:
  void run();
  std::deque<Job> jobs;
  bool closing = false;
  std::thread worker;
};

void IoThread::run() {
  for (;;) {
    Job j;
    {
      std::unique_lock<std::mutex> lock(mu);
      cv.wait(lock, [&] { return closing || !jobs.empty(); });
      if (jobs.empty()) return;
      j = jobs.front();
      jobs.pop_front();
    }
    std::exception_ptr e;
    try {
      j.file->writeAt(j.file->bufs_[j.slot], j.file->cap_, j.offset);
    } catch (...) {
      e = std::current_exception();
    }
    {
      std::lock_guard<std::mutex> lock(mu);
      j.file->busy_[j.slot] = false;
      if (e && !j.file->error_) j.file->error_ = e;
    }
    cv.notify_all();
  }
}

void DirectFile::waitIdle(int slot) {
  auto& io = IoThread::get();
  std::unique_lock<std::mutex> lock(io.mu);
  io.cv.wait(lock, [&] { return slot < 0 ? !busy_[0] && !busy_[1] : !busy_[slot]; });
  if (error_) {
    auto e = error_;
    error_ = nullptr;
    std::rethrow_exception(e);
  }
}

DirectFile::DirectFile(std::string path, std::size_t buffer, bool direct) : path_(std::move(path)) {
  fd_ = openMaybeDirect(path_, O_WRONLY | O_CREAT | O_TRUNC, direct);
  direct_ = direct;
  if (fd_ < 0) throw Error(path_, "cannot open for writing: " + std::string(std::strerror(errno)));
  cap_ = roundUp(std::max(buffer, kAlign));
  try {
    bufs_[0] = alignedBuffer(cap_, path_);  // the second on the first full one: small files
  } catch (...) {                           // (labels) need one
    ::close(fd_);
    throw;
  }
}

DirectFile::~DirectFile() {
  try {
    waitIdle(-1);  // the I/O thread holds this file's buffers until its writes are done
  } catch (...) {  // an error nobody asked for: the file is abandoned anyway
  }
  if (fd_ >= 0) ::close(fd_);
  std::free(bufs_[0]);
  std::free(bufs_[1]);
  std::free(head_);
}

void DirectFile::writeAt(const unsigned char* data, std::size_t n, std::uint64_t offset) {
  while (n > 0) {
    const ssize_t w = ::pwrite(fd_, data, n, static_cast<off_t>(offset));
    if (w < 0) {
      if (errno == EINTR || dropDirect(fd_, direct_)) continue;
      throw Error(path_, "write failed (disk full?): " + std::string(std::strerror(errno)));
    }
    if (w == 0) throw Error(path_, "write failed (disk full?)");
    // A short transfer leaves the rest unaligned: it goes on through the page cache.
    if (static_cast<std::size_t>(w) < n && direct_ && (w % kAlign) != 0) {
      errno = EINVAL;
      dropDirect(fd_, direct_);
    }
    data += w;
    n -= static_cast<std::size_t>(w);
    offset += static_cast<std::uint64_t>(w);
  }
}

// A full buffer goes to the I/O thread; the other buffer takes the next bytes once its own
// write is done.
void DirectFile::flushFull() {
  if (on_disk_ == 0) {  // block 0 leaves the buffer: keep it for patchHead()
    head_ = alignedBuffer(kAlign, path_);
    std::memcpy(head_, bufs_[cur_], kAlign);
  }
  auto& io = IoThread::get();
  {
    std::lock_guard<std::mutex> lock(io.mu);
    busy_[cur_] = true;
  }
  io.submit({this, cur_, on_disk_});
  on_disk_ += cap_;
  used_ = 0;
  cur_ ^= 1;
  if (!bufs_[cur_]) bufs_[cur_] = alignedBuffer(cap_, path_);
  waitIdle(cur_);
}

void DirectFile::write(const void* data, std::size_t n) {
  if (fd_ < 0) throw Error(path_, "write after close");
  const auto* p = static_cast<const unsigned char*>(data);
  while (n > 0) {
    const std::size_t take = std::min(n, cap_ - used_);
    std::memcpy(bufs_[cur_] + used_, p, take);
    used_ += take;
    p += take;
    n -= take;
    if (used_ == cap_) flushFull();
  }
}

void DirectFile::patchHead(std::size_t offset, const void* data, std::size_t n) {
  if (fd_ < 0 || offset + n > kAlign || offset + n > size())
    throw Error(path_, "patch of bytes " + std::to_string(offset) + ".." +
                           std::to_string(offset + n) + " outside the written header");
  if (on_disk_ == 0) {
    std::memcpy(bufs_[cur_] + offset, data, n);
  } else {
    std::memcpy(head_ + offset, data, n);
    head_dirty_ = true;
  }
}

void DirectFile::close() {
  if (fd_ < 0) return;
  waitIdle(-1);
  const std::uint64_t total = size();
  // The last block whole (O_DIRECT transfers whole blocks), then the file cut to its size.
  const std::size_t out = direct_ ? roundUp(used_) : used_;
  std::memset(bufs_[cur_] + used_, 0, out - used_);
  writeAt(bufs_[cur_], out, on_disk_);
  if (head_dirty_) writeAt(head_, kAlign, 0);
  if (out != used_ && ::ftruncate(fd_, static_cast<off_t>(total)) != 0)
    throw Error(path_, "cannot set the file's size: " + std::string(std::strerror(errno)));
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0)
    throw Error(path_, "write failed (disk full?): " + std::string(std::strerror(errno)));
}

DirectReader::DirectReader(std::string path, std::size_t buffer, bool direct)
    : path_(std::move(path)), direct_(direct) {
  fd_ = openMaybeDirect(path_, O_RDONLY, direct_);
  if (fd_ < 0) throw Error(path_, "cannot open for reading: " + std::string(std::strerror(errno)));
  cap_ = roundUp(std::max(buffer, kAlign));
  buf_ = alignedBuffer(cap_, path_);
}

DirectReader::~DirectReader() {
  if (fd_ >= 0) ::close(fd_);
  std::free(buf_);
}

void DirectReader::fill() {
  pos_ = end_ = 0;
  if (eof_) return;
  for (;;) {
    const ssize_t r = ::pread(fd_, buf_, cap_, static_cast<off_t>(offset_));
    if (r < 0) {
      if (errno == EINTR || dropDirect(fd_, direct_)) continue;
      throw Error(path_, "read failed: " + std::string(std::strerror(errno)));
    }
    if (r == 0) eof_ = true;
    // A short read before the end would leave the offset unaligned: plain reads from there on.
    if (r > 0 && direct_ && (r % kAlign) != 0) {
      errno = EINVAL;
      dropDirect(fd_, direct_);
    }
    end_ = static_cast<std::size_t>(r);
    offset_ += static_cast<std::uint64_t>(r);
    return;
  }
}

void DirectReader::read(void* data, std::size_t n) {
  auto* p = static_cast<unsigned char*>(data);
  while (n > 0) {
    if (pos_ == end_) {
      fill();
      if (end_ == 0) throw Error(path_, "truncated (the file ends early)");
    }
    const std::size_t take = std::min(n, end_ - pos_);
    std::memcpy(p, buf_ + pos_, take);
    pos_ += take;
    p += take;
    n -= take;
  }
}

PositionalFile::PositionalFile(std::string path, bool writable)
    : path_(std::move(path)), direct_(!writable) {
  fd_ = openMaybeDirect(path_, writable ? O_RDWR : O_RDONLY, direct_);
  if (fd_ < 0) throw Error(path_, "cannot open: " + std::string(std::strerror(errno)));
}

PositionalFile::~PositionalFile() {
  if (fd_ >= 0) ::close(fd_);
  std::free(buf_);
}

// With O_DIRECT (a read-only spool written past the page cache) the aligned blocks around the
// range are read into an aligned buffer: no page of the cache is filled for them (issue #16).
void PositionalFile::readAt(std::uint64_t offset, void* data, std::size_t n) {
  if (n == 0) return;  // (an empty vector's data() may be null)
  auto* out = static_cast<unsigned char*>(data);
  if (direct_) {
    const std::uint64_t first = offset / kAlign * kAlign;
    const std::size_t span = roundUp(static_cast<std::size_t>(offset - first) + n);
    if (span > cap_) {
      std::free(buf_);
      buf_ = nullptr;
      cap_ = 0;
      buf_ = alignedBuffer(span, path_);
      cap_ = span;
    }
    std::size_t got = 0;
    while (got < span) {
      const ssize_t r = ::pread(fd_, buf_ + got, span - got, static_cast<off_t>(first + got));
      if (r < 0 && errno == EINTR) continue;
      if (r < 0 && dropDirect(fd_, direct_)) break;  // plainly, below
      if (r < 0) throw Error(path_, "read failed: " + std::string(std::strerror(errno)));
      if (r == 0) break;  // the file's end: the rest of the last block
      got += static_cast<std::size_t>(r);
    }
    if (direct_) {
      if (got < static_cast<std::size_t>(offset - first) + n)
        throw Error(path_, "truncated (the file ends early)");
      std::memcpy(out, buf_ + (offset - first), n);
      return;
    }
  }
  while (n > 0) {
    const ssize_t r = ::pread(fd_, out, n, static_cast<off_t>(offset));
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) throw Error(path_, "read failed: " + std::string(std::strerror(errno)));
    if (r == 0) throw Error(path_, "truncated (the file ends early)");
    out += r;
    n -= static_cast<std::size_t>(r);
    offset += static_cast<std::uint64_t>(r);
  }
}

void PositionalFile::writeAt(std::uint64_t offset, const void* data, std::size_t n) {
  const auto* p = static_cast<const unsigned char*>(data);
  while (n > 0) {
    const ssize_t r = ::pwrite(fd_, p, n, static_cast<off_t>(offset));
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0)
      throw Error(path_, "write failed (disk full?): " + std::string(std::strerror(errno)));
    p += r;
    n -= static_cast<std::size_t>(r);
    offset += static_cast<std::uint64_t>(r);
  }
}

void writeBytesAtomic(const std::string& path, const void* data, std::size_t n) {
  namespace fs = std::filesystem;
  const fs::path target(path);
  const std::string tmp = atomicTemporaryFor(path);
  try {
    DirectFile f(tmp, n + 1);  // one buffer holds it all: a single write at close()
    f.write(data, n);
    f.close();
    std::error_code ec;
    fs::rename(tmp, target, ec);
    if (ec) throw Error(path, "cannot move the finished file into place: " + ec.message());
  } catch (const Error& e) {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    std::string what = e.what();  // named by the real file, not the temporary
    const std::string prefix = Error::printable(tmp) + ": ";
    if (what.rfind(prefix, 0) != 0) throw;
    throw Error(path, what.substr(prefix.size()));
  }
}

}  // namespace cleanmap::io
