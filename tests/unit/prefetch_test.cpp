// SPDX-License-Identifier: BSD-3-Clause
// io::PrefetchSource (issue #16): the frames of the source it wraps, in order, with its errors
// where they occur and its camera as it was after each frame.
#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>

#include "cleanmap/core/error.h"
#include "cleanmap/io/prefetch.h"

namespace {

using namespace cleanmap;

// Frames 0..n-1 (frame i holds i points); throws at frame `fail` (if < n). Its camera appears
// with frame `camera_at`, as a rawlog's does with its first image.
class Counting : public FrameSource {
 public:
  Counting(std::size_t n, std::size_t fail, std::size_t camera_at, std::atomic<std::size_t>* reads)
      : n_(n), fail_(fail), camera_at_(camera_at), reads_(reads) {}
  std::optional<Frame> next() override {
    if (i_ == fail_) throw Error("fake.rawlog", "entry " + std::to_string(i_) + " is truncated");
    if (i_ >= n_) return std::nullopt;
    Frame f;
    f.index = i_;
    f.scan.points.resize(i_);
    if (i_ == camera_at_) camera_ = PinholeCamera{};
    ++i_;
    if (reads_) ++*reads_;
    return f;
  }
  std::optional<std::size_t> sizeHint() const override { return n_; }
  std::optional<PinholeCamera> camera() const override { return camera_; }

 private:
  std::size_t n_, fail_, camera_at_, i_ = 0;
  std::atomic<std::size_t>* reads_;
  std::optional<PinholeCamera> camera_;
};

TEST(PrefetchSource, GivesTheSameFramesInOrderThenTheEnd) {
  for (const std::size_t depth : {1, 3}) {
    io::PrefetchSource src(std::make_unique<Counting>(50, 999, 999, nullptr), depth);
    EXPECT_EQ(src.sizeHint(), 50u);
    for (std::size_t i = 0; i < 50; ++i) {
      const auto f = src.next();
      ASSERT_TRUE(f);
      EXPECT_EQ(f->index, i);
      EXPECT_EQ(f->scan.points.size(), i);
    }
    EXPECT_FALSE(src.next());
    EXPECT_FALSE(src.next());  // and stays at the end
  }
}

TEST(PrefetchSource, ThrowsTheErrorWhereTheSourceDoes) {
  io::PrefetchSource src(std::make_unique<Counting>(50, 7, 999, nullptr));
  for (std::size_t i = 0; i < 7; ++i) ASSERT_EQ(src.next()->index, i);
  try {
    src.next();
    FAIL() << "the source's error was not thrown";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("fake.rawlog"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("entry 7 is truncated"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(src.next());
}

TEST(PrefetchSource, CameraIsTheSourcesAsOfTheLastFrameReturned) {
  io::PrefetchSource src(std::make_unique<Counting>(10, 999, 3, nullptr));
  for (std::size_t i = 0; i < 10; ++i) {
    ASSERT_TRUE(src.next());
    EXPECT_EQ(src.camera().has_value(), i >= 3) << i;  // not earlier, though read ahead
  }
}

TEST(PrefetchSource, ReadsAtMostDepthAheadAndStopsWhenDropped) {
  std::atomic<std::size_t> reads{0};
  {
    io::PrefetchSource src(std::make_unique<Counting>(1000, 999999, 999999, &reads), 2);
    ASSERT_EQ(src.next()->index, 0u);
    ASSERT_EQ(src.next()->index, 1u);
    // Two returned, at most two waiting, and one more being read: never the whole input.
    for (int k = 0; k < 1000 && reads < 4; ++k) std::this_thread::yield();
    EXPECT_LE(reads.load(), 5u);
  }  // destroyed mid-stream: joins its thread, no hang
  EXPECT_LE(reads.load(), 5u);
}

}  // namespace

// The app stops reading ahead to ask the source what it counted (a rawlog's skipped sensors):
// release() waits for the read in progress and hands the source back, where it stopped (one frame
// ahead of the consumer at most); the prefetching source then gives nothing more.
TEST(PrefetchSource, ReleaseHandsTheSourceBackWhereItStopped) {
  std::atomic<std::size_t> reads{0};
  io::PrefetchSource src(std::make_unique<Counting>(50, 999, 999, &reads), 1);
  for (std::size_t i = 0; i < 5; ++i) ASSERT_EQ(src.next()->index, i);
  auto inner = src.release();
  ASSERT_TRUE(inner);
  EXPECT_GE(reads.load(), 5u);
  EXPECT_LE(reads.load(), 7u);
  EXPECT_FALSE(src.next());
  const auto f = inner->next();  // the source goes on from where the reading stopped
  ASSERT_TRUE(f);
  EXPECT_EQ(f->index, reads.load() - 1);
}
