// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/io/background_files.h"

#include <algorithm>
#include <filesystem>
#include <utility>

#include "cleanmap/io/files.h"

namespace cleanmap::io {

BackgroundFiles::BackgroundFiles(std::size_t max_pending)
    : worker_([](std::function<void()>& job) { job(); }, std::max<std::size_t>(max_pending, 1)) {}

BackgroundFiles::~BackgroundFiles() {
  try {
    worker_.wait();  // the jobs left run first
  } catch (...) {
  }
}

void BackgroundFiles::writeLabels(std::string path, Labels labels) {
  worker_.push(
      [path = std::move(path), labels = std::move(labels)] { io::writeLabels(path, labels); });
}

void BackgroundFiles::remove(std::string path) {
  worker_.push([path = std::move(path)] {
    std::error_code ec;
    std::filesystem::remove(path, ec);
  });
}

void BackgroundFiles::wait() {
  worker_.wait();
}

}  // namespace cleanmap::io
