// Internal: nearest-triangle queries on a triangle mesh through a uniform grid (GLM only). The
// runtime measures its made levels with it (lod_generate.cpp); the offline decimation its
// distances (decimate/src), which include it from here.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

namespace bb::runtime::detail {

// Closest point on triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5).
inline glm::vec3 closest_on_triangle(const glm::vec3& p, const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  glm::vec3 ab = b - a, ac = c - a, ap = p - a;
  float d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return a;
  glm::vec3 bp = p - b;
  float d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return b;
  float vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + ab * (d1 / (d1 - d3));
  glm::vec3 cp = p - c;
  float d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return c;
  float vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + ac * (d2 / (d2 - d6));
  float va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  float denom = 1.0f / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

// The triangles `idx` (of vertices `p`) in a uniform grid over their own bounds, cells
// `cell_edges` times the mean edge length, stored flat (offsets + triangle lists). Queries search growing
// shells of cells and stop once no unseen triangle can be nearer than the best found.
class TriangleGrid {
 public:
  TriangleGrid(const std::vector<glm::vec3>& p, const std::vector<uint32_t>& idx, float cell_edges = 2.0f) : p_(p), idx_(idx) {
    const size_t tris = idx.size() / 3;
    double edge_sum = 0;
    for (size_t t = 0; t < tris; ++t) {
      const glm::vec3 &a = p[idx[3 * t]], &b = p[idx[3 * t + 1]], &c = p[idx[3 * t + 2]];
      lo_ = glm::min(lo_, glm::min(a, glm::min(b, c)));
      hi_ = glm::max(hi_, glm::max(a, glm::max(b, c)));
      edge_sum += glm::length(b - a) + glm::length(c - b) + glm::length(a - c);
    }
    if (tris == 0) lo_ = hi_ = glm::vec3(0);
    glm::vec3 size = glm::max(hi_ - lo_, glm::vec3(1e-6f));
    cell_ = std::max(1e-5f, static_cast<float>(cell_edges * edge_sum / std::max<size_t>(1, 3 * tris)));
    // At most ~4 M cells: grow the cell until the grid fits.
    for (;;) {
      dims_ = glm::max(glm::ivec3(glm::ceil(size / cell_)), glm::ivec3(1));
      if (static_cast<double>(dims_.x) * dims_.y * dims_.z <= 4.0e6) break;
      cell_ *= 1.25f;
    }
    const size_t ncells = static_cast<size_t>(dims_.x) * dims_.y * dims_.z;
    start_.assign(ncells + 1, 0);
    auto each_cell = [&](size_t t, auto&& f) {
      const glm::vec3 &a = p[idx[3 * t]], &b = p[idx[3 * t + 1]], &c = p[idx[3 * t + 2]];
      glm::ivec3 l = cell_of(glm::min(a, glm::min(b, c))), h = cell_of(glm::max(a, glm::max(b, c)));
      for (int z = l.z; z <= h.z; ++z)
        for (int y = l.y; y <= h.y; ++y)
          for (int x = l.x; x <= h.x; ++x) f(index(x, y, z));
    };
    for (size_t t = 0; t < tris; ++t) each_cell(t, [&](size_t i) { ++start_[i + 1]; });
    for (size_t i = 0; i < ncells; ++i) start_[i + 1] += start_[i];
    items_.resize(start_[ncells]);
    std::vector<uint32_t> fill(start_.begin(), start_.end() - 1);
    for (size_t t = 0; t < tris; ++t) each_cell(t, [&](size_t i) { items_[fill[i]++] = static_cast<uint32_t>(t); });
    box_.resize(tris);
    for (size_t t = 0; t < tris; ++t) {
      const glm::vec3 &a = p[idx[3 * t]], &b = p[idx[3 * t + 1]], &c = p[idx[3 * t + 2]];
      box_[t] = {glm::min(a, glm::min(b, c)), glm::max(a, glm::max(b, c))};
    }
  }

  float distance(const glm::vec3& q) const {
    glm::vec3 p;
    return closest(q, &p, nullptr);
  }

  // Distance from q to the nearest triangle; its closest point and triangle index. `upper`, when
  // given, must be at least that distance (e.g. the previous query's distance plus how far the
  // query moved): triangles whose box lies farther are skipped and the search stops sooner.
  // `hint`, when given, is a triangle tried first (e.g. the previous query's nearest): its
  // distance bounds the search the same way. Cells and triangles whose box lies farther than the
  // best so far are skipped.
  float closest(const glm::vec3& q, glm::vec3* point, uint32_t* triangle, float upper = 1e15f,
                uint32_t hint = UINT32_MAX) const {
    float best2 = upper < 1e15f ? upper * upper * 1.0001f + 1e-12f : 1e30f;
    if (items_.empty()) return std::sqrt(best2);
    bool found = false;
    if (hint < idx_.size() / 3) {  // a triangle likely to be the nearest: its distance bounds the search
      glm::vec3 cp = closest_on_triangle(q, p_[idx_[3 * hint]], p_[idx_[3 * hint + 1]], p_[idx_[3 * hint + 2]]);
      float d2 = glm::dot(cp - q, cp - q);
      if (d2 < best2) {
        best2 = d2;
        *point = cp;
        if (triangle) *triangle = hint;
        found = true;
      }
    }
    glm::ivec3 c = cell_of(q);
    int max_ring = std::max(dims_.x, std::max(dims_.y, dims_.z));
    for (int r = 0; r <= max_ring; ++r) {
      if (r > 0) {
        // Cells within r - 1 of c are searched; an unseen triangle touches none of them, so it
        // lies outside that block: at least as far as the block's nearest face (a face on the
        // grid's border has nothing beyond it).
        float bound = 1e30f;
        for (int k = 0; k < 3; ++k) {
          if (c[k] - (r - 1) > 0) bound = std::min(bound, q[k] - (lo_[k] + (c[k] - (r - 1)) * cell_));
          if (c[k] + r < dims_[k]) bound = std::min(bound, lo_[k] + (c[k] + r) * cell_ - q[k]);
        }
        if (bound >= 1e30f) break;  // the block covers the whole grid
        if (bound > 0 && best2 <= bound * bound) break;
      }
      for (int z = std::max(0, c.z - r); z <= std::min(dims_.z - 1, c.z + r); ++z)
        for (int y = std::max(0, c.y - r); y <= std::min(dims_.y - 1, c.y + r); ++y) {
          bool shell_zy = std::abs(z - c.z) == r || std::abs(y - c.y) == r;
          for (int x = std::max(0, c.x - r); x <= std::min(dims_.x - 1, c.x + r); ++x) {
            if (!shell_zy && std::abs(x - c.x) != r) {
              x = c.x + r - 1;  // jump to the shell's far face
              continue;
            }
            if (r > 0) {  // a cell farther than the best so far cannot hold a nearer triangle
              glm::vec3 cl = lo_ + glm::vec3(x, y, z) * cell_;
              glm::vec3 out = glm::max(glm::max(cl - q, q - (cl + cell_)), glm::vec3(0.0f));
              if (glm::dot(out, out) >= best2) continue;
            }
            size_t cell = index(x, y, z);
            for (uint32_t i = start_[cell]; i < start_[cell + 1]; ++i) {
              uint32_t t = items_[i];
              glm::vec3 out = glm::max(glm::max(box_[t].lo - q, q - box_[t].hi), glm::vec3(0.0f));
              if (glm::dot(out, out) >= best2) continue;  // its box is already too far
              glm::vec3 cp = closest_on_triangle(q, p_[idx_[3 * t]], p_[idx_[3 * t + 1]], p_[idx_[3 * t + 2]]);
              glm::vec3 d = cp - q;
              float d2 = glm::dot(d, d);
              if (d2 < best2) {
                best2 = d2;
                *point = cp;
                if (triangle) *triangle = t;
                found = true;
              }
            }
          }
        }
    }
    if (!found && upper < 1e15f) return closest(q, point, triangle, 1e15f, hint);  // `upper` was too tight
    return std::sqrt(best2);
  }

 private:
  glm::ivec3 cell_of(const glm::vec3& v) const {
    return glm::clamp(glm::ivec3(glm::floor((v - lo_) / cell_)), glm::ivec3(0), dims_ - 1);
  }
  size_t index(int x, int y, int z) const { return (static_cast<size_t>(z) * dims_.y + y) * dims_.x + x; }

  const std::vector<glm::vec3>& p_;
  const std::vector<uint32_t>& idx_;
  glm::vec3 lo_{1e30f}, hi_{-1e30f};
  float cell_ = 1;
  glm::ivec3 dims_{1};
  std::vector<uint32_t> start_;  // cell i holds items_[start_[i] .. start_[i + 1])
  std::vector<uint32_t> items_;
  struct Box {
    glm::vec3 lo, hi;
  };
  std::vector<Box> box_;  // per triangle
};

}  // namespace bb::runtime::detail
