// The impostor logic without GL: snapshot camera, cache tests, window choice, atlas packing and
// the frame planner's decisions.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <string>
#include <tuple>

#include <glm/gtc/constants.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include "bb/runtime/animation.h"
#include "bb/runtime/crowd.h"
#include "bb/runtime/impostor.h"
#include "step_clip_model.h"
#include "tube_model.h"

namespace bb::runtime {
namespace {

void expect_vec3(glm::vec3 a, glm::vec3 b, float eps = 1e-6f) {
  EXPECT_NEAR(a.x, b.x, eps);
  EXPECT_NEAR(a.y, b.y, eps);
  EXPECT_NEAR(a.z, b.z, eps);
}

// The scene camera of the aligned-snapshot tests: 1280x1024, looking down at the origin's surroundings.
SceneCamera screen_camera() {
  SceneCamera cam;
  cam.width = 1280;
  cam.height = 1024;
  cam.eye = {3, 7, 18};
  cam.target = {0, 1, 0};
  return cam;
}

// An aligned snapshot camera cuts its window out of the scene camera's image: its centre lies on
// a pixel corner, and any point lands in the window exactly where it lands on the screen, one
// texel per pixel (half a texel with 2 texels per pixel).
TEST(SnapshotCamera, AlignedWindowIsCutOutOfTheScreen) {
  const SceneCamera cam = screen_camera();
  const glm::mat4 screen = cam.projection() * cam.view();
  auto pixel = [&](const glm::mat4& m, glm::vec3 p, glm::vec2 size) {
    glm::vec4 c = m * glm::vec4(p, 1.0f);
    return (glm::vec2(c) / c.w * 0.5f + 0.5f) * size;
  };
  const glm::vec3 centre(-4.3f, 0.9f, 2.2f);  // off the axis
  for (float tpp : {1.0f, 2.0f}) {
    auto a = make_aligned_snapshot_camera(cam, centre, 0.5f, 256, tpp);
    ASSERT_TRUE(a.has_value());
    EXPECT_TRUE(a->perspective);
    const glm::vec2 c = pixel(screen, a->ta, glm::vec2(1280, 1024));
    EXPECT_NEAR(c.x, std::round(c.x), 2e-3f);
    EXPECT_NEAR(c.y, std::round(c.y), 2e-3f);
    const glm::mat4 snap = a->projection() * a->view();
    for (glm::vec3 d : {glm::vec3(0.3f, 0.8f, -0.4f), glm::vec3(-0.5f, -0.7f, 0.6f), glm::vec3(0.0f)}) {
      const glm::vec2 on_screen = pixel(screen, centre + d, glm::vec2(1280, 1024)) - c;
      const glm::vec2 in_window = pixel(snap, centre + d, glm::vec2(256)) - glm::vec2(128);
      EXPECT_NEAR(in_window.x, tpp * on_screen.x, 2e-3f * tpp);
      EXPECT_NEAR(in_window.y, tpp * on_screen.y, 2e-3f * tpp);
    }
  }
  // The sphere's picture widens off the axis; a window too small for it, or an eye inside it,
  // gives no aligned camera.
  const float px = aligned_pixels(cam, centre, 1.0f);
  const float depth = glm::dot(centre - cam.eye, glm::normalize(cam.target - cam.eye));
  EXPECT_GT(px, 2.0f * cam.pixels_per_metre(depth));
  EXPECT_FALSE(make_aligned_snapshot_camera(cam, centre, 1.0f, static_cast<int>(px) - 1, 1.0f).has_value());
  EXPECT_TRUE(make_aligned_snapshot_camera(cam, centre, 1.0f, static_cast<int>(px) + 1, 1.0f).has_value());
  EXPECT_FALSE(make_aligned_snapshot_camera(cam, cam.eye + glm::vec3(0.1f, 0, 0), 1.0f, 256, 1.0f).has_value());
  EXPECT_TRUE(std::isinf(aligned_pixels(cam, cam.eye + 5.0f * glm::normalize(cam.eye - cam.target), 1.0f)));  // behind
  // With a phase the window's centre sits that far right of and above a pixel corner, and points
  // still land in the window where they land on the screen.
  for (float phase : {0.125f, 0.5f, 0.875f}) {
    auto a = make_aligned_snapshot_camera(cam, centre, 0.5f, 256, 1.0f, phase);
    ASSERT_TRUE(a.has_value());
    const glm::vec2 c = pixel(screen, a->ta, glm::vec2(1280, 1024));
    EXPECT_NEAR(c.x - std::floor(c.x), phase, 2e-3f) << phase;
    EXPECT_NEAR(c.y - std::floor(c.y), phase, 2e-3f) << phase;
    // The nearest such point to the centre's own projection: at most half a pixel away.
    const glm::vec2 p = pixel(screen, centre, glm::vec2(1280, 1024));
    EXPECT_LE(std::abs(c.x - p.x), 0.5f + 2e-3f);
    EXPECT_LE(std::abs(c.y - p.y), 0.5f + 2e-3f);
    const glm::mat4 snap = a->projection() * a->view();
    const glm::vec3 d(0.3f, 0.8f, -0.4f);
    const glm::vec2 on_screen = pixel(screen, centre + d, glm::vec2(1280, 1024)) - c;
    const glm::vec2 in_window = pixel(snap, centre + d, glm::vec2(256)) - glm::vec2(128);
    EXPECT_NEAR(in_window.x, on_screen.x, 2e-3f);
    EXPECT_NEAR(in_window.y, on_screen.y, 2e-3f);
  }
}

// aligned_pixels is the widest half of the sphere's picture about its centre's projection, either
// axis, doubled: the same as the extremes over points of the sphere's surface, projected.
TEST(SnapshotCamera, AlignedPixelsHoldTheSpheresPicture) {
  const SceneCamera cam = screen_camera();
  glm::vec3 right, up, fwd;
  camera_axes(cam, right, up, fwd);
  const float ppm1 = cam.pixels_per_metre(1.0f);
  const glm::vec3 centres[] = {{-4.3f, 0.9f, 2.2f}, {0, 1, 0}, {12, 0, -30}, {-20, 3, 5}, {2, 6.5f, 15}};
  for (const glm::vec3& c : centres)
    for (float r : {0.3f, 1.0f, 2.5f}) {
      const glm::vec3 v = c - cam.eye;
      const float z0 = glm::dot(v, fwd);
      const glm::vec2 t0(glm::dot(v, right) / z0, glm::dot(v, up) / z0);
      glm::vec2 lo(1e9f), hi(-1e9f);
      const int n = 400;
      for (int i = 0; i <= n; ++i)
        for (int j = 0; j < 2 * n; ++j) {
          const float th = glm::pi<float>() * static_cast<float>(i) / n, ph = glm::pi<float>() * static_cast<float>(j) / n;
          const glm::vec3 p = v + r * glm::vec3(std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph));
          const float z = glm::dot(p, fwd);
          const glm::vec2 t(glm::dot(p, right) / z, glm::dot(p, up) / z);
          lo = glm::min(lo, t);
          hi = glm::max(hi, t);
        }
      const glm::vec2 half = glm::max(hi - t0, t0 - lo);
      const float expected = 2.0f * ppm1 * std::max(half.x, half.y);
      EXPECT_NEAR(aligned_pixels(cam, c, r), expected, 2e-3f * expected) << c.x << " " << c.y << " " << c.z << " r " << r;
      // The planner's form, from the frame's axes: the same number.
      EXPECT_EQ(aligned_pixels(cam.eye, right, up, fwd, ppm1, c, r), aligned_pixels(cam, c, r));
    }
}

TEST(SnapshotCamera, FrameFromEyeAndUp) {
  auto c = make_snapshot_camera({0, 1, 0}, {0, 1, 10}, {0, 1, 0}, 1.0f, 3.0f);
  expect_vec3(c.vo, {0, 0, -1});
  expect_vec3(c.ho, {1, 0, 0});
  expect_vec3(c.uo, {0, 1, 0});
  expect_vec3(c.to, {0, 1, 3});
  // Seen from the +X side: Vo = -X, Ho = Vo x Us = -Z, Uo = Ho x Vo = +Y.
  auto s = make_snapshot_camera({0, 1, 0}, {10, 1, 0}, {0, 2, 0}, 1.0f, 3.0f);
  expect_vec3(s.vo, {-1, 0, 0});
  expect_vec3(s.ho, {0, 0, -1});
  expect_vec3(s.uo, {0, 1, 0});
  // Ta projects to the centre of the window, at mid depth; the sphere of radius h fits.
  glm::vec4 p = s.projection() * s.view() * glm::vec4(0, 1, 0, 1);
  expect_vec3(glm::vec3(p) / p.w, {0, 0, 0});
  glm::vec4 q = s.projection() * s.view() * glm::vec4(0, 2, -1, 1);  // up 1, right 1
  expect_vec3(glm::vec3(q) / q.w, {1, 1, 0});
  // Looking straight down the up vector still gives a right-handed frame.
  auto d = make_snapshot_camera({0, 0, 0}, {0, 10, 0}, {0, 1, 0}, 1.0f);
  EXPECT_NEAR(glm::dot(glm::cross(d.ho, d.uo), -d.vo), 1.0f, 1e-5f);
  EXPECT_FLOAT_EQ(d.distance, 2.0f);
}

glm::vec3 orbit(float deg, float dist = 10.0f) {
  return {dist * std::sin(glm::radians(deg)), 1.0f, dist * std::cos(glm::radians(deg))};
}

TEST(ViewTest, AngleOfRelativeRotation) {
  const glm::vec3 ta(0, 1, 0), up(0, 1, 0);
  auto a = view_rotation(make_snapshot_camera(ta, orbit(0), up, 1), 0.0f);
  auto b = view_rotation(make_snapshot_camera(ta, orbit(10), up, 1), 0.0f);
  EXPECT_NEAR(glm::degrees(rotation_angle(a, b)), 10.0f, 1e-3f);
  // The character turning by 10 degrees looks the same as the camera orbiting by -10 degrees.
  auto c = view_rotation(make_snapshot_camera(ta, orbit(0), up, 1), glm::radians(10.0f));
  EXPECT_NEAR(glm::degrees(rotation_angle(a, c)), 10.0f, 1e-3f);
  // Camera orbiting and character turning together: nothing changes in the character's frame.
  auto d = view_rotation(make_snapshot_camera(ta, orbit(25), up, 1), glm::radians(25.0f));
  EXPECT_NEAR(glm::degrees(rotation_angle(a, d)), 0.0f, 0.05f);
  EXPECT_NEAR(rotation_cosine(a, a), 1.0f, 1e-6f);
  // Rising above the character tilts the view.
  auto e = view_rotation(make_snapshot_camera(ta, glm::vec3(0, 1 + 10 * std::tan(glm::radians(20.0f)), 10), up, 1), 0);
  EXPECT_NEAR(glm::degrees(rotation_angle(a, e)), 20.0f, 1e-2f);
}

TEST(PostureTest, RelativeThresholdOnSquaredDistances) {
  std::array<float, 4> stored{1.0f, 2.0f, 4.0f, 0.0f};
  EXPECT_FALSE(posture_changed(stored, stored, 0.0f));
  EXPECT_FALSE(posture_changed(stored, {1.3f, 2.0f, 4.0f, 0.0f}, 0.4f));
  EXPECT_TRUE(posture_changed(stored, {1.5f, 2.0f, 4.0f, 0.0f}, 0.4f));
  EXPECT_TRUE(posture_changed(stored, {1.0f, 2.0f, 2.0f, 0.0f}, 0.4f));  // shrinking counts too
  EXPECT_TRUE(posture_changed(stored, {1.0f, 2.0f, 4.0f, 0.5f}, 0.4f));  // stored 0: absolute m^2
  EXPECT_TRUE(posture_changed(stored, {1.0001f, 2.0f, 4.0f, 0.0f}, 0.0f));
}

TEST(DistanceWeight, GrowsBeyondReference) {
  CacheConfig c;
  EXPECT_FLOAT_EQ(distance_weight(c, 50.0f), 1.0f);  // off by default
  c.distance_weighting = true;
  c.reference_distance = 10.0f;
  EXPECT_FLOAT_EQ(distance_weight(c, 5.0f), 1.0f);
  EXPECT_FLOAT_EQ(distance_weight(c, 30.0f), 3.0f);
}

TEST(DistanceWeight, ScreenSizeWeightsSmallCharacters) {
  CacheConfig c;
  EXPECT_FLOAT_EQ(distance_weight(c, 50.0f, 4.0f), 1.0f);  // off by default
  c.reference_pixels = 32.0f;
  EXPECT_FLOAT_EQ(distance_weight(c, 50.0f, 64.0f), 1.0f);  // taller than the reference
  EXPECT_FLOAT_EQ(distance_weight(c, 50.0f, 8.0f), 4.0f);
  EXPECT_FLOAT_EQ(distance_weight(c, 50.0f, 0.0f), 1.0f);  // no size known
  c.distance_weighting = true;  // both: the larger weight
  EXPECT_FLOAT_EQ(distance_weight(c, 50.0f, 16.0f), 5.0f);
  EXPECT_FLOAT_EQ(distance_weight(c, 20.0f, 4.0f), 8.0f);
}

TEST(WindowChoice, SmallestThatHolds) {
  WindowSizes w;
  EXPECT_EQ(choose_window(w, 400.0f), 0);
  EXPECT_EQ(choose_window(w, 256.0f), 0);
  EXPECT_EQ(choose_window(w, 200.0f), 0);
  EXPECT_EQ(choose_window(w, 128.0f), 1);
  EXPECT_EQ(choose_window(w, 100.0f), 1);
  EXPECT_EQ(choose_window(w, 64.0f), 2);
  EXPECT_EQ(choose_window(w, 33.0f), 2);
  EXPECT_EQ(choose_window(w, 32.0f), 3);
  EXPECT_EQ(choose_window(w, 17.0f), 3);
  EXPECT_EQ(choose_window(w, 16.0f), 4);
  EXPECT_EQ(choose_window(w, 9.0f), 4);
  EXPECT_EQ(choose_window(w, 8.0f), 5);
  EXPECT_EQ(choose_window(w, 1.0f), 5);
  // The paper's four sizes alone: the smallest is 32.
  WindowSizes paper;
  paper.count = 4;
  EXPECT_EQ(choose_window(paper, 8.0f), 3);
}

TEST(Atlas, PacksSharesAndReleasesPages) {
  WindowSizes w;
  AtlasAllocator a(1024, 3, w);
  std::vector<AtlasWindow> big;
  std::set<std::tuple<int, int, int>> places;
  for (int i = 0; i < 16; ++i) {
    auto x = a.allocate(0);
    ASSERT_TRUE(x);
    EXPECT_EQ(x->page, 0);
    EXPECT_EQ(x->size, 256);
    EXPECT_LE(x->x + x->size, 1024);
    EXPECT_LE(x->y + x->size, 1024);
    EXPECT_TRUE(places.insert({x->page, x->x, x->y}).second);  // no two windows at one place
    big.push_back(*x);
  }
  EXPECT_FLOAT_EQ(a.pixel_use(), 1.0f);
  auto small = a.allocate(3);  // a 32-pixel window opens page 1 for its class
  ASSERT_TRUE(small);
  EXPECT_EQ(small->page, 1);
  EXPECT_EQ(a.pages_used(), 2);
  auto x = a.allocate(0);  // page 0 is full: page 2
  ASSERT_TRUE(x);
  EXPECT_EQ(x->page, 2);
  for (int i = 1; i < 16; ++i) ASSERT_TRUE(a.allocate(0));  // fills page 2
  EXPECT_FALSE(a.allocate(0));  // every page in use
  EXPECT_FALSE(a.allocate(1));
  a.release(big[5]);
  auto again = a.allocate(0);
  ASSERT_TRUE(again);
  EXPECT_EQ(again->page, 0);
  EXPECT_EQ(again->x, big[5].x);
  EXPECT_EQ(again->y, big[5].y);
  a.release(*small);  // page 1 empties and can serve another class
  EXPECT_EQ(a.pages_used(), 2);
  auto mid = a.allocate(1);
  ASSERT_TRUE(mid);
  EXPECT_EQ(mid->page, 1);
  EXPECT_EQ(a.windows_used(), 16 + 16 + 1);
}

// A part of a shared atlas (ImpostorConfig::first_page): the same packing, its pages numbered from
// the first; release and page_class take those numbers.
TEST(Atlas, PartOfASharedAtlasNumbersItsPagesFromItsFirst) {
  WindowSizes w;
  AtlasAllocator a(1024, 2, w, 5);
  EXPECT_EQ(a.first_page(), 5);
  auto big = a.allocate(0);
  auto small = a.allocate(3);
  ASSERT_TRUE(big && small);
  EXPECT_EQ(big->page, 5);
  EXPECT_EQ(small->page, 6);
  EXPECT_EQ(a.page_class(5), 0);
  EXPECT_EQ(a.page_class(6), 3);
  EXPECT_FALSE(a.allocate(1));  // both pages in use by other classes
  a.release(*small);
  EXPECT_EQ(a.page_class(6), -1);
  auto mid = a.allocate(1);
  ASSERT_TRUE(mid);
  EXPECT_EQ(mid->page, 6);
  EXPECT_EQ(coverage_slot(*mid, 1024, 8), (6 * 128 + mid->y / 8) * 128 + mid->x / 8);
  a.release(*big);
  a.release(*mid);
  EXPECT_EQ(a.pages_used(), 0);
}

// A one-joint model with one triangle and a 1 s clip that stretches a second joint.
Model tiny_model() {
  Model m;
  m.nodes = {Node{"root", -1, {}}, Node{"arm", 0, {glm::vec3(0, 1, 0), glm::quat(1, 0, 0, 0), glm::vec3(1)}}};
  m.palette = {PaletteEntry{0, glm::mat4(1)}, PaletteEntry{1, glm::translate(glm::mat4(1), glm::vec3(0, -1, 0))}};
  MeshLod lod;
  lod.vertices.resize(3);
  lod.vertices[0].position = {-0.5f, 0, 0};
  lod.vertices[1].position = {0.5f, 0, 0};
  lod.vertices[2].position = {0, 2, 0};
  lod.vertices[2].joints = glm::u16vec4(1, 0, 0, 0);
  lod.indices = {0, 1, 2};
  lod.primitives = {Primitive{0, 3, 0}};
  m.lods = {lod};
  m.materials = {Material{}};
  Clip clip;
  clip.name = "stretch";
  clip.duration = 1.0f;
  Channel c;
  c.node = 1;
  c.path = ChannelPath::kTranslation;
  c.times = {0.0f, 0.5f, 1.0f};
  c.values = {{0, 1, 0, 0}, {0, 2, 0, 0}, {0, 1, 0, 0}};
  clip.channels = {c};
  m.clips = {clip};
  m.bake(60.0f);
  return m;
}

// `n` characters standing still in a row along x, `spacing` metres apart, centred on the origin.
Crowd standing_row(const Model& m, int n, float spacing) {
  Crowd crowd(m);
  for (int i = 0; i < n; ++i)
    crowd.add(Character{glm::vec3(spacing * (static_cast<float>(i) - 0.5f * static_cast<float>(n - 1)), 0, 0), 0.0f,
                        1.0f, 0, 0.0f, 0.0f});
  return crowd;
}

// The cache's view test alone, at `degrees`.
ImpostorConfig view_test_only(float degrees) {
  ImpostorConfig cfg;
  cfg.cache.posture_test = false;
  cfg.cache.view_threshold_deg = degrees;
  return cfg;
}

// The same with snapshots cut out of the screen's image at one texel a pixel (aligned snapshots).
ImpostorConfig aligned_view_test_only(float degrees) {
  ImpostorConfig cfg = view_test_only(degrees);
  cfg.aligned_snapshots = true;
  cfg.texels_per_pixel = 1.0f;
  return cfg;
}

// Part cards with the cache's view test alone, at `degrees`.
ImpostorConfig part_cards_view_only(float degrees) {
  ImpostorConfig cfg = view_test_only(degrees);
  cfg.part_cards = true;
  return cfg;
}

// The default camera looking down -Z at y = 1.5 from `distance` metres.
SceneCamera facing_camera(float distance) {
  SceneCamera cam;
  cam.eye = {0, 1.5f, distance};
  cam.target = {0, 1.5f, 0};
  return cam;
}

TEST(FramePlanner, TinyModelBoundsAndPairs) {
  Model m = tiny_model();
  EXPECT_NEAR(m.bounds_max.y, 3.0f, 1e-5f);  // tip reaches y = 3 at t = 0.5
  EXPECT_NEAR(m.ta.y, 1.5f, 1e-5f);
  EXPECT_GE(m.radius, 1.5f);
}

TEST(FramePlanner, CacheTestsDriveSnapshots) {
  Model m = tiny_model();
  Crowd crowd = standing_row(m, 5, 2.0f);
  ImpostorConfig cfg = view_test_only(8.0f);
  FramePlanner planner(m, cfg);
  const SceneCamera cam = facing_camera(30.0f);
  auto s0 = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
  EXPECT_EQ(s0.impostors, 5);
  EXPECT_EQ(s0.snapshots, 5);
  EXPECT_EQ(s0.new_snapshots, 5);
  EXPECT_FLOAT_EQ(s0.refresh_fraction, 1.0f);
  auto s1 = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
  EXPECT_EQ(s1.snapshots, 0);
  EXPECT_EQ(s1.refresh_fraction, 0.0f);
  // A geometry frame in between draws everything as geometry and leaves the cache alone.
  const FramePlan& g = planner.plan(crowd, cam, 0.0f, RenderMode::kGeometry);
  EXPECT_EQ(g.stats.geometry, 5);
  EXPECT_EQ(g.geometry[0].size(), 5u);
  // Turning the middle character by 7 degrees: below the threshold; by 9: above.
  crowd[2].yaw = glm::radians(7.0f);
  EXPECT_EQ(planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats.snapshots, 0);
  crowd[2].yaw = glm::radians(9.0f);
  auto s2 = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
  EXPECT_EQ(s2.snapshots, 1);
  EXPECT_EQ(s2.view_refreshes, 1);
  // View test off: nothing refreshes however far it turns.
  planner.config().cache.view_test = false;
  crowd[2].yaw = glm::radians(90.0f);
  EXPECT_EQ(planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats.snapshots, 0);
  // Posture test: the clip stretches the arm; at a 0 threshold every moving character refreshes.
  planner.config().cache.posture_test = true;
  planner.config().cache.posture_threshold = 0.0f;
  for (std::size_t i = 0; i < crowd.size(); ++i) crowd[i].speed = 1.0f;
  auto s3 = planner.plan(crowd, cam, 0.25f, RenderMode::kImpostor).stats;
  EXPECT_EQ(s3.snapshots, 5);
  EXPECT_EQ(s3.posture_refreshes, 5);
  // 0.25 -> 0.26 s changes the squared distances by about 1 %: a 40 % threshold keeps the windows.
  planner.config().cache.posture_threshold = 0.4f;
  EXPECT_EQ(planner.plan(crowd, cam, 0.26f, RenderMode::kImpostor).stats.snapshots, 0);
  planner.invalidate();
  EXPECT_EQ(planner.plan(crowd, cam, 0.26f, RenderMode::kImpostor).stats.snapshots, 5);
}

// A billboard's atlas window, as one value: its page and uv rectangle.
glm::vec4 window_of(const BillboardGpu& b) {
  return glm::vec4(b.uv_rect.x + b.layer.x * 10.0f, b.uv_rect.y, b.uv_rect.z, b.uv_rect.w);
}

// Each billboard's window by its character's x (the characters stand in a row, so x names them).
std::map<int, glm::vec4> windows_by_x(const FramePlan& plan) {
  std::map<int, glm::vec4> out;
  for (const BillboardGpu& b : plan.billboards) out[static_cast<int>(std::lround(b.ta_half.x * 10.0f))] = window_of(b);
  return out;
}

// A game removes, reorders and replaces characters: each keeps its own snapshot (the ids
// Crowd::add gives), whether the crowd is changed with Crowd::remove or through characters(), and a
// removed character's window goes back to the atlas. The row's neighbours are seen within 8 degrees
// of each other from 30 m, so a snapshot left with the index would pass the view test and show
// another character's picture.
TEST(FramePlanner, SnapshotsFollowTheirCharactersWhenTheCrowdChanges) {
  Model m = tiny_model();
  Crowd crowd = standing_row(m, 5, 2.0f);
  for (std::size_t i = 0; i < crowd.size(); ++i) EXPECT_NE(crowd[i].id, 0u);
  EXPECT_NE(crowd[0].id, crowd[1].id);
  FramePlanner planner(m, view_test_only(8.0f));
  const SceneCamera cam = facing_camera(30.0f);
  ASSERT_EQ(planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats.snapshots, 5);
  const std::map<int, glm::vec4> before = windows_by_x(planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor));
  ASSERT_EQ(before.size(), 5u);
  const int windows = planner.atlas().windows_used();
  // Crowd::remove(1): the last character takes index 1.
  const std::uint32_t last = crowd[4].id;
  crowd.remove(1);
  ASSERT_EQ(crowd.size(), 4u);
  EXPECT_EQ(crowd[1].id, last);
  const FramePlan& p1 = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor);
  EXPECT_EQ(p1.stats.snapshots, 0);
  for (const auto& [x, w] : windows_by_x(p1)) {
    EXPECT_EQ(w, before.at(x)) << "x " << x;
  }
  EXPECT_EQ(planner.atlas().windows_used(), windows - 1);
  // Erased through characters(), order kept.
  crowd.characters().erase(crowd.characters().begin());
  const FramePlan& p2 = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor);
  EXPECT_EQ(p2.stats.snapshots, 0);
  EXPECT_EQ(p2.billboards.size(), 3u);
  for (const auto& [x, w] : windows_by_x(p2)) {
    EXPECT_EQ(w, before.at(x)) << "x " << x;
  }
  EXPECT_EQ(planner.atlas().windows_used(), windows - 2);
  // Reversed: the same windows.
  std::reverse(crowd.characters().begin(), crowd.characters().end());
  const FramePlan& p3 = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor);
  EXPECT_EQ(p3.stats.snapshots, 0);
  for (const auto& [x, w] : windows_by_x(p3)) {
    EXPECT_EQ(w, before.at(x)) << "x " << x;
  }
  // Taken out and added again (its id kept): the same character, the same window.
  Character moved = crowd[0];
  crowd.remove(0);
  crowd.add(moved);
  const FramePlan& p4 = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor);
  EXPECT_EQ(p4.stats.snapshots, 0);
  for (const auto& [x, w] : windows_by_x(p4)) {
    EXPECT_EQ(w, before.at(x)) << "x " << x;
  }
  // A new character (id 0 given: the crowd's next) where one was removed gets a snapshot of its own.
  crowd.remove(crowd.size() - 1);
  moved.id = 0;
  crowd.add(moved);
  const FramePlan& p5 = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor);
  EXPECT_EQ(p5.stats.snapshots, 1);
  EXPECT_EQ(planner.atlas().windows_used(), windows - 2);
}

// A character scaled between frames (a game's grow or shrink) keeps its snapshot, whose picture is
// the same scaled about Ta: its quad grows with it (whole impostors, facing the eye and aligned with
// the screen; part cards are carried by their bones, which scale).
TEST(FramePlanner, ScaledCharactersQuadsScaleWithThem) {
  Model m = tiny_model();
  for (const bool aligned : {false, true}) {
    Crowd crowd = standing_row(m, 1, 2.0f);
    ImpostorConfig cfg = view_test_only(8.0f);
    cfg.aligned_snapshots = aligned;
    FramePlanner planner(m, cfg);
    const SceneCamera cam = facing_camera(30.0f);
    ASSERT_EQ(planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats.snapshots, 1);
    const BillboardGpu b0 = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).billboards.at(0);
    const glm::vec3 ta0 = character_ta(m, crowd[0], 0.0f);
    crowd[0].scale = 1.1f;
    const FramePlan& p = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor);
    ASSERT_EQ(p.stats.snapshots, 0) << aligned;  // the same window class
    const BillboardGpu& b1 = p.billboards.at(0);
    const glm::vec3 ta1 = character_ta(m, crowd[0], 0.0f);
    EXPECT_NEAR(b1.ta_half.w, 1.1f * b0.ta_half.w, 1e-5f) << aligned;
    // The quad's centre keeps its place relative to Ta, scaled.
    expect_vec3(glm::vec3(b1.ta_half) - ta1, 1.1f * (glm::vec3(b0.ta_half) - ta0), 1e-5f);
    if (aligned) expect_vec3(glm::vec3(b1.axis_x), 1.1f * glm::vec3(b0.axis_x), 1e-5f);
  }
}

// A crowd a game changes at random, frame after frame (seeded): characters removed, erased, shuffled
// and added, with their own ids or the crowd's. Standing still before a still camera, only the new
// ones take snapshots, every old one keeps the window it had, and the atlas holds a window a
// character, no more.
TEST(FramePlanner, RandomCrowdChangesKeepEveryCharactersWindow) {
  Model m = tiny_model();
  Crowd crowd(m);
  std::mt19937 rng(7);
  std::uint32_t next_own = 1000;
  auto add_one = [&](bool own_id) {
    Character c{glm::vec3(std::uniform_real_distribution<float>(-8.0f, 8.0f)(rng), 0,
                          std::uniform_real_distribution<float>(-4.0f, 4.0f)(rng)),
                0.0f, 1.0f, 0, 0.0f, 0.0f};
    c.id = own_id ? next_own++ : 0u;
    crowd.add(c);
  };
  for (int i = 0; i < 12; ++i) add_one(i % 2 == 0);
  FramePlanner planner(m, view_test_only(8.0f));
  const SceneCamera cam = facing_camera(40.0f);
  std::map<std::uint32_t, glm::vec4> known;  // each character's window by id, since its snapshot
  for (int f = 0; f < 200; ++f) {
    int added = 0;
    if (f > 0) {
      auto any = [&] { return std::uniform_int_distribution<std::size_t>(0, crowd.size() - 1)(rng); };
      const int op = std::uniform_int_distribution<int>(0, 4)(rng);
      if (op == 0 && crowd.size() > 2) {
        crowd.remove(any());
      } else if (op == 1 && crowd.size() > 2) {
        crowd.characters().erase(crowd.characters().begin() + static_cast<std::ptrdiff_t>(any()));
      } else if (op == 2) {
        std::shuffle(crowd.characters().begin(), crowd.characters().end(), rng);
      } else if (op >= 3 && crowd.size() < 24) {
        add_one(f % 3 == 0);
        ++added;
      }
    }
    const FramePlan& p = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor);
    ASSERT_EQ(p.billboards.size(), crowd.size()) << "frame " << f;
    EXPECT_EQ(p.stats.snapshots, f == 0 ? static_cast<int>(crowd.size()) : added) << "frame " << f;
    EXPECT_EQ(planner.atlas().windows_used(), static_cast<int>(crowd.size())) << "frame " << f;
    // Each billboard's character: the one whose Ta it is drawn at.
    std::map<std::pair<long, long>, std::uint32_t> id_at;
    auto key = [](const glm::vec3& ta) { return std::make_pair(std::lround(ta.x * 1e3f), std::lround(ta.z * 1e3f)); };
    for (std::size_t i = 0; i < crowd.size(); ++i) id_at[key(character_ta(m, crowd[i], 0.0f))] = crowd[i].id;
    ASSERT_EQ(id_at.size(), crowd.size());
    std::map<std::uint32_t, glm::vec4> now;
    for (const BillboardGpu& b : p.billboards) {
      const glm::vec4 w = window_of(b);
      const auto found = id_at.find(key(glm::vec3(b.ta_half)));
      ASSERT_NE(found, id_at.end()) << "frame " << f;
      const std::uint32_t id = found->second;
      if (const auto it = known.find(id); it != known.end()) {
        EXPECT_EQ(w, it->second) << "frame " << f << ", character " << id;
      }
      now[id] = w;
    }
    known = now;
  }
}

// A game that rebuilds its crowd every frame keeps the snapshots: in the same order with the crowd's
// ids (clear() starts them over), in any order with ids of its own.
TEST(FramePlanner, CrowdsRebuiltEveryFrameKeepTheirSnapshots) {
  Model m = tiny_model();
  const Crowd row = standing_row(m, 4, 2.0f);
  Crowd crowd(m);
  auto rebuild = [&](bool reversed, bool own_ids) {
    crowd.clear();
    for (std::size_t k = 0; k < row.size(); ++k) {
      const std::size_t i = reversed ? row.size() - 1 - k : k;
      Character c = row[i];
      c.id = own_ids ? static_cast<std::uint32_t>(100 + i) : 0u;
      crowd.add(c);
    }
  };
  FramePlanner planner(m, view_test_only(8.0f));
  const SceneCamera cam = facing_camera(30.0f);
  for (const bool own : {false, true}) {
    planner.invalidate();
    rebuild(false, own);
    ASSERT_EQ(planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats.snapshots, 4);
    const std::map<int, glm::vec4> before = windows_by_x(planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor));
    rebuild(false, own);
    EXPECT_EQ(planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats.snapshots, 0) << own;
    if (!own) continue;
    rebuild(true, own);
    const FramePlan& p = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor);
    EXPECT_EQ(p.stats.snapshots, 0);
    for (const auto& [x, w] : windows_by_x(p)) {
      EXPECT_EQ(w, before.at(x)) << "x " << x;
    }
  }
}

// Screen-size weighting (CacheConfig::reference_pixels): a character 30 m away and one 300 m away
// (ten times smaller on screen) both turn. Without the weighting both are refreshed past 8
// degrees; with a reference of 4 times the far one's size, the far one's threshold is 32 degrees
// and the near one's stays 8.
TEST(FramePlanner, ScreenWeightingSparesSmallCharacters) {
  Model m = tiny_model();
  Crowd crowd(m);
  crowd.add(Character{glm::vec3(0, 0, 0), 0.0f, 1.0f, 0, 0.0f, 0.0f});
  crowd.add(Character{glm::vec3(0, 0, -270.0f), 0.0f, 1.0f, 0, 0.0f, 0.0f});
  const SceneCamera cam = facing_camera(30.0f);
  const float far_px = 2.0f * m.radius * cam.pixels_per_metre(300.0f);
  ASSERT_GT(far_px, 1.0f);
  for (float reference : {0.0f, 4.0f * far_px}) {
    ImpostorConfig cfg = view_test_only(8.0f);
    cfg.cache.reference_pixels = reference;
    FramePlanner planner(m, cfg);
    for (auto& c : crowd.characters()) c.yaw = 0.0f;
    EXPECT_EQ(planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats.snapshots, 2);
    for (auto& c : crowd.characters()) c.yaw = glm::radians(9.0f);
    const FrameStats a = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
    EXPECT_EQ(a.snapshots, reference > 0.0f ? 1 : 2) << reference;
    const FramePlan& p = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor);
    EXPECT_EQ(p.stats.snapshots, 0);
    for (auto& c : crowd.characters()) c.yaw = glm::radians(31.0f);  // far: 31 degrees since its snapshot
    EXPECT_EQ(planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats.snapshots, reference > 0.0f ? 1 : 2);
    for (auto& c : crowd.characters()) c.yaw = glm::radians(33.0f);  // far: 33 degrees, past 32
    EXPECT_EQ(planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats.snapshots, reference > 0.0f ? 1 : 0);
  }
}

// The paper's section 7, item 1: at most `refresh_budget` impostors refreshed per frame, the
// stalest first, the others kept one more frame; new impostors are refreshed whatever the budget.
TEST(FramePlanner, RefreshBudgetServesTheStalestFirst) {
  Model m = tiny_model();
  Crowd crowd = standing_row(m, 5, 2.0f);
  ImpostorConfig cfg = view_test_only(8.0f);
  cfg.cache.refresh_budget = 1;
  FramePlanner planner(m, cfg);
  const SceneCamera cam = facing_camera(30.0f);
  auto s0 = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
  EXPECT_EQ(s0.snapshots, 5);  // new: not held back by the budget
  EXPECT_EQ(s0.deferred_refreshes, 0);
  // Characters 1..4 turn by 10, 20, 30, 40 degrees: four stale, one refreshed per frame.
  for (int i = 1; i < 5; ++i) crowd[i].yaw = glm::radians(10.0f * i);
  const FramePlan& a = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor);
  EXPECT_EQ(a.stats.snapshots, 1);
  EXPECT_EQ(a.stats.deferred_refreshes, 3);
  EXPECT_EQ(a.stats.view_refreshes, 4);
  EXPECT_EQ(a.billboards.size(), 5u);  // the deferred ones still drawn, from their old snapshot
  // Character 4 (the stalest) was the one: 5 more degrees keep it fresh, so three are left.
  crowd[4].yaw = glm::radians(45.0f);
  auto b = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
  EXPECT_EQ(b.snapshots, 1);
  EXPECT_EQ(b.deferred_refreshes, 2);
  auto c = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
  EXPECT_EQ(c.deferred_refreshes, 1);
  auto d = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
  EXPECT_EQ(d.snapshots, 1);
  EXPECT_EQ(d.deferred_refreshes, 0);
  EXPECT_EQ(planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats.snapshots, 0);
  // Without a budget the same turn refreshes all four at once.
  planner.config().cache.refresh_budget = 0;
  for (int i = 1; i < 5; ++i) crowd[i].yaw = glm::radians(10.0f * i + 90.0f);
  auto e = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
  EXPECT_EQ(e.snapshots, 4);
  EXPECT_EQ(e.deferred_refreshes, 0);
  // Posture staleness ranks too: at a 0 threshold every moving character is stale; budget 2.
  planner.config().cache.refresh_budget = 2;
  planner.config().cache.view_test = false;
  planner.config().cache.posture_test = true;
  planner.config().cache.posture_threshold = 0.0f;
  for (std::size_t i = 0; i < crowd.size(); ++i) crowd[i].speed = 1.0f;
  auto f = planner.plan(crowd, cam, 0.25f, RenderMode::kImpostor).stats;
  EXPECT_EQ(f.snapshots, 2);
  EXPECT_EQ(f.deferred_refreshes, 3);
}

// Refreshes ahead (CacheConfig::ahead_fraction): a frame that takes a snapshot anyway also
// refreshes the impostors past the fraction of their thresholds, the stalest first, up to
// ahead_count; a frame with no stale impostor takes none. View test at 10 degrees, fraction 0.7.
TEST(FramePlanner, RefreshAheadGathersRefreshesIntoFramesThatTakeSnapshots) {
  Model m = tiny_model();
  Crowd crowd = standing_row(m, 5, 2.0f);
  ImpostorConfig cfg = view_test_only(10.0f);
  cfg.cache.ahead_fraction = 0.7f;
  cfg.cache.ahead_count = 2;
  FramePlanner planner(m, cfg);
  const SceneCamera cam = facing_camera(30.0f);
  EXPECT_EQ(planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats.snapshots, 5);  // new
  // Turned by 0, 9, 8, 5 and 7.5 degrees: none stale, so no snapshot, none ahead either.
  const float turn[5] = {0.0f, 9.0f, 8.0f, 5.0f, 7.5f};
  for (int i = 0; i < 5; ++i) crowd[i].yaw = glm::radians(turn[i]);
  auto a = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
  EXPECT_EQ(a.snapshots, 0);
  EXPECT_EQ(a.ahead_refreshes, 0);
  // Character 0 turns 12 degrees: stale. With it go the two stalest past 0.7 (0.9 and 0.8, not
  // 0.75: the count is 2), not the one at 0.5.
  crowd[0].yaw = glm::radians(12.0f);
  const FramePlan& b = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor);
  EXPECT_EQ(b.stats.view_refreshes, 1);
  EXPECT_EQ(b.stats.ahead_refreshes, 2);
  EXPECT_EQ(b.stats.snapshots, 3);
  EXPECT_EQ(b.billboards.size(), 5u);
  std::size_t snapshots = 0;
  for (const auto& l : b.snapshots) snapshots += l.size();
  EXPECT_EQ(snapshots, 3u);
  // Those refreshed ahead are fresh now: 1 more degree keeps characters 1 and 2 far from their
  // thresholds, while character 4 (7.5, never refreshed) is still only waiting.
  crowd[1].yaw = glm::radians(10.0f);
  crowd[2].yaw = glm::radians(9.0f);
  auto c = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
  EXPECT_EQ(c.snapshots, 0);
  EXPECT_EQ(c.ahead_refreshes, 0);
  // Character 0 stale again, count 4: character 4 (0.75) goes with it; 3 (0.5) does not.
  planner.config().cache.ahead_count = 4;
  crowd[0].yaw = glm::radians(24.0f);
  auto d = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
  EXPECT_EQ(d.snapshots, 2);
  EXPECT_EQ(d.ahead_refreshes, 1);
  // Within a refresh budget, those ahead take only what the stale ones leave: budget 2, three
  // stale (characters 0, 1, 2 past 10 degrees), character 3 at 0.9: none ahead.
  planner.config().cache.refresh_budget = 2;
  crowd[0].yaw = glm::radians(36.0f);
  crowd[1].yaw = glm::radians(21.0f);
  crowd[2].yaw = glm::radians(20.0f);
  crowd[3].yaw = glm::radians(9.0f);
  auto e = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
  EXPECT_EQ(e.snapshots, 2);
  EXPECT_EQ(e.deferred_refreshes, 1);
  EXPECT_EQ(e.ahead_refreshes, 0);
  // One stale left (the deferred one): the budget's second refresh goes ahead, to character 3.
  auto f = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
  EXPECT_EQ(f.snapshots, 2);
  EXPECT_EQ(f.deferred_refreshes, 0);
  EXPECT_EQ(f.ahead_refreshes, 1);
  EXPECT_EQ(planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats.snapshots, 0);
}

template <typename V>
bool bytes_equal(const V& a, const V& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(a[0])) == 0);
}

// Plan p draws what ref draws, byte for byte and in the same order, and counts the same (cards,
// refreshes by cause, snapshot triangles, quad texels).
void expect_same_plan(const FramePlan& p, const FramePlan& ref) {
  EXPECT_TRUE(bytes_equal(p.billboards, ref.billboards));
  for (std::size_t l = 0; l < ref.geometry.size(); ++l) {
    EXPECT_TRUE(bytes_equal(p.geometry[l], ref.geometry[l]));
    EXPECT_TRUE(bytes_equal(p.snapshots[l], ref.snapshots[l]));
  }
  EXPECT_EQ(p.stats.impostors, ref.stats.impostors);
  EXPECT_EQ(p.stats.geometry, ref.stats.geometry);
  EXPECT_EQ(p.stats.culled, ref.stats.culled);
  EXPECT_EQ(p.stats.snapshots, ref.stats.snapshots);
  EXPECT_EQ(p.stats.deferred_refreshes, ref.stats.deferred_refreshes);
  EXPECT_EQ(p.stats.ahead_refreshes, ref.stats.ahead_refreshes);
  EXPECT_EQ(p.stats.part_cards, ref.stats.part_cards);
  EXPECT_EQ(p.stats.part_snapshots, ref.stats.part_snapshots);
  EXPECT_EQ(p.stats.view_refreshes, ref.stats.view_refreshes);
  EXPECT_EQ(p.stats.posture_refreshes, ref.stats.posture_refreshes);
  EXPECT_EQ(p.stats.window_refreshes, ref.stats.window_refreshes);
  EXPECT_EQ(p.stats.snapshot_triangles, ref.stats.snapshot_triangles);
  EXPECT_DOUBLE_EQ(p.stats.quad_texels, ref.stats.quad_texels);
}

// expect_same_plan up to the order of the plan's lists: a crowd planned in chunks lists the
// characters whose windows changed after the others (FramePlanner::plan_many's small crowds).
template <typename V>
V sorted_bytes(V v) {
  std::sort(v.begin(), v.end(), [](const auto& a, const auto& b) { return std::memcmp(&a, &b, sizeof(a)) < 0; });
  return v;
}
void expect_same_plan_in_any_order(const FramePlan& p, const FramePlan& ref) {
  EXPECT_TRUE(bytes_equal(sorted_bytes(p.billboards), sorted_bytes(ref.billboards)));
  for (std::size_t l = 0; l < ref.geometry.size(); ++l) {
    EXPECT_TRUE(bytes_equal(sorted_bytes(p.geometry[l]), sorted_bytes(ref.geometry[l])));
    EXPECT_TRUE(bytes_equal(sorted_bytes(p.snapshots[l]), sorted_bytes(ref.snapshots[l])));
  }
  EXPECT_EQ(p.stats.impostors, ref.stats.impostors);
  EXPECT_EQ(p.stats.geometry, ref.stats.geometry);
  EXPECT_EQ(p.stats.snapshots, ref.stats.snapshots);
  EXPECT_EQ(p.stats.window_refreshes, ref.stats.window_refreshes);
  EXPECT_DOUBLE_EQ(p.stats.quad_texels, ref.stats.quad_texels);
}

// A view threshold of 0 refreshes every impostor that turned at all, even by less than a float
// cosine shows (the paper's worst case: every character refreshed every frame). A turn of 1e-4
// radians a frame has a cosine of 1 - 5e-9, which rounds to 1; a character that does not turn is
// not refreshed.
TEST(FramePlanner, ViewThresholdZeroRefreshesAnyTurn) {
  Model m = tiny_model();
  Crowd crowd = standing_row(m, 3, 3.0f);
  ASSERT_EQ(std::cos(1e-4f), 1.0f);
  FramePlanner planner(m, view_test_only(0.0f));
  const SceneCamera cam = facing_camera(20.0f);
  planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor);
  for (int f = 1; f <= 5; ++f) {
    crowd[0].yaw += 1e-4f;  // turns a little
    crowd[1].yaw -= 1e-4f;
    const FramePlan& p = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor);  // the pose held
    EXPECT_EQ(p.stats.impostors, 3) << "frame " << f;
    EXPECT_EQ(p.stats.view_refreshes, 2) << "frame " << f;
    EXPECT_EQ(p.stats.snapshots, 2) << "frame " << f;
  }
}

// Leading whole impostors (ImpostorConfig::view_lead): a character turning on the spot at 45
// degrees a second (1.5 degrees a frame at 30 frames a second) before a still camera, view test at
// 8 degrees. Without a lead the snapshot's view trails the eye by 0 to 7.5 degrees and is taken
// anew every sixth frame; with a lead of half the threshold it is taken 4 degrees ahead, so the
// eye passes through it and it lasts 13 degrees of turn; with a lead of the whole threshold (two
// frames' turn short of it: 5 degrees) 14. No snapshot is ever seen further off than the
// threshold plus a frame's turn, aligned snapshots stay on the screen's grid, and the first
// snapshot (no turn seen yet) and a still character take none.
TEST(FramePlanner, LeadingWholeImpostorsAreSeenFromBothSides) {
  Model m = tiny_model();
  Crowd crowd(m);
  crowd.add(Character{glm::vec3(0, 0, 0), 0.0f, 1.0f, 0, 0.0f, 0.0f});  // the pose held
  const SceneCamera cam = facing_camera(30.0f);
  const float leads[3] = {0.0f, 0.5f, 1.0f};
  int snapshots[3] = {0, 0, 0}, led[3] = {0, 0, 0};
  double mean[3] = {0, 0, 0}, most[3] = {0, 0, 0};
  const int frames = 60;
  for (int k = 0; k < 3; ++k) {
    ImpostorConfig cfg = view_test_only(8.0f);
    cfg.view_lead = leads[k];
    FramePlanner planner(m, cfg);
    float snap_azimuth = 0.0f;  // of the snapshot's eye about the character, in its frame (degrees)
    for (int f = 0; f < frames; ++f) {
      crowd[0].yaw = glm::radians(1.5f * static_cast<float>(f));
      const FramePlan& p = planner.plan(crowd, cam, static_cast<float>(f) / 30.0f, RenderMode::kImpostor);
      ASSERT_EQ(p.stats.impostors, 1);
      if (f == 0) {
        EXPECT_EQ(p.stats.lead_snapshots, 0);  // no turn seen yet
      }
      led[k] += p.stats.lead_snapshots;
      // The eye's azimuth in the character's frame: the eye stands at +Z, the character turns by
      // +yaw, so the eye goes round it by -yaw.
      const float eye_azimuth = -1.5f * static_cast<float>(f);
      if (p.stats.snapshots > 0) {
        if (f > 0) ++snapshots[k];
        ASSERT_EQ(p.snapshots.size(), 1u);
        ASSERT_EQ(p.snapshots[0].size(), 1u);
        // Vo runs from the snapshot's eye to Ta: the eye lies along -Vo, here in world; in the
        // character's frame turned back by the yaw.
        const glm::vec3 vo(p.snapshots[0][0].vo);
        snap_azimuth = glm::degrees(std::atan2(-vo.x, -vo.z)) - glm::degrees(crowd[0].yaw);
        // Ahead of the eye along its way round (towards smaller azimuths), by the lead.
        const float ahead = eye_azimuth - snap_azimuth;
        if (f > 0) {
          const float want = leads[k] == 0.0f ? 0.0f : std::min(8.0f * leads[k], 8.0f - 2.0f * 1.5f);
          EXPECT_NEAR(ahead, want, 0.05f) << "lead " << leads[k] << " frame " << f;
        }
      }
      const double off = std::abs(eye_azimuth - snap_azimuth);
      mean[k] += off / frames;
      most[k] = std::max(most[k], off);
    }
  }
  EXPECT_EQ(led[0], 0);
  EXPECT_EQ(led[1], snapshots[1]);
  EXPECT_EQ(snapshots[0], 9);  // past 8 degrees at 9: every sixth frame
  EXPECT_LT(snapshots[1], snapshots[0]);
  EXPECT_LE(snapshots[2], snapshots[1]);
  EXPECT_LE(static_cast<double>(snapshots[2]), 0.7 * snapshots[0]);
  for (int k = 0; k < 3; ++k) EXPECT_LE(most[k], 8.0 + 1.5 + 1e-3) << "lead " << leads[k];
  EXPECT_LT(mean[1], mean[0]);  // seen from both sides: nearer on average, for fewer snapshots
  // On the screen's pixel grid (aligned snapshots, 1/8 pixel off): the camera turned about Ta's
  // vertical keeps Ta on its pixel, so a leading impostor's quad still has its window's centre
  // 1/8 pixel right of and above a pixel corner, its axes the screen's, and its picture's scale.
  {
    ImpostorConfig cfg = view_test_only(8.0f);
    cfg.view_lead = 0.5f;
    cfg.aligned_snapshots = true;
    cfg.aligned_phase = 0.125f;
    cfg.texel_per_pixel = true;  // the flow test bed's whole impostors (tuned_config)
    cfg.texels_per_pixel = 1.0f;
    FramePlanner planner(m, cfg);
    const glm::mat4 screen = cam.projection() * cam.view();
    int checked = 0;
    float half_size = 0.0f;
    for (int f = 0; f < frames; ++f) {
      crowd[0].yaw = glm::radians(1.5f * static_cast<float>(f));
      const FramePlan& p = planner.plan(crowd, cam, static_cast<float>(f) / 30.0f, RenderMode::kImpostor);
      ASSERT_EQ(p.billboards.size(), 1u);
      const BillboardGpu& b = p.billboards[0];
      if (f == 0) {
        half_size = b.ta_half.w;
        EXPECT_EQ(b.axis_x.w, 1.0f);  // aligned without a lead
      }
      if (p.stats.lead_snapshots == 0) continue;
      ++checked;
      EXPECT_EQ(b.axis_x.w, 1.0f);  // drawn parallel to the screen
      EXPECT_NEAR(b.ta_half.w, half_size, 1e-4f * half_size);
      const glm::vec4 c = screen * glm::vec4(glm::vec3(b.ta_half), 1.0f);
      const glm::vec2 px = (glm::vec2(c) / c.w * 0.5f + 0.5f) * glm::vec2(cam.width, cam.height);
      EXPECT_NEAR(px.x - std::floor(px.x), 0.125f, 2e-3f) << "frame " << f;
      EXPECT_NEAR(px.y - std::floor(px.y), 0.125f, 2e-3f) << "frame " << f;
    }
    EXPECT_GE(checked, 5);
  }
  // A still character before a still camera: nothing to lead by.
  ImpostorConfig cfg = view_test_only(8.0f);
  cfg.view_lead = 1.0f;
  FramePlanner still(m, cfg);
  crowd[0].yaw = 0.0f;
  for (int f = 0; f < 5; ++f) {
    const FramePlan& p = still.plan(crowd, cam, static_cast<float>(f) / 30.0f, RenderMode::kImpostor);
    EXPECT_EQ(p.stats.lead_snapshots, 0);
    EXPECT_EQ(p.stats.snapshots, f == 0 ? 1 : 0);
  }
}

// Crowds of FramePlanner::kParallelCharacters and more are planned on a pool of threads; the
// plan must not depend on how many: same draws, same order, same counts, frame after frame, while
// characters animate, turn, change window size (the camera comes closer) and wait on a budget.
TEST(FramePlanner, PlanIsTheSameWhateverTheThreads) {
  Model m = tiny_model();
  Crowd crowd(m);
  // Enough characters for five threads (FramePlanner::kCharactersPerThread each).
  const int n = 2600;
  for (int i = 0; i < n; ++i)
    crowd.add(Character{glm::vec3(1.5f * static_cast<float>(i % 64) - 48.0f, 0, -1.5f * static_cast<float>(i / 64)),
                        0.1f * static_cast<float>(i % 7), 1.0f, 0, 0.013f * static_cast<float>(i), 1.0f});
  ASSERT_GE(crowd.size(), 5 * FramePlanner::kCharactersPerThread);
  // 200: the budget's refreshes planned on several threads too; -1: no budget, short-lived
  // snapshots drawn as geometry (a view threshold of 3 degrees, which most turning characters pass
  // every frame); -2: refreshes ahead (fraction 0.5, up to 30 a frame; their budget interplay is
  // RefreshAheadGathersRefreshesIntoFramesThatTakeSnapshots's). With the budget of 40 the
  // snapshots lead the eye (ImpostorConfig::view_lead), those the budget reaches too.
  for (int budget : {0, 40, 200, -1, -2}) {
    ImpostorConfig cfg;
    cfg.view_lead = budget == 40 ? 0.5f : 0.0f;
    cfg.cache.refresh_budget = std::max(budget, 0);
    cfg.short_lived_as_geometry = budget == -1;
    if (budget == -1) cfg.cache.view_threshold_deg = 3.0f;
    if (budget == -2) {
      cfg.cache.ahead_fraction = 0.5f;
      cfg.cache.ahead_count = 30;
    }
    cfg.max_pages = 64;
    std::vector<FramePlanner> planners;
    for (unsigned threads : {1u, 2u, 5u}) {
      cfg.planner_threads = threads;
      planners.emplace_back(m, cfg);
    }
    int changes = 0, deferred = 0, served = 0, most = 0, short_lived = 0, ahead = 0, led = 0, led_served = 0;
    for (int f = 0; f < 12; ++f) {
      // The camera comes closer for four frames (windows change size), then stays (the budget
      // then serves stale impostors).
      SceneCamera cam = facing_camera(120.0f - 12.0f * static_cast<float>(std::min(f, 4)));
      cam.eye.x = 2.0f * static_cast<float>(std::min(f, 4));
      // Every fifth character turns, each at its own rate, so the stalest lie all over the crowd.
      for (std::size_t i = 0; i < crowd.size(); i += 5) crowd[i].yaw += 0.02f + 0.01f * static_cast<float>((i * 37) % 11);
      const float t = 0.04f * static_cast<float>(f);
      const FramePlan& ref = planners[0].plan(crowd, cam, t, RenderMode::kAuto);
      changes += ref.stats.window_refreshes;
      deferred += ref.stats.deferred_refreshes;
      if (f > 4) served += ref.stats.view_refreshes > 0 ? ref.stats.snapshots : 0;
      if (ref.stats.deferred_refreshes > 0) most = std::max(most, ref.stats.snapshots);
      short_lived += ref.stats.short_lived_geometry;
      ahead += ref.stats.ahead_refreshes;
      led += ref.stats.lead_snapshots;
      if (f > 4 && ref.stats.deferred_refreshes > 0) led_served += ref.stats.lead_snapshots;
      for (std::size_t k = 1; k < planners.size(); ++k) {
        SCOPED_TRACE(testing::Message() << "budget " << budget << ", frame " << f << ", planner " << k);
        const FramePlan& p = planners[k].plan(crowd, cam, t, RenderMode::kAuto);
        expect_same_plan(p, ref);
        EXPECT_EQ(p.stats.impostors_per_window, ref.stats.impostors_per_window);
        EXPECT_EQ(p.stats.atlas_windows_used, ref.stats.atlas_windows_used);
        EXPECT_EQ(p.stats.short_lived_geometry, ref.stats.short_lived_geometry);
        EXPECT_EQ(p.stats.lead_snapshots, ref.stats.lead_snapshots);
        EXPECT_EQ(p.stats.geometry, ref.stats.geometry);
      }
      EXPECT_EQ(ref.stats.impostors + ref.stats.geometry + ref.stats.culled, n);
    }
    // The run did exercise what the threads must agree on.
    EXPECT_GT(changes, 0);
    EXPECT_GT(served, 0);
    if (budget > 0) {
      EXPECT_GT(deferred, 0);
    }
    EXPECT_EQ(short_lived > 0, budget == -1);
    EXPECT_EQ(ahead > 0, budget == -2);
    EXPECT_EQ(led > 0, budget == 40);
    EXPECT_EQ(led_served > 0, budget == 40);  // led where the budget reached them
    if (budget >= 200) {  // a frame whose budget-reached refreshes took several threads
      EXPECT_GE(most, 2 * static_cast<int>(FramePlanner::kForcedPerThread));
    }
  }
}

// A refresh costs about FramePlanner::kRefreshWork characters' planning, so a crowd too small
// for threads by its size (the test bed's worst case: 250 characters a model, all refreshed every
// frame) is planned on threads once a frame has refreshed it; and its plan is still the one a
// single thread makes, windows changing size included (the camera comes closer).
TEST(FramePlanner, CrowdsThatRefreshMuchArePlannedOnThreads) {
  Model m = tiny_model();
  Crowd crowd(m);
  const int n = 250;
  ASSERT_LT(static_cast<std::size_t>(n), FramePlanner::kParallelCharacters);
  for (int i = 0; i < n; ++i)
    crowd.add(Character{glm::vec3(1.5f * static_cast<float>(i % 25) - 18.0f, 0, -1.5f * static_cast<float>(i / 25)),
                        0.1f * static_cast<float>(i % 7), 1.0f, 0, 0.013f * static_cast<float>(i), 1.0f});
  ImpostorConfig cfg;
  cfg.cache.posture_threshold = 0.0f;
  cfg.cache.view_threshold_deg = 0.0f;
  cfg.max_pages = 64;
  cfg.planner_threads = 1;
  FramePlanner one(m, cfg);
  cfg.planner_threads = 3;
  FramePlanner three(m, cfg);
  int threaded = 0, changes = 0;
  for (int f = 0; f < 8; ++f) {
    SceneCamera cam = facing_camera(80.0f - 10.0f * static_cast<float>(std::min(f, 4)));
    const float t = 0.04f * static_cast<float>(f);
    SCOPED_TRACE(testing::Message() << "frame " << f);
    const FramePlan& ref = one.plan(crowd, cam, t, RenderMode::kImpostor);
    const FramePlan& p = three.plan(crowd, cam, t, RenderMode::kImpostor);
    expect_same_plan(p, ref);
    EXPECT_EQ(ref.stats.planner_threads, 1);
    EXPECT_EQ(ref.stats.snapshots, n - ref.stats.culled);  // every impostor refreshed
    // The first frame knows of no refresh: 250 characters are one thread's work.
    EXPECT_EQ(p.stats.planner_threads, f == 0 ? 1 : 3);
    threaded += p.stats.planner_threads > 1;
    changes += ref.stats.window_refreshes;
  }
  EXPECT_EQ(threaded, 7);
  EXPECT_GT(changes, 0);
}

// FramePlanner::plan_many plans several models' crowds together; each plan must be the one
// plan() makes: three crowds (parallel, parallel, serial sizes), frame after frame. The serial one
// is planned in chunks with the others, so its lists may be in the chunks' order.
TEST(FramePlanner, PlanManyMakesTheSamePlansAsPlan) {
  Model m = tiny_model();
  std::vector<Crowd> crowds(3, Crowd(m));
  const int sizes[3] = {1800, 700, 100};
  for (int k = 0; k < 3; ++k)
    for (int i = 0; i < sizes[k]; ++i)
      crowds[k].add(Character{glm::vec3(1.5f * static_cast<float>(i % 48) - 36.0f + 0.5f * static_cast<float>(k), 0,
                                        -1.5f * static_cast<float>(i / 48)),
                              0.1f * static_cast<float>((i + k) % 7), 1.0f, 0, 0.011f * static_cast<float>(i + 3 * k), 1.0f});
  ImpostorConfig cfg;
  cfg.max_pages = 64;
  cfg.cache.refresh_budget = 60;
  cfg.planner_threads = 3;
  std::vector<FramePlanner> alone, together;
  for (int k = 0; k < 3; ++k) {
    alone.emplace_back(m, cfg);
    together.emplace_back(m, cfg);
  }
  const std::array<FramePlanner*, 3> ptrs{&together[0], &together[1], &together[2]};
  const std::array<const Crowd*, 3> cptrs{&crowds[0], &crowds[1], &crowds[2]};
  int snapshots = 0;
  for (int f = 0; f < 8; ++f) {
    SceneCamera cam = facing_camera(100.0f - 10.0f * static_cast<float>(std::min(f, 3)));
    for (auto& c : crowds)
      for (std::size_t i = 0; i < c.size(); i += 4) c[i].yaw += 0.03f;
    const float t = 0.05f * static_cast<float>(f);
    const RenderMode mode = f == 5 ? RenderMode::kGeometry : RenderMode::kAuto;
    FramePlanner::plan_many(ptrs, cptrs, cam, t, mode);
    for (int k = 0; k < 3; ++k) {
      SCOPED_TRACE(testing::Message() << "frame " << f << ", crowd " << k);
      const FramePlan& ref = alone[k].plan(crowds[k], cam, t, mode);
      const FramePlan& p = together[k].plan_of_last_frame();
      if (k < 2) {
        expect_same_plan(p, ref);
      } else {
        expect_same_plan_in_any_order(p, ref);
      }
      EXPECT_EQ(p.stats.characters, sizes[k]);
      snapshots += ref.stats.snapshots;
    }
  }
  EXPECT_GT(snapshots, 0);
}

// Crowds each too small for threads alone (under FramePlanner::kParallelCharacters) are planned on
// threads where plan_many's joint work is enough (the flow test bed's four bodies at 1,000 humans):
// the same plans whatever the threads, and what plan() makes for each on its own, serially, in the
// chunks' order (the characters whose windows changed listed last).
TEST(FramePlanner, PlanManyPutsSmallCrowdsOnThreadsTogether) {
  Model m = tiny_model();
  std::vector<Crowd> crowds(4, Crowd(m));
  const int n = 200;
  ASSERT_LT(static_cast<std::size_t>(n), FramePlanner::kParallelCharacters);
  ASSERT_GE(static_cast<std::size_t>(4 * n), FramePlanner::kParallelCharacters);
  for (int k = 0; k < 4; ++k)
    for (int i = 0; i < n; ++i)
      crowds[k].add(Character{glm::vec3(1.5f * static_cast<float>(i % 20) - 15.0f + 0.4f * static_cast<float>(k), 0,
                                        -1.5f * static_cast<float>(i / 20) - 0.4f * static_cast<float>(k)),
                              0.1f * static_cast<float>((i + k) % 7), 1.0f, 0, 0.017f * static_cast<float>(i + 5 * k), 1.0f});
  ImpostorConfig cfg;
  cfg.max_pages = 64;
  cfg.planner_threads = 3;
  std::vector<FramePlanner> alone, together, one_thread;
  for (int k = 0; k < 4; ++k) {
    alone.emplace_back(m, cfg);
    together.emplace_back(m, cfg);
  }
  cfg.planner_threads = 1;
  for (int k = 0; k < 4; ++k) one_thread.emplace_back(m, cfg);
  std::array<FramePlanner*, 4> ptrs{}, one_ptrs{};
  std::array<const Crowd*, 4> cptrs{};
  for (std::size_t k = 0; k < 4; ++k) {
    ptrs[k] = &together[k];
    one_ptrs[k] = &one_thread[k];
    cptrs[k] = &crowds[k];
  }
  int reordered = 0;
  int snapshots = 0;
  for (int f = 0; f < 6; ++f) {
    SceneCamera cam = facing_camera(90.0f - 10.0f * static_cast<float>(std::min(f, 3)));
    for (auto& c : crowds)
      for (std::size_t i = 0; i < c.size(); i += 3) c[i].yaw += 0.04f;
    const float t = 0.05f * static_cast<float>(f);
    FramePlanner::plan_many(ptrs, cptrs, cam, t, RenderMode::kAuto);
    FramePlanner::plan_many(one_ptrs, cptrs, cam, t, RenderMode::kAuto);
    for (std::size_t k = 0; k < 4; ++k) {
      SCOPED_TRACE(testing::Message() << "frame " << f << ", crowd " << k);
      const FramePlan& ref = alone[k].plan(crowds[k], cam, t, RenderMode::kAuto);
      const FramePlan& p = together[k].plan_of_last_frame();
      expect_same_plan(p, one_thread[k].plan_of_last_frame());
      expect_same_plan_in_any_order(p, ref);
      reordered += !bytes_equal(p.billboards, ref.billboards);
      EXPECT_EQ(p.stats.planner_threads, 3);
      if (f == 0) {
        EXPECT_EQ(ref.stats.planner_threads, 1);  // alone: too small (no refresh known yet)
      }
      snapshots += ref.stats.snapshots;
    }
  }
  EXPECT_GT(snapshots, 0);
  EXPECT_GT(reordered, 0);  // windows did change (the camera comes closer): the order is the chunks'
}

TEST(FramePlanner, WindowSizeCullingAndNearSwitch) {
  Model m = tiny_model();
  Crowd crowd(m);
  crowd.add(Character{});
  crowd.add(Character{glm::vec3(0, 0, -1000)});  // behind the far plane: culled
  crowd.add(Character{glm::vec3(0, 0, 200)});    // behind the camera: culled
  ImpostorConfig one_to_one;
  one_to_one.texels_per_pixel = 1.0f;  // section 4.3's rule
  FramePlanner planner(m, one_to_one);
  SceneCamera cam;
  cam.far_plane = 500.0f;
  cam.target = m.ta;
  cam.height = 1024;
  const float r = m.radius;
  // On-screen diameter d = 2 r * ppm(distance): place the camera for d = 100 px -> the 128 window.
  auto place = [&](float pixels) { cam.eye = m.ta + glm::vec3(0, 0, 2 * r * cam.pixels_per_metre(1.0f) / pixels); };
  place(100.0f);
  auto s = planner.plan(crowd, cam, 0.0f, RenderMode::kAuto).stats;
  EXPECT_EQ(s.culled, 2);
  EXPECT_EQ(s.impostors, 1);
  EXPECT_EQ(s.impostors_per_window[1], 1);
  place(50.0f);  // smaller: the 64 window, which is a refresh
  s = planner.plan(crowd, cam, 0.0f, RenderMode::kAuto).stats;
  EXPECT_EQ(s.impostors_per_window[2], 1);
  EXPECT_EQ(s.window_refreshes, 1);
  EXPECT_EQ(s.snapshots, 1);
  EXPECT_EQ(planner.atlas().windows_used(), 1);  // the old window went back
  place(300.0f);  // larger than the largest window: geometry in auto mode, impostor if forced
  EXPECT_EQ(planner.plan(crowd, cam, 0.0f, RenderMode::kAuto).stats.geometry, 1);
  EXPECT_EQ(planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats.impostors, 1);
  // The default supersamples twice: 100 px -> 200 texels wanted -> the 256 window, 50 px -> 128.
  FramePlanner twice(m);
  place(100.0f);
  EXPECT_EQ(twice.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats.impostors_per_window[0], 1);
  place(50.0f);
  EXPECT_EQ(twice.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats.impostors_per_window[1], 1);
}

// The snapshot draws the level the geometry path would draw for the character now, so the
// impostor shows the same silhouette; the window's level is the literal section 4.3 rule.
TEST(FramePlanner, SnapshotUsesTheGeometryLevelOfTheCharacter) {
  Model m = tiny_model();
  MeshLod coarse = m.lods[0];
  m.lods[0].indices = {0, 1, 2, 0, 2, 1};  // the fine level: two triangles
  m.lods[0].primitives = {Primitive{0, 6, 0}};
  m.lods[0].screen_coverage = 0.2f;  // diameter >= 20 % of the viewport height
  m.lods.push_back(coarse);          // the coarse level: one triangle
  Crowd crowd(m);
  crowd.add(Character{});
  SceneCamera cam;
  cam.height = 1024;
  cam.target = m.ta;
  // 100 px on screen: geometry level 1 (coverage 0.098); 2 texels per pixel -> the 256 window,
  // whose level is 0 (coverage 0.25).
  cam.eye = m.ta + glm::vec3(0, 0, 2 * m.radius * cam.pixels_per_metre(1.0f) / 100.0f);
  FramePlanner screen(m);
  const FramePlan& g = screen.plan(crowd, cam, 0.0f, RenderMode::kGeometry);
  EXPECT_EQ(g.geometry[1].size(), 1u);
  EXPECT_EQ(g.stats.geometry_triangles, 1u);
  const FramePlan& p = screen.plan(crowd, cam, 0.0f, RenderMode::kImpostor);
  EXPECT_EQ(p.stats.impostors_per_window[0], 1);
  ASSERT_EQ(p.snapshots.size(), 2u);
  EXPECT_TRUE(p.snapshots[0].empty());
  EXPECT_EQ(p.snapshots[1].size(), 1u);
  EXPECT_EQ(p.stats.snapshot_triangles, 1u);
  ImpostorConfig literal;
  literal.snapshot_lod_from_screen = false;
  FramePlanner window(m, literal);
  const FramePlan& w = window.plan(crowd, cam, 0.0f, RenderMode::kImpostor);
  EXPECT_EQ(w.snapshots[0].size(), 1u);
  EXPECT_TRUE(w.snapshots[1].empty());
  EXPECT_EQ(w.stats.snapshot_triangles, 2u);
  // The snapshot's page travels in window.w.
  EXPECT_EQ(static_cast<int>(w.snapshots[0][0].window.w), window.atlas().page_class(0) >= 0 ? 0 : -1);
}

// ImpostorConfig::texel_per_pixel: the snapshot holds the texels per pixel asked for, in part of
// its power-of-two window, instead of filling the window (1-2x as many per axis).
TEST(FramePlanner, ExactScaleSnapshotsHoldTheTexelsPerPixelAsked) {
  Model m = tiny_model();
  Crowd crowd(m);
  crowd.add(Character{});
  SceneCamera cam;
  cam.height = 1024;
  cam.target = m.ta;
  cam.eye = m.ta + glm::vec3(0, 0, 2 * m.radius * cam.pixels_per_metre(1.0f) / 100.0f);  // 100 px across
  const float ppm1 = cam.pixels_per_metre(1.0f);
  auto texels_per_pixel = [&](float asked, bool exact) {
    ImpostorConfig cfg;
    cfg.texels_per_pixel = asked;
    cfg.texel_per_pixel = exact;
    FramePlanner planner(m, cfg);
    const FramePlan& p = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor);
    int size = 0;
    for (int k = 0; k < cfg.windows.count; ++k)
      if (p.stats.impostors_per_window[k] == 1) size = cfg.windows.size[k];
    for (const auto& level : p.snapshots)
      for (const SnapshotGpu& s : level) return static_cast<float>(size) * s.uo_dist.w / (2.0f * s.ho_half.w * ppm1);
    ADD_FAILURE() << "no snapshot";
    return 0.0f;
  };
  // 100 px: the 128 window at 1 texel per pixel, the 256 one at 2.
  EXPECT_NEAR(texels_per_pixel(1.0f, false), 1.28f, 0.02f);
  EXPECT_NEAR(texels_per_pixel(1.0f, true), 1.0f, 0.01f);
  EXPECT_NEAR(texels_per_pixel(2.0f, false), 2.56f, 0.03f);
  EXPECT_NEAR(texels_per_pixel(2.0f, true), 2.0f, 0.02f);
}

TEST(FramePlanner, AtlasFullFallsBackToGeometry) {
  Model m = tiny_model();
  Crowd crowd(m);
  for (int i = 0; i < 20; ++i) crowd.add(Character{glm::vec3(0.1f * i, 0, 0)});
  ImpostorConfig cfg;
  cfg.page_size = 256;
  cfg.max_pages = 1;
  FramePlanner planner(m, cfg);
  SceneCamera cam;
  cam.eye = {0, 1.5f, 300};  // far: 32-pixel windows, 64 per 256 page
  cam.target = {0, 1.5f, 0};
  auto s = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
  EXPECT_EQ(s.impostors, 20);
  cam.eye = {0, 1.5f, 15};  // near: 256 windows, one fits
  s = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
  EXPECT_EQ(s.impostors + s.geometry, 20);
  EXPECT_GT(s.atlas_fallbacks, 0);
}

// A config that breaks a contract of the atlas or the planner is named with the setting and why
// (Renderer::create returns the same error; a planner asserts it).
TEST(ImpostorConfigCheck, BrokenContractsNameTheSetting) {
  EXPECT_TRUE(validate_impostor_config(ImpostorConfig{}).ok());
  auto where = [](const ImpostorConfig& c) {
    const Status s = validate_impostor_config(c);
    return s.ok() ? std::string("ok") : s.error().where + ": " + s.error().reason;
  };
  ImpostorConfig c;
  c.page_size = 128;  // the 256-pixel window fits no page
  EXPECT_EQ(where(c).rfind("ImpostorConfig::page_size: 128 is smaller than the largest window (256", 0), 0u) << where(c);
  c.windows.count = 4;
  c.windows.size = {128, 64, 32, 16};
  EXPECT_EQ(where(c), "ok");  // windows that fit
  c = ImpostorConfig{};
  c.max_pages = 0;
  EXPECT_EQ(where(c).rfind("ImpostorConfig::max_pages", 0), 0u) << where(c);
  c = ImpostorConfig{};
  c.windows.size[5] = 0;  // a window of no pixel
  EXPECT_EQ(where(c).rfind("ImpostorConfig::windows: size[5] is 0", 0), 0u) << where(c);
  c = ImpostorConfig{};
  c.windows.count = 0;
  EXPECT_EQ(where(c).rfind("ImpostorConfig::windows: count 0", 0), 0u) << where(c);
  c.windows.count = 9;
  EXPECT_EQ(where(c).rfind("ImpostorConfig::windows: count 9", 0), 0u) << where(c);
  c = ImpostorConfig{};
  c.windows.size[2] = 512;  // not largest first
  EXPECT_EQ(where(c).rfind("ImpostorConfig::windows: size[2] (512) is larger than size[1]", 0), 0u) << where(c);
  c = ImpostorConfig{};
  c.first_page = -1;
  EXPECT_EQ(where(c).rfind("ImpostorConfig::first_page", 0), 0u) << where(c);
  c = shared_atlas_config(ImpostorConfig{}, 1, 2);
  EXPECT_EQ(where(c), "ok");
  c.atlas_pages = 40;  // pages 32 to 63 of 40
  EXPECT_EQ(where(c).rfind("ImpostorConfig::atlas_pages", 0), 0u) << where(c);
  c = ImpostorConfig{};
  c.texels_per_pixel = 0.0f;
  EXPECT_EQ(where(c).rfind("ImpostorConfig::texels_per_pixel", 0), 0u) << where(c);
  c = ImpostorConfig{};
  c.aligned_phase = 1.0f;
  EXPECT_EQ(where(c).rfind("ImpostorConfig::aligned_phase", 0), 0u) << where(c);
  c = ImpostorConfig{};
  c.quad_fetch = 2;
  EXPECT_EQ(where(c), "ok");
  c.quad_fetch = 3;
  EXPECT_EQ(where(c).rfind("ImpostorConfig::quad_fetch: 3", 0), 0u) << where(c);
}

// A page smaller than the largest window (a broken contract, asserted where assertions are on):
// the allocator gives no window of that size, so a character that wants one is drawn as geometry
// instead of the first frame reading past a page of no slots.
TEST(Atlas, NoWindowLargerThanThePage) {
#ifndef NDEBUG
  GTEST_SKIP() << "the contract is asserted in this build";
#else
  WindowSizes w;
  AtlasAllocator a(128, 2, w);
  EXPECT_FALSE(a.allocate(0));  // 256 pixels: none
  auto x = a.allocate(1);       // 128: one a page
  ASSERT_TRUE(x);
  EXPECT_EQ(x->size, 128);
  w.size[5] = 0;  // a window of no pixel: none either
  AtlasAllocator b(1024, 1, w);
  EXPECT_FALSE(b.allocate(5));
  EXPECT_TRUE(b.allocate(4));
  Model m = tiny_model();
  Crowd crowd = standing_row(m, 3, 2.0f);
  ImpostorConfig cfg;
  cfg.page_size = 128;
  FramePlanner planner(m, cfg);
  SceneCamera cam = facing_camera(12.0f);  // 256-pixel windows wanted
  FrameStats st = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
  EXPECT_EQ(st.geometry, 3);
  EXPECT_EQ(st.atlas_fallbacks, 3);
  cam = facing_camera(100.0f);  // 128 pixels and less: impostors
  st = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
  EXPECT_EQ(st.impostors, 3);
#endif
}

// A camera looking along its up vector (straight down, up +Y): glm::lookAt's right axis would be
// the cross product of two parallel vectors, the view NaN, nothing culled and nothing drawn. The
// camera takes another up (+Z; +X along Z), as the impostor quads do.
TEST(SceneCamera, UpAlongTheViewDirectionTakesAnother) {
  SceneCamera cam;
  cam.eye = {0, 10, 0};
  cam.target = {0, 0, 0};
  cam.up = {0, 1, 0};
  const glm::mat4 v = cam.view();
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) ASSERT_TRUE(std::isfinite(v[c][r])) << c << ", " << r;
  glm::vec3 right, up, fwd;
  camera_axes(cam, right, up, fwd);
  expect_vec3(fwd, {0, -1, 0}, 1e-6f);
  expect_vec3(up, {0, 0, 1}, 1e-6f);
  EXPECT_NEAR(glm::dot(right, up), 0.0f, 1e-6f);
  cam.up = {0, 0, -1};  // a usable up stays
  camera_axes(cam, right, up, fwd);
  expect_vec3(up, {0, 0, -1}, 1e-6f);
  cam.eye = {0, 0, 5};  // along Z with up Z: +X
  cam.up = {0, 0, 2};
  camera_axes(cam, right, up, fwd);
  expect_vec3(up, {1, 0, 0}, 1e-6f);
  // The planner culls with it: one character below, one far off to the side.
  Model m = tiny_model();
  Crowd crowd(m);
  crowd.add(Character{});
  crowd.add(Character{glm::vec3(100, 0, 0)});
  SceneCamera down;
  down.eye = {0, 20, 0};
  down.target = {0, 0, 0};
  FramePlanner planner(m);
  const FramePlan& p = planner.plan(crowd, down, 0.0f, RenderMode::kImpostor);
  EXPECT_EQ(p.stats.culled, 1);
  ASSERT_EQ(p.stats.impostors, 1);
  EXPECT_TRUE(std::isfinite(p.billboards[0].ta_half.x) && std::isfinite(p.billboards[0].ta_half.w));
}

// A character placed nowhere (a position, yaw or scale that is not finite) lies outside no frustum
// plane by the comparisons (each is false with NaN): it is culled, and takes no window.
TEST(FramePlanner, CharactersPlacedNowhereAreCulled) {
  Model m = tiny_model();
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  Crowd crowd(m);
  crowd.add(Character{});
  crowd.add(Character{glm::vec3(nan, 0, 0)});
  crowd.add(Character{glm::vec3(0, inf, 0)});
  crowd.add(Character{glm::vec3(0), nan});
  Character scaled;
  scaled.scale = nan;
  crowd.add(scaled);
  FramePlanner planner(m);
  for (RenderMode mode : {RenderMode::kImpostor, RenderMode::kGeometry}) {
    const FramePlan& p = planner.plan(crowd, facing_camera(20.0f), 0.0f, mode);
    EXPECT_EQ(p.stats.culled, 4);
    EXPECT_EQ(p.stats.impostors + p.stats.geometry, 1);
  }
  EXPECT_EQ(planner.atlas().windows_used(), 1);
}

// Aligned snapshots are cut out of the screen's image along its axes, and the quad is drawn along
// the axes of the moment: a camera turned in place (mouse look: no line of sight changes, so the
// view test of section 5.2 does not fire) would stretch the old picture. The turn of the axes is
// tested against the view threshold too.
TEST(FramePlanner, AlignedSnapshotsRefreshWhenTheCameraTurnsInPlace) {
  Model m = tiny_model();
  Crowd crowd(m);
  crowd.add(Character{});
  FramePlanner planner(m, aligned_view_test_only(8.0f));
  FramePlanner free_grid(m, view_test_only(8.0f));  // snapshots facing the eye: exact whatever the turn
  auto turned = [](float degrees) {
    SceneCamera cam = facing_camera(30.0f);
    const float a = glm::radians(degrees);
    cam.target = cam.eye + 30.0f * glm::vec3(std::sin(a), 0.0f, -std::cos(a));
    return cam;
  };
  const FramePlan& p0 = planner.plan(crowd, turned(0.0f), 0.0f, RenderMode::kImpostor);
  ASSERT_EQ(p0.stats.snapshots, 1);
  EXPECT_EQ(p0.billboards[0].axis_x.w, 1.0f);  // aligned: drawn parallel to the screen
  EXPECT_EQ(free_grid.plan(crowd, turned(0.0f), 0.0f, RenderMode::kImpostor).stats.snapshots, 1);
  // 5 degrees: within the threshold.
  EXPECT_EQ(planner.plan(crowd, turned(5.0f), 0.0f, RenderMode::kImpostor).stats.snapshots, 0);
  EXPECT_EQ(free_grid.plan(crowd, turned(5.0f), 0.0f, RenderMode::kImpostor).stats.snapshots, 0);
  // 10 degrees from the snapshot's axes: past it.
  const FrameStats s = planner.plan(crowd, turned(10.0f), 0.0f, RenderMode::kImpostor).stats;
  EXPECT_EQ(s.culled, 0);
  EXPECT_EQ(s.snapshots, 1);
  EXPECT_EQ(s.view_refreshes, 1);
  EXPECT_EQ(free_grid.plan(crowd, turned(10.0f), 0.0f, RenderMode::kImpostor).stats.snapshots, 0);
  // And measured from the new snapshot: 15 degrees is 5 from it.
  EXPECT_EQ(planner.plan(crowd, turned(15.0f), 0.0f, RenderMode::kImpostor).stats.snapshots, 0);
  // A roll of the camera (its up turned about the line of sight) turns the axes too.
  SceneCamera rolled = turned(15.0f);
  rolled.up = glm::vec3(std::sin(glm::radians(12.0f)), std::cos(glm::radians(12.0f)), 0.0f);
  EXPECT_EQ(planner.plan(crowd, rolled, 0.0f, RenderMode::kImpostor).stats.view_refreshes, 1);
}

// A clip whose channels are all STEP holds each pose until its next key: a time between two baked
// frames takes the earlier one rather than a blend of both (the 60 Hz bake blended a step into the
// next pose for 1/60 s, drawing the stretch half done at 0.499 s). A linear clip still blends.
TEST(FramePlanner, SteppedClipsHoldTheirPosesBetweenBakedFrames) {
  auto blend_at = [](Interpolation interpolation, float time) {
    Model m = tiny_model();
    m.clips[0].channels[0].interpolation = interpolation;
    m.bake(60.0f);
    Crowd crowd(m);
    crowd.add(Character{});
    FramePlanner planner(m, view_test_only(8.0f));
    const FramePlan& p = planner.plan(crowd, facing_camera(30.0f), time, RenderMode::kGeometry);
    for (const auto& lod : p.geometry)
      if (!lod.empty()) return lod[0].anim.w;
    return -1.0f;
  };
  EXPECT_EQ(blend_at(Interpolation::kStep, 0.495f), 0.0f);
  EXPECT_EQ(tiny_model().baked_clips()[0].stepped, false);
  EXPECT_NEAR(blend_at(Interpolation::kLinear, 0.495f), 0.7f, 1e-3f);  // 0.495 s is frame 29.7
}

// In a clip that mixes STEP and LINEAR channels, the STEP joint holds its key until the next and
// jumps exactly at it, whatever time the game plays between the 60 Hz baked frames, while the LINEAR
// joint goes on interpolating. Read as the GPU skins: the instance's two palette rows and blend.
// (Each frame's palette used to be blended whole: 0.505 s, frame 30.3, drew the STEP joint at x = 0.3,
// and it reached 1 only at frame 31, 0.5167 s.)
TEST(FramePlanner, MixedStepAndLinearChannelsStepExactlyAtTheirKeys) {
  const Model m = step_and_slide(Interpolation::kLinear);
  EXPECT_FALSE(m.baked_clips()[0].stepped);
  Crowd crowd(m);
  crowd.add(Character{});
  FramePlanner planner(m, view_test_only(8.0f));
  // Joint `entry`'s x (its palette matrix's translation) at scene time `time`, as drawn.
  auto x_at = [&](float time, int entry) {
    const FramePlan& p = planner.plan(crowd, facing_camera(30.0f), time, RenderMode::kGeometry);
    for (const auto& lod : p.geometry)
      if (!lod.empty()) {
        const glm::vec4 anim = lod[0].anim;
        const auto pal = m.baked_palette();
        auto x = [&](float row) { return pal[(static_cast<std::size_t>(row) * m.palette.size() + entry) * 3].w; };
        return x(anim.y) + (x(anim.z) - x(anim.y)) * anim.w;
      }
    return -1.0f;
  };
  // The STEP joint: held between baked frames, jumping at the key on a grid frame and off it.
  EXPECT_EQ(x_at(0.0f, 1), 0.0f);
  EXPECT_EQ(x_at(0.1f, 1), 0.0f);
  EXPECT_EQ(x_at(0.2499f, 1), 0.0f);  // frame 14.99
  EXPECT_EQ(x_at(0.25f, 1), 1.0f);
  EXPECT_EQ(x_at(0.2501f, 1), 1.0f);
  EXPECT_EQ(x_at(0.505f, 1), 1.0f);   // frame 30.3
  EXPECT_EQ(x_at(0.5099f, 1), 1.0f);  // frame 30.594
  EXPECT_EQ(x_at(0.51f, 1), 2.0f);
  EXPECT_EQ(x_at(0.5101f, 1), 2.0f);  // frame 30.606
  EXPECT_EQ(x_at(0.515f, 1), 2.0f);   // frame 30.9
  EXPECT_EQ(x_at(0.9f, 1), 2.0f);
  // The LINEAR joint: x = t, between baked frames and across the step's frames.
  for (float t : {0.1f, 0.2499f, 0.25f, 0.2501f, 0.505f, 0.5099f, 0.51f, 0.5101f, 0.515f, 0.9f})
    EXPECT_NEAR(x_at(t, 2), t, 1e-5f) << "t = " << t;
  // The root does not move.
  EXPECT_EQ(x_at(0.5099f, 0), 0.0f);
}

// A snapshot cut at a scale (aligned here) and then seen larger, by a zoom that leaves its window's
// size class alone, is taken anew once it is seen 1.5 times larger than cut (kMagnifiedRefresh):
// until then its texels were drawn blurred, however long the scene stood still. A snapshot that
// fills its window (the default) keeps it.
TEST(FramePlanner, MagnifiedSnapshotsAreTakenAnew) {
  Model m = tiny_model();
  Crowd crowd(m);
  crowd.add(Character{});
  FramePlanner planner(m, aligned_view_test_only(8.0f));
  FramePlanner filling(m, view_test_only(8.0f));
  auto zoomed = [](float zoom) {
    SceneCamera cam = facing_camera(30.0f);
    cam.fov_y = 2.0f * std::atan(std::tan(0.5f * cam.fov_y) / zoom);
    return cam;
  };
  auto window_width = [](const FramePlan& p) { return p.billboards.at(0).uv_rect.z - p.billboards.at(0).uv_rect.x; };
  const FramePlan& p0 = planner.plan(crowd, zoomed(1.0f), 0.0f, RenderMode::kImpostor);
  ASSERT_EQ(p0.stats.snapshots, 1);
  const float w0 = window_width(p0);
  EXPECT_EQ(filling.plan(crowd, zoomed(1.0f), 0.0f, RenderMode::kImpostor).stats.snapshots, 1);
  const FramePlan& p1 = planner.plan(crowd, zoomed(1.3f), 0.0f, RenderMode::kImpostor);
  EXPECT_EQ(p1.stats.snapshots, 0);
  EXPECT_EQ(window_width(p1), w0);
  const FramePlan& p2 = planner.plan(crowd, zoomed(1.6f), 0.0f, RenderMode::kImpostor);
  EXPECT_EQ(p2.stats.snapshots, 1);
  EXPECT_EQ(p2.stats.window_refreshes, 1);
  EXPECT_EQ(window_width(p2), w0);  // the same window size: the zoom alone asked for it
  EXPECT_EQ(filling.plan(crowd, zoomed(1.6f), 0.0f, RenderMode::kImpostor).stats.snapshots, 0);
  // Measured from the new snapshot: 2.2 is 1.375 times 1.6.
  EXPECT_EQ(planner.plan(crowd, zoomed(2.2f), 0.0f, RenderMode::kImpostor).stats.snapshots, 0);
}

// `n` characters standing on a circle of `radius` metres about the origin, facing it.
Crowd standing_ring(const Model& m, int n, float radius) {
  Crowd crowd(m);
  for (int i = 0; i < n; ++i) {
    const float a = 2.0f * glm::pi<float>() * static_cast<float>(i) / static_cast<float>(n);
    crowd.add(Character{radius * glm::vec3(std::sin(a), 0.0f, -std::cos(a)), a + glm::pi<float>(), 1.0f, 0, 0.0f, 0.0f});
  }
  return crowd;
}
// A 320x256 camera at the ring's centre, 1.5 m up, looking out `degrees` right of -Z.
SceneCamera looking_out(float degrees) {
  SceneCamera cam;
  cam.width = 320;
  cam.height = 256;
  const float a = glm::radians(degrees);
  cam.eye = {0.0f, 1.5f, 0.0f};
  cam.target = cam.eye + glm::vec3(std::sin(a), 0.0f, -std::cos(a));
  return cam;
}

// Characters out of view keep their windows (their snapshots serve again when they come back),
// but not at the expense of those in view: when the atlas is full, the windows of characters not
// drawn as impostors in the frame are taken back, the longest undrawn first. A camera turning
// round inside a ring of 40 characters, with room for 16 windows and about 10 in view: every
// character in view is an impostor all the way round (else from a quarter turn on the atlas
// held the windows of characters behind the camera, and those in view fell back to geometry).
TEST(FramePlanner, CharactersOutOfViewGiveTheirWindowsToThoseInView) {
  Model m = tiny_model();
  Crowd crowd = standing_ring(m, 40, 6.0f);
  ImpostorConfig cfg = view_test_only(8.0f);
  cfg.max_pages = 1;  // 16 windows of 256 pixels
  FramePlanner planner(m, cfg);
  int reclaimed = 0, most_in_view = 0;
  for (int f = 0; f <= 72; ++f) {
    SCOPED_TRACE(testing::Message() << "turned " << 5 * f << " degrees");
    const FrameStats st = planner.plan(crowd, looking_out(5.0f * static_cast<float>(f)), 0.0f, RenderMode::kImpostor).stats;
    const int in_view = st.characters - st.culled;
    most_in_view = std::max(most_in_view, in_view);
    EXPECT_EQ(st.impostors_per_window[0], st.impostors);  // all of one class: a window each
    EXPECT_EQ(st.atlas_fallbacks, 0);
    EXPECT_EQ(st.impostors, in_view);
    EXPECT_LE(st.atlas_windows_used, 16);
    reclaimed += st.atlas_reclaimed;
  }
  EXPECT_LT(most_in_view, 14);
  EXPECT_GT(reclaimed, 20);
  // The longest undrawn went first: those seen in the last frames kept their snapshots, so turning
  // back by a few steps takes none.
  for (int f = 71; f >= 68; --f) {
    SCOPED_TRACE(testing::Message() << "back at " << 5 * f << " degrees");
    const FrameStats st = planner.plan(crowd, looking_out(5.0f * static_cast<float>(f)), 0.0f, RenderMode::kImpostor).stats;
    EXPECT_EQ(st.snapshots, 0);
    EXPECT_EQ(st.impostors, st.characters - st.culled);
  }
}

// A character drawn as geometry (kAuto: too big on screen) keeps its window but draws none: when
// the one page of the atlas is of its window's size and another size is wanted, the page goes back
// whole.
TEST(FramePlanner, CharactersDrawnAsGeometryGiveBackAWholePage) {
  Model m = tiny_model();
  ImpostorConfig cfg = view_test_only(8.0f);
  cfg.max_pages = 1;
  FramePlanner planner(m, cfg);
  Crowd crowd(m);
  crowd.add(Character{glm::vec3(0.0f, 0.0f, -10.0f)});
  SceneCamera cam = looking_out(0.0f);
  FrameStats st = planner.plan(crowd, cam, 0.0f, RenderMode::kAuto).stats;
  ASSERT_EQ(st.impostors_per_window[0], 1);  // a 256-pixel window: its page takes no other size
  crowd.add(Character{glm::vec3(0.0f, 0.0f, -110.0f)});  // far: a small window
  cam.eye.z = -7.0f;  // the first 3 m away: geometry
  cam.target.z = -8.0f;
  st = planner.plan(crowd, cam, 0.0f, RenderMode::kAuto).stats;
  EXPECT_EQ(st.geometry, 1);
  EXPECT_EQ(st.impostors, 1);
  EXPECT_EQ(st.impostors_per_window[0], 0);
  EXPECT_EQ(st.atlas_fallbacks, 0);
  EXPECT_EQ(st.atlas_reclaimed, 1);
  EXPECT_EQ(planner.atlas().windows_used(), 1);
}


// A hinge: a root triangle and an arm triangle skinned to a joint 1 m up that turns 90 degrees
// about +Z over the 1 s clip.
Model hinge_model() {
  Model m;
  m.name = "hinge";
  m.nodes = {Node{"root", -1, {}}, Node{"arm", 0, {glm::vec3(0, 1, 0), glm::quat(1, 0, 0, 0), glm::vec3(1)}}};
  m.palette = {PaletteEntry{0, glm::mat4(1)}, PaletteEntry{1, glm::translate(glm::mat4(1), glm::vec3(0, -1, 0))}};
  MeshLod lod;
  lod.vertices.resize(6);
  const glm::vec3 pos[6] = {{-0.5f, 0, 0}, {0.5f, 0, 0}, {0, 1, 0}, {-0.1f, 1, 0}, {0.1f, 1, 0}, {0, 2, 0}};
  for (int v = 0; v < 6; ++v) {
    lod.vertices[v].position = pos[v];
    lod.vertices[v].joints = glm::u16vec4(v < 3 ? 0 : 1, 0, 0, 0);
  }
  lod.indices = {0, 1, 2, 3, 4, 5};
  lod.primitives = {Primitive{0, 6, 0}};
  m.lods = {lod};
  m.materials = {Material{}};
  m.clips = {bend_clip(1, 90.0f)};
  m.bake(60.0f);
  return m;
}

// Quads fitted to the coverage (ImpostorConfig::fit_quads_to_coverage) cost a pass over the new
// snapshot's texels that pays back only in the frames it is drawn again: a snapshot replacing one
// that lived a single impostor frame keeps the planner's box; one replacing a longer-lived one, or
// a character's first, is fitted. Geometry frames in between do not count.
// One hinge playing its bending clip, 2 m in front of the origin.
Crowd one_bending_hinge(const Model& h) {
  Crowd one(h);
  one.add(Character{glm::vec3(0, 0, -2), 0.0f, 1.0f, 0, 0.0f, 1.0f});
  return one;
}

// Part cards with the posture test alone at 0: a bending hinge's cards are due every frame.
ImpostorConfig hinge_cards_due_every_frame() {
  ImpostorConfig cfg;
  cfg.part_cards = true;
  cfg.cache.view_test = false;
  cfg.cache.posture_threshold = 0.0f;
  return cfg;
}

TEST(FramePlanner, ShortLivedSnapshotsKeepThePlannersBox) {
  Model m = tiny_model();
  Crowd crowd = standing_row(m, 3, 2.0f);
  FramePlanner planner(m, view_test_only(8.0f));
  const SceneCamera cam = facing_camera(30.0f);
  // The middle character's quad and its snapshot (if one is taken): fitted or not.
  auto plan = [&](float yaw_deg, RenderMode mode = RenderMode::kImpostor) {
    crowd[1].yaw = glm::radians(yaw_deg);
    const FramePlan& p = planner.plan(crowd, cam, 0.0f, mode);
    if (mode == RenderMode::kGeometry) return std::string("geometry");
    EXPECT_EQ(p.billboards.size(), 3u);
    std::string s = p.billboards[1].layer.z > 0.5f ? "fitted" : "box";
    for (const auto& level : p.snapshots)
      for (const SnapshotGpu& g : level) {
        EXPECT_EQ(g.part.z, p.billboards[1].layer.z);  // only the middle one's, once its first is taken
        s += "+snapshot";
      }
    return s;
  };
  EXPECT_EQ(plan(0), "fitted+snapshot+snapshot+snapshot");  // the first snapshots: fitted
  EXPECT_EQ(plan(9), "box+snapshot");    // its last lived one frame
  EXPECT_EQ(plan(18), "box+snapshot");   // so did this one
  EXPECT_EQ(plan(18), "box");            // kept: no snapshot
  EXPECT_EQ(plan(18), "box");
  EXPECT_EQ(plan(27), "fitted+snapshot");  // the last lived three frames
  EXPECT_EQ(plan(27, RenderMode::kGeometry), "geometry");
  EXPECT_EQ(plan(36), "box+snapshot");  // one impostor frame since, whatever the geometry frames
  // Fitting off: never fitted.
  planner.config().fit_quads_to_coverage = false;
  EXPECT_EQ(plan(36), "box");
  EXPECT_EQ(plan(36), "box");
  EXPECT_EQ(plan(45), "box+snapshot");
  // Part cards follow the same rule: a posture threshold of 0 refreshes the bending hinge's cards
  // every frame (the posture test is the character's).
  Model h = hinge_model();
  const Crowd one = one_bending_hinge(h);
  FramePlanner parts(h, hinge_cards_due_every_frame());
  for (int f = 0; f < 4; ++f) {
    const FramePlan& p = parts.plan(one, cam, 0.1f * static_cast<float>(f), RenderMode::kImpostor);
    ASSERT_EQ(p.billboards.size(), 2u);
    EXPECT_EQ(p.stats.part_snapshots, 2) << f;
    for (const BillboardGpu& b : p.billboards) EXPECT_EQ(b.layer.z, f == 0 ? 1.0f : 0.0f) << f;
    for (const SnapshotGpu& g : p.snapshots[0]) EXPECT_EQ(g.part.z, f == 0 ? 1.0f : 0.0f) << f;
  }
}

// ImpostorConfig::short_lived_as_geometry: a character whose snapshot is stale one impostor frame
// on is drawn as geometry, and stays so while it turns by more than the threshold from one frame
// to the next; then a snapshot is taken and it is an impostor again.
TEST(FramePlanner, ShortLivedCharactersAreDrawnAsGeometry) {
  Model m = tiny_model();
  for (bool on : {true, false}) {
    Crowd crowd = standing_row(m, 3, 2.0f);
    ImpostorConfig cfg = view_test_only(8.0f);
    cfg.short_lived_as_geometry = on;
    FramePlanner planner(m, cfg);
    const SceneCamera cam = facing_camera(30.0f);
    // What the middle character is drawn as: "geometry", "snapshot" (refreshed) or "kept".
    auto plan = [&](float yaw_deg, RenderMode mode = RenderMode::kImpostor) {
      crowd[1].yaw = glm::radians(yaw_deg);
      const FrameStats st = planner.plan(crowd, cam, 0.0f, mode).stats;
      EXPECT_EQ(st.short_lived_geometry, mode == RenderMode::kGeometry ? 0 : st.geometry);
      EXPECT_EQ(st.geometry + st.impostors, 3);
      if (mode == RenderMode::kGeometry) return std::string("geometry frame");
      if (st.geometry == 1) return std::string("geometry");
      return std::string(st.snapshots == 1 ? "snapshot" : st.snapshots == 0 ? "kept" : "all");
    };
    EXPECT_EQ(plan(0), "all");
    if (on) {
      EXPECT_EQ(plan(9), "geometry");   // its snapshot lived one frame
      EXPECT_EQ(plan(18), "geometry");  // 9 degrees a frame
      EXPECT_EQ(plan(18, RenderMode::kGeometry), "geometry frame");  // geometry frames do not count
      EXPECT_EQ(plan(23), "snapshot");  // 5 < 8 degrees: its window is brought up to date
      EXPECT_EQ(plan(23), "kept");
      EXPECT_EQ(plan(32), "snapshot");  // its snapshot lived two frames: refreshed as usual
      EXPECT_EQ(plan(41), "geometry");  // ... and this one would live one
      planner.invalidate();
      EXPECT_EQ(plan(41), "all");  // no usable snapshot: taken whatever
    } else {
      EXPECT_EQ(plan(9), "snapshot");  // every refresh a snapshot
      EXPECT_EQ(plan(18), "snapshot");
      EXPECT_EQ(plan(23), "kept");
      EXPECT_EQ(plan(30), "snapshot");
    }
  }
  // Part cards: the bending hinge with a posture threshold of 0 has both cards due every frame.
  Model h = hinge_model();
  const Crowd one = one_bending_hinge(h);
  ImpostorConfig cfg = hinge_cards_due_every_frame();
  cfg.short_lived_as_geometry = true;
  FramePlanner parts(h, cfg);
  const SceneCamera cam = facing_camera(30.0f);
  const float times[] = {0.0f, 0.1f, 0.2f, 0.2f, 0.2f, 0.3f, 0.4f};
  const int cards[] = {2, 0, 0, 2, 2, 2, 0};     // drawn
  const int taken[] = {2, 0, 0, 2, 0, 2, 0};     // refreshed
  for (int f = 0; f < 7; ++f) {
    const FrameStats st = parts.plan(one, cam, times[f], RenderMode::kImpostor).stats;
    EXPECT_EQ(st.part_cards, cards[f]) << f;
    EXPECT_EQ(st.part_snapshots, taken[f]) << f;
    EXPECT_EQ(st.short_lived_geometry, cards[f] == 0 ? 1 : 0) << f;
    EXPECT_EQ(st.geometry, cards[f] == 0 ? 1 : 0) << f;
    EXPECT_EQ(st.atlas_fallbacks, 0) << f;
  }
}

TEST(BodyParts, HingeSplitsIntoTwoPartsWithTheirOwnTriangles) {
  Model m = hinge_model();
  const auto parts = m.body_parts();
  ASSERT_EQ(parts.size(), 2u);
  EXPECT_EQ(parts[0].bone, 0);
  EXPECT_EQ(parts[1].bone, 1);
  EXPECT_NEAR(parts[1].mass, 0.5f, 1e-6f);
  const PartIndices& pi = m.part_indices(0);
  ASSERT_EQ(pi.ranges.size(), 2u);
  EXPECT_EQ(pi.ranges[0].count, 3u);
  EXPECT_EQ(pi.ranges[1].count, 3u);
  EXPECT_EQ(pi.indices[pi.ranges[1].first], 3u);
  // Two loose triangles: their edges are the mesh's own borders, not cuts, so nothing is capped.
  EXPECT_EQ(pi.ranges[0].caps, 0u);
  EXPECT_EQ(pi.ranges[1].caps, 0u);
  EXPECT_TRUE(pi.cap_vertices.empty());
  // The arm's box, in its palette (bind) space: the arm triangle, plus the margin.
  EXPECT_NEAR(parts[1].box_min.y, 1.0f, 0.05f);
  EXPECT_NEAR(parts[1].box_max.y, 2.0f, 0.05f);
  // Without clips nothing moves: one part.
  Model still = hinge_model();
  still.clips.clear();
  still.bake(60.0f);
  EXPECT_EQ(still.body_parts().size(), 1u);
  // Chosen by hand.
  const int bones[] = {0, 1};
  still.set_body_parts(bones);
  EXPECT_EQ(still.body_parts().size(), 2u);
}

// A closed square tube (tube_model.h) split at y = 1 into two parts: each part's cut at y = 1 is closed by a fan of 4 triangles from the
// ring's centre, facing out of the part, on vertices of their own after the level's.
TEST(BodyParts, CutsAreClosedByCapsFacingOutOfTheirPart) {
  const Model m = tube_model(0.0f);
  ASSERT_EQ(m.body_parts().size(), 2u);
  const PartIndices& pi = m.part_indices(0);
  ASSERT_EQ(pi.ranges.size(), 2u);
  ASSERT_EQ(pi.cap_vertices.size(), 24u);
  const std::vector<Vertex>& v = m.lods[0].vertices;
  auto corner = [&](std::uint32_t i) { return i < v.size() ? v[i] : pi.cap_vertices[i - v.size()]; };
  for (int p = 0; p < 2; ++p) {
    const PartIndices::Range& r = pi.ranges[static_cast<std::size_t>(p)];
    EXPECT_EQ(r.count, 30u) << p;  // its band and its end
    ASSERT_EQ(r.caps, 12u) << p;
    float area = 0.0f;
    for (std::uint32_t t = r.first + r.count; t < r.first + r.count + r.caps; t += 3) {
      for (int c = 0; c < 3; ++c) {
        EXPECT_GE(pi.indices[t + c], v.size());  // corners of their own
        EXPECT_FLOAT_EQ(corner(pi.indices[t + c]).position.y, 1.0f);
      }
      const Vertex centre = corner(pi.indices[t + 2]);
      EXPECT_EQ(centre.position, glm::vec3(0, 1, 0));
      EXPECT_NEAR(glm::length(centre.normal), 0.0f, 1e-6f);  // the ring's normals cancel
      EXPECT_EQ(centre.joints, glm::u16vec4(0, 1, 0, 0));
      EXPECT_EQ(centre.weights, glm::vec4(0.5f, 0.5f, 0, 0));
      const glm::vec3 a = corner(pi.indices[t]).position, b = corner(pi.indices[t + 1]).position;
      const glm::vec3 facing = glm::cross(b - a, centre.position - a);
      area += 0.5f * facing.y;
    }
    // The lower part's cap faces up, the upper part's down, and each covers the 2 x 2 opening.
    EXPECT_NEAR(area, p == 0 ? 4.0f : -4.0f, 1e-5f) << p;
  }
}

TEST(BodyParts, CardFollowsItsBoneWithoutARefresh) {
  Model m = hinge_model();
  Crowd crowd(m);
  crowd.add(Character{glm::vec3(1, 0, -2), 0.4f, 1.5f, 0, 0.0f, 1.0f});
  ImpostorConfig cfg;
  cfg.part_cards = true;
  cfg.cache.posture_test = false;
  cfg.cache.view_test = false;
  FramePlanner planner(m, cfg);
  SceneCamera cam;
  cam.eye = {0, 1.5f, 10};
  cam.target = {0, 1.5f, 0};
  const FramePlan& p0 = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor);
  EXPECT_EQ(p0.stats.snapshots, 1);
  EXPECT_EQ(p0.stats.part_cards, 2);
  ASSERT_EQ(p0.billboards.size(), 2u);
  ASSERT_EQ(p0.snapshots[0].size(), 2u);
  EXPECT_EQ(p0.snapshots[0][1].part.x, 1.0f);
  const std::array<BillboardGpu, 2> b0 = {p0.billboards[0], p0.billboards[1]};
  // At snapshot time each card faces the eye: its axes are perpendicular to the line of sight.
  for (const auto& b : b0) {
    const glm::vec3 los = glm::normalize(glm::vec3(b.ta_half) - cam.eye);
    EXPECT_NEAR(glm::dot(glm::vec3(b.axis_x), los), 0.0f, 1e-5f);
    EXPECT_NEAR(glm::dot(glm::vec3(b.axis_y), los), 0.0f, 1e-5f);
    EXPECT_EQ(b.axis_x.w, 1.0f);
  }
  // Half a second later (an exact baked frame) the arm has turned 45 degrees; no refresh.
  const FramePlan& p1 = planner.plan(crowd, cam, 0.5f, RenderMode::kImpostor);
  EXPECT_EQ(p1.stats.snapshots, 0);
  ASSERT_EQ(p1.billboards.size(), 2u);
  // World matrix of the arm's palette entry (placement x palette matrix) at t.
  auto arm_world = [&](float t) {
    std::vector<Transform> locals(m.nodes.size());
    std::vector<glm::mat4> world(m.nodes.size()), pal(m.palette.size());
    sample_clip(m, 0, t, locals);
    world_matrices(m, locals, world);
    palette_matrices(m, world, pal);
    const Character& ch = crowd[0];
    glm::mat4 place = glm::translate(glm::mat4(1), ch.position) * glm::rotate(glm::mat4(1), ch.yaw, glm::vec3(0, 1, 0)) *
                      glm::scale(glm::mat4(1), glm::vec3(ch.scale));
    return place * pal[1];
  };
  const glm::mat4 move = arm_world(0.5f) * glm::inverse(arm_world(0.0f));
  expect_vec3(glm::vec3(p1.billboards[1].ta_half), glm::vec3(move * glm::vec4(glm::vec3(b0[1].ta_half), 1)), 1e-4f);
  expect_vec3(glm::vec3(p1.billboards[1].axis_x), glm::vec3(move * glm::vec4(glm::vec3(b0[1].axis_x), 0)), 1e-4f);
  expect_vec3(glm::vec3(p1.billboards[1].axis_y), glm::vec3(move * glm::vec4(glm::vec3(b0[1].axis_y), 0)), 1e-4f);
  // It really moved (the arm turned 45 degrees), while the root's card stayed.
  EXPECT_GT(glm::distance(glm::vec3(p1.billboards[1].ta_half), glm::vec3(b0[1].ta_half)), 0.1f);
  expect_vec3(glm::vec3(p1.billboards[0].ta_half), glm::vec3(b0[0].ta_half), 1e-5f);
  // The card's texture coordinates and rect are those of the snapshot.
  EXPECT_EQ(p1.billboards[1].uv_rect, b0[1].uv_rect);
  EXPECT_EQ(p1.billboards[1].rect, b0[1].rect);
  // Without part cards the same model draws one camera-facing quad.
  planner.config().part_cards = false;
  const FramePlan& p2 = planner.plan(crowd, cam, 0.5f, RenderMode::kImpostor);
  ASSERT_EQ(p2.billboards.size(), 1u);
  EXPECT_EQ(p2.billboards[0].axis_x.w, 0.0f);
  EXPECT_EQ(p2.stats.snapshots, 1);
}

// Part cards follow their characters too: removing the first of three hinges (the last takes its
// index) leaves the other two with their own cards' windows, and gives the removed one's back.
TEST(BodyParts, CardsFollowTheirCharactersWhenTheCrowdChanges) {
  Model m = hinge_model();
  Crowd crowd(m);
  for (int i = 0; i < 3; ++i) crowd.add(Character{glm::vec3(2.0f * static_cast<float>(i - 1), 0, 0), 0.0f, 1.0f, 0, 0.0f, 0.0f});
  ImpostorConfig cfg = part_cards_view_only(20.0f);
  FramePlanner planner(m, cfg);
  const SceneCamera cam = facing_camera(20.0f);
  ASSERT_EQ(planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats.part_snapshots, 6);
  // Each card's window by its character (x, from the cards' order: two a character) and part.
  auto windows = [](const FramePlan& p) {
    std::map<std::pair<int, int>, glm::vec4> out;
    for (std::size_t k = 0; k < p.billboards.size(); ++k) {
      out[{static_cast<int>(std::lround(p.billboards[k - k % 2].ta_half.x)), static_cast<int>(k % 2)}] =
          window_of(p.billboards[k]);
    }
    return out;
  };
  const FramePlan& p0 = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor);
  ASSERT_EQ(p0.billboards.size(), 6u);
  const auto before = windows(p0);
  const int used = planner.atlas().windows_used();
  crowd.remove(0);
  const FramePlan& p1 = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor);
  EXPECT_EQ(p1.stats.part_snapshots, 0);
  ASSERT_EQ(p1.billboards.size(), 4u);
  for (const auto& [key, w] : windows(p1)) {
    EXPECT_EQ(w, before.at(key)) << "x " << key.first << ", part " << key.second;
  }
  EXPECT_EQ(planner.atlas().windows_used(), used - 2);
}

// Part cards out of view give their windows to those in view as whole impostors do (a character's
// cards go back together): a camera turning round inside a ring of 40 hinges, with room for the
// cards of 16.
TEST(BodyParts, CharactersOutOfViewGiveTheirWindowsToThoseInView) {
  Model m = hinge_model();
  Crowd crowd = standing_ring(m, 40, 6.0f);
  ImpostorConfig cfg = part_cards_view_only(20.0f);
  cfg.windows.count = 1;  // every card in a 128-pixel window, 16 a page
  cfg.windows.size[0] = 128;
  cfg.page_size = 512;
  cfg.max_pages = 2;
  FramePlanner planner(m, cfg);
  int reclaimed = 0, most_in_view = 0, most_windows = 0;
  for (int f = 0; f <= 72; ++f) {
    SCOPED_TRACE(testing::Message() << "turned " << 5 * f << " degrees");
    const FrameStats st = planner.plan(crowd, looking_out(5.0f * static_cast<float>(f)), 0.0f, RenderMode::kImpostor).stats;
    const int in_view = st.characters - st.culled;
    most_in_view = std::max(most_in_view, in_view);
    most_windows = std::max(most_windows, st.atlas_windows_used);
    EXPECT_EQ(st.atlas_fallbacks, 0);
    EXPECT_EQ(st.impostors, in_view);
    EXPECT_EQ(st.part_cards, 2 * in_view);
    reclaimed += st.atlas_reclaimed;
  }
  std::printf("hinges in view: %d at most; windows held: %d at most; taken back: %d\n", most_in_view, most_windows, reclaimed);
  EXPECT_GT(reclaimed, 20);
}

TEST(BodyParts, ViewTestIgnoresTheCardsRollButNotItsTilt) {
  Model m = hinge_model();
  Crowd crowd(m);
  crowd.add(Character{glm::vec3(0, 0, 0), 0.0f, 1.0f, 0, 0.0f, 1.0f});
  ImpostorConfig cfg = part_cards_view_only(8.0f);
  FramePlanner planner(m, cfg);
  const SceneCamera cam = facing_camera(30.0f);
  EXPECT_EQ(planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats.part_snapshots, 2);
  // The arm turns 45 degrees about the line of sight: its card rolls with it, no snapshot.
  const FrameStats s1 = planner.plan(crowd, cam, 0.5f, RenderMode::kImpostor).stats;
  EXPECT_EQ(s1.part_snapshots, 0);
  EXPECT_EQ(s1.refresh_fraction, 0.0f);
  // The character turns 10 degrees about +Y: both cards tilt past 8 degrees, both are refreshed.
  crowd[0].yaw = glm::radians(10.0f);
  const FrameStats s2 = planner.plan(crowd, cam, 0.5f, RenderMode::kImpostor).stats;
  EXPECT_EQ(s2.part_snapshots, 2);
  EXPECT_EQ(s2.view_refreshes, 1);
  EXPECT_FLOAT_EQ(s2.refresh_fraction, 1.0f);
  // 6 degrees more: under the threshold again.
  crowd[0].yaw = glm::radians(16.0f);
  EXPECT_EQ(planner.plan(crowd, cam, 0.5f, RenderMode::kImpostor).stats.part_snapshots, 0);
}

// The hinge with a round arm: a triangular prism 1 m long and 0.1 m in radius along +Y.
Model pole_model() {
  Model m = hinge_model();
  MeshLod& lod = m.lods[0];
  lod.vertices.resize(3);
  for (int end = 0; end < 2; ++end)
    for (int k = 0; k < 3; ++k) {
      Vertex v;
      const float a = glm::radians(120.0f * k);
      v.position = {0.1f * std::cos(a), 1.0f + end, 0.1f * std::sin(a)};
      v.joints = glm::u16vec4(1, 0, 0, 0);
      lod.vertices.push_back(v);
    }
  lod.indices = {0, 1, 2, 3, 4, 6, 4, 7, 6, 4, 5, 7, 5, 8, 7, 5, 3, 8, 3, 6, 8, 3, 5, 4, 6, 7, 8};
  lod.primitives = {Primitive{0, static_cast<std::uint32_t>(lod.indices.size()), 0}};
  m.bake(60.0f);
  return m;
}

// Leading part cards (ImpostorConfig::lead_cards): the pole bends towards a camera at its side
// (45 degrees a second, 1.5 degrees a frame at 30 frames a second), so its card tilts out of the
// line of sight. Taken along the mean line of sight over its coming life, the card is seen from
// both sides of its snapshot: the mean tilt falls, as many snapshots are taken, and no card is
// seen further off than the threshold (plus one frame's turn).
TEST(BodyParts, LeadingCardsAreSeenFromBothSides) {
  Model m = pole_model();
  Crowd crowd(m);
  crowd.add(Character{glm::vec3(0, 0, 0), 0.0f, 1.0f, 0, 0.0f, 0.5f});
  SceneCamera cam;
  cam.eye = {30.0f, 1.5f, 0.0f};
  cam.target = {0.0f, 1.5f, 0.0f};
  ImpostorConfig cfg = part_cards_view_only(8.0f);
  double mean[2] = {0, 0}, most[2] = {0, 0};
  int snapshots[2] = {0, 0};
  for (int lead = 0; lead < 2; ++lead) {
    cfg.lead_cards = lead == 1;
    FramePlanner planner(m, cfg);
    const int frames = 56;  // within the clip's first play (it loops after 2 s at half speed)
    for (int f = 0; f < frames; ++f) {
      const FramePlan& p = planner.plan(crowd, cam, static_cast<float>(f) / 30.0f, RenderMode::kImpostor);
      ASSERT_EQ(p.billboards.size(), 2u);
      if (f > 0) snapshots[lead] += p.stats.part_snapshots;
      const BillboardGpu& arm = p.billboards[1];
      const glm::vec3 n = glm::normalize(glm::cross(glm::vec3(arm.axis_y), glm::vec3(arm.axis_x)));
      const glm::vec3 los = glm::normalize(glm::vec3(arm.ta_half) - cam.eye);
      const double tilt = glm::degrees(std::acos(std::clamp(glm::dot(n, los), -1.0f, 1.0f)));
      mean[lead] += tilt / frames;
      most[lead] = std::max(most[lead], tilt);
    }
  }
  EXPECT_GT(mean[0], 3.0);  // without a lead: 0 to 7.5 degrees, refreshed past 8
  // With a lead: -3.75 to 3.75 degrees (mean 2.25 against 3.75 in steps of 1.5).
  EXPECT_LT(mean[1], 0.65 * mean[0]) << mean[0] << " " << mean[1];
  EXPECT_LE(snapshots[1], snapshots[0] + 1);
  EXPECT_GE(snapshots[0], 8);  // 1.5 degrees a frame, past 8 degrees: every sixth frame
  EXPECT_LT(most[0], 8.0 + 1.6);
  EXPECT_LT(most[1], 8.0 + 1.6);
}

TEST(BodyParts, LimbCardsTurnAboutTheLimbAxis) {
  Model m = pole_model();
  const auto parts = m.body_parts();
  ASSERT_EQ(parts.size(), 2u);
  // The prism: elongated along +Y (sd 0.5 m against 0.05 m across: 7), round across (1); the
  // root triangle is flat.
  EXPECT_NEAR(std::abs(parts[1].axis.y), 1.0f, 1e-4f);
  EXPECT_GT(parts[1].elongation, 5.0f);
  EXPECT_NEAR(parts[1].flatness, 1.0f, 0.05f);
  EXPECT_GT(parts[0].flatness, 100.0f);
  Crowd crowd(m);
  crowd.add(Character{glm::vec3(0, 0, 0), 0.0f, 1.0f, 0, 0.0f, 0.0f});
  ImpostorConfig cfg = part_cards_view_only(8.0f);
  const SceneCamera cam = facing_camera(30.0f);
  for (bool turn : {true, false}) {
    cfg.turn_limb_cards = turn;
    FramePlanner planner(m, cfg);
    crowd[0].yaw = 0.0f;
    EXPECT_EQ(planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats.part_snapshots, 2);
    // The character turns 20 degrees about +Y, the arm's axis: the root's card is refreshed;
    // the arm's turns to face the eye (turn) or is refreshed (fixed).
    crowd[0].yaw = glm::radians(20.0f);
    const FramePlan& p = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor);
    EXPECT_EQ(p.stats.part_snapshots, turn ? 1 : 2) << turn;
    const BillboardGpu& arm = p.billboards[1];
    const glm::vec3 los = glm::normalize(glm::vec3(arm.ta_half) - cam.eye);
    EXPECT_NEAR(glm::dot(glm::vec3(arm.axis_x), los), 0.0f, 1e-4f) << turn;
    EXPECT_NEAR(glm::dot(glm::vec3(arm.axis_y), los), 0.0f, 1e-4f) << turn;
  }
  // Tilting the arm's axis towards the eye is still a view change: with the character facing +X,
  // the arm's 45-degree bend about its +Z tilts it towards the eye, and its card is refreshed.
  cfg.turn_limb_cards = true;
  FramePlanner planner(m, cfg);
  crowd[0].yaw = glm::radians(90.0f);
  crowd[0].speed = 1.0f;
  EXPECT_EQ(planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats.part_snapshots, 2);
  EXPECT_EQ(planner.plan(crowd, cam, 0.5f, RenderMode::kImpostor).stats.part_snapshots, 1);
}

// A whole impostor's quad is the union of its body parts' boxes, each carried by its bone, within
// the pose's box: never smaller than what the skin covers, smaller than the pose's box seen
// obliquely (a 3D box's depth widens its picture).
TEST(BodyParts, WholeImpostorQuadHoldsTheSkinInsideThePoseBox) {
  Model m = pole_model();
  Model one = pole_model();
  const int root[] = {0};
  one.set_body_parts(root);
  ASSERT_EQ(one.body_parts().size(), 1u);
  SceneCamera cam;
  cam.eye = {6, 5, 8};
  cam.target = {0, 1, 0};
  const float t = 0.5f;  // the arm bent 45 degrees
  // At the origin, and moved and scaled (the parts' boxes are taken into the snapshot camera's
  // frame through the character's placement).
  for (const auto& [position, scale] : {std::pair{glm::vec3(0.0f), 1.0f}, std::pair{glm::vec3(2.0f, 0.0f, -1.0f), 1.3f}}) {
  SCOPED_TRACE(testing::Message() << "scale " << scale);
  auto quad = [&](const Model& model, double* texels) {
    Crowd crowd(model);
    crowd.add(Character{position, 0.3f, scale, 0, 0.0f, 1.0f});
    ImpostorConfig cfg;
    FramePlanner planner(model, cfg);
    const FramePlan& p = planner.plan(crowd, cam, t, RenderMode::kImpostor);
    EXPECT_EQ(p.billboards.size(), 1u);
    *texels = p.stats.quad_texels;
    return p.billboards[0];
  };
  double texels_parts = 0, texels_box = 0;
  const BillboardGpu bp = quad(m, &texels_parts), bb = quad(one, &texels_box);
  EXPECT_LT(texels_parts, 0.9 * texels_box);
  // Within the pose box's quad.
  EXPECT_GE(bp.rect.x, bb.rect.x - 1e-6f);
  EXPECT_GE(bp.rect.y, bb.rect.y - 1e-6f);
  EXPECT_LE(bp.rect.z, bb.rect.z + 1e-6f);
  EXPECT_LE(bp.rect.w, bb.rect.w + 1e-6f);
  // Every skinned vertex, seen from the eye, falls inside the quad (on the card's plane at Ta).
  std::vector<Transform> locals(m.nodes.size());
  std::vector<glm::mat4> world(m.nodes.size()), pal(m.palette.size());
  sample_clip(m, 0, t, locals);
  world_matrices(m, locals, world);
  palette_matrices(m, world, pal);
  const glm::mat4 place = glm::scale(glm::rotate(glm::translate(glm::mat4(1), position), 0.3f, glm::vec3(0, 1, 0)), glm::vec3(scale));
  const glm::vec3 ta(bp.ta_half);
  const float half = bp.ta_half.w;
  const glm::vec3 vo = glm::normalize(ta - cam.eye), ho = glm::normalize(glm::cross(vo, cam.up)),
                  uo = glm::cross(ho, vo);
  const float d = glm::dot(ta - cam.eye, vo);
  for (const Vertex& v : m.lods[0].vertices) {
    const glm::vec3 w(place * pal[v.joints[0]] * glm::vec4(v.position, 1.0f));
    const glm::vec3 q = cam.eye + (w - cam.eye) * (d / glm::dot(w - cam.eye, vo));
    const glm::vec2 c(glm::dot(q - ta, ho) / half, glm::dot(q - ta, uo) / half);
    EXPECT_GE(c.x, bp.rect.x);
    EXPECT_LE(c.x, bp.rect.z);
    EXPECT_GE(c.y, bp.rect.y);
    EXPECT_LE(c.y, bp.rect.w);
  }
  }
}

// Part cards too: with a view threshold of 0 every card of a character that turned at all is
// refreshed, the turn's cosine rounding to 1 or not (FramePlanner.ViewThresholdZeroRefreshesAnyTurn).
TEST(BodyParts, ViewThresholdZeroRefreshesAnyTurn) {
  Model m = pole_model();
  Crowd crowd(m);
  for (int i = 0; i < 2; ++i) crowd.add(Character{glm::vec3(3.0f * i - 1.5f, 0, 0), 0.0f, 1.0f, 0, 0.0f, 0.0f});
  ImpostorConfig cfg;
  cfg.part_cards = true;
  cfg.lead_cards = false;
  cfg.cache.posture_test = false;
  cfg.cache.view_threshold_deg = 0.0f;
  FramePlanner planner(m, cfg);
  const SceneCamera cam = facing_camera(30.0f);
  EXPECT_EQ(planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats.part_snapshots, 4);
  for (int f = 1; f <= 5; ++f) {
    crowd[0].yaw += 1e-4f;  // cos(1e-4) rounds to 1
    const FrameStats st = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
    EXPECT_EQ(st.part_cards, 4) << "frame " << f;
    EXPECT_EQ(st.part_snapshots, 2) << "frame " << f;  // the turning one's two cards
    EXPECT_EQ(st.snapshots, 1) << "frame " << f;
  }
}

// Part cards are planned in chunks on the threads too (a card is a unit of work): the plan must
// not depend on how many threads, while characters turn, windows change size (the camera comes
// closer) and, with a budget, stale cards wait.
TEST(BodyParts, PlanIsTheSameWhateverTheThreads) {
  Model m = pole_model();
  ASSERT_GT(m.body_parts().size(), 1u);
  Crowd crowd(m);
  const int n = 400;
  for (int i = 0; i < n; ++i)
    crowd.add(Character{glm::vec3(1.5f * static_cast<float>(i % 40) - 30.0f, 0, -1.5f * static_cast<float>(i / 40)),
                        0.1f * static_cast<float>(i % 7), 1.0f, 0, 0.013f * static_cast<float>(i), 0.5f});
  ASSERT_GE(static_cast<std::size_t>(n) * m.body_parts().size(), FramePlanner::kParallelCharacters);
  for (int budget : {0, 40}) {
    ImpostorConfig cfg;
    cfg.part_cards = true;
    cfg.cache.refresh_budget = budget;
    cfg.max_pages = 64;
    std::vector<FramePlanner> planners;
    for (unsigned threads : {1u, 2u, 5u}) {
      cfg.planner_threads = threads;
      planners.emplace_back(m, cfg);
    }
    int changes = 0, deferred = 0, threaded = 0;
    for (int f = 0; f < 10; ++f) {
      SceneCamera cam = facing_camera(90.0f - 10.0f * static_cast<float>(std::min(f, 4)));
      for (std::size_t i = 0; i < crowd.size(); i += 3) crowd[i].yaw += 0.03f + 0.01f * static_cast<float>((i * 37) % 5);
      const float t = 0.04f * static_cast<float>(f);
      const FramePlan& ref = planners[0].plan(crowd, cam, t, RenderMode::kImpostor);
      changes += ref.stats.window_refreshes;
      deferred += ref.stats.deferred_refreshes;
      EXPECT_EQ(ref.stats.planner_threads, 1);
      for (std::size_t k = 1; k < planners.size(); ++k) {
        SCOPED_TRACE(testing::Message() << "budget " << budget << ", frame " << f << ", planner " << k);
        const FramePlan& p = planners[k].plan(crowd, cam, t, RenderMode::kImpostor);
        expect_same_plan(p, ref);
        if (k == 2) threaded += p.stats.planner_threads > 1;
      }
      EXPECT_EQ(ref.stats.part_cards, static_cast<int>(ref.billboards.size()));
    }
    EXPECT_GT(changes, 0);
    EXPECT_GT(threaded, 0);
    if (budget > 0) {
      EXPECT_GT(deferred, 0);
    }
  }
}

// With part cards the budget counts cards: the stalest stale cards are refreshed, the others are
// drawn from their old snapshots meanwhile.
TEST(BodyParts, RefreshBudgetCountsCards) {
  Model m = pole_model();
  Crowd crowd(m);
  for (int i = 0; i < 3; ++i) crowd.add(Character{glm::vec3(3.0f * i - 3.0f, 0, 0), 0.0f, 1.0f, 0, 0.0f, 0.0f});
  ImpostorConfig cfg = part_cards_view_only(8.0f);
  cfg.cache.refresh_budget = 1;
  cfg.turn_limb_cards = true;
  FramePlanner planner(m, cfg);
  const SceneCamera cam = facing_camera(30.0f);
  auto s0 = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
  EXPECT_EQ(s0.part_snapshots, 6);  // new: every card, whatever the budget
  // Turning 20, 30, 40 degrees about +Y tilts each root card past 8 degrees (the round arm
  // turns to face the eye instead): three stale characters, the stalest refreshed.
  for (int i = 0; i < 3; ++i) crowd[i].yaw = glm::radians(20.0f + 10.0f * i);
  const FramePlan& a = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor);
  EXPECT_EQ(a.stats.snapshots, 1);
  EXPECT_EQ(a.stats.part_snapshots, 1);
  EXPECT_EQ(a.stats.deferred_refreshes, 2);
  ASSERT_EQ(a.billboards.size(), 6u);
  auto facing = [&](const BillboardGpu& b) {
    const glm::vec3 los = glm::normalize(glm::vec3(b.ta_half) - cam.eye);
    return std::abs(glm::dot(glm::normalize(glm::vec3(b.axis_x)), los));
  };
  EXPECT_LT(facing(a.billboards[4]), 1e-4f);  // character 2's root card: new, facing the eye
  EXPECT_GT(facing(a.billboards[0]), 0.3f);   // character 0's: its old card, turned 20 degrees
  EXPECT_GT(facing(a.billboards[2]), 0.4f);
  const FrameStats b = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
  EXPECT_EQ(b.snapshots, 1);
  EXPECT_EQ(b.deferred_refreshes, 1);
  const FrameStats c = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
  EXPECT_EQ(c.snapshots, 1);
  EXPECT_EQ(c.deferred_refreshes, 0);
  EXPECT_EQ(planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats.snapshots, 0);
  // The posture test at a 0 threshold with the arms moving: all six cards stale, one refreshed;
  // each card keeps the posture it was taken at, so the refreshed one is fresh in the next frame.
  planner.config().cache.view_test = false;
  planner.config().cache.posture_test = true;
  planner.config().cache.posture_threshold = 0.0f;
  for (std::size_t i = 0; i < crowd.size(); ++i) crowd[i].speed = 1.0f;
  const FrameStats d = planner.plan(crowd, cam, 0.25f, RenderMode::kImpostor).stats;
  EXPECT_EQ(d.part_snapshots, 1);
  EXPECT_EQ(d.deferred_refreshes, 5);
  EXPECT_EQ(d.posture_refreshes, 3);
  planner.config().cache.refresh_budget = 0;
  EXPECT_EQ(planner.plan(crowd, cam, 0.25f, RenderMode::kImpostor).stats.part_snapshots, 5);
}

// A stale part card waits for the budget with only its job; end_frame works its card out if the
// budget takes it. With a budget above the demand every stale card is taken, so the cards drawn
// and the snapshots taken are those of the same planner without a budget, which works each card
// out at once (leading cards too: their lead is worked out from the job's eye and velocity).
TEST(BodyParts, DeferredCardsAreTheCardsWorkedOutAtOnce) {
  Model m = pole_model();
  Crowd crowd(m);
  for (int i = 0; i < 12; ++i)
    crowd.add(Character{glm::vec3(1.5f * static_cast<float>(i % 4) - 2.25f, 0, -1.5f * static_cast<float>(i / 4)),
                        0.3f * static_cast<float>(i), 1.0f, 0, 0.05f * static_cast<float>(i), 1.0f + 0.1f * i});
  ImpostorConfig cfg;
  cfg.part_cards = true;
  cfg.cache.posture_threshold = 0.05f;
  cfg.cache.view_threshold_deg = 2.0f;
  FramePlanner now(m, cfg);
  cfg.cache.refresh_budget = 10000;
  FramePlanner deferred(m, cfg);
  // Snapshots by bytes, in one order (the deferred ones go to the end of their level's list).
  auto sorted = [](std::vector<SnapshotGpu> v) {
    std::sort(v.begin(), v.end(), [](const SnapshotGpu& a, const SnapshotGpu& b) { return std::memcmp(&a, &b, sizeof a) < 0; });
    return v;
  };
  int stale = 0;
  for (int f = 0; f < 20; ++f) {
    SCOPED_TRACE(testing::Message() << "frame " << f);
    SceneCamera cam = facing_camera(12.0f);
    cam.eye.x = 0.3f * static_cast<float>(f);  // the camera moves sideways: view refreshes too
    const float t = static_cast<float>(f) / 30.0f;
    const FramePlan& a = now.plan(crowd, cam, t, RenderMode::kImpostor);
    const FramePlan& b = deferred.plan(crowd, cam, t, RenderMode::kImpostor);
    EXPECT_TRUE(bytes_equal(a.billboards, b.billboards));
    ASSERT_EQ(a.snapshots.size(), b.snapshots.size());
    for (std::size_t l = 0; l < a.snapshots.size(); ++l) EXPECT_TRUE(bytes_equal(sorted(a.snapshots[l]), sorted(b.snapshots[l])));
    EXPECT_EQ(a.stats.part_snapshots, b.stats.part_snapshots);
    EXPECT_EQ(a.stats.snapshots, b.stats.snapshots);
    EXPECT_EQ(b.stats.deferred_refreshes, 0);
    if (f > 0) stale += b.stats.part_snapshots;
  }
  EXPECT_GT(stale, 100);  // the deferred path was taken (326 stale cards refreshed after the first frame)
}

TEST(BodyParts, CesiumManHasLimbParts) {
  std::string path = std::string(BB_SHARED_DATA_DIR) + "/gltf/CesiumMan.glb";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data absent: " << path;
  auto m = load_model(path);
  ASSERT_TRUE(m.ok());
  const auto parts = m->body_parts();
  EXPECT_GE(parts.size(), 5u);
  EXPECT_LE(parts.size(), static_cast<std::size_t>(kMaxBodyParts));
  float mass = 0.0f;
  for (const auto& p : parts) mass += p.mass;
  EXPECT_NEAR(mass, 1.0f, 1e-4f);
  // Every triangle of the finest level is in at least one part.
  const PartIndices& pi = m->part_indices(0);
  EXPECT_GE(pi.indices.size(), m->lods[0].indices.size());
}
}  // namespace
}  // namespace bb::runtime

namespace bb::runtime {
namespace {

TEST(FramePlanner, LodFromScreenCoverage) {
  Model m = tiny_model();
  m.lods.push_back(m.lods[0]);
  m.lods[0].screen_coverage = 0.4f;  // finest level while the character covers >= 40 % of the height
  m.lods[1].screen_coverage = 0.0f;
  FramePlanner planner(m);
  EXPECT_EQ(planner.lod_for(500.0f, 1024), 0);
  EXPECT_EQ(planner.lod_for(410.0f, 1024), 0);
  EXPECT_EQ(planner.lod_for(400.0f, 1024), 1);
  EXPECT_EQ(planner.lod_for(3.0f, 1024), 1);
}

}  // namespace
}  // namespace bb::runtime
