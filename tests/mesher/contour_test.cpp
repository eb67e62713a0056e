// Contour sampling on tiny fields with exact answers: a sphere, two overlapping metaballs, and
// rays into concave regions (the outermost crossing wins).
#include <cmath>
#include <memory>

#include <gtest/gtest.h>

#include "bb/mesher/mesher.h"
#include "bb/modeler/body.h"
#include "bb/modeler/implicit_surface.h"
#include "internal.h"

namespace bb::mesher {
namespace {

using detail::SubField;

// A body on the default skeleton with the given primitives on the root joint.
modeler::Body tiny_body(std::vector<modeler::Primitive> prims) {
  modeler::Body b;
  b.name = "tiny";
  b.skeleton = modeler::default_body().skeleton;
  b.primitives = std::move(prims);
  b.sample_posture = "neutral";
  return b;
}

modeler::Primitive prim(modeler::PrimitiveType type, glm::vec3 center, glm::vec3 radii) {
  modeler::Primitive p;
  p.type = type;
  p.joint = 0;
  p.center = center;
  p.radii = radii;
  return p;
}

glm::vec3 root_of(const modeler::Body& b) {
  return glm::vec3(b.skeleton->world_transforms(b.skeleton->posture(b.sample_posture))[0][3]);
}

TEST(Contour, SphereRingIsExact) {
  modeler::Body b = tiny_body({prim(modeler::PrimitiveType::kEllipsoid, {0, 0, 0}, glm::vec3(0.1f))});
  modeler::ImplicitSurface s(b, b.skeleton->posture("neutral"));
  SubField f(s);
  glm::vec3 c = root_of(b);
  // Rings at several heights along the Y axis: radius sqrt(r^2 - h^2).
  for (float h : {0.0f, 0.03f, 0.06f, 0.09f}) {
    auto ring = detail::sample_contour(f, c + glm::vec3(0, h, 0), {0, 1, 0}, {0, 0, 1}, 24);
    ASSERT_EQ(ring.size(), 24u);
    float expected = std::sqrt(0.01f - h * h);
    for (size_t k = 0; k < ring.size(); ++k) {
      glm::vec3 d = ring[k] - (c + glm::vec3(0, h, 0));
      EXPECT_NEAR(glm::length(d), expected, 2e-6f) << "h " << h << " k " << k;
      EXPECT_NEAR(d.y, 0.0f, 1e-6f);
      // Counter-clockwise around +Y starting on +Z: k = 6 is at 90 degrees, i.e. on +X.
      float ang = std::atan2(d.x, d.z);
      float want = std::remainder(6.2831853f * float(k) / 24.0f, 6.2831853f);
      EXPECT_NEAR(std::remainder(ang - want, 6.2831853f), 0.0f, 1e-4f);
    }
  }
}

TEST(Contour, EllipsoidRingIsExact) {
  modeler::Body b = tiny_body({prim(modeler::PrimitiveType::kEllipsoid, {0, 0, 0}, {0.05f, 0.2f, 0.08f})});
  modeler::ImplicitSurface s(b, b.skeleton->posture("neutral"));
  SubField f(s);
  glm::vec3 c = root_of(b);
  auto ring = detail::sample_contour(f, c, {0, 1, 0}, {0, 0, 1}, 16);
  for (const glm::vec3& p : ring) {
    glm::vec3 q = (p - c) / glm::vec3(0.05f, 0.2f, 0.08f);
    EXPECT_NEAR(glm::length(q), 1.0f, 3e-5f);
  }
}

// Two metaballs of radius R with centres at +-a on X: on the mid-plane x = 0 each contributes
// half the iso value, 2 s ((1 - q^2/k^2) / (1 - 1/k^2))^3 = 1, so q^2 = k^2 - (k^2 - 1) 2^(-1/3)
// and the ring radius is sqrt(q^2 R^2 - a^2).
TEST(Contour, TwoMetaballsMidRingIsExact) {
  const float R = 0.08f, a = 0.06f, k2 = modeler::kMetaballReach * modeler::kMetaballReach;
  modeler::Body b = tiny_body({prim(modeler::PrimitiveType::kMetaball, {-a, 0, 0}, glm::vec3(R)),
                               prim(modeler::PrimitiveType::kMetaball, {a, 0, 0}, glm::vec3(R))});
  modeler::ImplicitSurface s(b, b.skeleton->posture("neutral"));
  SubField f(s);
  glm::vec3 c = root_of(b);
  float q2 = k2 - (k2 - 1) * std::pow(2.0f, -1.0f / 3.0f);
  float expected = std::sqrt(q2 * R * R - a * a);
  auto ring = detail::sample_contour(f, c, {1, 0, 0}, {0, 1, 0}, 12);
  for (const glm::vec3& p : ring) EXPECT_NEAR(glm::distance(p, c), expected, 2e-5f);
  // The blended waist is wider than either ball's own section there would be.
  EXPECT_GT(expected, std::sqrt(R * R - a * a));
  // A subset field with one ball only gives that ball's section.
  SubField one(s, {0});
  auto ring1 = detail::sample_contour(one, c, {1, 0, 0}, {0, 1, 0}, 12);
  for (const glm::vec3& p : ring1) EXPECT_NEAR(glm::distance(p, c), std::sqrt(R * R - a * a), 2e-5f);
}

// A ray from inside one sphere through a gap into a second sphere: the outermost crossing is the
// far side of the second sphere, not the first exit; the contour never folds back.
TEST(Contour, ConcaveRayPicksOutermostCrossing) {
  modeler::Body b = tiny_body({prim(modeler::PrimitiveType::kEllipsoid, {0, 0, 0}, glm::vec3(0.05f)),
                               prim(modeler::PrimitiveType::kEllipsoid, {0, 0, 0.2f}, glm::vec3(0.04f))});
  modeler::ImplicitSurface s(b, b.skeleton->posture("neutral"));
  SubField f(s);
  glm::vec3 c = root_of(b);
  auto t = f.outermost(c, {0, 0, 1}, 1.0f);
  ASSERT_TRUE(t.has_value());
  EXPECT_NEAR(*t, 0.24f, 1e-5f);
  auto ring = detail::sample_contour(f, c, {0, 1, 0}, {0, 0, 1}, 8);
  EXPECT_NEAR(glm::distance(ring[0], c), 0.24f, 1e-5f);  // toward the second sphere
  EXPECT_NEAR(glm::distance(ring[4], c), 0.05f, 1e-5f);  // away from it
  // Rays into a concave notch of one metaball chain: every sample is on the skin and is the
  // outermost one (nothing of the skin beyond it along the ray).
  for (size_t k = 0; k < ring.size(); ++k) {
    glm::vec3 d = glm::normalize(ring[k] - c);
    EXPECT_NEAR(s.field(ring[k]), modeler::kIso, 1e-3f);
    for (float x = 0.001f; x < 0.4f; x += 0.001f) ASSERT_LT(s.field(ring[k] + x * d), modeler::kIso);
  }
}

TEST(BuildLodsInput, EmptyBodyIsAnError) {
  modeler::Body b = tiny_body({});
  auto r = build_lods(b);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message().find("no primitives"), std::string::npos);
}

TEST(BuildLodsInput, BadDensityIsAnError) {
  MesherOptions o;
  o.lods = default_lod_chain();
  o.lods[1].arm.points = 2;
  auto r = build_lods(modeler::default_body(), o);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message().find("lods[1]"), std::string::npos);
}

}  // namespace
}  // namespace bb::mesher
