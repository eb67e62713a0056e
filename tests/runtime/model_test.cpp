// Loading and animating skinned glTF: exact answers on SimpleSkin and hand-made channels, properties
// on the real models, and every malformed validator file rejected cleanly (never a crash).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <set>
#include <span>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include "bb/runtime/animation.h"
#include "bb/runtime/model.h"
#include "step_clip_model.h"

namespace bb::runtime {
namespace {

namespace fs = std::filesystem;

std::string gltf_dir() { return std::string(BB_SHARED_DATA_DIR) + "/gltf"; }

#define REQUIRE_SHARED(path)                                                         \
  if (!fs::exists(path)) GTEST_SKIP() << "shared data absent: " << (path)

glm::vec3 skin_cpu(const Model& m, const Vertex& v, std::span<const glm::mat4> pal) {
  glm::vec3 p(0.0f);
  for (int k = 0; k < 4; ++k) p += v.weights[k] * glm::vec3(pal[v.joints[k]] * glm::vec4(v.position, 1.0f));
  (void)m;
  return p;
}

struct Posed {
  std::vector<Transform> locals;
  std::vector<glm::mat4> world, pal;
  Posed(const Model& m, int clip, float t) : locals(m.nodes.size()), world(m.nodes.size()), pal(m.palette.size()) {
    sample_clip(m, clip, t, locals);
    world_matrices(m, locals, world);
    palette_matrices(m, world, pal);
  }
};

void expect_vec3(glm::vec3 a, glm::vec3 b, float eps) {
  EXPECT_NEAR(a.x, b.x, eps);
  EXPECT_NEAR(a.y, b.y, eps);
  EXPECT_NEAR(a.z, b.z, eps);
}

TEST(ClipTime, LoopsAndClamps) {
  EXPECT_FLOAT_EQ(clip_time(2.5f, 2.0f, true), 0.5f);
  EXPECT_FLOAT_EQ(clip_time(-0.5f, 2.0f, true), 1.5f);
  EXPECT_FLOAT_EQ(clip_time(4.0f, 2.0f, true), 0.0f);
  EXPECT_FLOAT_EQ(clip_time(2.5f, 2.0f, false), 2.0f);
  EXPECT_FLOAT_EQ(clip_time(-1.0f, 2.0f, false), 0.0f);
  // A time that is not finite stays inside the clip (the baked frames are indexed from it).
  EXPECT_EQ(clip_time(std::nanf(""), 2.0f, true), 0.0f);
  EXPECT_EQ(clip_time(INFINITY, 2.0f, true), 0.0f);
  EXPECT_EQ(clip_time(-INFINITY, 2.0f, false), 0.0f);
  EXPECT_FLOAT_EQ(clip_time(3.0f, 0.0f, true), 0.0f);
}

// A looped clip time is fmod's remainder to the bit (taken in doubles, not by glibc's fmodf), over
// times from -1e6 to 1e6 s and durations from 1/30 s to 100 s, as the old fmodf-based code gave it:
// the remainder, plus a period where negative, 0 where that rounds up to the duration.
TEST(ClipTime, LoopedIsFmodsRemainderToTheBit) {
  auto reference = [](float time, float duration) {
    float t = std::fmod(time, duration);
    if (t < 0.0f) t += duration;
    if (t >= duration) t = 0.0f;
    return t;
  };
  std::uint32_t state = 12345u;
  auto next = [&state] {  // xorshift32: a uniform float in [0, 1)
    state ^= state << 13;
    state ^= state >> 17;
    state ^= state << 5;
    return static_cast<float>(state >> 8) / 16777216.0f;
  };
  int checked = 0;
  for (int i = 0; i < 200000; ++i) {
    const float duration = std::exp2(-5.0f + 11.6f * next());                 // 1/32 to ~100 s
    const float time = (next() < 0.5f ? -1.0f : 1.0f) * std::exp2(-10.0f + 30.0f * next());  // to ~1e6 s
    const float got = clip_time(time, duration, true), want = reference(time, duration);
    if (got != want) ADD_FAILURE() << "time " << time << " duration " << duration << ": " << got << " against " << want;
    ++checked;
    if (::testing::Test::HasFailure()) break;
  }
  EXPECT_EQ(checked, 200000);
  // Whole periods and their neighbours.
  for (float d : {1.0f / 30.0f, 0.8f, 1.0f, 1.25f, 2.0f / 3.0f})
    for (int k = -1000; k <= 1000; k += 7)
      for (float t : {k * d, std::nextafter(k * d, -INFINITY), std::nextafter(k * d, INFINITY)})
        EXPECT_EQ(clip_time(t, d, true), reference(t, d)) << t << " " << d;
}

TEST(SampleChannel, StepLinearCubic) {
  Channel c;
  c.path = ChannelPath::kTranslation;
  c.times = {1.0f, 2.0f, 4.0f};
  c.values = {{0, 0, 0, 0}, {2, 4, 6, 0}, {4, 4, 4, 0}};
  c.interpolation = Interpolation::kLinear;
  EXPECT_EQ(sample_channel(c, 0.0f), glm::vec4(0, 0, 0, 0));    // before the first key
  EXPECT_EQ(sample_channel(c, 1.5f), glm::vec4(1, 2, 3, 0));
  EXPECT_EQ(sample_channel(c, 3.0f), glm::vec4(3, 4, 5, 0));
  EXPECT_EQ(sample_channel(c, 9.0f), glm::vec4(4, 4, 4, 0));    // after the last
  c.interpolation = Interpolation::kStep;
  EXPECT_EQ(sample_channel(c, 1.99f), glm::vec4(0, 0, 0, 0));
  EXPECT_EQ(sample_channel(c, 2.0f), glm::vec4(2, 4, 6, 0));
  // Cubic with zero tangents: smoothstep between the values.
  c.interpolation = Interpolation::kCubicSpline;
  c.values = {{}, {0, 0, 0, 0}, {}, {}, {2, 0, 0, 0}, {}, {}, {4, 0, 0, 0}, {}};
  EXPECT_FLOAT_EQ(sample_channel(c, 1.5f).x, 1.0f);
  EXPECT_FLOAT_EQ(sample_channel(c, 1.25f).x, 2.0f * (3 * 0.0625f - 2 * 0.015625f));
  // Out-tangent 2 at key 0 (dt = 1): adds (u^3 - 2u^2 + u) * 2.
  c.values[2] = {2, 0, 0, 0};
  EXPECT_FLOAT_EQ(sample_channel(c, 1.5f).x, 1.0f + (0.125f - 0.5f + 0.5f) * 2.0f);
}

TEST(SampleChannel, SlerpTakesShortestPath) {
  Channel c;
  c.path = ChannelPath::kRotation;
  c.times = {0.0f, 1.0f};
  const float s = std::sin(glm::radians(45.0f)), co = std::cos(glm::radians(45.0f));
  c.values = {{0, 0, 0, 1}, {0, 0, -s, -co}};  // 90 degrees about Z, given with a negative w
  glm::vec4 q = sample_channel(c, 0.5f);
  EXPECT_NEAR(std::abs(q.z), std::sin(glm::radians(22.5f)), 1e-6f);
  EXPECT_NEAR(std::abs(q.w), std::cos(glm::radians(22.5f)), 1e-6f);
  EXPECT_GT(q.z * q.w, 0.0f);  // the same sense as +90 about Z, not the long way round
}

// Just before a STEP key the channel still holds the key before it; other channels are continuous.
TEST(SampleClip, BeforeHoldsTheStepKeyBeforeTheTime) {
  const Model m = step_and_slide(Interpolation::kLinear);
  std::vector<Transform> at(3), before(3);
  for (float t : {0.25f, 0.51f, 0.3f, 0.0f, 1.0f}) {
    sample_clip(m, 0, t, at);
    sample_clip_before(m, 0, t, before);
    const float held_at = t >= 0.51f ? 2.0f : t >= 0.25f ? 1.0f : 0.0f;
    const float held_before = t > 0.51f ? 2.0f : t > 0.25f ? 1.0f : 0.0f;
    EXPECT_EQ(at[1].translation.x, held_at) << "t = " << t;
    EXPECT_EQ(before[1].translation.x, held_before) << "t = " << t;
    EXPECT_EQ(before[2].translation, at[2].translation) << "t = " << t;
  }
}

// A clip that mixes STEP and LINEAR channels is baked with the 60 Hz grid's 61 frames and, at each
// STEP key, the pose just before it (then the pose at it where no grid frame is at that time): 64
// frames. Each frame's palette rows, posture distances, bounds and root travel are its pose's, and
// BakedClip::sample picks the frames around any time so that the STEP joint holds then jumps exactly
// at its keys. A clip of STEP channels only needs the pose at an off-grid key alone, with blend 0.
TEST(BakedClip, StepKeysGetFramesOfTheirOwn) {
  const Model m = step_and_slide(Interpolation::kLinear);
  const BakedClip& bc = m.baked_clips()[0];
  EXPECT_FALSE(bc.stepped);
  ASSERT_EQ(bc.frame_count, 64);
  ASSERT_EQ(bc.grid.size(), 61u);
  ASSERT_EQ(bc.times.size(), 64u);
  ASSERT_EQ(bc.before_step.size(), 64u);
  EXPECT_EQ(bc.grid[14], 14);
  EXPECT_EQ(bc.grid[15], 16);  // frame 15: the pose just before 0.25 s
  EXPECT_EQ(bc.grid[30], 31);
  EXPECT_EQ(bc.grid[31], 34);  // frames 32 and 33: just before and at 0.51 s
  EXPECT_EQ(bc.grid[60], 63);
  EXPECT_EQ(bc.times[15], 0.25f);
  EXPECT_EQ(bc.times[32], 0.51f);
  EXPECT_EQ(bc.times[33], 0.51f);
  for (int f = 0; f < bc.frame_count; ++f) EXPECT_EQ(bc.before_step[f] != 0, f == 15 || f == 32) << f;
  EXPECT_EQ(bc.posture.size(), 64u);
  EXPECT_EQ(bc.bounds.size(), 64u);
  EXPECT_EQ(bc.root_offset.size(), 64u);
  // Every frame holds its own pose.
  const auto pal = m.baked_palette();
  auto x = [&](int f, int entry) { return pal[((bc.first_row + f) * m.palette.size() + entry) * 3].w; };
  std::vector<Transform> locals(3);
  std::vector<glm::mat4> world(3);
  for (int f = 0; f < bc.frame_count; ++f) {
    if (bc.before_step[f]) sample_clip_before(m, 0, bc.times[f], locals);
    else sample_clip(m, 0, bc.times[f], locals);
    world_matrices(m, locals, world);
    EXPECT_EQ(x(f, 1), locals[1].translation.x) << f;
    EXPECT_EQ(x(f, 2), locals[2].translation.x) << f;
    for (int k = 0; k < kPosturePairs; ++k) {
      const PosturePair& pp = m.posture_pairs()[k];
      const glm::vec3 d = point_position(pp.a, world) - point_position(pp.b, world);
      EXPECT_EQ(bc.posture[f][k], glm::dot(d, d)) << f;
    }
    EXPECT_LE(bc.bounds[f][0].x, std::min(x(f, 1), x(f, 2))) << f;
    EXPECT_GE(bc.bounds[f][1].x, std::max(x(f, 1), x(f, 2))) << f;
  }
  // The frames around a time, and what they show.
  auto held_at = [&](float t) {
    const BakedSample s = bc.sample(t);
    EXPECT_TRUE(s.blend >= 0.0f && s.blend <= 1.0f);
    return x(s.f0, 1) + (x(s.f1, 1) - x(s.f0, 1)) * s.blend;
  };
  auto slid_at = [&](float t) {
    const BakedSample s = bc.sample(t);
    return x(s.f0, 2) + (x(s.f1, 2) - x(s.f0, 2)) * s.blend;
  };
  const BakedSample s0 = bc.sample(0.2499f), s1 = bc.sample(0.25f), s2 = bc.sample(0.5099f), s3 = bc.sample(0.51f);
  EXPECT_EQ(s0.f0, 14);
  EXPECT_EQ(s0.f1, 15);
  EXPECT_EQ(s1.f0, 16);
  EXPECT_EQ(s1.f1, 17);
  EXPECT_EQ(s1.blend, 0.0f);
  EXPECT_EQ(s2.f0, 31);
  EXPECT_EQ(s2.f1, 32);
  EXPECT_NEAR(s2.blend, 0.99f, 1e-3f);
  EXPECT_EQ(s3.f0, 33);
  EXPECT_EQ(s3.f1, 34);
  EXPECT_EQ(s3.blend, 0.0f);
  EXPECT_EQ(bc.sample(1.0f).f0, 63);
  EXPECT_EQ(bc.sample(1.0f).f1, 63);
  for (float t : {0.0f, 0.1f, 0.2499f, 0.25f, 0.2501f, 0.505f, 0.5099f, 0.51f, 0.5101f, 0.515f, 0.9f, 0.999f}) {
    EXPECT_EQ(held_at(t), t >= 0.51f ? 2.0f : t >= 0.25f ? 1.0f : 0.0f) << "t = " << t;
    EXPECT_NEAR(slid_at(t), t, 1e-5f) << "t = " << t;
  }
  // CUBICSPLINE beside STEP is baked the same way.
  EXPECT_EQ(step_and_slide(Interpolation::kCubicSpline).baked_clips()[0].frame_count, 64);
  // STEP channels only: the off-grid key at 0.51 s gets the pose at it, nothing else does.
  const Model stepped = step_and_slide(Interpolation::kStep);
  const BakedClip& sc = stepped.baked_clips()[0];
  EXPECT_TRUE(sc.stepped);
  ASSERT_EQ(sc.frame_count, 62);
  EXPECT_EQ(sc.grid[30], 30);
  EXPECT_EQ(sc.grid[31], 32);
  EXPECT_EQ(sc.times[31], 0.51f);
  EXPECT_EQ(sc.before_step[31], 0);
  const BakedSample h = sc.sample(0.5099f), j = sc.sample(0.51f);
  EXPECT_EQ(h.f0, 30);
  EXPECT_EQ(h.blend, 0.0f);
  EXPECT_EQ(j.f0, 31);
  EXPECT_EQ(j.blend, 0.0f);
}

TEST(LoadModel, MissingAndEmptyFilesAreErrors) {
  auto r = load_model("/nonexistent/x.glb");
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message().find("no such file"), std::string::npos);
  fs::path tmp = fs::temp_directory_path() / "bb_runtime_empty.gltf";
  { std::ofstream(tmp) << "{"; }
  auto e = load_model(tmp.string());
  ASSERT_FALSE(e.ok());
  EXPECT_EQ(e.error().file, tmp.string());
  fs::remove(tmp);
}

TEST(LoadModel, SimpleSkinExactPoses) {
  std::string path = gltf_dir() + "/SimpleSkin.gltf";
  REQUIRE_SHARED(path);
  auto r = load_model(path);
  ASSERT_TRUE(r.ok()) << r.error().message();
  const Model& m = *r;
  ASSERT_EQ(m.nodes.size(), 3u);
  ASSERT_EQ(m.palette.size(), 2u);
  ASSERT_EQ(m.lods.size(), 1u);
  // No normals in the file: flat ones, as glTF asks, so each of the 8 triangles' corners is a vertex.
  EXPECT_EQ(m.lods[0].vertices.size(), 24u);
  EXPECT_EQ(m.lods[0].indices.size(), 24u);
  ASSERT_EQ(m.clips.size(), 1u);
  EXPECT_FLOAT_EQ(m.clips[0].duration, 5.5f);
  // Rest pose: skinning gives the bind positions back.
  Posed rest(m, 0, 0.0f);
  for (const Vertex& v : m.lods[0].vertices) expect_vec3(skin_cpu(m, v, rest.pal), v.position, 1e-6f);
  // t = 1 s: joint 1 (at y = 1) turned 90 degrees about Z.
  Posed p(m, 0, 1.0f);
  const auto& vs = m.lods[0].vertices;
  int top = -1, mid = -1;
  for (int i = 0; i < static_cast<int>(vs.size()); ++i) {
    if (vs[i].position == glm::vec3(0.5f, 2.0f, 0.0f)) top = i;
    if (vs[i].position == glm::vec3(-0.5f, 1.0f, 0.0f)) mid = i;
  }
  ASSERT_GE(top, 0);
  ASSERT_GE(mid, 0);
  expect_vec3(skin_cpu(m, vs[top], p.pal), glm::vec3(-1.0f, 1.5f, 0.0f), 1e-5f);
  // Half on each joint: the average of (-0.5, 1) and its rotated image (0, 0.5).
  expect_vec3(skin_cpu(m, vs[mid], p.pal), glm::vec3(-0.25f, 0.75f, 0.0f), 1e-5f);
  // Between keys (t = 0.25): slerp half way from identity to 45 degrees.
  Posed q(m, 0, 0.25f);
  glm::quat rot = q.locals[m.palette[1].node].rotation;
  EXPECT_NEAR(glm::degrees(glm::angle(rot)), 22.5f, 0.05f);
  // Baked palette row 60 (t = 1 s) matches the exact palette.
  const auto rows = m.baked_palette();
  const std::size_t f = 60;
  for (std::size_t j = 0; j < m.palette.size(); ++j)
    for (int row = 0; row < 3; ++row)
      for (int c = 0; c < 4; ++c) EXPECT_NEAR(rows[(f * m.palette.size() + j) * 3 + row][c], p.pal[j][c][row], 1e-5f);
}

TEST(LoadModel, RiggedSimplePostureTestSeesTheBend) {
  std::string path = gltf_dir() + "/RiggedSimple.gltf";
  REQUIRE_SHARED(path);
  auto r = load_model(path);
  ASSERT_TRUE(r.ok()) << r.error().message();
  const Model& m = *r;
  EXPECT_EQ(m.palette.size(), 2u);
  EXPECT_EQ(m.lods[0].vertices.size(), 96u);
  ASSERT_EQ(m.clips.size(), 1u);
  EXPECT_NEAR(m.clips[0].duration, 2.083333f, 1e-5f);
  // The root node's matrix turns Z up into Y up: the cylinder stands along +Y.
  glm::vec3 size = m.bounds_max - m.bounds_min;
  EXPECT_GT(size.y, size.x);
  EXPECT_GT(size.y, size.z);
  // The automatic posture pairs must change with the bend (a 2-joint chain: root to tip).
  const BakedClip& bc = m.baked_clips()[0];
  float lo = 1e30f, hi = 0.0f;
  for (const auto& d : bc.posture) lo = std::min(lo, d[0]), hi = std::max(hi, d[0]);
  EXPECT_GT(hi - lo, 0.01f * hi);
  // Every pose lies inside the snapshot sphere.
  for (int f = 0; f < bc.frame_count; f += 5) {
    Posed p(m, 0, f / bc.rate);
    for (const Vertex& v : m.lods[0].vertices) EXPECT_LE(glm::distance(skin_cpu(m, v, p.pal), m.ta), m.radius);
  }
}

TEST(LoadModel, CesiumManNonRootSkinnedNode) {
  std::string path = gltf_dir() + "/CesiumMan.glb";
  REQUIRE_SHARED(path);
  auto r = load_model(path);
  ASSERT_TRUE(r.ok()) << r.error().message();
  const Model& m = *r;
  EXPECT_EQ(m.palette.size(), 19u);
  EXPECT_EQ(m.lods[0].vertices.size(), 3273u);
  EXPECT_EQ(m.lods[0].triangle_count(), 4672u);
  ASSERT_EQ(m.textures.size(), 1u);
  EXPECT_GT(m.textures[0].width, 0);
  ASSERT_EQ(m.clips.size(), 1u);
  EXPECT_NEAR(m.clips[0].duration, 2.0f, 0.05f);
  // Standing man, Y up, about 1.5 m tall, feet near y = 0.
  glm::vec3 size = m.bounds_max - m.bounds_min;
  EXPECT_GT(size.y, 1.2f);
  EXPECT_LT(size.y, 2.0f);
  EXPECT_GT(size.y, size.x);
  EXPECT_NEAR(m.bounds_min.y, 0.0f, 0.1f);
  // The radius covers half the height at least and not absurdly more.
  EXPECT_GT(m.radius, 0.5f * size.y);
  EXPECT_LT(m.radius, 1.0f * size.y);
  // Posture distances vary while walking.
  const BakedClip& bc = m.baked_clips()[0];
  float lo = 1e30f, hi = 0.0f;
  for (const auto& d : bc.posture) lo = std::min(lo, d[0]), hi = std::max(hi, d[0]);
  EXPECT_GT(hi - lo, 0.02f * hi);
}

TEST(LoadModel, FoxClipsAndUnindexedMesh) {
  std::string path = gltf_dir() + "/Fox.glb";
  REQUIRE_SHARED(path);
  auto r = load_model(path);
  ASSERT_TRUE(r.ok()) << r.error().message();
  const Model& m = *r;
  EXPECT_EQ(m.palette.size(), 24u);
  ASSERT_EQ(m.clips.size(), 3u);
  EXPECT_EQ(m.find_clip("Survey"), 0);
  EXPECT_EQ(m.find_clip("Walk"), 1);
  EXPECT_EQ(m.find_clip("Run"), 2);
  EXPECT_EQ(m.lods[0].indices.size(), m.lods[0].vertices.size());
  for (const Vertex& v : m.lods[0].vertices) EXPECT_NEAR(glm::length(v.normal), 1.0f, 1e-4f);
  EXPECT_EQ(m.textures.size(), 1u);
}

// BakedClip::ground_speed on a hand-made walk: a root 1 unit up and two feet under it, each sliding
// back on the ground by `slide` units in half a second (stance), then lifted 0.2 units and brought
// forward (swing), the other foot half a cycle later. The body moves over its supporting foot at
// 2 * slide units per second. The same feet stepping in place (no slide) do not walk, nor do feet
// that stay 0.5 units above the pose's lowest point (a vertex on the root, 1.5 units below it).
TEST(GroundSpeed, HandMadeWalk) {
  auto walker = [](float slide, bool ground_below_feet) {
    Model m;
    m.nodes = {Node{"root", -1, {glm::vec3(0, 1, 0), glm::quat(1, 0, 0, 0), glm::vec3(1)}},
               Node{"foot_l", 0, {glm::vec3(0.2f, -1, 0), glm::quat(1, 0, 0, 0), glm::vec3(1)}},
               Node{"foot_r", 0, {glm::vec3(-0.2f, -1, 0), glm::quat(1, 0, 0, 0), glm::vec3(1)}}};
    m.palette = {PaletteEntry{0, glm::translate(glm::mat4(1), glm::vec3(0, -1, 0))},
                 PaletteEntry{1, glm::translate(glm::mat4(1), glm::vec3(-0.2f, 0, 0))},
                 PaletteEntry{2, glm::translate(glm::mat4(1), glm::vec3(0.2f, 0, 0))}};
    MeshLod lod;
    const glm::vec3 at[4] = {{0, 1, 0}, {0.2f, 0, 0}, {-0.2f, 0, 0}, {0, -0.5f, 0}};
    for (int j = 0; j < (ground_below_feet ? 4 : 3); ++j) {
      Vertex v;
      v.position = at[j];
      v.joints = glm::u16vec4(j == 3 ? 0 : j, 0, 0, 0);
      lod.vertices.push_back(v);
    }
    lod.indices = {0, 1, 2};
    lod.primitives = {Primitive{0, 3, 0}};
    m.lods = {lod};
    m.materials = {Material{}};
    Clip clip;
    clip.name = "walk";
    clip.duration = 1.0f;
    for (int side = 0; side < 2; ++side) {
      Channel ch;
      ch.node = 1 + side;
      ch.path = ChannelPath::kTranslation;
      const float x = side == 0 ? 0.2f : -0.2f, h = 0.5f * slide;
      // Keys at quarter cycles: stance from phase 0 to 0.5 (left) or 0.5 to 1 (right).
      const glm::vec4 keys[4] = {{x, -1, h, 0}, {x, -1, 0, 0}, {x, -1, -h, 0}, {x, -0.8f, 0, 0}};
      for (int k = 0; k <= 4; ++k) {
        ch.times.push_back(0.25f * static_cast<float>(k));
        ch.values.push_back(keys[(k + 2 * side) % 4]);
      }
      clip.channels.push_back(ch);
    }
    m.clips = {clip};
    m.bake();
    return m.baked_clips()[0].ground_speed;
  };
  EXPECT_NEAR(walker(0.5f, false), 1.0f, 0.01f);
  EXPECT_NEAR(walker(1.0f, false), 2.0f, 0.02f);
  EXPECT_EQ(walker(0.0f, false), 0.0f);  // stepping in place
  EXPECT_EQ(walker(0.5f, true), 0.0f);   // no foot near the ground
}

// On the shared models: the walks walk, the Fox's run faster than its walk; the Fox's survey, the
// bending cylinder and the strip do not.
TEST(GroundSpeed, SharedModels) {
  for (const char* name : {"CesiumMan.glb", "Fox.glb", "RiggedSimple.gltf", "SimpleSkin.gltf"})
    REQUIRE_SHARED(gltf_dir() + "/" + name);
  auto speeds = [](const char* name) {
    auto m = load_model(gltf_dir() + "/" + name);
    EXPECT_TRUE(m.ok()) << m.error().message();
    std::vector<float> v;
    if (m.ok())
      for (const BakedClip& bc : m->baked_clips()) v.push_back(bc.ground_speed / (m->bounds_max.y - m->bounds_min.y));
    return v;
  };
  const auto cesium = speeds("CesiumMan.glb"), fox = speeds("Fox.glb");
  ASSERT_EQ(cesium.size(), 1u);
  ASSERT_EQ(fox.size(), 3u);
  // Heights per second: a human walks at 0.4 to 1 (0.7 to 1.75 m/s), measured 0.52.
  EXPECT_GT(cesium[0], 0.4f);
  EXPECT_LT(cesium[0], 1.0f);
  EXPECT_EQ(fox[0], 0.0f);     // Survey
  EXPECT_GT(fox[1], 0.5f);     // Walk: measured 1.25
  EXPECT_GT(fox[2], 1.4f * fox[1]);  // Run: measured 2.23
  EXPECT_EQ(speeds("RiggedSimple.gltf"), std::vector<float>{0.0f});
  EXPECT_EQ(speeds("SimpleSkin.gltf"), std::vector<float>{0.0f});
}

// The (n + 1)^2 vertices of a unit grid in the z = 0 plane, row by row, normals +z.
std::vector<Vertex> grid_vertices(int n) {
  std::vector<Vertex> out;
  for (int y = 0; y <= n; ++y)
    for (int x = 0; x <= n; ++x) {
      Vertex v;
      v.position = {x / float(n), y / float(n), 0.0f};
      v.normal = {0, 0, 1};
      out.push_back(v);
    }
  return out;
}

// LoadOptions::lod_levels on a flat 16 x 16 grid of quads (a model with one level): the simplifier takes
// the inside away without error and keeps the border, so every level it makes lies in the grid's plane,
// with about half the triangles of the one before and the whole border; with no error, the finer level
// gives way at once (its screen coverage the bound of 1, or the finer one's).
TEST(GeneratedLods, AFlatGridLosesNothing) {
  Model m;
  m.nodes = {Node{"root", -1, {}}};
  m.palette = {PaletteEntry{0, glm::mat4(1)}};
  MeshLod lod;
  const int n = 16;
  lod.vertices = grid_vertices(n);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const std::uint32_t a = y * (n + 1) + x, b = a + 1, c = a + n + 1, d = c + 1;
      lod.indices.insert(lod.indices.end(), {a, b, d, a, d, c});
    }
  lod.primitives = {Primitive{0, static_cast<std::uint32_t>(lod.indices.size()), 0}};
  m.lods = {lod};
  m.materials = {Material{}};
  // A clip that turns and moves the whole grid: a rigid motion keeps every distance, so the levels'
  // error as drawn is their error in the bind pose, none.
  Clip turn;
  turn.name = "turn";
  turn.duration = 1.0f;
  Channel rot;
  rot.node = 0;
  rot.path = ChannelPath::kRotation;
  rot.times = {0.0f, 1.0f};
  const glm::quat q = glm::angleAxis(glm::radians(70.0f), glm::normalize(glm::vec3(1, 2, 3)));
  rot.values = {{0, 0, 0, 1}, {q.x, q.y, q.z, q.w}};
  Channel move;
  move.node = 0;
  move.path = ChannelPath::kTranslation;
  move.times = {0.0f, 1.0f};
  move.values = {{0, 0, 0, 0}, {3, -1, 2, 0}};
  turn.channels = {rot, move};
  m.clips = {turn};
  LoadOptions none;
  Model copy = m;
  EXPECT_EQ(add_generated_lods(copy, none), 0);  // lod_levels 0: none
  LoadOptions o;
  o.lod_levels = 3;
  ASSERT_EQ(add_generated_lods(m, o), 3);
  ASSERT_EQ(m.lods.size(), 4u);
  for (std::size_t l = 1; l < m.lods.size(); ++l) {
    const MeshLod& g = m.lods[l];
    EXPECT_LE(g.triangle_count() * 5, m.lods[l - 1].triangle_count() * 4);
    EXPECT_GE(g.triangle_count() * 5, m.lods[l - 1].triangle_count() * 2);  // about half
    EXPECT_TRUE(g.made_at_load);
    EXPECT_LT(g.generated_error, 1e-6f);
    EXPECT_LT(g.skinned_error, 1e-5f);
    int border = 0;
    for (const Vertex& v : g.vertices) {
      EXPECT_EQ(v.position.z, 0.0f);
      border += v.position.x == 0.0f || v.position.x == 1.0f || v.position.y == 0.0f || v.position.y == 1.0f;
    }
    EXPECT_EQ(border, 4 * n);  // the border kept whole
    EXPECT_EQ(m.lods[l - 1].screen_coverage, 1.0f);
  }
  EXPECT_EQ(m.lods.back().screen_coverage, 0.0f);
  EXPECT_FALSE(m.lods[0].made_at_load);
  EXPECT_EQ(add_generated_lods(m, o), 0);  // a model with levels keeps its own
}

// A flat-shaded mesh (every corner its own vertex with its triangle's normal, as the loader makes of
// a file without normals) is welded without its normals, simplified like the indexed grid above, and
// its levels are flat-shaded again.
TEST(GeneratedLods, AFlatShadedGridIsWeldedAndStaysFlat) {
  Model m;
  m.nodes = {Node{"root", -1, {}}};
  m.palette = {PaletteEntry{0, glm::mat4(1)}};
  MeshLod lod;
  const int n = 16;
  auto corner = [&](int x, int y) {
    Vertex v;
    v.position = {x / float(n), y / float(n), 0.0f};
    v.normal = {0, 0, 1};
    v.uv = {x / float(n), y / float(n)};
    lod.indices.push_back(static_cast<std::uint32_t>(lod.vertices.size()));
    lod.vertices.push_back(v);
  };
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      corner(x, y), corner(x + 1, y), corner(x + 1, y + 1);
      corner(x, y), corner(x + 1, y + 1), corner(x, y + 1);
    }
  lod.primitives = {Primitive{0, static_cast<std::uint32_t>(lod.indices.size()), 0}};
  m.lods = {lod};
  m.materials = {Material{}};
  LoadOptions o;
  o.lod_levels = 3;
  ASSERT_EQ(add_generated_lods(m, o), 3);
  for (std::size_t l = 1; l < m.lods.size(); ++l) {
    const MeshLod& g = m.lods[l];
    EXPECT_LE(g.triangle_count() * 5, m.lods[l - 1].triangle_count() * 4);
    EXPECT_GE(g.triangle_count() * 5, m.lods[l - 1].triangle_count() * 2);
    EXPECT_LT(g.generated_error, 1e-6f);
    ASSERT_EQ(g.vertices.size(), g.indices.size());  // a vertex per corner
    for (std::size_t k = 0; k < g.indices.size(); ++k) EXPECT_EQ(g.indices[k], k);
    for (const Vertex& v : g.vertices) {
      EXPECT_EQ(v.normal, glm::vec3(0, 0, 1));
      EXPECT_EQ(v.uv, glm::vec2(v.position.x, v.position.y));  // each corner keeps its own texture coordinates
    }
  }
}

// On CesiumMan (one level in the file): coarser levels, each at most 80 % of the one before, with
// growing errors; each finer level gives way where the next one's error shows as one pixel of a
// 1080-pixel-high view. The Fox has no normals in its file, so its triangles are flat-shaded and
// share no vertex: welded without its normals, it gets levels too, flat-shaded, whose every
// corner keeps a position and texture coordinates of the file's (the seams stay where they were).
TEST(GeneratedLods, SharedModels) {
  const std::string cesium = gltf_dir() + "/CesiumMan.glb", fox = gltf_dir() + "/Fox.glb";
  REQUIRE_SHARED(cesium);
  LoadOptions o;
  o.lod_levels = 3;
  auto m = load_model(cesium, o);
  ASSERT_TRUE(m.ok()) << m.error().message();
  ASSERT_GE(m->lods.size(), 3u);
  float lo = 1e30f, hi = -1e30f;
  for (const Vertex& v : m->lods[0].vertices) lo = std::min(lo, v.position.y), hi = std::max(hi, v.position.y);
  for (std::size_t l = 1; l < m->lods.size(); ++l) {
    const MeshLod &g = m->lods[l], &finer = m->lods[l - 1];
    std::printf("CesiumMan level %zu: %zu triangles, error %.3f %% of the height (%.3f %% as it walks), used below %.4f of the view\n",
                l, g.triangle_count(), 100.0 * g.generated_error / (hi - lo), 100.0 * g.skinned_error / (hi - lo),
                finer.screen_coverage);
    EXPECT_LE(g.triangle_count() * 5, finer.triangle_count() * 4);
    EXPECT_GT(g.generated_error, finer.generated_error);
    // The switch: where the larger of the two errors shows as one pixel of a 1080-pixel view.
    EXPECT_LE(finer.screen_coverage * std::max(g.generated_error, g.skinned_error) / (hi - lo) * 1080.0f, 1.0f + 1e-4f);
    EXPECT_EQ(g.primitives.size(), 1u);
    for (std::uint32_t i : g.indices) ASSERT_LT(i, g.vertices.size());
  }
  EXPECT_EQ(m->lods.back().screen_coverage, 0.0f);
  // The simplifier does not weigh the skin: its first level is 0.09 % of the height off in the bind
  // pose but 3 % as CesiumMan walks, where vertices merged across the shoulders drift off the arms.
  EXPECT_GT(m->lods[1].skinned_error, 10.0f * m->lods[1].generated_error);
  EXPECT_EQ(m->part_indices(static_cast<int>(m->lods.size()) - 1).ranges.size(),
            m->lods.back().primitives.size() * m->body_parts().size());  // parts made for every level
  REQUIRE_SHARED(fox);
  auto f = load_model(fox, o);
  ASSERT_TRUE(f.ok());
  ASSERT_GE(f->lods.size(), 3u);
  float flo = 1e30f, fhi = -1e30f;
  for (const Vertex& v : f->lods[0].vertices) flo = std::min(flo, v.position.y), fhi = std::max(fhi, v.position.y);
  std::set<std::array<float, 5>> source;
  for (const Vertex& v : f->lods[0].vertices) source.insert({v.position.x, v.position.y, v.position.z, v.uv.x, v.uv.y});
  for (std::size_t l = 1; l < f->lods.size(); ++l) {
    const MeshLod &g = f->lods[l], &finer = f->lods[l - 1];
    std::printf("Fox level %zu: %zu triangles, error %.3f of the height (%.3f as drawn), used below %.4f of the view\n", l,
                g.triangle_count(), g.generated_error / (fhi - flo), g.skinned_error / (fhi - flo), finer.screen_coverage);
    EXPECT_LE(g.triangle_count() * 5, finer.triangle_count() * 4);
    EXPECT_GT(g.generated_error, finer.generated_error);
    ASSERT_EQ(g.vertices.size(), g.indices.size());
    std::size_t unknown = 0;
    for (std::size_t t = 0; t < g.indices.size(); t += 3) {
      const Vertex &a = g.vertices[g.indices[t]], &b = g.vertices[g.indices[t + 1]], &c = g.vertices[g.indices[t + 2]];
      const glm::vec3 e = glm::cross(b.position - a.position, c.position - a.position);
      if (glm::length(e) > 0.0f) {
        for (const Vertex* v : {&a, &b, &c}) EXPECT_LT(glm::length(v->normal - glm::normalize(e)), 1e-4f);
      }
      for (const Vertex* v : {&a, &b, &c})
        unknown += source.count({v->position.x, v->position.y, v->position.z, v->uv.x, v->uv.y}) == 0;
    }
    EXPECT_EQ(unknown, 0u);
  }
}

// Vertices shaded per triangle by a FIFO post-transform cache of `size` entries.
double fifo_misses_per_triangle(std::span<const std::uint32_t> indices, std::size_t size) {
  std::vector<std::uint32_t> fifo;
  std::size_t misses = 0;
  for (std::uint32_t i : indices) {
    if (std::find(fifo.begin(), fifo.end(), i) != fifo.end()) continue;
    ++misses;
    fifo.push_back(i);
    if (fifo.size() > size) fifo.erase(fifo.begin());
  }
  return indices.empty() ? 0.0 : 3.0 * static_cast<double>(misses) / static_cast<double>(indices.size());
}

// A primitive's triangles as corner positions, each rotated to start at its smallest corner (the
// winding kept), sorted: the same list whatever order the triangles and vertices are in.
std::vector<std::array<float, 9>> triangle_set(const MeshLod& ml, const Primitive& p) {
  std::vector<std::array<float, 9>> out;
  for (std::uint32_t t = p.first_index; t < p.first_index + p.index_count; t += 3) {
    std::array<glm::vec3, 3> c{ml.vertices[ml.indices[t]].position, ml.vertices[ml.indices[t + 1]].position,
                               ml.vertices[ml.indices[t + 2]].position};
    auto less = [](glm::vec3 a, glm::vec3 b) { return std::tie(a.x, a.y, a.z) < std::tie(b.x, b.y, b.z); };
    const int first = static_cast<int>(std::min_element(c.begin(), c.end(), less) - c.begin());
    std::array<float, 9> f{};
    for (int k = 0; k < 3; ++k)
      for (int a = 0; a < 3; ++a) f[static_cast<std::size_t>(k * 3 + a)] = c[static_cast<std::size_t>((first + k) % 3)][a];
    out.push_back(f);
  }
  std::sort(out.begin(), out.end());
  return out;
}

// optimize_vertex_order on a 16x16 grid whose triangles come in a scrambled order, beside a blended
// primitive and a vertex no triangle uses: the same triangles with their winding, fewer vertices
// shaded, vertices numbered in first use, the blended primitive's triangles in the file's order.
TEST(VertexOrder, CacheOrderKeepsTheTrianglesAndShadesFewerVertices) {
  Model m;
  m.materials = {Material{}, Material{}};
  m.materials[1].alpha_blend = true;
  MeshLod lod;
  const int n = 16;
  lod.vertices = grid_vertices(n);
  std::vector<std::array<std::uint32_t, 3>> tris;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const std::uint32_t a = y * (n + 1) + x, b = a + 1, c = a + n + 1, d = c + 1;
      tris.push_back({a, b, d});
      tris.push_back({a, d, c});
    }
  for (std::size_t k = 0; k < tris.size(); ++k) std::swap(tris[k], tris[(k * 7919 + 13) % tris.size()]);  // scrambled
  for (const auto& t : tris) lod.indices.insert(lod.indices.end(), t.begin(), t.end());
  const std::uint32_t opaque = static_cast<std::uint32_t>(lod.indices.size());
  Vertex lone;  // used by no triangle
  lone.position = {5, 5, 5};
  lod.vertices.push_back(lone);
  const std::vector<std::uint32_t> blended{288, 0, 17, 16, 280, 5};  // two triangles over the grid, in this order
  lod.indices.insert(lod.indices.end(), blended.begin(), blended.end());
  lod.primitives = {Primitive{0, opaque, 0}, Primitive{opaque, 6, 1}};
  m.lods = {lod};
  const double before = fifo_misses_per_triangle(std::span(lod.indices).first(opaque), 16);

  optimize_vertex_order(m);
  const MeshLod& out = m.lods[0];
  ASSERT_EQ(out.primitives.size(), 2u);
  EXPECT_EQ(out.vertices.size(), lod.vertices.size() - 1);  // the lone vertex dropped
  EXPECT_EQ(triangle_set(out, out.primitives[0]), triangle_set(lod, lod.primitives[0]));
  std::uint32_t next = 0;  // first-use numbering: each new vertex is the next number
  for (std::uint32_t i : out.indices) {
    ASSERT_LE(i, next);
    if (i == next) ++next;
  }
  for (std::size_t k = 0; k < blended.size(); ++k)  // the blended triangles, corner for corner
    EXPECT_EQ(out.vertices[out.indices[opaque + k]].position, lod.vertices[blended[k]].position) << k;
  const double after = fifo_misses_per_triangle(std::span(out.indices).first(opaque), 16);
  std::printf("16x16 grid, scrambled: %.2f vertices shaded a triangle by a 16-entry FIFO, %.2f in cache order\n", before,
              after);
  EXPECT_GT(before, 2.5);
  EXPECT_LT(after, 0.8);  // a grid's vertices are about half its triangles
}

// CesiumMan's file is in no cache order: the loader's order shades far fewer vertices, and draws
// the same triangles.
TEST(VertexOrder, CesiumManShadesFewerVertices) {
  const std::string path = gltf_dir() + "/CesiumMan.glb";
  REQUIRE_SHARED(path);
  LoadOptions file_order;
  file_order.optimize_vertex_order = false;
  auto a = load_model(path, file_order);
  auto b = load_model(path);
  ASSERT_TRUE(a.ok() && b.ok());
  const MeshLod &la = a->lods[0], &lb = b->lods[0];
  ASSERT_EQ(la.primitives.size(), lb.primitives.size());
  for (std::size_t k = 0; k < la.primitives.size(); ++k)
    EXPECT_EQ(triangle_set(la, la.primitives[k]), triangle_set(lb, lb.primitives[k]));
  const double fa = fifo_misses_per_triangle(la.indices, 32), fb = fifo_misses_per_triangle(lb.indices, 32);
  std::printf("CesiumMan: %.2f vertices shaded a triangle by a 32-entry FIFO in the file's order, %.2f in cache order "
              "(%zu vertices, %zu triangles)\n", fa, fb, lb.vertices.size(), lb.triangle_count());
  EXPECT_GT(fa, 1.8);
  EXPECT_LT(fb, 1.0);
  // The runtime's own figure (meshoptimizer's analyzer, which inspect prints) is this FIFO's.
  EXPECT_NEAR(vertices_shaded_per_triangle(la), fa, 1e-4);
  EXPECT_NEAR(vertices_shaded_per_triangle(lb), fb, 1e-4);
}

TEST(LoadModel, PosturePairsOverride) {
  std::string path = gltf_dir() + "/CesiumMan.glb";
  REQUIRE_SHARED(path);
  auto r = load_model(path);
  ASSERT_TRUE(r.ok());
  Model& m = *r;
  std::vector<std::pair<std::string, std::string>> bad = {{"nope", "Skeleton_neck_joint_1"}};
  auto s = m.set_posture_pairs(bad);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().reason.find("nope"), std::string::npos);
  int a = m.palette[0].node, b = m.palette[5].node;
  std::vector<std::pair<std::string, std::string>> good = {{m.nodes[a].name, m.nodes[b].name}};
  ASSERT_TRUE(m.set_posture_pairs(good).ok());
  EXPECT_EQ(m.posture_pairs()[0].a.node, a);
  EXPECT_EQ(m.posture_pairs()[3].b.node, b);
}

// Every malformed file of the Khronos validator's suite: loading never crashes; files whose
// errors matter to a skinned-animation loader are rejected, and every refusal names the file, a place in it
// (a byte, a line and column, a JSON path) and the reason.
TEST(LoadModel, ValidatorSuiteRejectedCleanly) {
  fs::path root = fs::path(BB_SHARED_DATA_DIR) / "bad-gltf" / "glTF-Validator";
  REQUIRE_SHARED(root);
  const std::set<std::string> must_reject = {
      "INVALID_JSON", "GLB_INVALID_MAGIC", "GLB_INVALID_VERSION", "GLB_LENGTH_TOO_SMALL", "GLB_LENGTH_MISMATCH",
      "GLB_CHUNK_TOO_BIG", "GLB_UNEXPECTED_END_OF_HEADER", "GLB_UNEXPECTED_END_OF_CHUNK_HEADER",
      "GLB_UNEXPECTED_END_OF_CHUNK_DATA", "NODE_LOOP", "NODE_PARENT_OVERRIDE", "ACCESSOR_TOO_LONG",
      "BUFFER_VIEW_TOO_LONG", "ACCESSOR_INDEX_OOB", "ACCESSOR_JOINTS_INDEX_OOB", "INVALID_IBM_ACCESSOR_COUNT",
      "ACCESSOR_ANIMATION_INPUT_NON_INCREASING", "ACCESSOR_ANIMATION_INPUT_NEGATIVE",
      "NODE_SKIN_NO_SCENE",
      "ANIMATION_SAMPLER_OUTPUT_ACCESSOR_INVALID_COUNT", "ACCESSOR_INVALID_FLOAT"};
  int files = 0, with_errors = 0, rejected = 0, must = 0;
  for (const auto& e : fs::recursive_directory_iterator(root)) {
    std::string p = e.path().string();
    if (!(e.path().extension() == ".gltf" || e.path().extension() == ".glb")) continue;
    ++files;
    std::ifstream rep(p + ".report.json");
    std::stringstream ss;
    ss << rep.rdbuf();
    std::string report = ss.str();
    auto pos = report.find("\"numErrors\"");
    int num_errors = pos == std::string::npos ? 0 : std::atoi(report.c_str() + report.find(':', pos) + 1);
    bool must_fail = false;
    std::string code;
    for (const auto& c : must_reject)
      if (num_errors > 0 && report.find("\"" + c + "\"") != std::string::npos) must_fail = true, code = c;
    auto r = load_model(p);  // must not crash, whatever the file
    if (num_errors > 0) ++with_errors;
    if (!r.ok()) {
      ++rejected;
      EXPECT_EQ(r.error().file, p);
      EXPECT_FALSE(r.error().where.empty()) << "no place: " << r.error().message();  // a byte, a line, a JSON path
      EXPECT_FALSE(r.error().reason.empty());
    }
    if (must_fail) {
      ++must;
      EXPECT_FALSE(r.ok()) << p << " (" << code << ") was accepted";
    }
  }
  std::cout << "validator suite: " << files << " files, " << with_errors << " with errors, " << rejected
            << " rejected, " << must << " that must be rejected\n";
  EXPECT_GT(files, 150);
}

}  // namespace
}  // namespace bb::runtime

namespace bb::runtime {
namespace {

// MSFT_lod on the skinned node: a second level (the same mesh here) and its screen coverage.
TEST(LoadModel, MsftLodLevelsAndCoverage) {
  std::string src = gltf_dir() + "/SimpleSkin.gltf";
  REQUIRE_SHARED(src);
  std::ifstream in(src);
  std::stringstream ss;
  ss << in.rdbuf();
  std::string text;
  for (char ch : ss.str())
    if (ch != '\r') text += ch;  // the file has CRLF line ends
  auto replace = [&](const std::string& a, const std::string& b) {
    auto p = text.find(a);
    ASSERT_NE(p, std::string::npos) << a;
    text.replace(p, a.size(), b);
  };
  replace("\"skin\" : 0,\n    \"mesh\" : 0\n  }",
          "\"skin\" : 0, \"mesh\" : 0, \"extensions\" : {\"MSFT_lod\" : {\"ids\" : [3]}},"
          " \"extras\" : {\"MSFT_screencoverage\" : [0.4, 0.0]}\n  }");
  replace("\"rotation\" : [ 0.0, 0.0, 0.0, 1.0 ]\n  } ]", "\"rotation\" : [ 0.0, 0.0, 0.0, 1.0 ]\n  }, {\"skin\" : 0, \"mesh\" : 0} ]");
  fs::path tmp = fs::temp_directory_path() / "bb_runtime_lod.gltf";
  { std::ofstream(tmp) << text; }
  auto r = load_model(tmp.string());
  fs::remove(tmp);
  ASSERT_TRUE(r.ok()) << r.error().message();
  ASSERT_EQ(r->lods.size(), 2u);
  EXPECT_FLOAT_EQ(r->lods[0].screen_coverage, 0.4f);
  EXPECT_FLOAT_EQ(r->lods[1].screen_coverage, 0.0f);
  EXPECT_EQ(r->lods[1].vertices.size(), 24u);  // flat normals: a vertex per corner
  EXPECT_EQ(r->palette.size(), 2u);  // both levels share the skin
}

}  // namespace
}  // namespace bb::runtime
