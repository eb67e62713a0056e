// The per-frame path allocates nothing: after warm-up frames, FramePlanner::plan and Renderer::draw
// make no heap allocation (global operator new is counted in this test binary).
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <new>

#include <gtest/gtest.h>

#include "bb/runtime/crowd.h"
#include "bb/runtime/renderer.h"
#include "gl_context.h"

namespace {
std::atomic<long> g_allocations{0};
}

// Sanitizers replace the allocator themselves: count only in ordinary builds.
#if defined(__SANITIZE_ADDRESS__)
#define BB_COUNT_ALLOCATIONS 0
#else
#define BB_COUNT_ALLOCATIONS 1
void* operator new(std::size_t n) {
  ++g_allocations;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) {
  ++g_allocations;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
#endif

namespace bb::runtime {
namespace {

// `churn`: every frame one character leaves from the middle of the crowd (Crowd::remove) and a new
// one arrives, as a game's do, so the planner moves slots with their ids (FramePlanner::follow_ids).
void expect_no_allocation(bool part_cards, bool churn = false) {
  if (!BB_COUNT_ALLOCATIONS) GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  std::string path = std::string(BB_SHARED_DATA_DIR) + "/gltf/CesiumMan.glb";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data absent: " << path;
  auto m = load_model(path);
  ASSERT_TRUE(m.ok());
  Crowd crowd(*m);
  for (int i = 0; i < 500; ++i)
    crowd.add(Character{glm::vec3((i % 25) * 1.5f - 18.0f, 0, -(i / 25) * 1.5f), 0.1f * i, 1.0f, 0, 0.05f * i, 1.0f});
  ImpostorConfig cfg;
  cfg.part_cards = part_cards;
  cfg.max_pages = part_cards ? 256 : cfg.max_pages;
  FramePlanner planner(*m, cfg);
  SceneCamera cam;
  cam.eye = {0, 20, 25};
  cam.target = {0, 0, -15};
  float t = 0.0f;
  auto come_and_go = [&](int f) {
    if (!churn) return;
    Character c = crowd[static_cast<std::size_t>(37 * f) % crowd.size()];
    crowd.remove(static_cast<std::size_t>(37 * f) % crowd.size());
    c.id = 0;  // a new character where the other stood
    crowd.add(c);
  };
  for (int f = 0; f < 5; ++f, t += 1.0f / 60.0f) {
    come_and_go(f);
    planner.plan(crowd, cam, t, RenderMode::kImpostor);
    planner.plan(crowd, cam, t, RenderMode::kGeometry);
  }
  const long before = g_allocations.load();
  int snapshots = 0;
  for (int f = 0; f < 60; ++f, t += 1.0f / 60.0f) {
    come_and_go(f);
    cam.eye.x = 0.05f * f;  // a moving camera: windows refresh, none is reallocated
    snapshots += planner.plan(crowd, cam, t, RenderMode::kImpostor).stats.snapshots;
    planner.plan(crowd, cam, t, RenderMode::kGeometry);
  }
  EXPECT_EQ(g_allocations.load() - before, 0);
  EXPECT_GT(snapshots, 0);
}

TEST(PerFrame, PlannerAllocatesNothingAfterWarmUp) { expect_no_allocation(false); }
TEST(PerFrame, PlannerWithPartCardsAllocatesNothingAfterWarmUp) { expect_no_allocation(true); }

// Renderer::draw after warm-up allocates nothing of ours either (the driver's own allocations, in C,
// are not counted): 60 walkers planned and drawn as impostors and as geometry, the camera moving.
TEST(PerFrame, RendererAllocatesNothingAfterWarmUp) {
  if (!BB_COUNT_ALLOCATIONS) GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  REQUIRE_GL();
  std::string path = std::string(BB_SHARED_DATA_DIR) + "/gltf/CesiumMan.glb";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data absent: " << path;
  auto m = load_model(path);
  ASSERT_TRUE(m.ok());
  Crowd crowd(*m);
  for (int i = 0; i < 60; ++i)
    crowd.add(Character{glm::vec3((i % 10) * 1.5f - 7.5f, 0, -(i / 10) * 1.5f), 0.1f * i, 1.0f, 0, 0.05f * i, 1.0f});
  ImpostorConfig cfg;
  FramePlanner planner(*m, cfg);
  auto renderer = Renderer::create(*m, cfg);
  ASSERT_TRUE(renderer.ok()) << renderer.error().message();
  auto target = OffscreenTarget::create(640, 512, 4);
  ASSERT_TRUE(target.ok());
  SceneCamera cam;
  cam.width = 640;
  cam.height = 512;
  cam.eye = {0, 10, 14};
  cam.target = {0, 0, -4};
  float t = 0.0f;
  auto frame = [&](int f) {
    cam.eye.x = 0.05f * f;
    for (RenderMode mode : {RenderMode::kImpostor, RenderMode::kGeometry}) {
      (*target)->bind(true);
      (*renderer)->draw(planner.plan(crowd, cam, t, mode));
    }
    gpu_finish();
    t += 1.0f / 60.0f;
  };
  for (int f = 0; f < 4; ++f) frame(f);
  const long before = g_allocations.load();
  for (int f = 4; f < 16; ++f) frame(f);
  EXPECT_EQ(g_allocations.load() - before, 0);
}
TEST(PerFrame, PlannerAllocatesNothingAsCharactersComeAndGo) {
  expect_no_allocation(false, true);
  expect_no_allocation(true, true);
}

// A full atlas takes windows back from the characters out of view (FramePlanner::reclaim) without
// allocating either: a camera turning round inside a ring of 200 walkers with room for a quarter of
// them, whole impostors and part cards, once warm (a first turn).
TEST(PerFrame, PlannerTakingWindowsBackAllocatesNothingAfterWarmUp) {
  if (!BB_COUNT_ALLOCATIONS) GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  std::string path = std::string(BB_SHARED_DATA_DIR) + "/gltf/CesiumMan.glb";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data absent: " << path;
  auto m = load_model(path);
  ASSERT_TRUE(m.ok());
  Crowd crowd(*m);
  for (int i = 0; i < 200; ++i) {
    const float a = 6.2831853f * static_cast<float>(i) / 200.0f;
    crowd.add(Character{glm::vec3(8.0f * std::sin(a), 0, -8.0f * std::cos(a)), a + 3.14159f, 1.0f, 0, 0.05f * i, 1.0f});
  }
  for (bool part_cards : {false, true}) {
    ImpostorConfig cfg;
    cfg.part_cards = part_cards;
    cfg.max_pages = part_cards ? 24 : 4;
    FramePlanner planner(*m, cfg);
    auto turn = [&](int f) {
      const float a = 0.1f * static_cast<float>(f);
      SceneCamera cam;
      cam.eye = {0, 1.0f, 0};
      cam.target = {std::sin(a), 0.9f, -std::cos(a)};
      return planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor).stats;
    };
    int reclaimed = 0;
    for (int f = 0; f < 63; ++f) reclaimed += turn(f).atlas_reclaimed;  // a full turn
    EXPECT_GT(reclaimed, 0) << "part cards " << part_cards;
    const long before = g_allocations.load();
    reclaimed = 0;
    for (int f = 63; f < 126; ++f) reclaimed += turn(f).atlas_reclaimed;
    EXPECT_EQ(g_allocations.load() - before, 0) << "part cards " << part_cards;
    EXPECT_GT(reclaimed, 0) << "part cards " << part_cards;
  }
}

}  // namespace
}  // namespace bb::runtime
