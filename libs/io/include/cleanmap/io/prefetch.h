// SPDX-License-Identifier: BSD-3-Clause
// A frame source that reads ahead on its own thread (issue #16): reading a KITTI scan and
// decoding its camera image take 5-10 ms, which then overlap the pipeline's work on the frame
// before instead of lying on its path.
#pragma once
#include <condition_variable>
#include <deque>
#include <exception>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include "cleanmap/core/frame.h"

namespace cleanmap::io {

/// The frames of `inner`, in the same order, read up to `depth` frames ahead. An error of the
/// inner source is thrown by the next() that reaches it (the frames before it come first); after
/// the end or an error, next() returns nullopt. camera() is the inner source's as it was when the
/// last returned frame had been read (a rawlog learns its camera from its first image). While
/// this source lives, only `inner`'s const methods that next() leaves alone may be called from
/// elsewhere (KittiSequence::loadLabels, for example).
class PrefetchSource : public FrameSource {
 public:
  explicit PrefetchSource(std::unique_ptr<FrameSource> inner, std::size_t depth = 1);
  ~PrefetchSource() override;
  PrefetchSource(const PrefetchSource&) = delete;
  PrefetchSource& operator=(const PrefetchSource&) = delete;

  std::optional<Frame> next() override;
  /// Stops reading ahead (a read in progress finishes first) and hands the inner source back, for
  /// what it counted; next() then returns nothing more.
  std::unique_ptr<FrameSource> release();
  std::optional<std::size_t> sizeHint() const override { return size_; }
  std::optional<PinholeCamera> camera() const override { return camera_; }

 private:
  struct Item {
    std::optional<Frame> frame;
    std::optional<PinholeCamera> camera;
    std::exception_ptr error;
  };
  void run();

  std::unique_ptr<FrameSource> inner_;
  std::optional<std::size_t> size_;
  std::optional<PinholeCamera> camera_;
  std::size_t depth_;
  bool ended_ = false;  // the consumer has seen the end or an error
  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<Item> queue_;
  bool stop_ = false;
  std::thread worker_;
};

}  // namespace cleanmap::io
