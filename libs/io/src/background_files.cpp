// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/io/background_files.h"

#include <algorithm>
#include <filesystem>
#include <utility>

#include "cleanmap/io/files.h"

namespace cleanmap::io {

BackgroundFiles::BackgroundFiles(std::size_t max_pending)
    : max_pending_(std::max<std::size_t>(max_pending, 1)) {}

BackgroundFiles::~BackgroundFiles() {
  {
    std::lock_guard<std::mutex> l(m_);
    closing_ = true;
  }
  cv_.notify_all();
  if (worker_.joinable()) worker_.join();  // it runs the jobs left first
}

void BackgroundFiles::push(std::function<void()> job) {
  std::unique_lock<std::mutex> l(m_);
  cv_.wait(l, [&] { return error_ || jobs_.size() + running_ < max_pending_; });
  if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
  jobs_.push_back(std::move(job));
  if (!worker_.joinable()) worker_ = std::thread([this] { run(); });
  l.unlock();
  cv_.notify_all();
}

void BackgroundFiles::writeLabels(std::string path, Labels labels) {
  push([path = std::move(path), labels = std::move(labels)] { io::writeLabels(path, labels); });
}

void BackgroundFiles::remove(std::string path) {
  push([path = std::move(path)] {
    std::error_code ec;
    std::filesystem::remove(path, ec);
  });
}

void BackgroundFiles::wait() {
  std::unique_lock<std::mutex> l(m_);
  cv_.wait(l, [&] { return jobs_.empty() && running_ == 0; });
  if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
}

void BackgroundFiles::run() {
  std::unique_lock<std::mutex> l(m_);
  for (;;) {
    cv_.wait(l, [&] { return closing_ || !jobs_.empty(); });
    if (jobs_.empty()) return;  // closing, nothing left
    std::function<void()> job = std::move(jobs_.front());
    jobs_.pop_front();
    ++running_;
    l.unlock();
    std::exception_ptr e;
    try {
      job();
    } catch (...) {
      e = std::current_exception();
    }
    job = nullptr;  // its labels go before the next is taken
    l.lock();
    --running_;
    if (e && !error_) error_ = e;
    cv_.notify_all();
  }
}

}  // namespace cleanmap::io
