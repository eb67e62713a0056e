// Tests: a bending clip, and a closed square tube of two body parts (impostor_test.cpp: the caps over
// the parts' cuts, and the hinge's clip; render_test.cpp: the caps drawn).
#pragma once

#include <cstdint>

#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>

#include "bb/runtime/animation.h"
#include "bb/runtime/model.h"

namespace bb::runtime {

// A 1 s clip "bend" that turns node `node` about z from 0 to `deg` degrees.
inline Clip bend_clip(int node, float deg) {
  Clip clip;
  clip.name = "bend";
  clip.duration = 1.0f;
  Channel c;
  c.node = node;
  c.path = ChannelPath::kRotation;
  c.times = {0.0f, 1.0f};
  const glm::quat q = glm::angleAxis(glm::radians(deg), glm::vec3(0, 0, 1));
  c.values = {{0, 0, 0, 1}, {q.x, q.y, q.z, q.w}};
  clip.channels = {c};
  return clip;
}

// A closed square tube along y from 0 to 2 m, 2 m wide, its faces wound out: the bottom ring on the
// root joint, the top ring on a joint at y = 1, the middle ring half on each. A 1 s clip "bend" turns
// the top joint about z from 0 to `bend_deg`. Split into two body parts at y = 1, one per joint.
inline Model tube_model(float bend_deg) {
  Model m;
  m.name = "tube";
  m.nodes = {Node{"root", -1, {}}, Node{"top", 0, {glm::vec3(0, 1, 0), glm::quat(1, 0, 0, 0), glm::vec3(1)}}};
  m.palette = {PaletteEntry{0, glm::mat4(1)}, PaletteEntry{1, glm::translate(glm::mat4(1), glm::vec3(0, -1, 0))}};
  MeshLod lod;
  const glm::vec2 square[4] = {{1, 1}, {1, -1}, {-1, -1}, {-1, 1}};  // (x, z), clockwise from above
  for (int ring = 0; ring < 3; ++ring)
    for (const glm::vec2& c : square) {
      Vertex v;
      v.position = glm::vec3(c.x, static_cast<float>(ring), c.y);
      v.normal = glm::normalize(glm::vec3(c.x, 0, c.y));
      v.joints = glm::u16vec4(ring == 2 ? 1 : 0, 1, 0, 0);
      v.weights = ring == 1 ? glm::vec4(0.5f, 0.5f, 0, 0) : glm::vec4(1, 0, 0, 0);
      lod.vertices.push_back(v);
    }
  for (std::uint32_t band = 0; band < 2; ++band)
    for (std::uint32_t i = 0; i < 4; ++i) {
      const std::uint32_t a = band * 4 + i, b = band * 4 + (i + 1) % 4, c = a + 4, d = b + 4;
      lod.indices.insert(lod.indices.end(), {a, b, c, b, d, c});  // facing out
    }
  lod.indices.insert(lod.indices.end(), {0, 2, 1, 0, 3, 2, 8, 9, 10, 8, 10, 11});  // the ends, facing out
  lod.primitives = {Primitive{0, static_cast<std::uint32_t>(lod.indices.size()), 0}};
  m.lods = {lod};
  m.materials = {Material{}};
  m.clips = {bend_clip(1, bend_deg)};
  m.bake(60.0f);
  const int bones[] = {0, 1};
  m.set_body_parts(bones);
  return m;
}

}  // namespace bb::runtime
