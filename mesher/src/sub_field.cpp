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
  // The same scheme as ImplicitSurface::outermost_intersection, over this subset: per primitive
  // span of t where it contributes, march inwards from the far end, bisect the first bracket.
  struct Span { float t0, t1, a, b, c, inv_reach2, scale, step; };
  Span spans[128];
  int n = 0;
  float t_hi = -1;
  for (const auto& p : prims_) {
    glm::vec3 o = p.to_unit * (origin - p.center);
    glm::vec3 v = p.to_unit * d;
    float a = glm::dot(v, v), b = 2 * glm::dot(o, v), c = glm::dot(o, o);
    float disc = b * b - 4 * a * (c - p.reach2);
    if (disc <= 0) continue;
    float s = std::sqrt(disc);
    float t0 = (-b - s) / (2 * a), t1 = (-b + s) / (2 * a);
    if (t1 < 0 || t0 > max_t) continue;
    if (n == 128) break;
    spans[n++] = {std::max(t0, 0.0f), std::min(t1, max_t), a, b, c, p.inv_reach2, p.scale, 0.25f * p.min_radius};
    t_hi = std::max(t_hi, std::min(t1, max_t));
  }
  if (n == 0) return std::nullopt;
  auto eval = [&](float t, float* step) {
    float f = 0, h = 0.01f;
    for (int i = 0; i < n; ++i) {
      const Span& s = spans[i];
      if (s.t1 >= t - 0.01f && s.t0 <= t) h = std::min(h, s.step);
      if (t < s.t0 || t > s.t1) continue;
      float q2 = (s.a * t + s.b) * t + s.c;
      float w = 1 - q2 * s.inv_reach2;
      if (w > 0) f += s.scale * w * w * w;
    }
    if (step) *step = h;
    return f;
  };
  float t_out = t_hi, t = t_hi, h = 0;
  if (eval(t_hi, &h) >= kIso) return t_hi;  // still inside at max_t
  bool found = false;
  while (true) {
    t = std::max(0.0f, t_out - std::max(h, 1e-4f));
    if (eval(t, &h) >= kIso) { found = true; break; }
    if (t == 0) break;
    t_out = t;
  }
  if (!found) return std::nullopt;
  float t_in = t;
  for (int it = 0; it < 40 && t_out - t_in > 1e-6f; ++it) {
    float m = 0.5f * (t_in + t_out);
    if (eval(m, nullptr) >= kIso) t_in = m; else t_out = m;
  }
  return 0.5f * (t_in + t_out);
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
