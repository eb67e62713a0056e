#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "bb/modeler/implicit_surface.h"

using namespace bb::modeler;

namespace {

// A body of the given primitives on the built-in skeleton's root, in the neutral posture with
// the root moved to the origin.
Body body_of(std::vector<Primitive> prims) {
  Body b = default_body();
  b.primitives = std::move(prims);
  return b;
}

Posture at_origin(const Body& b) {
  Posture p = b.skeleton->neutral();
  p[b.skeleton->find_dof("HumanoidRoot.ty")] = -b.skeleton->joints()[0].offset.y;
  return p;
}

Primitive sphere(glm::vec3 c, float r, PrimitiveType t = PrimitiveType::kMetaball) {
  Primitive p;
  p.type = t;
  p.joint = 0;
  p.center = c;
  p.radii = glm::vec3(r);
  return p;
}

}  // namespace

TEST(ImplicitSurface, LoneSphereSkinIsTheSphere) {
  for (auto type : {PrimitiveType::kMetaball, PrimitiveType::kEllipsoid}) {
    Body b = body_of({sphere({0, 0, 0}, 0.1f, type)});
    ImplicitSurface s(b, at_origin(b));
    EXPECT_NEAR(s.field({0.1f, 0, 0}), kIso, 1e-5f);
    EXPECT_GT(s.field({0.05f, 0, 0}), kIso);
    EXPECT_LT(s.field({0.0, 0.12f, 0}), kIso);
    EXPECT_EQ(s.field({0.0, 0.5f, 0}), 0.0f);
    // From the centre, every ray meets the skin at the radius.
    for (int i = 0; i < 16; ++i) {
      float a = i * 0.4f;
      glm::vec3 d(std::cos(a), std::sin(a) * 0.6f, std::sin(a) * 0.8f);
      auto t = s.outermost_intersection({0, 0, 0}, d, 1.0f);
      ASSERT_TRUE(t);
      EXPECT_NEAR(*t, 0.1f, 2e-6f);
    }
    // A ray that misses, and one too short to reach the skin.
    EXPECT_FALSE(s.outermost_intersection({0, 0.3f, 0}, {1, 0, 0}, 1.0f));
    // Inside all the way: no crossing within reach.
    EXPECT_FALSE(s.outermost_intersection({0, 0, 0}, {1, 0, 0}, 0.05f));
  }
}

TEST(ImplicitSurface, EllipsoidFollowsItsOrientationAndJoint) {
  Primitive p = sphere({0, 0, 0}, 1.0f, PrimitiveType::kEllipsoid);
  p.radii = {0.3f, 0.1f, 0.1f};
  p.orientation = glm::angleAxis(glm::radians(90.0f), glm::vec3(0, 0, 1));  // long axis now along y
  Body b = body_of({p});
  ImplicitSurface s(b, at_origin(b));
  auto up = s.outermost_intersection({0, 0, 0}, {0, 1, 0}, 1.0f);
  auto side = s.outermost_intersection({0, 0, 0}, {1, 0, 0}, 1.0f);
  ASSERT_TRUE(up && side);
  EXPECT_NEAR(*up, 0.3f, 2e-6f);
  EXPECT_NEAR(*side, 0.1f, 2e-6f);
  // Turn the root by 90 degrees about z: the long axis follows to -x.
  Posture q = at_origin(b);
  q[b.skeleton->find_dof("HumanoidRoot.roll")] = glm::radians(90.0f);
  ImplicitSurface s2(b, q);
  EXPECT_NEAR(*s2.outermost_intersection({0, 0, 0}, {1, 0, 0}, 1.0f), 0.3f, 2e-6f);
}

TEST(ImplicitSurface, TwoOverlappingMetaballsBlendExactly) {
  // Metaballs of radius r at (+-a, 0, 0). On the y axis both contribute equally, so the skin
  // crosses the y axis where 2 f(q) = 1: q^2 = k^2 (1 - (1 - 1/k^2) 2^(-1/3)), y = sqrt(q^2 r^2 - a^2).
  const float r = 0.1f, a = 0.08f, k = kMetaballReach;
  Body b = body_of({sphere({a, 0, 0}, r), sphere({-a, 0, 0}, r)});
  ImplicitSurface s(b, at_origin(b));
  double q2 = k * k * (1.0 - (1.0 - 1.0 / (k * k)) * std::cbrt(0.5));
  double y = std::sqrt(q2 * r * r - a * a);
  auto t = s.outermost_intersection({0, 0, 0}, {0, 1, 0}, 1.0f);
  ASSERT_TRUE(t);
  EXPECT_NEAR(*t, y, 2e-6);
  EXPECT_GT(y, std::sqrt(r * r - a * a));  // blending swells the waist between them
  EXPECT_NEAR(s.field({0, static_cast<float>(y), 0}), kIso, 1e-4f);
}

TEST(ImplicitSurface, RaysIntoConcaveRegionsPickTheOutermostCrossing) {
  // Two separate spheres on the ray: the skin is crossed four times; the answer is the far side
  // of the far sphere. Also a ray starting inside the near sphere.
  Body b = body_of({sphere({0, 0, 0}, 0.05f, PrimitiveType::kEllipsoid),
                    sphere({0.3f, 0, 0}, 0.05f, PrimitiveType::kEllipsoid)});
  ImplicitSurface s(b, at_origin(b));
  auto t = s.outermost_intersection({-0.2f, 0, 0}, {1, 0, 0}, 1.0f);
  ASSERT_TRUE(t);
  EXPECT_NEAR(*t, 0.55f, 2e-6f);
  auto t2 = s.outermost_intersection({0, 0, 0}, {1, 0, 0}, 1.0f);
  ASSERT_TRUE(t2);
  EXPECT_NEAR(*t2, 0.35f, 2e-6f);
  // Limited reach: only the near sphere's far side is within 0.2 m.
  auto t3 = s.outermost_intersection({0, 0, 0}, {1, 0, 0}, 0.2f);
  ASSERT_TRUE(t3);
  EXPECT_NEAR(*t3, 0.05f, 2e-6f);
  // A thin finger-like ellipsoid behind a big one is not stepped over.
  Primitive big = sphere({0, 0, 0}, 0.12f);
  Primitive finger = sphere({0.4f, 0, 0}, 0.01f, PrimitiveType::kEllipsoid);
  finger.radii = {0.008f, 0.04f, 0.008f};
  Body b2 = body_of({big, finger});
  ImplicitSurface s2(b2, at_origin(b2));
  auto t4 = s2.outermost_intersection({0, 0, 0}, {1, 0, 0}, 1.0f);
  ASSERT_TRUE(t4);
  EXPECT_NEAR(*t4, 0.408f, 2e-6f);
}

TEST(ImplicitSurface, GradientMatchesFiniteDifferencesOnTheDefaultBody) {
  const Body& b = default_body();
  ImplicitSurface s(b, b.skeleton->posture("bind"));
  std::mt19937 rng(1);
  const auto& box = s.bounds();
  std::uniform_real_distribution<float> ux(box.min.x, box.max.x), uy(box.min.y, box.max.y),
      uz(box.min.z, box.max.z);
  int checked = 0;
  for (int i = 0; i < 20000 && checked < 300; ++i) {
    glm::vec3 x(ux(rng), uy(rng), uz(rng));
    glm::vec3 g;
    float f = s.field_gradient(x, &g);
    EXPECT_NEAR(f, s.field(x), 1e-5f * std::max(1.0f, f));
    if (f < 0.2f || f > 3.0f) continue;  // near the skin, where it matters
    const double h = 1e-4;
    for (int k = 0; k < 3; ++k) {
      glm::vec3 e(0);
      e[k] = static_cast<float>(h);
      double fd = (static_cast<double>(s.field(x + e)) - s.field(x - e)) / (2 * h);
      EXPECT_NEAR(g[k], fd, 0.02 * std::max(1.0, std::abs(fd)) + 0.05) << "at " << x.x << "," << x.y << "," << x.z;
    }
    ++checked;
  }
  EXPECT_GE(checked, 100);
}

TEST(ImplicitSurface, InsideOutsideAndOutermostPropertyOnTheDefaultBody) {
  const Body& b = default_body();
  ImplicitSurface s(b, b.skeleton->posture("bind"));
  const auto& sk = *b.skeleton;
  const auto& w = s.joint_transforms();
  // Joint centres of the trunk and limbs are inside the skin; points 30 cm beside the body are outside.
  for (const char* j : {"vl5", "vt10", "vc7", "skullbase", "l_knee", "r_elbow", "l_hip"})
    EXPECT_GT(s.field(glm::vec3(w[sk.find_joint(j)][3])), kIso) << j;
  EXPECT_LT(s.field({0, 1.0f, 0.4f}), kIso);
  EXPECT_LT(s.field({0.6f, 0.5f, 0}), kIso);
  // Outermost property: from the spine, along many directions, the point found is on the skin
  // and every point beyond it (sampled densely) is outside.
  glm::vec3 o(w[sk.find_joint("vt10")][3]);
  for (int i = 0; i < 64; ++i) {
    float a = i * 0.098f;
    glm::vec3 d(std::cos(a), 0.3f * std::sin(3 * a), std::sin(a));
    d = glm::normalize(d);
    auto t = s.outermost_intersection(o, d, 1.5f);
    ASSERT_TRUE(t);
    EXPECT_NEAR(s.field(o + d * *t), kIso, 1e-3f);
    for (float u = *t + 0.001f; u < 1.5f; u += 0.002f) ASSERT_LT(s.field(o + d * u), kIso) << i << " " << u;
  }
}
