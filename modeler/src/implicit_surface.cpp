#include "bb/modeler/implicit_surface.h"

#include <algorithm>
#include <cmath>

namespace bb::modeler {

namespace {
constexpr float kCell = 0.04f;  // grid cell edge, metres

inline float contribution(const PlacedPrimitive& p, const glm::vec3& x) {
  glm::vec3 u = p.to_unit * (x - p.center);
  float q2 = glm::dot(u, u);
  if (q2 >= p.reach2) return 0.0f;
  float a = 1.0f - q2 * p.inv_reach2;
  return p.scale * a * a * a;
}
}  // namespace

ImplicitSurface::ImplicitSurface(const Body& body, const Posture& posture) {
  joints_ = body.skeleton->world_transforms(posture);
  prims_.reserve(body.primitives.size());
  for (size_t i = 0; i < body.primitives.size(); ++i) {
    const Primitive& pr = body.primitives[i];
    const glm::mat4& jw = joints_[pr.joint];
    glm::mat3 rot = glm::mat3(jw) * glm::mat3_cast(pr.orientation);  // primitive axes in world
    float k = pr.type == PrimitiveType::kEllipsoid ? kEllipsoidReach : kMetaballReach;
    PlacedPrimitive p;
    // to_unit = diag(1/r) * rot^T
    glm::mat3 rt = glm::transpose(rot);
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) p.to_unit[c][r] = rt[c][r] / pr.radii[r];
    p.center = glm::vec3(jw * glm::vec4(pr.center, 1.0f));
    p.reach2 = k * k;
    p.inv_reach2 = 1.0f / (k * k);
    float norm = 1.0f - 1.0f / (k * k);
    p.scale = pr.strength / (norm * norm * norm);
    p.min_radius = std::min({pr.radii.x, pr.radii.y, pr.radii.z});
    p.joint = pr.joint;
    p.source = static_cast<int>(i);
    // Support box: half extent along world axis i is k * |row i of (rot * diag(r))|.
    glm::vec3 half;
    for (int r = 0; r < 3; ++r) {
      glm::vec3 row(rot[0][r] * pr.radii[0], rot[1][r] * pr.radii[1], rot[2][r] * pr.radii[2]);
      half[r] = k * glm::length(row);
    }
    p.support.min = p.center - half;
    p.support.max = p.center + half;
    bounds_.extend(p.support.min);
    bounds_.extend(p.support.max);
    prims_.push_back(p);
  }
  if (prims_.empty()) return;
  glm::vec3 size = bounds_.size();
  dims_ = glm::max(glm::ivec3(1), glm::ivec3(glm::ceil(size / kCell)));
  cell_size_ = size / glm::vec3(dims_);
  size_t cells = static_cast<size_t>(dims_.x) * dims_.y * dims_.z;
  std::vector<int> counts(cells + 1, 0);
  auto range = [&](const PlacedPrimitive& p, glm::ivec3& lo, glm::ivec3& hi) {
    lo = glm::clamp(glm::ivec3(glm::floor((p.support.min - bounds_.min) / cell_size_)), glm::ivec3(0), dims_ - 1);
    hi = glm::clamp(glm::ivec3(glm::floor((p.support.max - bounds_.min) / cell_size_)), glm::ivec3(0), dims_ - 1);
  };
  for (int pass = 0; pass < 2; ++pass) {
    if (pass == 1) {
      cell_start_.assign(cells + 1, 0);
      for (size_t c = 0; c < cells; ++c) cell_start_[c + 1] = cell_start_[c] + counts[c];
      cell_items_.resize(cell_start_[cells]);
      std::fill(counts.begin(), counts.end(), 0);
    }
    for (size_t i = 0; i < prims_.size(); ++i) {
      glm::ivec3 lo, hi;
      range(prims_[i], lo, hi);
      for (int z = lo.z; z <= hi.z; ++z)
        for (int y = lo.y; y <= hi.y; ++y)
          for (int x = lo.x; x <= hi.x; ++x) {
            size_t c = (static_cast<size_t>(z) * dims_.y + y) * dims_.x + x;
            if (pass == 0) ++counts[c];
            else cell_items_[cell_start_[c] + counts[c]++] = static_cast<int>(i);
          }
    }
  }
}

int ImplicitSurface::cell_of(const glm::vec3& x) const {
  if (cell_start_.empty()) return -1;
  glm::vec3 g = (x - bounds_.min) / cell_size_;
  if (!(g.x >= 0 && g.y >= 0 && g.z >= 0)) return -1;
  glm::ivec3 c(g);
  if (c.x >= dims_.x || c.y >= dims_.y || c.z >= dims_.z) {
    // Points exactly on the max face belong to the last cell.
    if (x.x > bounds_.max.x || x.y > bounds_.max.y || x.z > bounds_.max.z) return -1;
    c = glm::min(c, dims_ - 1);
  }
  return (c.z * dims_.y + c.y) * dims_.x + c.x;
}

float ImplicitSurface::field(const glm::vec3& x) const {
  int c = cell_of(x);
  if (c < 0) return 0.0f;
  float f = 0.0f;
  for (int k = cell_start_[c]; k < cell_start_[c + 1]; ++k) f += contribution(prims_[cell_items_[k]], x);
  return f;
}

float ImplicitSurface::field_of(const glm::vec3& x, const std::vector<char>& mask) const {
  int c = cell_of(x);
  if (c < 0) return 0.0f;
  float f = 0.0f;
  for (int k = cell_start_[c]; k < cell_start_[c + 1]; ++k) {
    const PlacedPrimitive& p = prims_[cell_items_[k]];
    if (mask[p.joint]) f += contribution(p, x);
  }
  return f;
}

float ImplicitSurface::field_gradient(const glm::vec3& x, glm::vec3* gradient) const {
  glm::vec3 g(0.0f);
  float f = 0.0f;
  int c = cell_of(x);
  if (c >= 0) {
    for (int k = cell_start_[c]; k < cell_start_[c + 1]; ++k) {
      const PlacedPrimitive& p = prims_[cell_items_[k]];
      glm::vec3 u = p.to_unit * (x - p.center);
      float q2 = glm::dot(u, u);
      if (q2 >= p.reach2) continue;
      float a = 1.0f - q2 * p.inv_reach2;
      f += p.scale * a * a * a;
      // d/dx = scale * 3a^2 * (-1/k^2) * 2 * to_unit^T u
      g += (-6.0f * p.scale * a * a * p.inv_reach2) * (glm::transpose(p.to_unit) * u);
    }
  }
  if (gradient) *gradient = g;
  return f;
}

std::optional<float> outermost_crossing(std::span<const PlacedPrimitive> prims, const glm::vec3& origin,
                                        const glm::vec3& d, float max_t, bool far_end_inside_counts) {
  // Per primitive on the ray: q^2(t) = a t^2 + b t + c, support where q^2 < k^2.
  struct Span { float t0, t1, a, b, c, inv_reach2, scale, step; };
  Span spans[256];
  int n = 0;
  float t_hi = -1.0f;
  for (const PlacedPrimitive& p : prims) {
    glm::vec3 o = p.to_unit * (origin - p.center);
    glm::vec3 v = p.to_unit * d;
    float a = glm::dot(v, v), b = 2.0f * glm::dot(o, v), c = glm::dot(o, o);
    float disc = b * b - 4.0f * a * (c - p.reach2);
    if (disc <= 0.0f) continue;
    float s = std::sqrt(disc);
    float t0 = (-b - s) / (2.0f * a), t1 = (-b + s) / (2.0f * a);
    if (t1 < 0.0f || t0 > max_t) continue;
    t0 = std::max(t0, 0.0f);
    t1 = std::min(t1, max_t);
    if (n == 256) break;  // more primitives than any body has on one ray
    spans[n++] = {t0, t1, a, b, c, p.inv_reach2, p.scale, 0.25f * p.min_radius};
    t_hi = std::max(t_hi, t1);
  }
  if (n == 0) return std::nullopt;
  auto eval = [&](float t, float* step) {
    float f = 0.0f, h = 0.01f;
    for (int i = 0; i < n; ++i) {
      const Span& s = spans[i];
      // The step never jumps over a primitive that starts within the next centimetre.
      if (s.t1 >= t - 0.01f && s.t0 <= t) h = std::min(h, s.step);
      if (t < s.t0 || t > s.t1) continue;
      float q2 = (s.a * t + s.b) * t + s.c;
      float w = 1.0f - q2 * s.inv_reach2;
      if (w > 0.0f) f += s.scale * w * w * w;
    }
    if (step) *step = h;
    return f;
  };
  // March from the far end of the supports towards the origin; the first inside point found
  // after an outside one brackets the outermost crossing.
  float t_out = t_hi, h = 0.0f;
  bool outside = eval(t_hi, &h) < kIso;
  if (!outside && far_end_inside_counts) return t_hi;
  bool found = false;
  float t = t_hi;
  while (t > 0.0f) {
    t = std::max(0.0f, t_out - std::max(h, 1e-4f));
    bool inside = eval(t, &h) >= kIso;
    if (inside && outside) { found = true; break; }
    outside = !inside;
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

std::optional<float> ImplicitSurface::outermost_intersection(const glm::vec3& origin,
                                                             const glm::vec3& direction,
                                                             float max_distance) const {
  float len = glm::length(direction);
  if (!(len > 0.0f) || !(max_distance > 0.0f)) return std::nullopt;
  // The ray may end inside the skin: the march goes on to the outermost crossing before it.
  return outermost_crossing(prims_, origin, direction / len, max_distance, false);
}

}  // namespace bb::modeler
