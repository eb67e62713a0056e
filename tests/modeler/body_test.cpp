#include <gtest/gtest.h>

#include "bb/modeler/body.h"
#include "bb/modeler/implicit_surface.h"

using namespace bb::modeler;

TEST(Body, DefaultBodyIsAnAdultOfAbout175WithBothLayers) {
  const Body& b = default_body();
  EXPECT_EQ(b.skeleton->dof_count(), 74);
  EXPECT_GT(b.count(PrimitiveType::kEllipsoid), 10);
  EXPECT_GT(b.count(PrimitiveType::kMetaball), 30);
  EXPECT_NEAR(b.height(), 1.75f, 0.03f);
  // Every body region has primitives: head, neck, torso, arms, legs, hands with five fingers, feet.
  for (const char* j : {"skullbase", "vc7", "vt10", "vl5", "l_shoulder", "r_elbow", "l_hip", "r_knee", "l_ankle",
                        "r_metatarsophalangeal", "l_wrist", "l_thumb1", "l_index1", "l_middle1", "l_ring1",
                        "l_pinky1", "r_thumb3", "r_pinky1"}) {
    int ji = b.skeleton->find_joint(j);
    bool found = false;
    for (const auto& p : b.primitives) found |= p.joint == ji;
    EXPECT_TRUE(found) << j;
  }
}

TEST(Body, DataFileOnDiskLoads) {
  auto r = load_body(std::string(BB_DATA_DIR) + "/bodies/default.json");
  ASSERT_TRUE(r) << r.error().message();
  EXPECT_EQ(r->primitives.size(), default_body().primitives.size());
}

TEST(Body, VariantsReachTheirHeightAndAreDeterministic) {
  const Body& b = default_body();
  Body tall = make_variant(b, {.height_m = 1.90f});
  EXPECT_NEAR(tall.height(), 1.90f, 0.02f);
  Body a = make_variant(b, {.seed = 7}, "_7"), a2 = make_variant(b, {.seed = 7}, "_7");
  Body c = make_variant(b, {.seed = 8}, "_8");
  EXPECT_EQ(a.name, "default_7");
  ASSERT_EQ(a.primitives.size(), a2.primitives.size());
  for (size_t i = 0; i < a.primitives.size(); ++i) EXPECT_EQ(a.primitives[i].radii, a2.primitives[i].radii);
  bool differs = false;
  for (size_t i = 0; i < a.primitives.size(); ++i) differs |= a.primitives[i].radii != c.primitives[i].radii;
  EXPECT_TRUE(differs);
  // A heavier build widens the torso: the waist's field reaches farther out.
  Body heavy = make_variant(b, {.build = 1.3f});
  auto waist_width = [](const Body& body) {
    ImplicitSurface s(body, body.skeleton->neutral());
    auto t = s.outermost_intersection({0, 1.12f, 0}, {1, 0, 0}, 1.0f);
    return t ? *t : 0.0f;
  };
  EXPECT_GT(waist_width(heavy), waist_width(b) * 1.15f);
  // Seeded variants stay human-sized.
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    float h = make_variant(b, {.seed = seed}).height();
    EXPECT_GT(h, 1.55f);
    EXPECT_LT(h, 1.95f);
  }
}

struct BadBody {
  const char* json;
  const char* where;
  const char* reason;
};

class BodyBadInput : public ::testing::TestWithParam<BadBody> {};

TEST_P(BodyBadInput, IsRejectedWithFilePathAndReason) {
  auto r = parse_body(GetParam().json, "body.json");
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().file, "body.json");
  EXPECT_EQ(r.error().where, GetParam().where) << r.error().message();
  EXPECT_NE(r.error().reason.find(GetParam().reason), std::string::npos) << r.error().message();
}

INSTANTIATE_TEST_SUITE_P(
    Cases, BodyBadInput,
    ::testing::Values(
        BadBody{"{\"name\": \"x\",\n \"primitives\": [}", "line 2, column 17", "invalid JSON"},
        BadBody{R"({"primitives": []})", "$", "missing required key \"name\""},
        BadBody{R"({"name": "x", "primitives": []})", "$.primitives", "at least one"},
        BadBody{R"({"name": "x", "primitives": [{"type": "metaball", "joint": "l_elbo", "center": [0,0,0],
                 "radii": [1,1,1]}]})",
                "$.primitives[0].joint", "unknown joint \"l_elbo\""},
        BadBody{R"({"name": "x", "primitives": [{"type": "metaball", "joint": "l_elbow", "center": [0,0,0],
                 "radii": [0.1,-0.02,0.1]}]})",
                "$.primitives[0].radii[1]", "radius must be positive"},
        BadBody{R"({"name": "x", "primitives": [{"type": "cube", "joint": "l_elbow", "center": [0,0,0],
                 "radii": [1,1,1]}]})",
                "$.primitives[0].type", "unknown primitive type"},
        BadBody{R"({"name": "x", "primitives": [{"type": "metaball", "joint": "l_elbow", "center": [0,"a",0],
                 "radii": [1,1,1]}]})",
                "$.primitives[0].center[1]", "expected a number"},
        BadBody{R"({"name": "x", "primitives": [{"type": "ellipsoid", "joint": "l_elbow", "center": [0,0,0],
                 "radii": [0.1,50,0.1]}]})",
                "$.primitives[0].radii[1]", "radius must be at most 2 m"},
        BadBody{R"({"name": "x", "primitives": [{"type": "ellipsoid", "joint": "l_elbow", "center": [0,0,1e30],
                 "radii": [0.1,0.1,0.1]}]})",
                "$.primitives[0].center[2]", "within 2 m of its joint"},
        BadBody{R"({"name": "x", "primitives": [{"type": "ellipsoid", "joint": "l_elbow", "center": [0,0,0],
                 "radii": [0.1,0.1,0.1], "rotation_deg": [0,1e30,0]}]})",
                "$.primitives[0].rotation_deg[1]", "[-360, 360] degrees"},
        BadBody{R"({"name": "x", "sample_posture": "dance", "primitives": [{"type": "metaball",
                 "joint": "l_elbow", "center": [0,0,0], "radii": [1,1,1]}]})",
                "$.sample_posture", "unknown posture"},
        // Found by body_fuzz_test.cpp: nlohmann throws out_of_range (not parse_error) for a number beyond
        // double's range, which escaped parse_body (std::terminate in the CLI).
        BadBody{"{\"name\": \"x\",\n \"primitives\": [{\"center\": [0, 1e400, 0]}]}", "line 2, column 36",
                "invalid JSON: number overflow parsing '1e400'"}),
    [](const auto& param_info) { return "case" + std::to_string(param_info.index); });

TEST(Body, MissingSkeletonFileIsNamed) {
  auto r = parse_body(R"({"name": "x", "skeleton": "nope.json", "primitives": []})", "body.json", "/tmp");
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().file, "/tmp/nope.json");
  EXPECT_NE(r.error().where.find("body.json"), std::string::npos);
}

// Found by body_fuzz_test.cpp: a "skeleton" naming a folder ("" or "..") read as an empty file, and the error
// named the folder, not the body.
TEST(Body, SkeletonNamingAFolderIsNamed) {
  auto r = parse_body(R"({"name": "x", "skeleton": "", "primitives": []})", "body.json", "/tmp");
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().file, "/tmp/");
  EXPECT_EQ(r.error().where, "(referenced from body.json $.skeleton)");
  EXPECT_EQ(r.error().reason, "is a directory, not a file");
}
