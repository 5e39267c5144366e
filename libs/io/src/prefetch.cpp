// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/io/prefetch.h"

#include <algorithm>

namespace cleanmap::io {

PrefetchSource::PrefetchSource(std::unique_ptr<FrameSource> inner, std::size_t depth)
    : inner_(std::move(inner)),
      size_(inner_->sizeHint()),
      camera_(inner_->camera()),
      depth_(std::max<std::size_t>(depth, 1)) {
  worker_ = std::thread([this] { run(); });
}

PrefetchSource::~PrefetchSource() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  if (worker_.joinable()) worker_.join();  // a read in progress finishes first
}

std::unique_ptr<FrameSource> PrefetchSource::release() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  if (worker_.joinable()) worker_.join();
  ended_ = true;
  queue_.clear();
  return std::move(inner_);
}

void PrefetchSource::run() {
  for (;;) {
    {
      std::unique_lock<std::mutex> lock(mu_);
      cv_.wait(lock, [&] { return stop_ || queue_.size() < depth_; });
      if (stop_) return;
    }
    Item it;
    try {
      it.frame = inner_->next();
      it.camera = inner_->camera();
    } catch (...) {
      it.error = std::current_exception();
    }
    const bool last = !it.frame || it.error;
    {
      std::lock_guard<std::mutex> lock(mu_);
      queue_.push_back(std::move(it));
    }
    cv_.notify_all();
    if (last) return;
  }
}

std::optional<Frame> PrefetchSource::next() {
  if (ended_) return std::nullopt;
  Item it;
  {
    std::unique_lock<std::mutex> lock(mu_);
    cv_.wait(lock, [&] { return !queue_.empty(); });
    it = std::move(queue_.front());
    queue_.pop_front();
  }
  cv_.notify_all();
  if (it.error) {
    ended_ = true;
    std::rethrow_exception(it.error);
  }
  if (!it.frame) {
    ended_ = true;
    return std::nullopt;
  }
  camera_ = it.camera;
  return std::move(it.frame);
}

}  // namespace cleanmap::io
