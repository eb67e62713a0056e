// runtime/src/depth_order.h: the blending order of impostor quads is std::sort's order of
// (key, index) pairs.
#include "depth_order.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace bb::runtime {
namespace {

std::vector<std::uint32_t> reference(const std::vector<float>& keys) {
  std::vector<std::pair<float, std::uint32_t>> p;
  for (std::size_t i = 0; i < keys.size(); ++i) p.emplace_back(keys[i], static_cast<std::uint32_t>(i));
  std::sort(p.begin(), p.end());
  std::vector<std::uint32_t> out;
  for (const auto& x : p) out.push_back(x.second);
  return out;
}

TEST(DepthOrder, TinyCases) {
  DepthOrder d;
  std::vector<std::uint32_t> order{7, 7};
  d.sort({}, order);
  EXPECT_TRUE(order.empty());
  const std::vector<float> keys{3.0f, -1.5f, 3.0f, 0.0f, -0.0f, -1.5f, 1e-30f, -2e30f};
  d.sort(keys, order);
  // Ascending, ties (3, 3; -1.5, -1.5; 0, -0) in index order.
  EXPECT_EQ(order, (std::vector<std::uint32_t>{7, 1, 5, 3, 4, 6, 0, 2}));
}

TEST(DepthOrder, MatchesStdSortOnRandomKeys) {
  std::mt19937 rng(5);
  DepthOrder d;
  std::vector<std::uint32_t> order;
  for (int n : {1, 2, 100, 2500, 10000}) {
    for (int kind = 0; kind < 4; ++kind) {
      std::vector<float> keys(static_cast<std::size_t>(n));
      for (float& k : keys) {
        switch (kind) {
          case 0: k = std::uniform_real_distribution<float>(-500.0f, -50.0f)(rng); break;  // one sign
          case 1: k = std::uniform_real_distribution<float>(-1e6f, 1e6f)(rng); break;
          case 2: k = static_cast<float>(std::uniform_int_distribution<int>(-3, 3)(rng)); break;  // many ties
          default: k = std::ldexp(1.0f, std::uniform_int_distribution<int>(-120, 120)(rng)); break;
        }
      }
      d.sort(keys, order);
      EXPECT_EQ(order, reference(keys)) << "n " << n << " kind " << kind;
    }
  }
}

}  // namespace
}  // namespace bb::runtime
