// Frame time to completion (plan + draw + glFinish) of the geometry and impostor paths, N
// CesiumMan walkers on a grid all in view, 1280x1024, headless EGL (llvmpipe without a GPU).
// Ratios matter, not absolute numbers: compare the two paths within one run.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>

#include <benchmark/benchmark.h>

#include "bb/runtime/crowd.h"
#include "bb/runtime/headless.h"
#include "bb/runtime/model.h"
#include "bb/runtime/renderer.h"

namespace {

using namespace bb::runtime;

struct World {
  std::unique_ptr<HeadlessContext> ctx;
  std::unique_ptr<Model> model;
  std::unique_ptr<OffscreenTarget> target;
  std::string error;
};

World& world() {
  static World w = [] {
    World x;
    auto c = HeadlessContext::create();
    if (!c) {
      x.error = c.error().message();
      return x;
    }
    x.ctx = std::move(*c);
    auto m = load_model(std::string(BB_SHARED_DATA_DIR) + "/gltf/CesiumMan.glb");
    if (!m) {
      x.error = m.error().message();
      return x;
    }
    x.model = std::make_unique<Model>(std::move(*m));
    x.target = std::move(OffscreenTarget::create(1280, 1024).value());
    std::fprintf(stderr, "GL: %s\n", x.ctx->description().c_str());
    return x;
  }();
  return w;
}

void run(benchmark::State& state, RenderMode mode, float posture, float view_deg, float texels_per_pixel = 2.0f) {
  World& w = world();
  if (!w.error.empty()) {
    state.SkipWithError(w.error.c_str());
    return;
  }
  const int n = static_cast<int>(state.range(0));
  Crowd crowd(*w.model);
  const int side = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(n))));
  for (int i = 0; i < n; ++i)
    crowd.add(Character{glm::vec3((i % side - side / 2) * 1.2f, 0.0f, -(i / side) * 1.2f), 0.7f * i, 1.0f, 0, 0.37f * i,
                        0.8f + 0.4f * ((i * 7919) % 100) / 100.0f});
  ImpostorConfig cfg;
  cfg.max_pages = 64;
  cfg.texels_per_pixel = texels_per_pixel;
  cfg.cache.posture_test = posture >= 0;
  cfg.cache.posture_threshold = posture;
  cfg.cache.view_test = view_deg >= 0;
  cfg.cache.view_threshold_deg = view_deg;
  FramePlanner planner(*w.model, cfg);
  auto renderer = Renderer::create(*w.model, cfg);
  if (!renderer) {
    state.SkipWithError(renderer.error().message().c_str());
    return;
  }
  SceneCamera cam;
  const float extent = side * 1.2f;
  cam.eye = {0.0f, 0.5f * extent + 2.0f, 0.6f * extent + 4.0f};
  cam.target = {0.0f, 0.0f, -0.45f * extent};
  cam.far_plane = 4.0f * extent + 50.0f;
  float t = 0.0f;
  double refresh = 0;
  long frames = 0;
  for (int warm = 0; warm < 2; ++warm, t += 1.0f / 30.0f) {
    w.target->bind(true);
    (*renderer)->draw(planner.plan(crowd, cam, t, mode));
    gpu_finish();
  }
  for (auto _ : state) {
    auto t0 = std::chrono::steady_clock::now();
    w.target->bind(true);
    const FramePlan& p = planner.plan(crowd, cam, t, mode);
    (*renderer)->draw(p);
    gpu_finish();
    state.SetIterationTime(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    refresh += p.stats.refresh_fraction;
    ++frames;
    t += 1.0f / 30.0f;
  }
  state.counters["refresh_fraction"] = frames ? refresh / frames : 0.0;
}

void BM_Geometry(benchmark::State& s) { run(s, RenderMode::kGeometry, -1, -1); }
void BM_ImpostorWorstCase(benchmark::State& s) { run(s, RenderMode::kImpostor, 0.0f, 0.0f); }
// Windows at one texel per pixel (section 4.3; the default is 2, supersampled).
void BM_ImpostorWorstCaseOneTexel(benchmark::State& s) { run(s, RenderMode::kImpostor, 0.0f, 0.0f, 1.0f); }
void BM_ImpostorView8(benchmark::State& s) { run(s, RenderMode::kImpostor, -1, 8.0f); }
void BM_ImpostorPaper(benchmark::State& s) { run(s, RenderMode::kImpostor, 0.4f, 8.0f); }

#define BB_SIZES ->Arg(20)->Arg(200)->Arg(2000)->Arg(10000)->UseManualTime()->Unit(benchmark::kMillisecond)->MinTime(1.0)
BENCHMARK(BM_Geometry) BB_SIZES;
BENCHMARK(BM_ImpostorWorstCase) BB_SIZES;
BENCHMARK(BM_ImpostorWorstCaseOneTexel) BB_SIZES;
BENCHMARK(BM_ImpostorView8) BB_SIZES;
BENCHMARK(BM_ImpostorPaper) BB_SIZES;

}  // namespace

BENCHMARK_MAIN();
