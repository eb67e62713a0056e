// The order in which a frame's impostor quads are blended, in linear time: a stable LSD radix sort
// of 32-bit float keys. It gives exactly the order std::sort gives to (key, index) pairs: keys
// ascending, equal keys in index order (-0 counts as +0). Flow test bed, 10,000 humans: the sort
// and the gather behind it were 1.2 ms of the impostor frame's 1.6 ms of submission on the H100's
// host with std::sort. Allocates only when a frame has more quads than any before.
#pragma once

#include <array>
#include <cstdint>
#include <cstring>
#include <span>
#include <vector>

namespace bb::runtime {

class DepthOrder {
 public:
  // order = the indices of `keys` sorted by key (ascending), ties in index order. Keys must not
  // be NaN.
  void sort(std::span<const float> keys, std::vector<std::uint32_t>& order) {
    const std::size_t n = keys.size();
    a_.resize(n);
    b_.resize(n);
    std::array<std::array<std::uint32_t, kBuckets>, kPasses> count{};
    for (std::size_t i = 0; i < n; ++i) {
      const float k = keys[i] + 0.0f;  // -0 -> +0
      std::uint32_t u;
      std::memcpy(&u, &k, sizeof u);
      u = (u & 0x80000000u) ? ~u : (u | 0x80000000u);  // unsigned order = float order
      a_[i] = (std::uint64_t{u} << 32) | i;
      for (int p = 0; p < kPasses; ++p) ++count[p][(u >> (kBits * p)) & (kBuckets - 1)];
    }
    std::vector<std::uint64_t>* from = &a_;
    std::vector<std::uint64_t>* to = &b_;
    for (int p = 0; p < kPasses; ++p) {
      auto& c = count[p];
      // A pass whose digit is the same for every key leaves the order as it is.
      if (n == 0 || c[((*from)[0] >> (32 + kBits * p)) & (kBuckets - 1)] == n) continue;
      std::uint32_t sum = 0;
      for (auto& x : c) {
        const std::uint32_t v = x;
        x = sum;
        sum += v;
      }
      for (std::size_t i = 0; i < n; ++i) {
        const std::uint64_t r = (*from)[i];
        (*to)[c[(r >> (32 + kBits * p)) & (kBuckets - 1)]++] = r;
      }
      std::swap(from, to);
    }
    order.resize(n);
    for (std::size_t i = 0; i < n; ++i) order[i] = static_cast<std::uint32_t>((*from)[i]);
  }

 private:
  static constexpr int kBits = 11, kPasses = 3;  // 33 bits >= 32
  static constexpr std::size_t kBuckets = std::size_t{1} << kBits;
  std::vector<std::uint64_t> a_, b_;  // (key bits << 32) | index
};

}  // namespace bb::runtime
