// A persistent pool of worker threads for per-frame work in the runtime (the planner): threads
// are started once and sleep between calls, so a call costs a wake-up, not a thread start, and
// allocates nothing. A call wakes only the workers it asks for: in a virtual machine (the H100's
// host) each wake-up and the wait for it cost tens of microseconds, more than a few hundred
// characters' planning. Pools are shared by thread count (WorkerPool::shared): planners of several
// models take turns on one set of threads instead of each starting its own.
#pragma once

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <map>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace bb::runtime {

class WorkerPool {
 public:
  // `threads` in all, the calling thread included (at least 1: then run() calls inline).
  explicit WorkerPool(unsigned threads) {
    for (unsigned t = 1; t < threads; ++t) threads_.emplace_back([this] { work_loop(); });
  }
  ~WorkerPool() {
    {
      std::lock_guard<std::mutex> lock(m_);
      stop_ = true;
    }
    wake_.notify_all();
    for (auto& t : threads_) t.join();
  }
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  unsigned size() const { return static_cast<unsigned>(threads_.size()) + 1; }

  // The pool of `threads` threads that every caller asking for that many shares (started at the
  // first request, ended with its last user).
  static std::shared_ptr<WorkerPool> shared(unsigned threads) {
    static std::mutex m;
    static std::map<unsigned, std::weak_ptr<WorkerPool>> pools;
    std::lock_guard<std::mutex> lock(m);
    std::shared_ptr<WorkerPool> p = pools[threads].lock();
    if (!p) {
      p = std::make_shared<WorkerPool>(threads);
      pools[threads] = p;
    }
    return p;
  }

  // Calls fn(k) for every k in [0, count) on at most `threads` threads, the calling thread
  // included; returns when every call has returned. fn must be safe to call concurrently for
  // different k and not throw. Calls from several threads take turns.
  template <typename Fn>
  void run(std::size_t count, Fn& fn, unsigned threads = ~0u) {
    const std::size_t helpers = std::min({threads_.size(), std::size_t{std::max(threads, 1u)} - 1, count - std::min<std::size_t>(count, 1)});
    if (helpers == 0) {
      for (std::size_t k = 0; k < count; ++k) fn(k);
      return;
    }
    std::lock_guard<std::mutex> turn(turn_);
    {
      std::lock_guard<std::mutex> lock(m_);
      call_ = [](void* f, std::size_t k) { (*static_cast<Fn*>(f))(k); };
      ctx_ = &fn;
      count_ = count;
      next_.store(0);
      busy_ = slots_ = helpers;
    }
    if (helpers == threads_.size()) {
      wake_.notify_all();
    } else {
      for (std::size_t h = 0; h < helpers; ++h) wake_.notify_one();
    }
    drain(call_, ctx_, count);
    std::unique_lock<std::mutex> lock(m_);
    done_.wait(lock, [this] { return busy_ == 0; });
  }

 private:
  void drain(void (*call)(void*, std::size_t), void* ctx, std::size_t count) {
    for (std::size_t k; (k = next_.fetch_add(1)) < count;) call(ctx, k);
  }
  void work_loop() {
    for (;;) {
      void (*call)(void*, std::size_t);
      void* ctx;
      std::size_t count;
      {
        // Wakes while the call still wants helpers: each wake-up a call sends is then a helper
        // (a worker woken again after helping, or one that was not asleep, takes a place no
        // wake-up is lost on), so the call's wait for its helpers ends.
        std::unique_lock<std::mutex> lock(m_);
        wake_.wait(lock, [&] { return stop_ || slots_ > 0; });
        if (stop_) return;
        --slots_;
        call = call_;
        ctx = ctx_;
        count = count_;
      }
      drain(call, ctx, count);
      {
        std::lock_guard<std::mutex> lock(m_);
        if (--busy_ == 0) done_.notify_one();
      }
    }
  }

  std::vector<std::thread> threads_;
  std::mutex m_, turn_;
  std::condition_variable wake_, done_;
  bool stop_ = false;
  // busy_: helpers of the current call not yet done; slots_: helpers it still wants.
  std::size_t busy_ = 0, slots_ = 0, count_ = 0;
  void (*call_)(void*, std::size_t) = nullptr;
  void* ctx_ = nullptr;
  std::atomic<std::size_t> next_{0};
};

}  // namespace bb::runtime
