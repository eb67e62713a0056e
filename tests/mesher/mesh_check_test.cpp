#include <gtest/gtest.h>

#include "bb/mesher/mesh_check.h"

namespace bb::mesher {
namespace {

// A unit cube's corners and 12 outward triangles.
std::vector<glm::vec3> cube_points(glm::vec3 o = glm::vec3(0)) {
  std::vector<glm::vec3> p;
  for (int i = 0; i < 8; ++i) p.push_back(o + glm::vec3(i & 1, (i >> 1) & 1, (i >> 2) & 1));
  return p;
}
const std::vector<uint32_t> kCube = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                                     2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};

TEST(CheckMesh, EmptyMeshIsNotClosed) {
  MeshCheck c = check_mesh({}, {});
  EXPECT_FALSE(c.closed);
  EXPECT_EQ(c.connected_components, 0u);
}

TEST(CheckMesh, CubeIsClosedManifoldOriented) {
  auto p = cube_points();
  MeshCheck c = check_mesh(p, kCube);
  EXPECT_TRUE(c.closed);
  EXPECT_TRUE(c.manifold);
  EXPECT_TRUE(c.oriented);
  EXPECT_EQ(c.self_intersections, 0u);
  EXPECT_EQ(c.connected_components, 1u);
  EXPECT_NEAR(c.volume_m3, 1.0, 1e-9);
  EXPECT_NEAR(c.area_m2, 6.0, 1e-9);
  EXPECT_TRUE(c.ok());
}

TEST(CheckMesh, FlippedTriangleIsNotOriented) {
  auto p = cube_points();
  auto idx = kCube;
  std::swap(idx[1], idx[2]);
  MeshCheck c = check_mesh(p, idx);
  EXPECT_TRUE(c.closed);
  EXPECT_FALSE(c.oriented);
}

TEST(CheckMesh, MissingTriangleLeavesBorder) {
  auto p = cube_points();
  std::vector<uint32_t> idx(kCube.begin(), kCube.end() - 3);
  MeshCheck c = check_mesh(p, idx);
  EXPECT_FALSE(c.closed);
  EXPECT_EQ(c.border_edges, 3u);
}

TEST(CheckMesh, InterpenetratingCubesSelfIntersect) {
  auto a = cube_points(), b = cube_points(glm::vec3(0.5f, 0.3f, 0.2f));
  std::vector<glm::vec3> p = a;
  p.insert(p.end(), b.begin(), b.end());
  std::vector<uint32_t> idx = kCube;
  for (uint32_t i : kCube) idx.push_back(i + 8);
  MeshCheck c = check_mesh(p, idx);
  EXPECT_TRUE(c.closed);
  EXPECT_EQ(c.connected_components, 2u);
  EXPECT_GT(c.self_intersections, 0u);
  EXPECT_FALSE(c.ok());
}

TEST(CheckMesh, TwoCubesSharingAVertexAreNonManifold) {
  auto a = cube_points(), b = cube_points(glm::vec3(1, 1, 1));
  std::vector<glm::vec3> p = a;
  p.insert(p.end(), b.begin(), b.end());
  std::vector<uint32_t> idx = kCube;
  for (uint32_t i : kCube) idx.push_back(i == 0 ? 7 : i + 8);  // b's corner 0 is a's corner 7
  MeshCheck c = check_mesh(p, idx);
  EXPECT_EQ(c.non_manifold_vertices, 1u);
  EXPECT_FALSE(c.manifold);
}

TEST(Hausdorff, ShiftedCubeIsTheShift) {
  auto a = cube_points(), b = cube_points(glm::vec3(0, 0.25f, 0));
  EXPECT_NEAR(hausdorff_distance(a, kCube, a, kCube), 0.0, 1e-6);  // float samples
  EXPECT_NEAR(hausdorff_distance(a, kCube, b, kCube), 0.25, 1e-6);
  EXPECT_EQ(hausdorff_distance({}, {}, a, kCube), -1.0);
}

}  // namespace
}  // namespace bb::mesher
