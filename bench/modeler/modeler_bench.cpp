// Field evaluations and outermost intersections per second on the default body (one core).
// Run: build/bin/bench_modeler
#include <cmath>
#include <random>

#include <benchmark/benchmark.h>

#include "bb/modeler/implicit_surface.h"

using namespace bb::modeler;

namespace {

const ImplicitSurface& surface() {
  static ImplicitSurface s(default_body(), default_body().skeleton->posture("bind"));
  return s;
}

// Points spread over the body's box; most near the skin the way the mesher queries it.
std::vector<glm::vec3> points(size_t n) {
  const auto& b = surface().bounds();
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0, 1);
  std::vector<glm::vec3> p(n);
  for (auto& x : p) x = b.min + glm::vec3(u(rng), u(rng), u(rng)) * b.size();
  return p;
}

void BM_Field(benchmark::State& state) {
  const auto& s = surface();
  auto p = points(4096);
  size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(s.field(p[i++ & 4095]));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_Field);

// Points within 2 cm of the skin, where the mesher and OpenVDB sampling spend their queries.
std::vector<glm::vec3> near_skin_points(size_t n) {
  const auto& s = surface();
  auto p = points(n * 20);
  std::vector<glm::vec3> out;
  for (const auto& x : p) {
    glm::vec3 g;
    float f = s.field_gradient(x, &g);
    float gl = glm::length(g);
    if (gl > 1e-3f && std::abs(f - kIso) / gl < 0.02f) out.push_back(x);
    if (out.size() == n) break;
  }
  return out;
}

void BM_FieldNearSkin(benchmark::State& state) {
  const auto& s = surface();
  auto p = near_skin_points(4096);
  size_t i = 0, n = p.size();
  for (auto _ : state) {
    benchmark::DoNotOptimize(s.field(p[i++ % n]));
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["points"] = static_cast<double>(n);
}
BENCHMARK(BM_FieldNearSkin);

void BM_FieldGradient(benchmark::State& state) {
  const auto& s = surface();
  auto p = points(4096);
  size_t i = 0;
  glm::vec3 g;
  for (auto _ : state) {
    benchmark::DoNotOptimize(s.field_gradient(p[i++ & 4095], &g));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_FieldGradient);

// Star-shaped rays as the mesher casts them: from points on the limb links, perpendicular to
// the link, 0.5 m long.
void BM_OutermostIntersection(benchmark::State& state) {
  const auto& s = surface();
  const Skeleton& sk = *default_body().skeleton;
  const auto& w = s.joint_transforms();
  struct Ray { glm::vec3 o, d; };
  std::vector<Ray> rays;
  for (size_t j = 1; j < sk.joints().size(); ++j) {
    int parent = sk.joints()[j].parent;
    glm::vec3 a(w[parent][3]), b(w[j][3]);
    glm::vec3 axis = b - a;
    if (glm::length(axis) < 1e-4f) continue;
    axis = glm::normalize(axis);
    glm::vec3 side = glm::normalize(glm::cross(axis, std::abs(axis.y) < 0.9f ? glm::vec3(0, 1, 0) : glm::vec3(1, 0, 0)));
    glm::vec3 up = glm::cross(axis, side);
    for (int c = 0; c < 4; ++c)
      for (int k = 0; k < 16; ++k) {
        float ang = k * 6.2831853f / 16;
        rays.push_back({glm::mix(a, b, (c + 0.5f) / 4), std::cos(ang) * side + std::sin(ang) * up});
      }
  }
  size_t i = 0, hits = 0;
  for (auto _ : state) {
    const Ray& r = rays[i++ % rays.size()];
    auto t = s.outermost_intersection(r.o, r.d, 0.5f);
    hits += t.has_value();
    benchmark::DoNotOptimize(t);
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["hit_fraction"] = static_cast<double>(hits) / state.iterations();
  state.counters["rays"] = static_cast<double>(rays.size());
}
BENCHMARK(BM_OutermostIntersection);

void BM_BuildSurface(benchmark::State& state) {
  const Body& b = default_body();
  Posture p = b.skeleton->posture("bind");
  for (auto _ : state) {
    ImplicitSurface s(b, p);
    benchmark::DoNotOptimize(s.bounds());
  }
}
BENCHMARK(BM_BuildSurface);

}  // namespace

BENCHMARK_MAIN();
