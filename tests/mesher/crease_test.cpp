// Crease fitting (detail::fit_creases) on the smallest crease there is: two overlapping
// metaballs. Each ball's own skin is a sphere; their union has a sharp crease where the spheres
// meet, while the blended skin has a waist that fills it (the groin and armpit of the body, where
// the contour pieces meet, in miniature). The fitted mesh must follow the waist and stay a clean
// closed 2-manifold.
#include <algorithm>
#include <cmath>

#include <glm/gtc/constants.hpp>
#include <gtest/gtest.h>

#include "bb/mesher/mesh_check.h"
#include "bb/modeler/body.h"
#include "bb/modeler/implicit_surface.h"
#include "internal.h"
#include "sphere.h"

namespace bb::mesher {
namespace {

using detail::PlainMesh;
using detail::SubField;
using test::sphere;

// First-order distance |F - iso| / |grad F| of the vertices and edge midpoints.
float worst_deviation(const PlainMesh& m, const SubField& skin, glm::vec3* where) {
  float worst = 0;
  auto test = [&](const glm::vec3& p) {
    glm::vec3 g;
    float d = std::abs(skin.field_gradient(p, &g) - modeler::kIso) / glm::length(g);
    if (d > worst) worst = d, *where = p;
  };
  for (const glm::vec3& p : m.positions) test(p);
  for (size_t t = 0; t < m.indices.size(); t += 3)
    for (int e = 0; e < 3; ++e) test(0.5f * (m.positions[m.indices[t + e]] + m.positions[m.indices[t + (e + 1) % 3]]));
  return worst;
}

// Two metaballs of radius R at x = -a and x = +a on the root joint, in the neutral posture.
modeler::Body two_metaballs(float R, float a) {
  modeler::Body b;
  b.name = "two balls";
  b.skeleton = modeler::default_body().skeleton;
  b.sample_posture = "neutral";
  for (float x : {-a, a}) {
    modeler::Primitive p;
    p.type = modeler::PrimitiveType::kMetaball;
    p.joint = 0;
    p.center = {x, 0, 0};
    p.radii = glm::vec3(R);
    b.primitives.push_back(p);
  }
  return b;
}

TEST(CreaseFit, TwoMetaballsUnionFollowsTheWaist) {
  const float R = 0.08f, a = 0.06f;
  const modeler::Body b = two_metaballs(R, a);
  modeler::ImplicitSurface s(b, b.skeleton->posture("neutral"));
  SubField whole(s);
  const glm::vec3 c(b.skeleton->world_transforms(b.skeleton->posture("neutral"))[0][3]);
  // Each ball alone: a sphere of radius R (its own skin); their union has the sharp crease.
  auto joined = detail::mesh_union({sphere(c - glm::vec3(a, 0, 0), R, 24, 40), sphere(c + glm::vec3(a, 0, 0), R, 24, 40)});
  ASSERT_TRUE(joined.ok()) << joined.error().message();
  PlainMesh m = *joined;
  ASSERT_TRUE(check_mesh(m.positions, m.indices).ok());
  glm::vec3 where;
  const float before = worst_deviation(m, whole, &where);
  // The crease is on the mid-plane, well inside the blended waist.
  EXPECT_GT(before, 0.01f);
  EXPECT_NEAR(where.x, c.x, 0.01f);

  const float tol = 0.001f;
  size_t added = detail::fit_creases(m, whole, tol, 0.03f, 0.001f, 4, {});
  EXPECT_GT(added, 0u);
  MeshCheck check = check_mesh(m.positions, m.indices);
  EXPECT_TRUE(check.closed);
  EXPECT_TRUE(check.manifold);
  EXPECT_TRUE(check.oriented);
  EXPECT_EQ(check.self_intersections, 0u);
  EXPECT_EQ(check.connected_components, 1u);
  const float after = worst_deviation(m, whole, &where);
  std::printf("crease: worst deviation %.4f m before, %.4f m after, %zu vertices added\n", before, after, added);
  EXPECT_LT(after, 0.25f * before);
  // Vertices are on the skin (the guard may leave a few short of it, never worse than before).
  size_t off = 0;
  for (const glm::vec3& p : m.positions) {
    glm::vec3 g;
    off += std::abs(whole.field_gradient(p, &g) - modeler::kIso) > tol * glm::length(g);
  }
  EXPECT_LE(off, m.positions.size() / 50);
}

// Frozen vertices and the edges between them are left alone.
TEST(CreaseFit, FrozenEdgesAreKept) {
  const float R = 0.08f, a = 0.06f;
  const modeler::Body b = two_metaballs(R, a);
  modeler::ImplicitSurface s(b, b.skeleton->posture("neutral"));
  SubField whole(s);
  const glm::vec3 c(b.skeleton->world_transforms(b.skeleton->posture("neutral"))[0][3]);
  auto joined = detail::mesh_union({sphere(c - glm::vec3(a, 0, 0), R, 16, 24), sphere(c + glm::vec3(a, 0, 0), R, 16, 24)});
  ASSERT_TRUE(joined.ok());
  PlainMesh m = *joined;
  const PlainMesh original = m;
  std::vector<char> frozen(m.positions.size(), 1);
  EXPECT_EQ(detail::fit_creases(m, whole, 0.001f, 0.03f, 0.001f, 4, frozen), 0u);
  EXPECT_EQ(m.positions, original.positions);
  EXPECT_EQ(m.indices, original.indices);
}

}  // namespace
}  // namespace bb::mesher
