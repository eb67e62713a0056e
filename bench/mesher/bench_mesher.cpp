// The whole default body: every level of the default chain, OpenVDB extremities included
// (issue 3 asks for under 300 ms on the 2-core machine), with the per-stage split as counters.
// The error measurement and the CGAL self-intersection checks are benchmarked separately: they
// are a report, not part of building.
#include <benchmark/benchmark.h>

#include "bb/mesher/mesher.h"
#include "bb/modeler/body.h"

namespace {

void report_stages(benchmark::State& state) {
  const auto& t = bb::mesher::last_stage_times();
  state.counters["field_ms"] = 1e3 * t.field;
  state.counters["contours_ms"] = 1e3 * t.contours;
  state.counters["extremities_ms"] = 1e3 * t.extremities;
  state.counters["joining_ms"] = 1e3 * t.joining;
  state.counters["refining_ms"] = 1e3 * t.refining;
  state.counters["skinning_ms"] = 1e3 * t.skinning;
  state.counters["checks_ms"] = 1e3 * t.checks;
  state.counters["errors_ms"] = 1e3 * t.errors;
}

void BM_DefaultChain(benchmark::State& state) {
  bb::mesher::MesherOptions o;
  o.error_samples = 0;
  o.check_topology = false;
  size_t tris = 0;
  for (auto _ : state) {
    auto lods = bb::mesher::build_lods(bb::modeler::default_body(), o);
    if (!lods) state.SkipWithError(lods.error().message().c_str());
    tris = 0;
    for (const auto& l : *lods) tris += l.report.triangles;
  }
  report_stages(state);
  state.counters["triangles"] = double(tris);
}
BENCHMARK(BM_DefaultChain)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// Contour sampling only: all levels with contour-sampled extremities (no OpenVDB), no checks.
void BM_ContourOnlyChain(benchmark::State& state) {
  bb::mesher::MesherOptions o;
  o.lods = bb::mesher::default_lod_chain();
  for (auto& l : o.lods) l.vdb_extremities = false;
  o.error_samples = 0;
  o.check_topology = false;
  for (auto _ : state) {
    auto lods = bb::mesher::build_lods(bb::modeler::default_body(), o);
    if (!lods) state.SkipWithError(lods.error().message().c_str());
  }
  report_stages(state);
}
BENCHMARK(BM_ContourOnlyChain)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// With the report: CGAL checks and distances to the reference skin.
void BM_DefaultChainWithReport(benchmark::State& state) {
  for (auto _ : state) {
    auto lods = bb::mesher::build_lods(bb::modeler::default_body());
    if (!lods) state.SkipWithError(lods.error().message().c_str());
  }
  report_stages(state);
}
BENCHMARK(BM_DefaultChainWithReport)->Unit(benchmark::kMillisecond)->Iterations(2);

}  // namespace

BENCHMARK_MAIN();
