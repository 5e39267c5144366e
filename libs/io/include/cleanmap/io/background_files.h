// SPDX-License-Identifier: BSD-3-Clause
// Label files written, and spent temporaries removed, on a thread of their own (issue #16): a
// label file goes past the page cache (O_DIRECT, files.h), so its write waits for the device,
// and removing a large spool waits for the file system; the pipeline's thread should do neither.
#pragma once
#include <cstddef>
#include <functional>
#include <string>

#include "cleanmap/core/serial_worker.h"
#include "cleanmap/core/types.h"

namespace cleanmap::io {

class BackgroundFiles {
 public:
  /// `max_pending`: jobs queued at most; a call that would exceed it waits for the oldest.
  explicit BackgroundFiles(std::size_t max_pending = 2);
  /// Finishes the queued jobs (their errors are dropped: call wait() to see them).
  ~BackgroundFiles();
  BackgroundFiles(const BackgroundFiles&) = delete;
  BackgroundFiles& operator=(const BackgroundFiles&) = delete;

  /// Queues writeLabels(path, labels). An earlier job's error is rethrown here first (it names
  /// its file), and nothing is queued then.
  void writeLabels(std::string path, Labels labels);
  /// Queues the removal of a file (a missing one is no error).
  void remove(std::string path);
  /// Returns once every queued job is done; rethrows the first error of one.
  void wait();

 private:
  SerialWorker<std::function<void()>> worker_;
};

}  // namespace cleanmap::io
