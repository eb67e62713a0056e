// ImpostorLayers (runtime/src/impostor_layers.h): the layers Renderer::draw_many draws several
// models' blended quads in, exact on tiny cases, and the ordering property on random screens.
#include <cstdint>
#include <numeric>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "impostor_layers.h"

namespace bb::runtime {
namespace {

std::vector<std::uint32_t> in_order(std::size_t n) {
  std::vector<std::uint32_t> o(n);
  std::iota(o.begin(), o.end(), 0u);
  return o;
}

TEST(ImpostorLayers, OverlapsAcrossModelsGoUpALayerAndWithinAModelDoNot) {
  ImpostorLayers l;
  std::vector<int> layers;
  // Farthest first: A (model 0), B (model 1) over A, C (model 0) over B, D (model 1) apart.
  const std::vector<LayerQuad> q = {{0, {0, 0, 40, 40}}, {1, {30, 30, 70, 70}}, {0, {60, 60, 90, 90}}, {1, {200, 0, 240, 40}}};
  EXPECT_EQ(l.assign(q, in_order(q.size()), 320, 240, 8, layers), 3);
  EXPECT_EQ(layers, (std::vector<int>{0, 1, 2, 0}));
  // One model: overlapping quads share the layer (its draw is sorted back to front).
  const std::vector<LayerQuad> same = {{0, {0, 0, 40, 40}}, {0, {30, 30, 70, 70}}, {0, {60, 60, 90, 90}}};
  EXPECT_EQ(l.assign(same, in_order(same.size()), 320, 240, 8, layers), 1);
  EXPECT_EQ(layers, (std::vector<int>{0, 0, 0}));
  // Touching edges do not overlap (half-open pixels).
  const std::vector<LayerQuad> touch = {{0, {0, 0, 40, 40}}, {1, {40, 0, 80, 40}}};
  l.assign(touch, in_order(touch.size()), 320, 240, 8, layers);
  EXPECT_EQ(layers, (std::vector<int>{0, 0}));
  // The order given is what counts: C nearest, then B, then A farthest.
  l.assign(q, std::vector<std::uint32_t>{2, 1, 0, 3}, 320, 240, 8, layers);
  EXPECT_EQ(layers, (std::vector<int>{2, 1, 0, 0}));
}

TEST(ImpostorLayers, CapsTheLayersAndKeepsMinimumLayers) {
  ImpostorLayers l;
  std::vector<int> layers;
  std::vector<LayerQuad> chain;
  for (int i = 0; i < 5; ++i) chain.push_back({i % 2, {20.0f * i, 0, 20.0f * i + 30, 30}});
  EXPECT_EQ(l.assign(chain, in_order(chain.size()), 320, 240, 3, layers), 3);
  EXPECT_EQ(layers, (std::vector<int>{0, 1, 2, 2, 2}));
  // Quads with no rectangle (small, or off screen) take their min_layer and constrain nothing.
  const std::vector<LayerQuad> q = {{0, {0, 0, 0, 0}, 0}, {1, {0, 0, 50, 50}, 1}, {0, {-90, -90, -10, -10}, 1},
                                    {1, {10, 10, 60, 60}, 1}};
  EXPECT_EQ(l.assign(q, in_order(q.size()), 320, 240, 8, layers), 2);
  EXPECT_EQ(layers, (std::vector<int>{0, 1, 1, 1}));
}

// On random screens of three models: every overlapping pair of different models is drawn far
// before near (below the cap), and of one model never near before far.
TEST(ImpostorLayers, FarBeforeNearForEveryOverlappingPair) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> pos(-20.0f, 660.0f), size(4.0f, 120.0f);
  ImpostorLayers l;
  std::vector<int> layers;
  for (int trial = 0; trial < 50; ++trial) {
    std::vector<LayerQuad> q(60);
    for (std::size_t i = 0; i < q.size(); ++i) {
      const float x = pos(rng), y = pos(rng) * 0.75f;
      q[i] = {static_cast<int>(rng() % 3), {x, y, x + size(rng), y + size(rng)}};
    }
    std::vector<std::uint32_t> order = in_order(q.size());
    std::shuffle(order.begin(), order.end(), rng);
    const int cap = 32;
    const int used = l.assign(q, order, 640, 480, cap, layers);
    ASSERT_LT(used, cap) << "trial " << trial << ": raise the cap for this check";
    for (std::size_t a = 0; a < order.size(); ++a)
      for (std::size_t b = a + 1; b < order.size(); ++b) {
        const LayerQuad &far = q[order[a]], &near = q[order[b]];
        const bool overlap = far.rect.x < near.rect.z && near.rect.x < far.rect.z && far.rect.y < near.rect.w &&
                             near.rect.y < far.rect.w;
        auto seen = [](const LayerQuad& r) { return r.rect.z > 0 && r.rect.w > 0 && r.rect.x < 640 && r.rect.y < 480; };
        const bool on_screen = seen(far) && seen(near);  // a quad wholly off screen constrains nothing
        if (!overlap || !on_screen) continue;
        if (far.model == near.model)
          EXPECT_LE(layers[order[a]], layers[order[b]]);
        else
          EXPECT_LT(layers[order[a]], layers[order[b]]);
      }
  }
}

}  // namespace
}  // namespace bb::runtime
