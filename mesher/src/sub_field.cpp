#include <algorithm>
#include <cmath>

#include "internal.h"

namespace bb::mesher::detail {

using modeler::kIso;

SubField::SubField(const modeler::ImplicitSurface& surface, const std::vector<int>& ids) {
  for (int i : ids) {
    prims_.push_back(surface.primitives()[i]);
    bounds_.extend(prims_.back().support.min);
    bounds_.extend(prims_.back().support.max);
  }
}

SubField::SubField(const modeler::ImplicitSurface& surface) : whole_(&surface), prims_(surface.primitives()) {
  bounds_ = surface.bounds();
}

float SubField::field(const glm::vec3& x) const {
  if (whole_) return whole_->field(x);
  float f = 0;
  for (const auto& p : prims_) {
    glm::vec3 u = p.to_unit * (x - p.center);
    float q2 = glm::dot(u, u);
    if (q2 >= p.reach2) continue;
    float a = 1.0f - q2 * p.inv_reach2;
    f += p.scale * a * a * a;
  }
  return f;
}

float SubField::field_gradient(const glm::vec3& x, glm::vec3* g) const {
  if (whole_) return whole_->field_gradient(x, g);
  float f = 0;
  glm::vec3 grad(0);
  for (const auto& p : prims_) {
    glm::vec3 u = p.to_unit * (x - p.center);
    float q2 = glm::dot(u, u);
    if (q2 >= p.reach2) continue;
    float a = 1.0f - q2 * p.inv_reach2;
    f += p.scale * a * a * a;
    grad += (-6.0f * p.scale * a * a * p.inv_reach2) * (glm::transpose(p.to_unit) * u);
  }
  if (g) *g = grad;
  return f;
}

glm::vec3 SubField::project(const glm::vec3& x0, float max_move, int iterations) const {
  glm::vec3 x = x0;
  for (int it = 0; it < iterations; ++it) {
    glm::vec3 g;
    float f = field_gradient(x, &g) - kIso;
    float g2 = glm::dot(g, g);
    if (g2 < 1e-12f) break;
    glm::vec3 step = -f / g2 * g;
    x += step;
    glm::vec3 d = x - x0;
    float len = glm::length(d);
    if (len > max_move) { x = x0 + d * (max_move / len); break; }
    if (glm::length(step) < 1e-7f) break;
  }
  return x;
}

std::optional<float> SubField::outermost(const glm::vec3& origin, const glm::vec3& d, float max_t) const {
  if (whole_) return whole_->outermost_intersection(origin, d, max_t);
  // Over this subset of the primitives, a ray whose far end is inside gives that end.
  return modeler::outermost_crossing(prims_, origin, d, max_t, true);
}

void PieceMesh::append(const PieceMesh& o) {
  uint32_t base = uint32_t(positions.size());
  positions.insert(positions.end(), o.positions.begin(), o.positions.end());
  part.insert(part.end(), o.part.begin(), o.part.end());
  seam.insert(seam.end(), o.seam.begin(), o.seam.end());
  region.insert(region.end(), o.region.begin(), o.region.end());
  for (uint32_t i : o.indices) indices.push_back(base + i);
}

}  // namespace bb::mesher::detail
