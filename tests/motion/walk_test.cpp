#include <cmath>

#include <gtest/gtest.h>

#include "bb/modeler/body.h"
#include "bb/motion/walk.h"

using namespace bb;

namespace {

// World position of a joint when the character is moved forward at the clip's speed.
glm::vec3 world_joint(const modeler::Skeleton& sk, const motion::Clip& c, size_t f, int joint) {
  auto w = sk.world_transforms(c.frames[f]);
  glm::vec3 p(w[joint][3]);
  if (c.loops) p.z += c.speed_mps * (f / c.fps);
  return p;
}

}  // namespace

TEST(Walk, CycleFollowsTheGlobalWalkingModel) {
  const auto& sk = modeler::default_skeleton();
  auto c = motion::walk_cycle(sk, 1.2f);
  EXPECT_NEAR(c.leg_length_m, 0.91f, 0.02f);
  EXPECT_NEAR(c.relative_velocity, 1.2f / c.leg_length_m, 1e-5f);
  EXPECT_NEAR(c.cycle_length_m, 1.346f * std::sqrt(c.relative_velocity) * c.leg_length_m, 1e-5f);
  EXPECT_NEAR(c.cycle_duration_s, c.cycle_length_m / 1.2f, 1e-5f);
  // About one second per cycle at a normal pace, faster cycles when walking faster.
  EXPECT_GT(c.cycle_duration_s, 0.8f);
  EXPECT_LT(c.cycle_duration_s, 1.4f);
  EXPECT_LT(motion::walk_cycle(sk, 2.0f).cycle_duration_s, c.cycle_duration_s);
}

TEST(Walk, LoopsSeamlesslyWithinLimits) {
  const auto& sk = modeler::default_skeleton();
  for (float v : {0.6f, 1.2f, 1.8f}) {
    auto clip = motion::make_walk(sk, {.speed_mps = v});
    ASSERT_TRUE(clip) << clip.error().message();
    EXPECT_TRUE(clip->loops);
    EXPECT_GE(clip->frames.size(), 9u);
    char name[32];
    std::snprintf(name, sizeof name, "walk_%.2fmps", v);
    EXPECT_EQ(clip->name, name);
    for (const auto& f : clip->frames) EXPECT_TRUE(sk.within_limits(f));
    // Last frame equals the first: the loop has no seam.
    for (int i = 0; i < sk.dof_count(); ++i) EXPECT_NEAR(clip->frames.back()[i], clip->frames.front()[i], 1e-5f);
    EXPECT_NEAR(clip->duration(), motion::walk_cycle(sk, v).cycle_duration_s, 1e-4f);
  }
}

TEST(Walk, DrivingFootStaysPlanted) {
  const auto& sk = modeler::default_skeleton();
  for (float v : {0.8f, 1.2f, 1.6f}) {
    auto clip = motion::make_walk(sk, {.speed_mps = v, .fps = 60});
    ASSERT_TRUE(clip);
    size_t n = clip->frames.size() - 1;
    int ankle[2] = {sk.find_joint("l_ankle"), sk.find_joint("r_ankle")};
    for (int s = 0; s < 2; ++s) {
      // The side drives during its half cycle: left [0, n/2), right [n/2, n).
      size_t a = s == 0 ? 0 : (n + 1) / 2, b = s == 0 ? (n + 1) / 2 : n;  // phase < 0.5: left
      glm::vec3 start = world_joint(sk, *clip, a, ankle[s]);
      float slide = 0;
      for (size_t f = a; f < b; ++f) {
        glm::vec3 p = world_joint(sk, *clip, f, ankle[s]);
        slide = std::max(slide, glm::length(glm::vec2(p.x - start.x, p.z - start.z)));
      }
      EXPECT_LT(slide, 0.02f) << "speed " << v << " side " << s;
    }
    // The swinging foot does move forward.
    glm::vec3 a = world_joint(sk, *clip, 0, ankle[1]), b = world_joint(sk, *clip, n / 2, ankle[1]);
    EXPECT_GT(b.z - a.z, 0.5f * motion::walk_cycle(sk, v).cycle_length_m);
  }
}

TEST(Walk, FeetStayOnTheGround) {
  const auto& sk = modeler::default_skeleton();
  auto clip = motion::make_walk(sk, {.speed_mps = 1.2f});
  ASSERT_TRUE(clip);
  auto rest = sk.world_transforms(sk.neutral());
  int toe[2] = {sk.find_joint("l_metatarsophalangeal"), sk.find_joint("r_metatarsophalangeal")};
  int ankle[2] = {sk.find_joint("l_ankle"), sk.find_joint("r_ankle")};
  float ground = std::min(rest[toe[0]][3].y, rest[ankle[0]][3].y);
  for (const auto& f : clip->frames) {
    auto w = sk.world_transforms(f);
    float low = 1e9f;
    for (int s = 0; s < 2; ++s) low = std::min({low, w[toe[s]][3].y, w[ankle[s]][3].y});
    EXPECT_NEAR(low, ground, 0.01f);
  }
}

TEST(Walk, BadParametersAreErrors) {
  const auto& sk = modeler::default_skeleton();
  EXPECT_FALSE(motion::make_walk(sk, {.speed_mps = 5.0f}));
  EXPECT_FALSE(motion::make_walk(sk, {.speed_mps = 1.0f, .fps = 0.0f}));
  EXPECT_FALSE(motion::make_walk(sk, {.arm_abduction_rad = -0.1f}));
  EXPECT_FALSE(motion::make_walk(sk, {.arm_abduction_rad = 0.8f}));
  EXPECT_FALSE(motion::make_walk(sk, {.arm_abduction_rad = std::nanf("")}));
}

// The arms hang as far out as asked in every frame (9 degrees by default; a broad body's build asks
// for more, modeler::walk_arm_abduction), and nothing else changes.
TEST(Walk, ArmsHangAsFarOutAsAsked) {
  const auto& sk = modeler::default_skeleton();
  auto plain = motion::make_walk(sk, {});
  auto wide = motion::make_walk(sk, {.arm_abduction_rad = 0.35f});
  ASSERT_TRUE(plain && wide);
  ASSERT_EQ(plain->frames.size(), wide->frames.size());
  const int abd[2] = {sk.find_dof("l_shoulder.abduction"), sk.find_dof("r_shoulder.abduction")};
  for (size_t f = 0; f < plain->frames.size(); ++f)
    for (int d = 0; d < sk.dof_count(); ++d) {
      if (d == abd[0] || d == abd[1]) {
        EXPECT_FLOAT_EQ(plain->frames[f][d], modeler::kWalkArmAbductionRad);
        EXPECT_FLOAT_EQ(wide->frames[f][d], 0.35f);
      } else {
        EXPECT_EQ(plain->frames[f][d], wide->frames[f][d]) << "frame " << f << " dof " << d;
      }
    }
}
