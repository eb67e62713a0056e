// Internal: nearest-triangle queries on a triangle mesh through a uniform grid.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

namespace bb::decimate::detail {

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

// Triangles of one mesh in a uniform grid; nearest-distance queries search rings of cells.
class TriangleGrid {
 public:
  TriangleGrid(const std::vector<glm::vec3>& p, const std::vector<uint32_t>& idx) : p_(p), idx_(idx) {
    for (const auto& v : p) { lo_ = glm::min(lo_, v); hi_ = glm::max(hi_, v); }
    size_t tris = idx.size() / 3;
    glm::vec3 size = glm::max(hi_ - lo_, glm::vec3(1e-6f));
    float vol = size.x * size.y * size.z;
    cell_ = std::max(1e-4f, std::cbrt(vol / std::max<size_t>(1, tris) * 2.0f));
    dims_ = glm::clamp(glm::ivec3(glm::ceil(size / cell_)), glm::ivec3(1), glm::ivec3(256));
    cells_.resize(static_cast<size_t>(dims_.x) * dims_.y * dims_.z);
    for (size_t t = 0; t < tris; ++t) {
      glm::vec3 a = p[idx[3 * t]], b = p[idx[3 * t + 1]], c = p[idx[3 * t + 2]];
      glm::ivec3 l = cell_of(glm::min(a, glm::min(b, c))), h = cell_of(glm::max(a, glm::max(b, c)));
      for (int z = l.z; z <= h.z; ++z)
        for (int y = l.y; y <= h.y; ++y)
          for (int x = l.x; x <= h.x; ++x) cells_[index(x, y, z)].push_back(static_cast<uint32_t>(t));
    }
  }

  float distance(const glm::vec3& q) const {
    glm::vec3 p;
    return closest(q, &p, nullptr);
  }

  // Distance from q to the nearest triangle; its closest point and triangle index.
  float closest(const glm::vec3& q, glm::vec3* point, uint32_t* triangle) const {
    glm::ivec3 c = cell_of(q);
    float best2 = 1e30f;
    int max_ring = std::max(dims_.x, std::max(dims_.y, dims_.z));
    for (int r = 0; r <= max_ring; ++r) {
      // Every triangle not yet seen lies at least (r - 1) cells away (plus the query's offset).
      float bound = std::max(0, r - 1) * cell_;
      if (best2 < bound * bound) break;
      for (int z = c.z - r; z <= c.z + r; ++z)
        for (int y = c.y - r; y <= c.y + r; ++y)
          for (int x = c.x - r; x <= c.x + r; ++x) {
            if (std::max({std::abs(x - c.x), std::abs(y - c.y), std::abs(z - c.z)}) != r) continue;
            if (x < 0 || y < 0 || z < 0 || x >= dims_.x || y >= dims_.y || z >= dims_.z) continue;
            for (uint32_t t : cells_[index(x, y, z)]) {
              glm::vec3 cp = closest_on_triangle(q, p_[idx_[3 * t]], p_[idx_[3 * t + 1]], p_[idx_[3 * t + 2]]);
              glm::vec3 d = cp - q;
              float d2 = glm::dot(d, d);
              if (d2 < best2) {
                best2 = d2;
                *point = cp;
                if (triangle) *triangle = t;
              }
            }
          }
    }
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
  std::vector<std::vector<uint32_t>> cells_;
};

}  // namespace bb::decimate::detail
