// Per-character CPU cost of the frame update (animation state, culling, both cache tests, LOD and
// window choice) at 10,000 characters of CesiumMan: the paper's "cost per character per frame"; and
// loading each shared model, with the share of it the document checks take.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <benchmark/benchmark.h>

#include "bb/runtime/crowd.h"
#include "bb/runtime/model.h"
#include "gltf_document.h"

namespace {

using namespace bb::runtime;

const Model& model() {
  static std::unique_ptr<Model> m = [] {
    auto r = load_model(std::string(BB_SHARED_DATA_DIR) + "/gltf/CesiumMan.glb");
    if (!r) {
      std::fprintf(stderr, "%s\n", r.error().message().c_str());
      std::exit(1);
    }
    return std::make_unique<Model>(std::move(*r));
  }();
  return *m;
}

// n characters on a grid in front of the camera, all in view, walking at various speeds.
Crowd make_crowd(int n) {
  Crowd c(model());
  int side = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(n))));
  for (int i = 0; i < n; ++i)
    c.add(Character{glm::vec3((i % side - side / 2) * 1.5f, 0.0f, -(i / side) * 1.5f), 0.3f * i, 1.0f, 0,
                    0.37f * i, 0.8f + 0.4f * ((i * 7919) % 100) / 100.0f});
  return c;
}

SceneCamera camera(int n) {
  SceneCamera cam;
  float side = std::ceil(std::sqrt(static_cast<float>(n))) * 1.5f;
  cam.eye = {0.0f, side * 0.8f, side * 0.9f};
  cam.target = {0.0f, 0.0f, -side * 0.4f};
  cam.far_plane = 10.0f * side + 100.0f;
  return cam;
}

// Characters that need no new snapshot: still time and camera, cache warm. `reorder`: the crowd
// reversed before every frame, as a game that sorts its characters (by distance, say) reorders
// it: each keeps its snapshot by its id (FramePlanner::follow_ids moves every slot).
void still(benchmark::State& state, bool reorder) {
  const int n = static_cast<int>(state.range(0));
  Crowd crowd = make_crowd(n);
  FramePlanner planner(model(), ImpostorConfig{.max_pages = 256});
  SceneCamera cam = camera(n);
  planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor);
  int snaps = 0;
  for (auto _ : state) {
    if (reorder) std::reverse(crowd.characters().begin(), crowd.characters().end());
    const FramePlan& p = planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor);
    snaps += p.stats.snapshots;
    benchmark::DoNotOptimize(p.billboards.data());
  }
  state.SetItemsProcessed(state.iterations() * n);
  state.counters["ns_per_character"] =
      benchmark::Counter(static_cast<double>(n) * state.iterations(), benchmark::Counter::kIsRate | benchmark::Counter::kInvert) ;
  state.counters["snapshots"] = snaps;
}
void BM_UpdateNoSnapshot(benchmark::State& state) { still(state, false); }
BENCHMARK(BM_UpdateNoSnapshot)->Arg(10000)->Unit(benchmark::kMicrosecond);
void BM_UpdateReordered(benchmark::State& state) { still(state, true); }
BENCHMARK(BM_UpdateReordered)->Arg(10000)->Unit(benchmark::kMicrosecond);

// Walking at 60 Hz under `cfg`: each frame's plan, the refresh fraction (named `refresh_name`) and,
// with a budget, the refreshes held back.
void walk(benchmark::State& state, const ImpostorConfig& cfg, const char* refresh_name = "refresh_fraction") {
  const int n = static_cast<int>(state.range(0));
  Crowd crowd = make_crowd(n);
  FramePlanner planner(model(), cfg);
  SceneCamera cam = camera(n);
  float t = 0.0f;
  double refresh = 0, deferred = 0;
  for (auto _ : state) {
    t += 1.0f / 60.0f;
    const FramePlan& p = planner.plan(crowd, cam, t, RenderMode::kImpostor);
    refresh += p.stats.refresh_fraction;
    deferred += p.stats.deferred_refreshes;
    benchmark::DoNotOptimize(p.billboards.data());
  }
  state.SetItemsProcessed(state.iterations() * n);
  state.counters["ns_per_character"] =
      benchmark::Counter(static_cast<double>(n) * state.iterations(), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.counters[refresh_name] = refresh / static_cast<double>(state.iterations());
  if (cfg.cache.refresh_budget > 0) state.counters["deferred_per_frame"] = deferred / static_cast<double>(state.iterations());
}

// The paper's thresholds (posture 40 %, view 8 degrees); a few refresh. `budget` > 0: at most that
// many refreshes a frame (the paper's section 7, item 1), the stalest first; the others wait and
// cost only their tests.
ImpostorConfig paper_thresholds(int budget) {
  ImpostorConfig cfg{.max_pages = 256};
  cfg.cache.refresh_budget = budget;
  return cfg;
}
void BM_UpdateWalking(benchmark::State& state) { walk(state, paper_thresholds(0)); }
BENCHMARK(BM_UpdateWalking)->Arg(10000)->Unit(benchmark::kMicrosecond);
// The same with each refreshed impostor's quad fitted on the CPU from its skinned vertices
// (ImpostorConfig::fit_quads_from_vertices) instead of by the GPU's coverage pass.
void BM_UpdateWalkingVertexFit(benchmark::State& state) {
  ImpostorConfig cfg = paper_thresholds(0);
  cfg.fit_quads_from_vertices = true;
  walk(state, cfg);
}
BENCHMARK(BM_UpdateWalkingVertexFit)->Arg(10000)->Unit(benchmark::kMicrosecond);
void BM_UpdateWalkingBudget(benchmark::State& state) { walk(state, paper_thresholds(100)); }
BENCHMARK(BM_UpdateWalkingBudget)->Arg(10000)->Unit(benchmark::kMicrosecond);

// The worst case of the paper's test bed: both thresholds 0, every character refreshed every
// frame (its snapshot camera, window and skinning job planned), on one thread and on the default's.
void BM_UpdateRefreshAll(benchmark::State& state) {
  ImpostorConfig cfg{.max_pages = 256};
  cfg.cache.posture_threshold = 0.0f;
  cfg.cache.view_threshold_deg = 0.0f;
  cfg.planner_threads = static_cast<unsigned>(state.range(1));
  walk(state, cfg);
  state.counters["body_parts"] = static_cast<double>(model().body_parts().size());
}
BENCHMARK(BM_UpdateRefreshAll)->Args({1000, 1})->Args({1000, 0})->Unit(benchmark::kMicrosecond);

// Part cards (one card per body part, the paper's future work), view 8 degrees, posture test off:
// each character's parts tested every frame, about a fifth of the cards refreshed; a card is a
// unit of planning work (FramePlanner::kParallelCharacters), so 1,000 characters of 16 parts are
// planned on every thread.
void BM_UpdatePartCards(benchmark::State& state) {
  ImpostorConfig cfg{.max_pages = 256};
  cfg.part_cards = true;
  cfg.cache.posture_test = false;
  walk(state, cfg, "card_refresh_fraction");
}
BENCHMARK(BM_UpdatePartCards)->Arg(1000)->Unit(benchmark::kMicrosecond);
void BM_UpdatePartCardsVertexFit(benchmark::State& state) {
  ImpostorConfig cfg{.max_pages = 256};
  cfg.part_cards = true;
  cfg.cache.posture_test = false;
  cfg.fit_quads_from_vertices = true;
  walk(state, cfg, "card_refresh_fraction");
}
BENCHMARK(BM_UpdatePartCardsVertexFit)->Arg(1000)->Unit(benchmark::kMicrosecond);

// The geometry path's CPU work: animation state, culling, LOD.
void BM_UpdateGeometry(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  Crowd crowd = make_crowd(n);
  FramePlanner planner(model());
  SceneCamera cam = camera(n);
  float t = 0.0f;
  for (auto _ : state) {
    t += 1.0f / 60.0f;
    const FramePlan& p = planner.plan(crowd, cam, t, RenderMode::kGeometry);
    benchmark::DoNotOptimize(p.geometry.data());
  }
  state.SetItemsProcessed(state.iterations() * n);
  state.counters["ns_per_character"] =
      benchmark::Counter(static_cast<double>(n) * state.iterations(), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_UpdateGeometry)->Arg(10000)->Unit(benchmark::kMicrosecond);

// Loading (parse, validate, build, bake at 60 Hz, bounds, posture pairs) of each shared model.
void BM_Load(benchmark::State& state, const char* file) {
  const std::string path = std::string(BB_SHARED_DATA_DIR) + "/gltf/" + file;
  for (auto _ : state) {
    auto r = load_model(path);
    if (!r) {
      state.SkipWithError(r.error().message().c_str());
      return;
    }
    benchmark::DoNotOptimize(r->lods.data());
  }
}
BENCHMARK_CAPTURE(BM_Load, CesiumMan, "CesiumMan.glb")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Load, Fox, "Fox.glb")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Load, RiggedSimple, "RiggedSimple.gltf")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Load, SimpleSkin, "SimpleSkin.gltf")->Unit(benchmark::kMillisecond);

// The checks of the container and the JSON made before tinygltf reads a file (part of BM_Load above).
void BM_CheckDocument(benchmark::State& state, const char* file) {
  const std::string path = std::string(BB_SHARED_DATA_DIR) + "/gltf/" + file;
  std::ifstream in(path, std::ios::binary);
  const std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const bool glb = path.size() > 4 && path.compare(path.size() - 4, 4, ".glb") == 0;
  for (auto _ : state) {
    bb::Status s = bb::Ok{};
    if (glb) {
      auto layout = bb::runtime::detail::check_glb_container(bytes.data(), bytes.size(), path);
      if (layout) {
        const std::string_view text(reinterpret_cast<const char*>(bytes.data()) + layout->json_at, layout->json_length);
        s = bb::runtime::detail::check_gltf_json(text, path, &*layout);
      } else {
        s = layout.error();
      }
    } else {
      s = bb::runtime::detail::check_gltf_json(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()), path, nullptr);
    }
    if (!s) {
      state.SkipWithError(s.error().message().c_str());
      return;
    }
  }
}
BENCHMARK_CAPTURE(BM_CheckDocument, CesiumMan, "CesiumMan.glb")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_CheckDocument, Fox, "Fox.glb")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_CheckDocument, RiggedSimple, "RiggedSimple.gltf")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_CheckDocument, SimpleSkin, "SimpleSkin.gltf")->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
