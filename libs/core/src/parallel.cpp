// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/parallel.h"

#include <unistd.h>

#include <condition_variable>
#include <cstdint>
#include <exception>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

namespace cleanmap::detail {
namespace {

// The helper threads of one calling thread. Each waits for the next job's generation; a job
// needs the helpers 1 .. width - 1, and returns once all of those have run it.
class Workers {
 public:
  Workers() = default;
  Workers(const Workers&) = delete;
  Workers& operator=(const Workers&) = delete;
  ~Workers() {
    if (::getpid() != pid_) {  // a fork's child: the helpers stayed in the parent
      for (auto& t : threads_) t.detach();
      return;
    }
    {
      std::lock_guard<std::mutex> l(m_);
      stop_ = true;
    }
    start_.notify_all();
    for (auto& t : threads_) t.join();
  }

  /// False while a job runs on this thread, and in a fork's child (its helpers did not follow).
  bool usable() const { return !busy_ && ::getpid() == pid_; }

  void run(int t, const std::function<void(int)>& work) {
    // Only this thread writes gen_: a new helper starts from the generation it was made in. (A
    // thread that cannot start throws here, before anything is marked busy.)
    while (static_cast<int>(threads_.size()) < t - 1) {
      const int w = static_cast<int>(threads_.size()) + 1;
      threads_.emplace_back([this, w, g = gen_] { loop(w, g); });
    }
    busy_ = true;
    {
      std::lock_guard<std::mutex> l(m_);
      work_ = &work;
      width_ = t;
      pending_ = t - 1;
      error_ = nullptr;
      ++gen_;
    }
    start_.notify_all();
    std::exception_ptr mine;
    try {
      work(0);
    } catch (...) {
      mine = std::current_exception();
    }
    std::exception_ptr theirs;
    {
      std::unique_lock<std::mutex> l(m_);
      done_.wait(l, [&] { return pending_ == 0; });
      work_ = nullptr;
      theirs = std::exchange(error_, nullptr);
    }
    busy_ = false;
    if (mine) std::rethrow_exception(mine);
    if (theirs) std::rethrow_exception(theirs);
  }

 private:
  void loop(int w, uint64_t seen) {
    std::unique_lock<std::mutex> l(m_);
    for (;;) {
      start_.wait(l, [&] { return stop_ || gen_ != seen; });
      if (stop_) return;
      seen = gen_;
      if (w >= width_) continue;  // a narrower job than this helper's number
      const std::function<void(int)>* work = work_;
      l.unlock();
      std::exception_ptr e;
      try {
        (*work)(w);
      } catch (...) {
        e = std::current_exception();
      }
      l.lock();
      if (e && !error_) error_ = e;
      if (--pending_ == 0) done_.notify_one();
    }
  }

  std::mutex m_;
  std::condition_variable start_, done_;
  std::vector<std::thread> threads_;
  const std::function<void(int)>* work_ = nullptr;
  std::exception_ptr error_;
  uint64_t gen_ = 0;
  int width_ = 0, pending_ = 0;
  bool stop_ = false, busy_ = false;
  const pid_t pid_ = ::getpid();
};

}  // namespace

void runOnWorkers(int t, const std::function<void(int)>& work) {
  thread_local Workers workers;
  if (workers.usable()) {
    workers.run(t, work);
    return;
  }
  // Nested in this thread's own job, or in a fork's child: threads of its own, as before the
  // helpers were kept.
  std::vector<std::thread> pool;
  std::vector<std::exception_ptr> errors(static_cast<std::size_t>(t));
  pool.reserve(static_cast<std::size_t>(t - 1));
  for (int w = 1; w < t; ++w)
    pool.emplace_back([&, w] {
      try {
        work(w);
      } catch (...) {
        errors[std::size_t(w)] = std::current_exception();
      }
    });
  try {
    work(0);
  } catch (...) {
    errors[0] = std::current_exception();
  }
  for (auto& th : pool) th.join();
  for (const auto& e : errors)
    if (e) std::rethrow_exception(e);
}

}  // namespace cleanmap::detail
