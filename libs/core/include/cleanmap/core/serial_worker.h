// SPDX-License-Identifier: BSD-3-Clause
// One thread of its own that runs the jobs given to it, one at a time, in the order given (issue
// #16: the free-space insertions, the registration ahead, the label files, the MRPT outputs;
// DESIGN §4, "Threads"). The first job that throws keeps its error: the jobs queued after it are
// dropped, none is taken any more, and the caller's next push(), wait() or takeMs() rethrows it
// (every later one too).
#pragma once
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <utility>

namespace cleanmap {

template <class Job>
class SerialWorker {
 public:
  using Run = std::function<void(Job&)>;

  /// `run` is called on the worker's thread, once per job. `max_pending`: jobs queued or
  /// running at most; push() waits while that many are (0: no bound). The thread starts with
  /// the first job.
  explicit SerialWorker(Run run, std::size_t max_pending = 0)
      : run_(std::move(run)), max_pending_(max_pending) {}
  /// Drops the queued jobs and waits for the running one (call wait() first to finish them).
  ~SerialWorker() { stop(); }
  SerialWorker(const SerialWorker&) = delete;
  SerialWorker& operator=(const SerialWorker&) = delete;

  /// Queues a job. `tag` orders it for doneThrough() / waitThrough() (a scan's index; tags never
  /// decrease from one push to the next). Rethrows an earlier job's error, and queues nothing then.
  void push(Job&& job, long tag = 0) {
    std::unique_lock<std::mutex> lock(mu_);
    cv_.wait(lock,
             [&] { return error_ || max_pending_ == 0 || jobs_.size() + running_ < max_pending_; });
    if (error_) std::rethrow_exception(error_);
    jobs_.push_back({std::move(job), tag});
    if (!thread_.joinable()) thread_ = std::thread([this] { loop(); });
    lock.unlock();
    cv_.notify_all();
  }
  /// True when no job tagged `tag` or less is queued or running (does not wait).
  bool doneThrough(long tag) {
    std::lock_guard<std::mutex> lock(mu_);
    return doneThroughLocked(tag);
  }
  /// Waits until no job tagged `tag` or less is queued or running (after an error, at once).
  void waitThrough(long tag) {
    std::unique_lock<std::mutex> lock(mu_);
    cv_.wait(lock, [&] { return doneThroughLocked(tag); });
  }
  /// Waits until every job is done; rethrows a job's error.
  void wait() {
    std::unique_lock<std::mutex> lock(mu_);
    cv_.wait(lock, [&] { return jobs_.empty() && !running_; });
    if (error_) std::rethrow_exception(error_);
  }
  /// The time the jobs finished since the last call took to run, in ms; rethrows a job's error.
  double takeMs() {
    std::lock_guard<std::mutex> lock(mu_);
    if (error_) std::rethrow_exception(error_);
    return std::exchange(ms_, 0.0);
  }
  /// Drops the queued jobs, waits for the running one and ends the thread (a later push()
  /// starts it again).
  void stop() {
    {
      std::lock_guard<std::mutex> lock(mu_);
      closing_ = true;
      jobs_.clear();
    }
    cv_.notify_all();
    if (thread_.joinable()) thread_.join();
    std::lock_guard<std::mutex> lock(mu_);
    closing_ = false;
  }

 private:
  struct Entry {
    Job job;
    long tag;
  };
  bool doneThroughLocked(long tag) const {
    return (jobs_.empty() || jobs_.front().tag > tag) && (!running_ || busy_ > tag);
  }
  void loop() {
    std::unique_lock<std::mutex> lock(mu_);
    for (;;) {
      cv_.wait(lock, [&] { return closing_ || !jobs_.empty(); });
      if (jobs_.empty()) return;  // closing
      std::exception_ptr e;
      double ms = 0;
      {
        Entry entry = std::move(jobs_.front());
        jobs_.pop_front();
        busy_ = entry.tag;
        running_ = true;
        lock.unlock();
        const auto t0 = std::chrono::steady_clock::now();
        try {
          run_(entry.job);
        } catch (...) {
          e = std::current_exception();
        }
        ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                 .count();
      }  // the job is freed before the next is taken
      lock.lock();
      running_ = false;
      ms_ += ms;
      if (e && !error_) {
        error_ = e;
        jobs_.clear();
      }
      cv_.notify_all();
    }
  }

  Run run_;
  std::size_t max_pending_;
  std::mutex mu_;
  std::condition_variable cv_;  // a job queued, a job done, closing
  std::deque<Entry> jobs_;
  bool running_ = false;
  long busy_ = 0;  // the running job's tag
  bool closing_ = false;
  double ms_ = 0;
  std::exception_ptr error_;
  std::thread thread_;
};

}  // namespace cleanmap
