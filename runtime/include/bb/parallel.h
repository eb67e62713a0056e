// A small worker pool for the offline tools: no third-party code, no state between calls.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <thread>
#include <vector>

namespace bb {

// Calls fn(i) for every i in [0, count) on up to `threads` threads (0: one per hardware thread),
// the calling thread included, and returns when all calls have returned. Indices are handed out
// in increasing order from a shared counter, so long jobs placed first balance best. fn must be
// safe to call concurrently for different i; it must not throw.
template <typename Fn>
void parallel_for(std::size_t count, unsigned threads, Fn&& fn) {
  if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
  const std::size_t workers = std::min<std::size_t>(threads, count);
  std::atomic<std::size_t> next{0};
  auto work = [&] {
    for (std::size_t i; (i = next++) < count;) fn(i);
  };
  std::vector<std::thread> pool;
  pool.reserve(workers > 0 ? workers - 1 : 0);
  for (std::size_t w = 1; w < workers; ++w) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
}

}  // namespace bb
