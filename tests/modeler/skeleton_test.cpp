#include <cmath>

#include <gtest/gtest.h>
#include <glm/gtc/constants.hpp>

#include "bb/modeler/skeleton.h"

using namespace bb::modeler;

namespace {

// A 3-joint chain: root (translation x + rotation z) -> a (rotation z) -> tip.
const char* kChain = R"({
  "name": "chain",
  "joints": [
    {"name": "root", "parent": null, "offset": [0, 0, 0],
     "dofs": [{"name": "tx", "type": "translation", "axis": [1, 0, 0], "min_m": -10, "max_m": 10},
              {"name": "rz", "type": "rotation", "axis": [0, 0, 1], "min_deg": -90, "max_deg": 90}]},
    {"name": "a", "parent": "root", "offset": [0, 1, 0],
     "dofs": [{"name": "bend", "type": "rotation", "axis": [0, 0, 2], "min_deg": 0, "max_deg": 120}]},
    {"name": "tip", "parent": "a", "offset": [0, 2, 0]}
  ],
  "postures": {"up": {"a.bend": 90}}
})";

void expect_vec(const glm::vec3& a, const glm::vec3& b, float eps = 1e-5f) {
  EXPECT_NEAR(a.x, b.x, eps);
  EXPECT_NEAR(a.y, b.y, eps);
  EXPECT_NEAR(a.z, b.z, eps);
}

}  // namespace

TEST(Skeleton, ForwardKinematicsOfASmallChainIsExact) {
  auto sk = parse_skeleton(kChain, "chain.json");
  ASSERT_TRUE(sk) << sk.error().message();
  EXPECT_EQ(sk->dof_count(), 3);
  EXPECT_EQ(sk->joints().size(), 3u);
  Posture p = sk->neutral();
  auto w = sk->world_transforms(p);
  expect_vec(glm::vec3(w[2][3]), {0, 3, 0});
  // Root moved 0.5 along x and turned 90 degrees about z: +y becomes -x.
  p[sk->find_dof("root.tx")] = 0.5f;
  p[sk->find_dof("root.rz")] = glm::half_pi<float>();
  w = sk->world_transforms(p);
  expect_vec(glm::vec3(w[1][3]), {0.5f - 1.0f, 0, 0});
  expect_vec(glm::vec3(w[2][3]), {0.5f - 3.0f, 0, 0});
  // Then bend a by 90 degrees more (axis normalized from [0,0,2]): the tip points along -y.
  p[sk->find_dof("a.bend")] = glm::half_pi<float>();
  w = sk->world_transforms(p);
  expect_vec(glm::vec3(w[2][3]), {-0.5f, -2.0f, 0});
}

TEST(Skeleton, NamedPosturesAreInRadians) {
  auto sk = parse_skeleton(kChain, "chain.json");
  ASSERT_TRUE(sk);
  Posture up = sk->posture("up");
  EXPECT_NEAR(up[sk->find_dof("a.bend")], glm::half_pi<float>(), 1e-6f);
  EXPECT_EQ(sk->posture("nonexistent"), sk->neutral());
}

TEST(Skeleton, ClampingBringsEveryDofIntoItsLimits) {
  auto sk = parse_skeleton(kChain, "chain.json");
  ASSERT_TRUE(sk);
  Posture p = {20.0f, -3.0f, 1.0f};
  EXPECT_FALSE(sk->within_limits(p));
  EXPECT_EQ(sk->clamp(p), 2);
  EXPECT_TRUE(sk->within_limits(p));
  EXPECT_FLOAT_EQ(p[0], 10.0f);
  EXPECT_NEAR(p[1], -glm::half_pi<float>(), 1e-6f);
  EXPECT_FLOAT_EQ(p[2], 1.0f);
  EXPECT_EQ(sk->clamp(p), 0);
}

TEST(Skeleton, DefaultSkeletonHas74LimitedDofs) {
  const Skeleton& sk = default_skeleton();
  EXPECT_EQ(sk.dof_count(), 74);
  int root_dofs = static_cast<int>(sk.joints()[0].dofs.size());
  EXPECT_EQ(root_dofs, 6);  // global mobility: 3 translations, 3 rotations
  for (int i = 0; i < sk.dof_count(); ++i) {
    EXPECT_TRUE(std::isfinite(sk.dof(i).min) && std::isfinite(sk.dof(i).max));
    EXPECT_LT(sk.dof(i).min, sk.dof(i).max) << i;
  }
  EXPECT_FALSE(sk.limits_source.empty());
  for (const char* j : {"HumanoidRoot", "vl5", "skullbase", "l_shoulder", "r_elbow", "l_wrist", "r_knee",
                        "l_ankle", "l_thumb1", "r_pinky1"})
    EXPECT_GE(sk.find_joint(j), 0) << j;
  // Parents come before children.
  for (size_t j = 1; j < sk.joints().size(); ++j) EXPECT_LT(sk.joints()[j].parent, static_cast<int>(j));
  // Every named posture respects the limits.
  for (const auto& name : sk.posture_names()) EXPECT_TRUE(sk.within_limits(sk.posture(name))) << name;
}

TEST(Skeleton, MaxExtentRaisesTheHandsAboveTheHeadAndDefinesTa) {
  const Skeleton& sk = default_skeleton();
  auto w = sk.world_transforms(sk.posture("max_extent"));
  float head = w[sk.find_joint("skull_tip")][3].y;
  EXPECT_GT(w[sk.find_joint("l_middle_tip")][3].y, head + 0.3f);
  EXPECT_GT(w[sk.find_joint("r_middle_tip")][3].y, head + 0.3f);
  // Left hand stays on the left: the arms go straight up, not across.
  EXPECT_GT(w[sk.find_joint("l_middle_tip")][3].x, 0.1f);
  EXPECT_LT(w[sk.find_joint("r_middle_tip")][3].x, -0.1f);
  glm::vec3 ta = sk.ta();
  glm::vec3 vl5 = glm::vec3(w[sk.find_joint("vl5")][3]);
  expect_vec(ta, vl5);
  EXPECT_NEAR(ta.y, 1.02f, 0.05f);
}

TEST(Skeleton, LeftAndRightMirror) {
  const Skeleton& sk = default_skeleton();
  // Same DOF values on both sides give mirrored positions (x -> -x).
  Posture p = sk.neutral();
  for (const char* d : {"shoulder.flexion", "shoulder.abduction", "elbow.flexion", "hip.flexion", "knee.flexion"}) {
    p[sk.find_dof(std::string("l_") + d)] = 0.5f;
    p[sk.find_dof(std::string("r_") + d)] = 0.5f;
  }
  auto w = sk.world_transforms(p);
  for (const char* j : {"wrist", "ankle", "middle_tip"}) {
    glm::vec3 l(w[sk.find_joint(std::string("l_") + j)][3]), r(w[sk.find_joint(std::string("r_") + j)][3]);
    expect_vec(l, glm::vec3(-r.x, r.y, r.z), 1e-4f);
  }
  // Positive flexion brings the thigh forward (+Z), positive knee flexion brings the foot back.
  EXPECT_GT(w[sk.find_joint("l_knee")][3].z, 0.1f);
}

struct BadSkeleton {
  const char* json;
  const char* where;   // expected JSON path (prefix) in the error
  const char* reason;  // expected words in the reason
};

class SkeletonBadInput : public ::testing::TestWithParam<BadSkeleton> {};

TEST_P(SkeletonBadInput, IsRejectedWithFilePathAndReason) {
  auto r = parse_skeleton(GetParam().json, "bad.json");
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().file, "bad.json");
  EXPECT_EQ(r.error().where.rfind(GetParam().where, 0), 0u) << r.error().message();
  EXPECT_NE(r.error().reason.find(GetParam().reason), std::string::npos) << r.error().message();
}

INSTANTIATE_TEST_SUITE_P(
    Cases, SkeletonBadInput,
    ::testing::Values(
        BadSkeleton{R"({"joints": [ {"name": "a", )", "line 1", "invalid JSON"},
        BadSkeleton{R"([1,2])", "$", "object"},
        BadSkeleton{R"({"joints": []})", "$.joints", "at least one"},
        BadSkeleton{R"({"joints": [{"name":"a","parent":"nope","offset":[0,0,0]}]})", "$.joints[0].parent",
                    "unknown joint"},
        BadSkeleton{R"({"joints": [{"name":"a","parent":null,"offset":[0,0,0]},
                                   {"name":"b","parent":"c","offset":[0,0,0]},
                                   {"name":"c","parent":"b","offset":[0,0,0]}]})",
                    "$.joints[1].parent", "cycle"},
        BadSkeleton{R"({"joints": [{"name":"a","parent":null,"offset":[0,0,0],
                      "dofs":[{"name":"x","type":"rotation","axis":[1,0,0],"min_deg":30,"max_deg":10}]}]})",
                    "$.joints[0].dofs[0]", "min > max"},
        BadSkeleton{R"({"joints": [{"name":"a","parent":null,"offset":[0,0]}]})", "$.joints[0].offset",
                    "3 numbers"},
        BadSkeleton{R"({"joints": [{"name":"a","parent":null,"offset":[0,0,0],
                      "dofs":[{"name":"x","type":"twist","axis":[1,0,0],"min_deg":0,"max_deg":10}]}]})",
                    "$.joints[0].dofs[0].type", "unknown DOF type"},
        BadSkeleton{R"({"joints": [{"name":"a","parent":null,"offset":[0,0,0]},
                                   {"name":"a","parent":"a","offset":[0,0,0]}]})",
                    "$.joints[1].name", "duplicate"},
        BadSkeleton{R"({"joints": [{"name":"a","parent":null,"offset":[0,0,0]}],
                       "postures": {"p": {"a.x": 3}}})",
                    "$.postures.p.a.x", "unknown DOF"},
        // Found in an audit: the last of two equal keys won silently.
        BadSkeleton{"{\"joints\": [{\"name\":\"a\",\"parent\":null,\n\"offset\":[0,0,0],\"offset\":[1,0,0]}]}",
                    "$.joints[0]", "duplicate key \"offset\" (line 2)"}),
    [](const auto& param_info) { return "case" + std::to_string(param_info.index); });

TEST(Skeleton, MissingFileNamesTheFile) {
  auto r = load_skeleton("/nonexistent/skeleton.json");
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().file, "/nonexistent/skeleton.json");
  EXPECT_NE(r.error().reason.find("cannot open"), std::string::npos);
}

TEST(Skeleton, DataFileOnDiskMatchesTheBuiltInOne) {
  auto r = load_skeleton(std::string(BB_DATA_DIR) + "/skeleton.json");
  ASSERT_TRUE(r) << r.error().message();
  EXPECT_EQ(r->dof_count(), default_skeleton().dof_count());
  EXPECT_EQ(r->joints().size(), default_skeleton().joints().size());
}
