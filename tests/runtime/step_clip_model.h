// Tests: a tiny model whose clip mixes a STEP channel with another interpolation (model_test.cpp and
// impostor_test.cpp: the baked frames at STEP keys, and the planner reading them).
#pragma once

#include <glm/glm.hpp>

#include "bb/runtime/animation.h"
#include "bb/runtime/model.h"

namespace bb::runtime {

// A root and two joints beside it, one moved along x by a STEP channel (0 until 0.25 s, 1 until
// 0.51 s, then 2), the other by a channel of `slid` interpolation (x = t over the 1 s clip), a
// vertex on each.
inline Model step_and_slide(Interpolation slid_interpolation) {
  Model m;
  m.nodes = {Node{"root", -1, {}}, Node{"held", 0, {}}, Node{"slid", 0, {}}};
  m.palette = {PaletteEntry{0, glm::mat4(1)}, PaletteEntry{1, glm::mat4(1)}, PaletteEntry{2, glm::mat4(1)}};
  MeshLod lod;
  lod.vertices.resize(3);
  lod.vertices[0].position = {0, 1, 0};
  lod.vertices[1].joints = glm::u16vec4(1, 0, 0, 0);
  lod.vertices[2].joints = glm::u16vec4(2, 0, 0, 0);
  lod.indices = {0, 1, 2};
  lod.primitives = {Primitive{0, 3, 0}};
  m.lods = {lod};
  m.materials = {Material{}};
  Channel held;
  held.node = 1;
  held.interpolation = Interpolation::kStep;
  held.times = {0.0f, 0.25f, 0.51f};  // 0.25 s is grid frame 15, 0.51 s lies between frames 30 and 31
  held.values = {{0, 0, 0, 0}, {1, 0, 0, 0}, {2, 0, 0, 0}};
  Channel slid;
  slid.node = 2;
  slid.interpolation = slid_interpolation;
  slid.times = {0.0f, 1.0f};
  slid.values = {{0, 0, 0, 0}, {1, 0, 0, 0}};
  if (slid_interpolation == Interpolation::kCubicSpline) slid.values = {{}, {0, 0, 0, 0}, {}, {}, {1, 0, 0, 0}, {}};
  m.clips = {Clip{"mixed", 1.0f, {held, slid}}};
  m.bake(60.0f);
  return m;
}

}  // namespace bb::runtime
