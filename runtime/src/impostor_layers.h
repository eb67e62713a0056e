// Blended impostors of several models in one frame (Renderer::draw_many): each model's quads are
// one draw sorted back to front, so where a nearer quad of one model overlaps a farther quad of
// another, the farther one must be drawn in an earlier draw, or the nearer one's soft edge (which
// writes depth, or, for part cards, nothing) is not blended over it. This assigns each quad a
// layer: drawn layer by layer, each layer a draw per model, every overlapping pair of quads of
// different models is then drawn far before near, and pairs of one model keep their order within
// the model's sorted draws. Pure CPU code on screen rectangles; no GL.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include <glm/glm.hpp>

namespace bb::runtime {

// A quad on screen: its model, its rectangle in pixels (x0, y0, x1, y1; empty when x0 >= x1 or
// y0 >= y1: it overlaps nothing), and the lowest layer it may take.
struct LayerQuad {
  int model = 0;
  glm::vec4 rect{0.0f};
  int min_layer = 0;
};

class ImpostorLayers {
 public:
  // layers[q] for the quads in `far_to_near` order (indices into `quads`, farthest first) on a
  // `width` x `height` screen: the smallest layer from the quad's min_layer on that is at least
  // each farther overlapping quad's of the same model and above each farther overlapping quad's
  // of another model, capped at
  // max_layers - 1 (past the cap, order between models is no longer kept: crowds whose overlaps
  // chain deeper than that across models). Returns the number of layers used.
  int assign(std::span<const LayerQuad> quads, std::span<const std::uint32_t> far_to_near, int width, int height,
             int max_layers, std::vector<int>& layers) {
    layers.assign(quads.size(), 0);
    cols_ = std::max(1, (width + kCell - 1) / kCell);
    rows_ = std::max(1, (height + kCell - 1) / kCell);
    cells_.resize(static_cast<std::size_t>(cols_) * rows_);
    for (auto& cell : cells_) cell.clear();  // keeps their memory from frame to frame
    int used = quads.empty() ? 0 : 1;
    for (std::uint32_t q : far_to_near) {
      const LayerQuad& a = quads[q];
      int layer = std::clamp(a.min_layer, 0, max_layers - 1);
      int c0, r0, c1, r1;
      if (!cells_of(a.rect, width, height, c0, r0, c1, r1)) {  // overlaps nothing
        layers[q] = layer;
        used = std::max(used, layer + 1);
        continue;
      }
      for (int r = r0; r <= r1; ++r)
        for (int c = c0; c <= c1; ++c)
          for (std::uint32_t p : cells_[static_cast<std::size_t>(r) * cols_ + c]) {
            const LayerQuad& b = quads[p];
            if (!overlap(a.rect, b.rect)) continue;
            layer = std::max(layer, b.model == a.model ? layers[p] : layers[p] + 1);
          }
      layer = std::min(layer, max_layers - 1);
      layers[q] = layer;
      used = std::max(used, layer + 1);
      for (int r = r0; r <= r1; ++r)
        for (int c = c0; c <= c1; ++c) cells_[static_cast<std::size_t>(r) * cols_ + c].push_back(q);
    }
    return used;
  }

 private:
  static constexpr int kCell = 32;  // pixels a grid cell

  static bool overlap(const glm::vec4& a, const glm::vec4& b) {
    return a.x < b.z && b.x < a.z && a.y < b.w && b.y < a.w;
  }
  bool cells_of(const glm::vec4& r, int width, int height, int& c0, int& r0, int& c1, int& r1) const {
    if (!(r.x < r.z && r.y < r.w)) return false;  // empty (or NaN)
    if (r.z <= 0.0f || r.w <= 0.0f || r.x >= static_cast<float>(width) || r.y >= static_cast<float>(height)) return false;
    c0 = std::clamp(static_cast<int>(std::floor(r.x / kCell)), 0, cols_ - 1);
    r0 = std::clamp(static_cast<int>(std::floor(r.y / kCell)), 0, rows_ - 1);
    c1 = std::clamp(static_cast<int>(std::floor(r.z / kCell)), 0, cols_ - 1);
    r1 = std::clamp(static_cast<int>(std::floor(r.w / kCell)), 0, rows_ - 1);
    return true;
  }

  int cols_ = 1, rows_ = 1;
  std::vector<std::vector<std::uint32_t>> cells_;
};

}  // namespace bb::runtime
