// The air between the hanging arms and the torso (bb/modeler/clearance.h).
#include "bb/modeler/clearance.h"

#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include "bb/modeler/body.h"

namespace bb::modeler {
namespace {

constexpr float kDeg = 3.14159265f / 180;

Body variant(uint64_t seed) { return make_variant(default_body(), {.seed = seed}, "_v" + std::to_string(seed)); }

// The gap grows as the arms rise, on the default body and on seeded variants (the bisection in
// arm_abduction_for_clearance relies on it). Measured: the default body 5.5 / 17 / 36 mm at
// 5 / 9 / 15 deg; variant 1 -32 / -21 / -3 mm.
TEST(ArmClearance, GrowsAsTheArmsRise) {
  for (uint64_t seed : {0u, 1u, 2u, 3u, 4u}) {
    const Body body = seed ? variant(seed) : default_body();
    float last = -1e9f;
    for (float a = 0; a <= 30; a += 3) {
      const float gap = arm_torso_gap_m(body, a * kDeg);
      ASSERT_TRUE(std::isfinite(gap)) << body.name << " at " << a << " deg";
      EXPECT_GE(gap, last) << body.name << " at " << a << " deg";
      last = gap;
    }
  }
  EXPECT_NEAR(arm_torso_gap_m(default_body(), 9 * kDeg), 0.017f, 0.003f);
}

// The default body keeps the walk's 9 degrees (17 mm of air there); a broad variant whose arms sink
// into its torso at 9 degrees gets the smallest angle that gives it the clearance, to 0.1 degree.
TEST(ArmClearance, WalkRaisesTheArmsOfABroadBodyJustEnough) {
  EXPECT_FLOAT_EQ(walk_arm_abduction(default_body()), kWalkArmAbductionRad);
  const Body broad = variant(1);  // 19 % broader than the default body
  const float clearance = kWalkArmClearanceM * broad.height() / 1.75f;
  EXPECT_LT(arm_torso_gap_m(broad, kWalkArmAbductionRad), 0.0f);  // at 9 degrees: the arms in the torso
  const float a = walk_arm_abduction(broad);
  EXPECT_GT(a, kWalkArmAbductionRad);
  EXPECT_LT(a, kWalkArmAbductionMaxRad);
  EXPECT_GE(arm_torso_gap_m(broad, a), clearance);
  EXPECT_LT(arm_torso_gap_m(broad, a - 0.2f * kDeg), clearance);
  // More air asks for more; none at all can be had without lifting the arms past 30 degrees.
  EXPECT_GT(walk_arm_abduction(broad, 2 * kWalkArmClearanceM), a);
  EXPECT_FLOAT_EQ(walk_arm_abduction(broad, 1.0f), kWalkArmAbductionMaxRad);
}

// Without arms (their primitives taken off) nothing can sink into the torso: no gap to measure,
// and the walk keeps its 9 degrees.
TEST(ArmClearance, ABodyWithoutArmsKeepsTheWalksAngle) {
  Body body = variant(1);
  const Skeleton& sk = *body.skeleton;
  std::erase_if(body.primitives, [&](const Primitive& p) {
    const std::string& j = sk.joints()[p.joint].name;
    return j.find("shoulder") != std::string::npos || j.find("elbow") != std::string::npos;
  });
  EXPECT_TRUE(std::isinf(arm_torso_gap_m(body, 0.0f)));
  EXPECT_FLOAT_EQ(walk_arm_abduction(body), kWalkArmAbductionRad);
}

}  // namespace
}  // namespace bb::modeler
