#include <cmath>
#include <map>
#include <set>
#include <tuple>

#include <gtest/gtest.h>

#include "bb/decimate/decimate.h"

using bb::mesher::SkinnedMesh;
using namespace bb::decimate;

namespace {

// An n x n grid of quads in the z = 0 plane, unit square, counter-clockwise seen from +z.
SkinnedMesh grid(int n) {
  SkinnedMesh m;
  for (int y = 0; y <= n; ++y)
    for (int x = 0; x <= n; ++x) {
      m.positions.push_back({float(x) / n, float(y) / n, 0});
      m.normals.push_back({0, 0, 1});
      m.joints.push_back({0, 0, 0, 0});
      m.weights.push_back({1, 0, 0, 0});
    }
  auto id = [n](int x, int y) { return static_cast<uint32_t>(y * (n + 1) + x); };
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      m.indices.insert(m.indices.end(), {id(x, y), id(x + 1, y), id(x + 1, y + 1)});
      m.indices.insert(m.indices.end(), {id(x, y), id(x + 1, y + 1), id(x, y + 1)});
    }
  return m;
}

// A closed capsule-like tube along y (rings x segments, capped with a vertex at each end),
// skinned to joint 1 below y = 0 and joint 2 above, with the weights switching over one ring.
SkinnedMesh tube(int rings, int segments, float radius = 0.05f, float half = 0.2f) {
  SkinnedMesh m;
  const float pi = 3.14159265f;
  auto add = [&](glm::vec3 p, glm::vec3 n) {
    m.positions.push_back(p);
    m.normals.push_back(glm::normalize(n));
    float s = glm::clamp(p.y / 0.02f * 0.5f + 0.5f, 0.0f, 1.0f);  // blends over 2 cm around y = 0
    if (s <= 0) {
      m.joints.push_back({1, 0, 0, 0});
      m.weights.push_back({1, 0, 0, 0});
    } else if (s >= 1) {
      m.joints.push_back({2, 0, 0, 0});
      m.weights.push_back({1, 0, 0, 0});
    } else {
      m.joints.push_back({1, 2, 0, 0});
      m.weights.push_back({1 - s, s, 0, 0});
    }
  };
  add({0, -half - radius, 0}, {0, -1, 0});
  for (int r = 0; r < rings; ++r) {
    float y = -half + 2 * half * r / (rings - 1);
    for (int s = 0; s < segments; ++s) {
      float a = 2 * pi * s / segments;
      add({radius * std::cos(a), y, radius * std::sin(a)}, {std::cos(a), 0, std::sin(a)});
    }
  }
  add({0, half + radius, 0}, {0, 1, 0});
  uint32_t top = static_cast<uint32_t>(m.positions.size() - 1);
  auto v = [&](int r, int s) { return static_cast<uint32_t>(1 + r * segments + (s % segments)); };
  for (int s = 0; s < segments; ++s) m.indices.insert(m.indices.end(), {0, v(0, s), v(0, s + 1)});
  for (int r = 0; r + 1 < rings; ++r)
    for (int s = 0; s < segments; ++s) {
      m.indices.insert(m.indices.end(), {v(r, s), v(r + 1, s), v(r + 1, s + 1)});
      m.indices.insert(m.indices.end(), {v(r, s), v(r + 1, s + 1), v(r, s + 1)});
    }
  for (int s = 0; s < segments; ++s) m.indices.insert(m.indices.end(), {top, v(rings - 1, s + 1), v(rings - 1, s)});
  return m;
}

// Every directed edge appears once and its twin once: closed, oriented 2-manifold.
bool closed_and_oriented(const SkinnedMesh& m) {
  std::map<std::pair<uint32_t, uint32_t>, int> directed;
  for (size_t t = 0; t < m.indices.size(); t += 3)
    for (int k = 0; k < 3; ++k) ++directed[{m.indices[t + k], m.indices[t + (k + 1) % 3]}];
  for (const auto& [e, n] : directed) {
    if (n != 1) return false;
    auto it = directed.find({e.second, e.first});
    if (it == directed.end() || it->second != 1) return false;
  }
  return true;
}

}  // namespace

TEST(Decimate, PlanarGridWithLockedBorderKeepsItsBorderAndLosesNothing) {
  SkinnedMesh g = grid(8);  // 81 vertices, 128 triangles, 32 on the border
  Options opt;
  opt.locked.resize(g.positions.size());
  size_t border = 0;
  for (size_t i = 0; i < g.positions.size(); ++i) {
    glm::vec3 p = g.positions[i];
    opt.locked[i] = p.x == 0 || p.y == 0 || p.x == 1 || p.y == 1;
    border += opt.locked[i];
  }
  ASSERT_EQ(border, 32u);
  Report rep;
  auto r = decimate(g, opt, &rep);
  ASSERT_TRUE(r) << r.error().message();
  // Interior vertices go without error: a polygon of 32 vertices needs 30 triangles; the last
  // interior vertex may stay when every collapse of it would fold a triangle.
  EXPECT_LE(rep.triangles_after, 32u);
  EXPECT_LE(r->positions.size(), 33u);
  EXPECT_LT(rep.hausdorff_m, 1e-6);
  EXPECT_EQ(rep.locked_vertices, 32u);
  std::set<std::pair<float, float>> kept;
  for (auto p : r->positions) kept.insert({p.x, p.y});
  for (size_t i = 0; i < g.positions.size(); ++i) {
    if (opt.locked[i]) {
      EXPECT_TRUE(kept.count({g.positions[i].x, g.positions[i].y}));
    }
  }
  // Every triangle still faces +z (no flips).
  for (size_t t = 0; t < r->indices.size(); t += 3) {
    glm::vec3 a = r->positions[r->indices[t]], b = r->positions[r->indices[t + 1]], c = r->positions[r->indices[t + 2]];
    EXPECT_GT(glm::cross(b - a, c - a).z, 0.0f);
  }
}

TEST(Decimate, ClosedTubeStaysClosedOrientedAndReportsItsError) {
  SkinnedMesh t = tube(41, 24);
  ASSERT_TRUE(closed_and_oriented(t));
  Options opt;
  opt.target_triangles = t.triangle_count() / 8;
  Report rep;
  auto r = decimate(t, opt, &rep);
  ASSERT_TRUE(r) << r.error().message();
  EXPECT_LE(rep.triangles_after, opt.target_triangles + 2);
  EXPECT_GE(rep.triangles_after, opt.target_triangles / 2);
  EXPECT_TRUE(closed_and_oriented(*r));
  // The reported error is the measured one, and small for a smooth tube.
  Distance d = mesh_distance(t.positions, t.indices, r->positions, r->indices);
  EXPECT_DOUBLE_EQ(d.hausdorff_m, rep.hausdorff_m);
  EXPECT_LT(rep.hausdorff_m, 0.01);
  EXPECT_GT(rep.hausdorff_m, 0.0);
  // Every face normal agrees with its vertices' original (outward) normals: nothing flipped.
  for (size_t k = 0; k < r->indices.size(); k += 3) {
    uint32_t i0 = r->indices[k], i1 = r->indices[k + 1], i2 = r->indices[k + 2];
    glm::vec3 a = r->positions[i0], b = r->positions[i1], c = r->positions[i2];
    glm::vec3 n = glm::normalize(glm::cross(b - a, c - a));
    glm::vec3 vn = glm::normalize(r->normals[i0] + r->normals[i1] + r->normals[i2]);
    EXPECT_GT(glm::dot(n, vn), 0.0f);
  }
  // Survivors keep their own weights, which still sum to one.
  for (size_t i = 0; i < r->positions.size(); ++i) {
    glm::vec4 w = r->weights[i];
    EXPECT_NEAR(w.x + w.y + w.z + w.w, 1.0f, 1e-6f);
  }
}

TEST(Decimate, SurvivorsAreInputVerticesWithAllTheirAttributes) {
  // The passes and the final polish (a survivor may take the place of an input vertex it
  // absorbed) never invent a vertex nor mix attributes of different input vertices.
  SkinnedMesh t = tube(41, 24);
  t.uvs.resize(t.positions.size());
  for (size_t i = 0; i < t.positions.size(); ++i) t.uvs[i] = {float(i), float(i) * 0.5f};
  Options opt;
  opt.target_triangles = t.triangle_count() / 10;
  auto r = decimate(t, opt);
  ASSERT_TRUE(r) << r.error().message();
  EXPECT_LE(r->triangle_count(), opt.target_triangles);
  EXPECT_GE(r->triangle_count(), opt.target_triangles - 2);
  ASSERT_EQ(r->uvs.size(), r->positions.size());
  std::set<size_t> sources;
  for (size_t i = 0; i < r->positions.size(); ++i) {
    size_t s = static_cast<size_t>(r->uvs[i].x);  // the uv names the input vertex
    ASSERT_LT(s, t.positions.size());
    EXPECT_EQ(r->positions[i], t.positions[s]);
    EXPECT_EQ(r->normals[i], t.normals[s]);
    EXPECT_EQ(r->joints[i], t.joints[s]);
    EXPECT_EQ(r->weights[i], t.weights[s]);
    EXPECT_EQ(r->uvs[i], t.uvs[s]);
    EXPECT_TRUE(sources.insert(s).second);  // no input vertex twice
  }
  EXPECT_TRUE(closed_and_oriented(*r));
}

TEST(Decimate, SkinWeightRuleKeepsTheJointRing) {
  SkinnedMesh t = tube(41, 24);
  auto count_blended = [](const SkinnedMesh& m) {
    size_t n = 0;
    for (const auto& w : m.weights) n += (w.x > 0 && w.x < 1);
    return n;
  };
  size_t before = count_blended(t);
  ASSERT_GT(before, 0u);
  Options with;
  with.target_triangles = 100;
  with.max_weight_difference = 0.6f;
  Options without = with;
  without.max_weight_difference = 2.0f;
  auto a = decimate(t, with), b = decimate(t, without);
  ASSERT_TRUE(a && b);
  // With the rule, collapses across the fast weight change are refused: more of the blended
  // ring survives than without it.
  EXPECT_GT(count_blended(*a), count_blended(*b));
}

TEST(Decimate, MeshDistanceIsExactOnTinyCases) {
  // Two parallel unit squares 0.25 apart.
  SkinnedMesh a = grid(1), b = grid(1);
  for (auto& p : b.positions) p.z = 0.25f;
  Distance d = mesh_distance(a.positions, a.indices, b.positions, b.indices);
  EXPECT_NEAR(d.hausdorff_m, 0.25, 1e-6);
  EXPECT_NEAR(d.mean_m, 0.25, 1e-6);
  Distance same = mesh_distance(a.positions, a.indices, a.positions, a.indices);
  EXPECT_LT(same.hausdorff_m, 1e-6);
}

TEST(Decimate, SnapshotIsTakenAfterThePassThatReachesItAndChangesNothing) {
  SkinnedMesh t = tube(41, 24);
  Options opt;
  opt.target_triangles = t.triangle_count() / 10;
  opt.snapshot_triangles = t.triangle_count() / 3;
  SkinnedMesh snap;
  auto with = decimate(t, opt, nullptr, &snap);
  auto without = decimate(t, opt);
  ASSERT_TRUE(with && without);
  // The passes do not depend on the snapshot: the same result.
  EXPECT_EQ(with->indices, without->indices);
  EXPECT_EQ(with->positions, without->positions);
  // A lightly decimated copy between the input and the result, made of input vertices, closed.
  EXPECT_LE(snap.triangle_count(), opt.snapshot_triangles);
  EXPECT_GT(snap.triangle_count(), with->triangle_count());
  EXPECT_LT(snap.triangle_count(), t.triangle_count());
  EXPECT_TRUE(closed_and_oriented(snap));
  std::set<std::tuple<float, float, float>> input;
  for (auto p : t.positions) input.insert({p.x, p.y, p.z});
  for (auto p : snap.positions) EXPECT_TRUE(input.count({p.x, p.y, p.z}));
  EXPECT_EQ(snap.weights.size(), snap.positions.size());
}

TEST(Decimate, ReferenceDistanceMatchesMeshDistanceAndGivesUpEarly) {
  SkinnedMesh t = tube(41, 24);
  Options a, b;
  a.target_triangles = t.triangle_count() / 8;
  b.target_triangles = t.triangle_count() / 30;
  auto fine = decimate(t, a), coarse = decimate(t, b);
  ASSERT_TRUE(fine && coarse);
  Distance df = mesh_distance(t.positions, t.indices, fine->positions, fine->indices);
  Distance dc = mesh_distance(t.positions, t.indices, coarse->positions, coarse->indices);
  ASSERT_LT(df.hausdorff_m, dc.hausdorff_m);
  ReferenceDistance ref(t.positions, t.indices);
  // Complete measurements: with the mean, exactly mesh_distance; without, the same Hausdorff.
  auto m1 = ref.measure(fine->positions, fine->indices);
  ASSERT_TRUE(m1.complete);
  EXPECT_DOUBLE_EQ(m1.distance.hausdorff_m, df.hausdorff_m);
  EXPECT_DOUBLE_EQ(m1.distance.mean_m, df.mean_m);
  auto m2 = ref.measure(coarse->positions, coarse->indices, 1e30, false);
  ASSERT_TRUE(m2.complete);
  EXPECT_DOUBLE_EQ(m2.distance.hausdorff_m, dc.hausdorff_m);
  // A candidate worse than the bound is given up on, with a distance above the bound.
  auto m3 = ref.measure(coarse->positions, coarse->indices, df.hausdorff_m, false);
  EXPECT_FALSE(m3.complete);
  EXPECT_GT(m3.distance.hausdorff_m, df.hausdorff_m);
  // One within the bound is measured in full.
  auto m4 = ref.measure(fine->positions, fine->indices, dc.hausdorff_m, false);
  ASSERT_TRUE(m4.complete);
  EXPECT_DOUBLE_EQ(m4.distance.hausdorff_m, df.hausdorff_m);
}

TEST(Decimate, BadMeshesAreRejected) {
  SkinnedMesh g = grid(2);
  SkinnedMesh bad = g;
  bad.indices[4] = 999;
  auto r = decimate(bad, {});
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message().find("out of range"), std::string::npos);
  SkinnedMesh nm = g;
  // A third triangle on an existing edge: non-manifold.
  nm.positions.push_back({0.5f, 0.5f, 1.0f});
  nm.normals.push_back({0, 0, 1});
  nm.joints.push_back({0, 0, 0, 0});
  nm.weights.push_back({1, 0, 0, 0});
  nm.indices.insert(nm.indices.end(), {nm.indices[0], nm.indices[1], static_cast<uint32_t>(nm.positions.size() - 1)});
  auto r2 = decimate(nm, {});
  ASSERT_FALSE(r2);
  EXPECT_NE(r2.error().message().find("non-manifold"), std::string::npos);
  Options opt;
  opt.locked = {1, 0};
  EXPECT_FALSE(decimate(g, opt));
}
