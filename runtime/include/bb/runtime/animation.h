// Clip sampling and forward kinematics on the CPU (exact; the per-frame paths use the baked
// clips of Model instead). All functions write into caller-owned spans and allocate nothing.
#pragma once

#include <span>

#include <glm/glm.hpp>

#include "bb/runtime/model.h"

namespace bb::runtime {

// Time inside a clip of `duration` seconds: looping wraps into [0, duration) (0 when duration
// is 0); otherwise clamps to [0, duration]. A time that is not finite (NaN, infinite) gives 0, so
// that the frames sampled from it stay inside the clip.
float clip_time(float time, float duration, bool loop);

// Value of `channel` at `time` seconds (clamped to its first/last key). Step holds the previous
// key; linear lerps (rotations: shortest-path slerp); cubic spline uses the glTF Hermite form.
// Rotations come back as a unit quaternion in (x, y, z, w).
glm::vec4 sample_channel(const Channel& channel, float time);

// Local transforms of every node for clip `clip` at `time` (not wrapped; clamped to the keys).
// `clip` may be -1 for the rest pose. locals.size() == model.nodes.size().
void sample_clip(const Model& model, int clip, float time, std::span<Transform> locals);

// The same just before `time` (the limit from the left): a STEP channel with a key at `time` still
// holds the key before it; every other channel is continuous there and takes its value at `time`.
// The first frame of a baked step edge (BakedClip::before_step).
void sample_clip_before(const Model& model, int clip, float time, std::span<Transform> locals);

// Model-space matrices of every node from their local transforms (sizes == nodes.size()).
void world_matrices(const Model& model, std::span<const Transform> locals,
                    std::span<glm::mat4> world);

// Skinning matrices: out[i] = world[palette[i].node] * palette[i].inverse_bind
// (out.size() == model.palette.size()).
void palette_matrices(const Model& model, std::span<const glm::mat4> world,
                      std::span<glm::mat4> out);

// A vertex skinned by `palette` (palette_matrices' output): the linear blend of its four joints'
// matrices applied to its position (model space). Joints outside the palette count for nothing.
inline glm::vec3 skinned_position(const Vertex& v, std::span<const glm::mat4> palette) {
  glm::mat4 m(0.0f);
  for (int k = 0; k < 4; ++k)
    if (v.weights[k] > 0.0f && v.joints[k] < palette.size()) m += v.weights[k] * palette[v.joints[k]];
  return glm::vec3(m * glm::vec4(v.position, 1.0f));
}

// Position of a posture point given the node world matrices.
inline glm::vec3 point_position(const PosturePoint& p, std::span<const glm::mat4> world) {
  return glm::vec3(world[p.node] * glm::vec4(p.offset, 1.0f));
}

}  // namespace bb::runtime
