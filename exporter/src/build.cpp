#include "bb/exporter/build.h"

#include <algorithm>
#include <atomic>
#include <thread>
#include <chrono>

#include "bb/decimate/extremities.h"
#include "bb/mesher/mesh_check.h"
#include "bb/motion/walk.h"

namespace bb::exporter {

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

size_t extremity_triangles(const mesher::SkinnedMesh& m) {
  if (m.part.size() != m.positions.size()) return 0;
  size_t n = 0;
  for (size_t t = 0; t < m.indices.size(); t += 3) {
    uint8_t p = m.part[m.indices[t]];
    n += p != 0 && m.part[m.indices[t + 1]] == p && m.part[m.indices[t + 2]] == p;
  }
  return n;
}

// The default chain resampled to `k` levels: always the finest and the coarsest, then the
// default's middle levels, then copies of the middle levels (k > 4 repeats densities halfway).
std::vector<mesher::LodDensity> chain_of(int k) {
  auto d = mesher::default_lod_chain();
  std::vector<mesher::LodDensity> c;
  if (k <= 2) return {d.front(), d.back()};
  if (k == 3) return {d[0], d[2], d[3]};
  c = d;
  while (static_cast<int>(c.size()) < k) {
    mesher::LodDensity mid = c[c.size() - 2];
    mid.screen_coverage = 0.5f * (c[c.size() - 2].screen_coverage + c.back().screen_coverage);
    c.insert(c.end() - 1, mid);
  }
  return c;
}

}  // namespace

Result<BuildOutput> build_body(const modeler::Body& body, const BuildOptions& opt) {
  auto t_all = Clock::now();
  if (opt.lods < 2 || opt.lods > 8) return Error{"", "--lods", "expected 2 to 8 levels"};
  BuildOutput out;
  mesher::MesherOptions mo;
  mo.lods = chain_of(opt.lods);
  const int k = static_cast<int>(mo.lods.size());
  for (int l = 1; l + 1 < k; ++l) mo.lods[l].vdb_extremities = true;  // decimated below
  if (!opt.measure_errors) mo.error_samples = 0;
  auto t0 = Clock::now();
  auto lods = mesher::build_lods(body, mo);
  if (!lods) return lods.error();
  out.times.mesh = since(t0);

  // LOD 0 and the middle levels: decimate the full-resolution extremities to a budget (LOD 0: a
  // fixed one; then in proportion with the body's contours at that level). LOD 0 keeps the
  // undecimated extremities as the source of the proxies' texture.
  t0 = Clock::now();
  mesher::SkinnedMesh full_extremities = (*lods)[0].mesh;
  // Levels are independent: decimate them on all cores.
  std::vector<std::string> errors(k);
  auto level = [&](int l) {
    mesher::Lod& lod = (*lods)[l];
    size_t ext = extremity_triangles(lod.mesh);
    size_t body_tris = lod.mesh.triangle_count() - ext;
    size_t budget = l == 0 ? opt.lod0_extremity_triangles : std::max<size_t>(200, body_tris * 45 / 100);
    if (budget == 0 || ext <= budget) return;
    decimate::Report rep;
    auto dec = decimate::decimate_extremities(lod.mesh, budget, &rep);
    if (!dec) {
      errors[l] = "level " + std::to_string(l) + ": decimation failed: " + dec.error().message();
      return;
    }
    lod.mesh = std::move(*dec);
    auto check = mesher::check_mesh(lod.mesh.positions, lod.mesh.indices, true);
    lod.report.triangles = lod.mesh.triangle_count();
    lod.report.vertices = lod.mesh.positions.size();
    lod.report.extremity_triangles = extremity_triangles(lod.mesh);
    lod.report.closed = check.closed;
    lod.report.manifold = check.manifold;
    lod.report.oriented = check.oriented;
    lod.report.self_intersection_count = check.self_intersections;
    lod.report.self_intersections = check.self_intersections > 0;
    // Triangle inequality: the decimated mesh is within (its distance to the full one) + (the
    // full one's distance to the skin) of the skin.
    double height = lod.report.hausdorff_rel > 0 ? lod.report.hausdorff_m / lod.report.hausdorff_rel : 0.0;
    lod.report.hausdorff_m += rep.hausdorff_m;
    lod.report.mean_m += rep.mean_m;
    if (height > 0) {
      lod.report.hausdorff_rel = lod.report.hausdorff_m / height;
      lod.report.mean_rel = lod.report.mean_m / height;
    }
  };
  {
    std::vector<std::thread> threads;
    unsigned cores = std::max(1u, std::thread::hardware_concurrency());
    std::atomic<int> next{0};
    auto worker = [&] {
      for (int l; (l = next++) < k - 1;) level(l);
    };
    for (unsigned c = 1; c < std::min<unsigned>(cores, k - 1); ++c) threads.emplace_back(worker);
    worker();
    for (auto& t : threads) t.join();
  }
  for (const auto& e : errors)
    if (!e.empty()) return Error{"", "", e};
  out.times.decimate = since(t0);

  out.input.body = &body;
  for (int l = 0; l < k; ++l) {
    ExportLod e;
    e.mesh = std::move((*lods)[l].mesh);
    e.report = (*lods)[l].report;
    e.screen_coverage = mo.lods[l].screen_coverage;
    out.input.lods.push_back(std::move(e));
  }
  // Lowest level: textured proxies baked from LOD 0.
  t0 = Clock::now();
  if (opt.proxies) {
    auto prox = decimate::bake_proxies(out.input.lods.back().mesh, full_extremities);
    if (!prox) return Error{"", "proxies", prox.error().message()};
    out.input.lods.back().mesh = std::move(prox->mesh);
    out.input.lods.back().texture = 0;
    out.input.textures.push_back(Image{prox->width, prox->height, std::move(prox->rgba)});
  }
  out.times.proxies = since(t0);

  t0 = Clock::now();
  for (float v : opt.walk_speeds) {
    motion::WalkParams wp;
    wp.speed_mps = v;
    auto walk = motion::make_walk(*body.skeleton, wp);
    if (!walk) return walk.error();
    out.input.clips.push_back(std::move(*walk));
  }
  for (const auto& c : opt.extra_clips) out.input.clips.push_back(c);
  out.times.clips = since(t0);

  t0 = Clock::now();
  auto glb = encode_glb(out.input);
  if (!glb) return glb.error();
  out.glb = std::move(*glb);
  out.times.encode = since(t0);
  out.times.total = since(t_all);
  return out;
}

}  // namespace bb::exporter
