// A UV sphere for the mesher's tests (closed, oriented: counter-clockwise seen from outside).
#pragma once

#include <cmath>
#include <cstdint>

#include <glm/glm.hpp>
#include <glm/gtc/constants.hpp>

#include "internal.h"

namespace bb::mesher::test {

// UV sphere, counter-clockwise seen from outside.
inline detail::PlainMesh sphere(glm::vec3 c, float r, int rings, int segments) {
  detail::PlainMesh m;
  m.positions.push_back(c + glm::vec3(0, r, 0));
  for (int i = 1; i < rings; ++i) {
    float phi = glm::pi<float>() * float(i) / float(rings);
    for (int j = 0; j < segments; ++j) {
      float th = glm::two_pi<float>() * float(j) / float(segments);
      m.positions.push_back(c + r * glm::vec3(std::sin(phi) * std::cos(th), std::cos(phi), std::sin(phi) * std::sin(th)));
    }
  }
  m.positions.push_back(c - glm::vec3(0, r, 0));
  const uint32_t bottom = uint32_t(m.positions.size() - 1);
  auto at = [&](int ring, int j) { return uint32_t(1 + (ring - 1) * segments + (j % segments)); };
  for (int j = 0; j < segments; ++j) m.indices.insert(m.indices.end(), {0u, at(1, j + 1), at(1, j)});
  for (int i = 1; i + 1 < rings; ++i)
    for (int j = 0; j < segments; ++j)
      m.indices.insert(m.indices.end(), {at(i, j), at(i, j + 1), at(i + 1, j + 1), at(i, j), at(i + 1, j + 1), at(i + 1, j)});
  for (int j = 0; j < segments; ++j) m.indices.insert(m.indices.end(), {bottom, at(rings - 1, j), at(rings - 1, j + 1)});
  return m;
}

}  // namespace bb::mesher::test
