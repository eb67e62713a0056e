// detail::mesh_union (CGAL corefinement) numbers its result the same way whatever the order of
// its input: vertices by position, triangles by their vertices. Corefinement itself numbers the
// vertices it creates by where its boxes lie in memory, which made the default body's level 1
// come out in three vertex orders over four runs of `bodybuilder mesh`.
#include <algorithm>
#include <numeric>
#include <random>

#include <gtest/gtest.h>

#include "bb/mesher/mesh_check.h"
#include "internal.h"
#include "sphere.h"

namespace bb::mesher {
namespace {

using detail::PlainMesh;

// The same mesh with its vertices renumbered at random, each triangle turned to start at another
// corner, and the triangles in reverse order.
PlainMesh shuffled(const PlainMesh& m, unsigned seed) {
  std::vector<uint32_t> perm(m.positions.size());
  std::iota(perm.begin(), perm.end(), 0u);
  std::mt19937 rng(seed);
  std::shuffle(perm.begin(), perm.end(), rng);
  PlainMesh out;
  out.positions.resize(m.positions.size());
  for (size_t i = 0; i < perm.size(); ++i) out.positions[perm[i]] = m.positions[i];
  for (size_t t = m.indices.size(); t >= 3; t -= 3) {
    const uint32_t a = perm[m.indices[t - 3]], b = perm[m.indices[t - 2]], c = perm[m.indices[t - 1]];
    out.indices.insert(out.indices.end(), {b, c, a});
  }
  return out;
}

TEST(MeshUnion, NumberedTheSameWhateverTheInputOrder) {
  const PlainMesh a = test::sphere(glm::vec3(0.0f), 0.10f, 18, 30);
  const PlainMesh b = test::sphere(glm::vec3(0.07f, 0.02f, 0.01f), 0.08f, 14, 22);
  auto first = detail::mesh_union({a, b});
  ASSERT_TRUE(first.ok()) << first.error().message();
  const PlainMesh& u = *first;
  const MeshCheck check = check_mesh(u.positions, u.indices);
  EXPECT_TRUE(check.closed);
  EXPECT_TRUE(check.manifold);
  EXPECT_TRUE(check.oriented);
  EXPECT_EQ(check.self_intersections, 0u);
  // The corefinement made vertices of its own on the intersection curve.
  EXPECT_GT(u.positions.size(), a.positions.size());
  // Vertices in increasing position (x, then y, then z), all distinct.
  auto less = [](const glm::vec3& p, const glm::vec3& q) {
    return p.x != q.x ? p.x < q.x : p.y != q.y ? p.y < q.y : p.z < q.z;
  };
  for (size_t i = 1; i < u.positions.size(); ++i) EXPECT_TRUE(less(u.positions[i - 1], u.positions[i])) << i;
  // Each triangle starts at its smallest index, and the triangles are in increasing order.
  for (size_t t = 0; t < u.indices.size(); t += 3) {
    EXPECT_LT(u.indices[t], u.indices[t + 1]);
    EXPECT_LT(u.indices[t], u.indices[t + 2]);
    if (t >= 3) {
      EXPECT_TRUE(std::lexicographical_compare(u.indices.begin() + long(t) - 3, u.indices.begin() + long(t),
                                               u.indices.begin() + long(t), u.indices.begin() + long(t) + 3))
          << t / 3;
    }
  }
  for (unsigned seed : {1u, 2u, 3u}) {
    auto again = detail::mesh_union({shuffled(a, seed), shuffled(b, seed + 10)});
    ASSERT_TRUE(again.ok()) << again.error().message();
    EXPECT_EQ(again->positions, u.positions) << "seed " << seed;
    EXPECT_EQ(again->indices, u.indices) << "seed " << seed;
  }
  // The pieces in the other order: the same union.
  auto swapped = detail::mesh_union({b, a});
  ASSERT_TRUE(swapped.ok());
  EXPECT_EQ(swapped->positions, u.positions);
  EXPECT_EQ(swapped->indices, u.indices);
}

}  // namespace
}  // namespace bb::mesher
