#include <string>
#include <vector>

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
        // Past a float's range: named with its value (it was "got inf").
        BadBody{R"({"name": "x", "primitives": [{"type": "ellipsoid", "joint": "l_elbow", "center": [0,0,0],
                 "radii": [0.1,1e300,0.1]}]})",
                "$.primitives[0].radii[1]", "expected a number a float holds, within +-3.4e38 (got 1e+300)"},
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

namespace {

// A one-primitive body named `name_json` (a JSON string literal, quotes included).
std::string body_named(const std::string& name_json) {
  return "{\"name\": " + name_json +
         R"(, "primitives": [{"type": "metaball", "joint": "l_elbow", "center": [0,0,0], "radii": [0.1,0.1,0.1]}]})";
}

}  // namespace

// Found in an audit: a key given twice in one object was accepted, the last one silently winning.
TEST(Body, DuplicateKeysAreErrors) {
  struct Case { std::string json, where, reason; };
  const std::vector<Case> cases = {
      {R"({"name": "a", "name": "b", "primitives": []})", "$", "duplicate key \"name\" (line 1)"},
      {"{\"name\": \"x\", \"primitives\": [\n"
       R"({"type": "metaball", "joint": "l_elbow", "center": [0,0,0], "radii": [1,1,1]},)"
       "\n{\"type\": \"metaball\", \"joint\": \"l_elbow\", \"center\": [0,0,0],\n\"center\": [1,0,0], \"radii\": [1,1,1]}]}",
       "$.primitives[1]", "duplicate key \"center\" (line 4)"},
      // Scalars, arrays and objects before it count in an array's index; nested objects give their keys.
      {R"({"name": "x", "extra": [1, "s", null, [2], {}, {"k": 1, "k": 2}]})", "$.extra[5]", "duplicate key \"k\""},
      {R"({"name": "x", "a": {"b": {"c": 1, "d": [], "c": 2}}})", "$.a.b", "duplicate key \"c\""},
      {R"({"a": {"k": 1}, "b": [{"k": 1}], "b": 2})", "$", "duplicate key \"b\""},
  };
  for (const auto& c : cases) {
    auto r = parse_body(c.json, "dup.json");
    ASSERT_FALSE(r) << c.json;
    EXPECT_EQ(r.error().file, "dup.json");
    EXPECT_EQ(r.error().where, c.where) << r.error().message();
    EXPECT_NE(r.error().reason.find(c.reason), std::string::npos) << r.error().message();
  }
  // The same key in different objects is no duplicate.
  auto ok = parse_body(R"({"name": "x", "meta": {"name": "y", "k": {"name": 1}}, "primitives": [
      {"name": "p", "type": "metaball", "joint": "l_elbow", "center": [0,0,0], "radii": [1,1,1]},
      {"name": "q", "type": "metaball", "joint": "l_elbow", "center": [0,0,0], "radii": [1,1,1]}]})",
                       "ok.json");
  ASSERT_TRUE(ok) << ok.error().message();
  ASSERT_EQ(ok->primitives.size(), 2u);
  EXPECT_EQ(ok->primitives[1].name, "q");
}

// Found in an audit: the CLI writes DIR/<name>.glb, and "../escape" or "/abs/path" wrote outside DIR.
TEST(Body, NamesThatAreNotFileStemsAreRefused) {
  struct Case { std::string json, reason; };
  const std::vector<Case> cases = {
      {R"("../escape")", "holds a '/'"},
      {R"("/abs/path")", "holds a '/'"},
      {R"("x/y")", "holds a '/'"},
      {R"("")", "body name is empty"},
      {R"(".")", "names a directory"},
      {R"("..")", "names a directory"},
      {R"("a\\b")", "holds a '\\'"},
      {R"("a\u0000b")", "holds a control character (at byte 1)"},
      {R"("a\tb")", "holds a control character (at byte 1)"},
      {R"("ab\u007f")", "holds a control character (at byte 2)"},
      {R"("\u0085")", "holds a control character (at byte 0)"},  // C1, NEL
      {"\"" + std::string(201, 'n') + "\"", "body name is 201 bytes long"},
  };
  for (const auto& c : cases) {
    auto r = parse_body(body_named(c.json), "name.json");
    ASSERT_FALSE(r) << c.json << " was accepted";
    EXPECT_EQ(r.error().where, "$.name") << r.error().message();
    EXPECT_NE(r.error().reason.find(c.reason), std::string::npos) << r.error().message();
    EXPECT_NE(r.error().reason.find("1 to 200 bytes of UTF-8 without '/', '\\' or control characters"), std::string::npos)
        << r.error().message();
  }
  // Bytes that are not UTF-8 are invalid JSON before they are a name (nlohmann checks strings).
  auto latin1 = parse_body(body_named("\"caf\xE9\""), "name.json");
  ASSERT_FALSE(latin1);
  EXPECT_EQ(latin1.error().where, "line 1, column 15");
  EXPECT_NE(latin1.error().reason.find("invalid JSON"), std::string::npos) << latin1.error().message();
  // Other names load as they are.
  for (const std::string& name : std::vector<std::string>{"default", "a b", "v1.2", "...", "-x", std::string(200, 'n'), std::string("\xC3\x89milie")}) {
    auto r = parse_body(body_named("\"" + name + "\""), "name.json");
    ASSERT_TRUE(r) << r.error().message();
    EXPECT_EQ(r->name, name);
  }
}

TEST(Body, NameRuleChecksUtf8AndVariantNamesPassIt) {
  EXPECT_EQ(body_name_problem("default"), "");
  EXPECT_EQ(body_name_problem("\xE2\x82\xAC"), "");        // U+20AC
  EXPECT_EQ(body_name_problem("\xF0\x9F\x98\x80"), "");    // U+1F600
  for (const char* bad : {"caf\xE9", "\xC0\xAF", "\xE0\x80\xAF", "\xED\xA0\x80", "\xF4\x90\x80\x80", "\xE2\x82", "\x80"}) {
    const std::string problem = body_name_problem(bad);
    EXPECT_NE(problem.find("is not valid UTF-8"), std::string::npos) << bad << ": " << problem;
  }
  EXPECT_NE(body_name_problem("x\xC2\x85").find("control character (at byte 1)"), std::string::npos);
  // make_variant's names, as the CLI gives them, stay valid.
  const Body& b = default_body();
  EXPECT_EQ(body_name_problem(b.name), "");
  for (const char* suffix : {"_v1", "_v12", "_seed42"}) {
    const Body v = make_variant(b, {.seed = 3}, suffix);
    EXPECT_EQ(v.name, "default" + std::string(suffix));
    EXPECT_EQ(body_name_problem(v.name), "") << v.name;
  }
}
