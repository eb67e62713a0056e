#include "bb/runtime/animation.h"

#include <algorithm>
#include <cassert>
#include <cmath>

#include <glm/gtc/matrix_transform.hpp>

namespace bb::runtime {

glm::mat4 Transform::matrix() const {
  glm::mat4 m = glm::mat4_cast(rotation);
  m[0] *= scale.x;
  m[1] *= scale.y;
  m[2] *= scale.z;
  m[3] = glm::vec4(translation, 1.0f);
  return m;
}

float clip_time(float time, float duration, bool loop) {
  if (!(duration > 0.0f) || !std::isfinite(time)) return 0.0f;
  if (!loop) return std::clamp(time, 0.0f, duration);
  if (time >= 0.0f && time < duration) return time;
  float t;
  const double q = std::floor(static_cast<double>(time) / duration);
  if (std::abs(q) < 536870912.0) {
    // time - q * duration in doubles is exact (a product of 24 and 29 significant bits, then the
    // difference of two exact values whose result a float holds), so this is fmod's remainder,
    // the quotient's rounding put right by a period; glibc's fmodf took a tenth of the planner's
    // time per character (bench_runtime BM_UpdateWalking).
    double r = static_cast<double>(time) - q * duration;
    if (r < 0.0) r += duration;
    if (r >= duration) r -= duration;
    t = static_cast<float>(r);
  } else {
    t = std::fmod(time, duration);
    if (t < 0.0f) t += duration;
  }
  if (t >= duration) t = 0.0f;  // rounding
  return t;
}

namespace {

glm::vec4 slerp_xyzw(const glm::vec4& a, const glm::vec4& b, float u) {
  glm::quat qa(a.w, a.x, a.y, a.z), qb(b.w, b.x, b.y, b.z);
  float d = glm::dot(qa, qb);
  if (d < 0.0f) {
    qb = -qb;
    d = -d;
  }
  glm::quat q;
  if (d > 0.9995f) {
    q = glm::normalize(qa * (1.0f - u) + qb * u);
  } else {
    float th = std::acos(std::min(d, 1.0f));
    float s = std::sin(th);
    q = qa * (std::sin((1.0f - u) * th) / s) + qb * (std::sin(u * th) / s);
    q = glm::normalize(q);
  }
  return {q.x, q.y, q.z, q.w};
}

glm::vec4 normalize_quat(glm::vec4 v) {
  float l = glm::length(v);
  return l > 0.0f ? v / l : glm::vec4(0, 0, 0, 1);
}

}  // namespace

glm::vec4 sample_channel(const Channel& c, float time) {
  const auto& ts = c.times;
  assert(!ts.empty());
  const bool cubic = c.interpolation == Interpolation::kCubicSpline;
  const bool rot = c.path == ChannelPath::kRotation;
  auto value = [&](std::size_t k) { return cubic ? c.values[3 * k + 1] : c.values[k]; };
  if (time <= ts.front() || ts.size() == 1) return rot ? normalize_quat(value(0)) : value(0);
  if (time >= ts.back()) return rot ? normalize_quat(value(ts.size() - 1)) : value(ts.size() - 1);
  // First key with time > t; k0 = the one before.
  std::size_t k1 = static_cast<std::size_t>(std::upper_bound(ts.begin(), ts.end(), time) - ts.begin());
  std::size_t k0 = k1 - 1;
  float dt = ts[k1] - ts[k0];
  float u = dt > 0.0f ? (time - ts[k0]) / dt : 0.0f;
  switch (c.interpolation) {
    case Interpolation::kStep:
      return rot ? normalize_quat(c.values[k0]) : c.values[k0];
    case Interpolation::kLinear:
      if (rot) return slerp_xyzw(c.values[k0], c.values[k1], u);
      return c.values[k0] * (1.0f - u) + c.values[k1] * u;
    case Interpolation::kCubicSpline: {
      // glTF 2.0 appendix C: p(u) = (2u^3-3u^2+1)v0 + (u^3-2u^2+u)dt*b0 + (-2u^3+3u^2)v1 + (u^3-u^2)dt*a1
      glm::vec4 v0 = c.values[3 * k0 + 1], b0 = c.values[3 * k0 + 2];
      glm::vec4 a1 = c.values[3 * k1 + 0], v1 = c.values[3 * k1 + 1];
      float u2 = u * u, u3 = u2 * u;
      glm::vec4 p = (2 * u3 - 3 * u2 + 1) * v0 + (u3 - 2 * u2 + u) * dt * b0 + (-2 * u3 + 3 * u2) * v1 +
                    (u3 - u2) * dt * a1;
      return rot ? normalize_quat(p) : p;
    }
  }
  return value(k0);
}

namespace {

// A STEP channel's value just before `time`: the last key strictly before it (the first key where
// none is).
glm::vec4 step_value_before(const Channel& c, float time) {
  const auto& ts = c.times;
  assert(!ts.empty() && c.interpolation == Interpolation::kStep);
  const std::size_t before = static_cast<std::size_t>(std::lower_bound(ts.begin(), ts.end(), time) - ts.begin());
  const glm::vec4& v = c.values[before > 0 ? before - 1 : 0];
  return c.path == ChannelPath::kRotation ? normalize_quat(v) : v;
}

void sample_clip_at(const Model& model, int clip, float time, bool before, std::span<Transform> locals) {
  assert(locals.size() == model.nodes.size());
  for (std::size_t i = 0; i < locals.size(); ++i) locals[i] = model.nodes[i].rest;
  if (clip < 0 || clip >= static_cast<int>(model.clips.size())) return;
  for (const Channel& c : model.clips[clip].channels) {
    glm::vec4 v = before && c.interpolation == Interpolation::kStep ? step_value_before(c, time) : sample_channel(c, time);
    Transform& t = locals[c.node];
    switch (c.path) {
      case ChannelPath::kTranslation: t.translation = glm::vec3(v); break;
      case ChannelPath::kRotation: t.rotation = glm::quat(v.w, v.x, v.y, v.z); break;
      case ChannelPath::kScale: t.scale = glm::vec3(v); break;
    }
  }
}

}  // namespace

void sample_clip(const Model& model, int clip, float time, std::span<Transform> locals) {
  sample_clip_at(model, clip, time, false, locals);
}

void sample_clip_before(const Model& model, int clip, float time, std::span<Transform> locals) {
  sample_clip_at(model, clip, time, true, locals);
}

void world_matrices(const Model& model, std::span<const Transform> locals, std::span<glm::mat4> world) {
  assert(locals.size() == model.nodes.size() && world.size() == model.nodes.size());
  for (std::size_t i = 0; i < locals.size(); ++i) {
    glm::mat4 m = locals[i].matrix();
    int p = model.nodes[i].parent;
    world[i] = p >= 0 ? world[p] * m : m;
  }
}

void palette_matrices(const Model& model, std::span<const glm::mat4> world, std::span<glm::mat4> out) {
  assert(out.size() == model.palette.size());
  for (std::size_t i = 0; i < out.size(); ++i)
    out[i] = world[model.palette[i].node] * model.palette[i].inverse_bind;
}

}  // namespace bb::runtime
