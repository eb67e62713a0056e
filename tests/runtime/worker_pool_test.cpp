// runtime/src/worker_pool.h: every index is run exactly once, whatever the number of threads a
// call asks for, and a call never waits for a helper that nobody woke (a call that woke fewer
// helpers than the pool has once hung on the H100's host).
#include "worker_pool.h"

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <future>
#include <random>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace bb::runtime {
namespace {

TEST(WorkerPool, EveryIndexOnceWhateverTheThreadsAsked) {
  auto body = [] {
    WorkerPool pool(8);
    std::mt19937 rng(3);
    std::vector<std::atomic<int>> hits(64);
    int bad = 0;
    for (int call = 0; call < 100000; ++call) {
      const std::size_t count = std::uniform_int_distribution<std::size_t>(0, 64)(rng);
      const unsigned threads = std::uniform_int_distribution<unsigned>(1, 9)(rng);
      for (auto& h : hits) h.store(0);
      auto fn = [&](std::size_t k) { hits[k].fetch_add(1); };
      pool.run(count, fn, threads);
      for (std::size_t k = 0; k < hits.size(); ++k) bad += hits[k].load() != (k < count ? 1 : 0);
    }
    return bad;
  };
  auto result = std::async(std::launch::async, body);
  if (result.wait_for(std::chrono::seconds(60)) != std::future_status::ready) {
    std::fprintf(stderr, "WorkerPool.EveryIndexOnceWhateverTheThreadsAsked: a call did not return in 60 s (deadlock)\n");
    std::_Exit(1);
  }
  EXPECT_EQ(result.get(), 0);
}

// Planners of several models share a pool; calls from several threads take turns.
TEST(WorkerPool, SharedPoolServesCallersFromSeveralThreads) {
  auto a = WorkerPool::shared(4), b = WorkerPool::shared(4);
  EXPECT_EQ(a.get(), b.get());
  EXPECT_NE(WorkerPool::shared(3).get(), a.get());
  std::atomic<long> sum{0};
  std::vector<std::thread> callers;
  for (int t = 0; t < 3; ++t)
    callers.emplace_back([&] {
      for (int call = 0; call < 2000; ++call) {
        auto fn = [&](std::size_t k) { sum.fetch_add(static_cast<long>(k) + 1); };
        a->run(10, fn, 2 + call % 3);
      }
    });
  for (auto& c : callers) c.join();
  EXPECT_EQ(sum.load(), 3L * 2000 * 55);
}

}  // namespace
}  // namespace bb::runtime
