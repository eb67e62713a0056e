#include "bb/exporter/build.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <future>
#include <memory>
#include <thread>

#include "bb/decimate/extremities.h"
#include "bb/mesher/mesh_check.h"
#include "bb/modeler/clearance.h"
#include "bb/modeler/implicit_surface.h"
#include "bb/motion/walk.h"
#include "bb/parallel.h"

namespace bb::exporter {

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

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

// Distance of a level to the skin, metres. Mesh -> skin: from every vertex and face centre, the
// distance to a skin point (an upper bound of the true distance). Skin -> mesh: `skin` points (on
// the iso-surface) to the nearest triangle.
struct SkinError {
  double hausdorff_m = 0, mean_m = 0;
};
SkinError skin_error(const modeler::ImplicitSurface& surface, const mesher::SkinnedMesh& m,
                     const std::vector<glm::vec3>& skin) {
  // Distance from x0 to the skin: first along the gradient line (towards the inside from outside,
  // the outside from inside), in steps of the first-order estimate (at most 2 mm, so thin fingers
  // are not stepped over) and bisection; where that finds no crossing near the first-order
  // estimate (between fingers the gradient may point away from the nearest skin), rays in 162
  // directions marched in 0.5 mm steps take the nearest crossing. Either way the result is the
  // distance to a point of the skin: an upper bound of the true distance, capped at 5 cm. (Plain
  // Newton iterations wander where the field is steep and far from linear.)
  const float kCap = 0.05f;
  auto crossing = [&](const glm::vec3& x0, const glm::vec3& d, float f0, float gl, float limit, float max_step) {
    float lo = 0, f = f0;
    while (lo < limit) {
      float t = std::min(limit, lo + std::clamp(0.8f * std::abs(f) / std::max(gl, 1e-6f), 1e-4f, max_step));
      float ft = surface.field(x0 + t * d) - modeler::kIso;
      if ((ft < 0) != (f0 < 0)) {
        float hi = t;
        for (int it = 0; it < 20; ++it) {
          float mid = 0.5f * (lo + hi);
          float fm = surface.field(x0 + mid * d) - modeler::kIso;
          ((fm < 0) == (f0 < 0) ? lo : hi) = mid;
        }
        return 0.5f * (lo + hi);
      }
      if (t >= limit) break;
      lo = t;
      f = ft;
    }
    return -1.0f;
  };
  static const std::vector<glm::vec3> kDirections = [] {
    std::vector<glm::vec3> v;
    const int n = 162;
    for (int i = 0; i < n; ++i) {  // Fibonacci sphere
      float z = 1 - 2 * (i + 0.5f) / n, r = std::sqrt(1 - z * z), phi = 2.39996323f * i;
      v.push_back({r * std::cos(phi), r * std::sin(phi), z});
    }
    return v;
  }();
  auto to_skin = [&](const glm::vec3& x0) -> double {
    glm::vec3 g;
    const float f0 = surface.field_gradient(x0, &g) - modeler::kIso;
    const float gl = glm::length(g);
    if (std::abs(f0) < 1e-5f) return 0.0;
    float t = gl > 1e-6f ? crossing(x0, (f0 < 0 ? 1.0f : -1.0f) * (g / gl), f0, gl, kCap, 0.002f) : -1.0f;
    const float first_order = gl > 1e-6f ? std::abs(f0) / gl : kCap;
    if (t < 0 || t > 3.0f * first_order + 0.002f) {
      float best = t < 0 ? kCap : t;
      for (const glm::vec3& d : kDirections) {
        float u = crossing(x0, d, f0, 0.0f, best, 0.0005f);
        if (u >= 0) best = std::min(best, u);
      }
      t = best;
    }
    return static_cast<double>(t);
  };
  SkinError e;
  double sum1 = 0;
  size_t n1 = 0;
  auto take = [&](double d) {
    e.hausdorff_m = std::max(e.hausdorff_m, d);
    sum1 += d;
    ++n1;
  };
  for (const auto& p : m.positions) take(to_skin(p));
  for (size_t t = 0; t < m.indices.size(); t += 3)
    take(to_skin((m.positions[m.indices[t]] + m.positions[m.indices[t + 1]] + m.positions[m.indices[t + 2]]) / 3.0f));
  std::vector<double> d(skin.size());
  mesher::distances_to_mesh(m.positions, m.indices, skin, d);
  double sum2 = 0;
  for (double x : d) {
    e.hausdorff_m = std::max(e.hausdorff_m, x);
    sum2 += x;
  }
  e.mean_m = 0.5 * (sum1 / std::max<size_t>(1, n1) + sum2 / std::max<size_t>(1, d.size()));
  return e;
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
  // Levels are checked and measured below, once final (the mesher's own checks and its
  // reference-mesh distances would measure the undecimated levels).
  mo.error_samples = 0;
  mo.check_topology = false;
  auto t0 = Clock::now();
  auto lods = mesher::build_lods(body, mo);
  if (!lods) return lods.error();
  out.times.mesh = since(t0);

  // Decimation, progressive: LOD 0's full-resolution extremities down to a fixed budget, then
  // each middle level starts from the previous level's decimated extremities (the same OpenVDB
  // meshes, seams locked) down to a budget in proportion with its contour triangles. LOD 0's
  // undecimated mesh is kept as the source of the proxies' texture and of the skin samples.
  t0 = Clock::now();
  mesher::SkinnedMesh full_lod0 = (*lods)[0].mesh;
  // The proxies need only the lowest level (never decimated) and the full-resolution
  // extremities: bake them alongside the decimation.
  double proxy_seconds = 0;
  std::future<Result<decimate::Proxies>> proxies_job;
  if (opt.proxies)
    proxies_job = std::async(opt.threads == 1 ? std::launch::deferred : std::launch::async, [&] {
      auto tp = Clock::now();
      auto r = decimate::bake_proxies((*lods)[k - 1].mesh, full_lod0);
      proxy_seconds = since(tp);
      return r;
    });
  // Level 0 also copies its parts out once lightly decimated (restart_mesh): coarser levels'
  // restart candidates start there. Every candidate is measured against full_lod0's parts.
  mesher::SkinnedMesh restart_mesh;
  const mesher::SkinnedMesh* restart = &full_lod0;
  auto reference_cache = decimate::new_reference_cache();  // full_lod0's parts, measured once
  for (int l = 0; l + 1 < k; ++l) {
    mesher::Lod& lod = (*lods)[l];
    if (l > 0) lod.mesh = decimate::with_extremities_of(lod.mesh, (*lods)[l - 1].mesh);
    size_t ext = lod.mesh.extremity_triangle_count();
    size_t body_tris = lod.mesh.triangle_count() - ext;
    size_t budget = l == 0 ? opt.lod0_extremity_triangles : std::max<size_t>(200, body_tris * 45 / 100);
    if (budget == 0 || ext <= budget) continue;
    decimate::ExtremityOptions eo = decimate::extremity_level_options(l, k);
    eo.budget = budget;
    eo.threads = opt.threads;
    eo.reference = &full_lod0;
    eo.restart = restart;
    eo.cache = reference_cache;
    auto dec = decimate::decimate_extremities(lod.mesh, eo, nullptr, l == 0 ? &restart_mesh : nullptr);
    if (l == 0) restart = &restart_mesh;
    if (!dec) return Error{"", "level " + std::to_string(l), "decimation failed: " + dec.error().message()};
    lod.mesh = std::move(*dec);
  }
  out.times.decimate = since(t0);

  // Checks (CGAL) and distances to the skin of the final levels, on all cores.
  t0 = Clock::now();
  std::unique_ptr<modeler::ImplicitSurface> surface;
  std::vector<glm::vec3> skin;
  const double height = body.height();
  if (opt.measure_errors) {
    surface = std::make_unique<modeler::ImplicitSurface>(body, body.skeleton->posture(body.sample_posture));
    // Skin samples: LOD 0's full-resolution vertices that lie on the iso-surface (contour
    // samples, projected OpenVDB vertices), at most ~20,000 of them.
    const auto& fp = full_lod0.positions;
    size_t stride = std::max<size_t>(1, fp.size() / 20000);
    for (size_t i = 0; i < fp.size(); i += stride)
      if (std::abs(surface->field(fp[i]) - modeler::kIso) < 1e-3f) skin.push_back(fp[i]);
  }
  auto finish = [&](int l) {
    mesher::Lod& lod = (*lods)[l];
    auto check = mesher::check_mesh(lod.mesh.positions, lod.mesh.indices, true);
    mesher::LodReport& r = lod.report;
    r.triangles = lod.mesh.triangle_count();
    r.vertices = lod.mesh.positions.size();
    r.extremity_triangles = lod.mesh.extremity_triangle_count();
    r.closed = check.closed && check.connected_components == 1;
    r.manifold = check.manifold;
    r.oriented = check.oriented;
    r.self_intersection_count = check.self_intersections;
    r.self_intersections = check.self_intersections > 0;
    if (surface) {
      SkinError e = skin_error(*surface, lod.mesh, skin);
      r.hausdorff_m = e.hausdorff_m;
      r.errors_measured = true;
      r.mean_m = e.mean_m;
      r.hausdorff_rel = e.hausdorff_m / height;
      r.mean_rel = e.mean_m / height;
    }
  };
  parallel_for(static_cast<std::size_t>(k), opt.threads, [&](std::size_t l) { finish(static_cast<int>(l)); });
  out.times.checks = since(t0);

  // Lowest level: the textured proxies (times.proxies: the baking itself, which overlaps the
  // decimation when more than one thread is allowed). The level was checked and measured above;
  // the proxies only give its extremity triangles vertices of their own with uvs.
  int proxy_texture = -1;
  if (opt.proxies) {
    auto prox = proxies_job.get();
    if (!prox) return Error{"", "proxies", prox.error().message()};
    (*lods)[k - 1].mesh = std::move(prox->mesh);
    proxy_texture = static_cast<int>(out.input.textures.size());
    out.input.textures.push_back(Image{prox->width, prox->height, std::move(prox->rgba)});
  }
  out.times.proxies = proxy_seconds;

  out.input.body = &body;
  for (int l = 0; l < k; ++l) {
    ExportLod e;
    e.mesh = std::move((*lods)[l].mesh);
    e.report = (*lods)[l].report;
    e.screen_coverage = mo.lods[l].screen_coverage;
    out.input.lods.push_back(std::move(e));
  }
  out.input.lods.back().texture = proxy_texture;

  t0 = Clock::now();
  out.walk_arm_abduction_rad = opt.walk_arm_clearance_m < 0 ? modeler::kWalkArmAbductionRad
                                                             : modeler::walk_arm_abduction(body, opt.walk_arm_clearance_m);
  for (float v : opt.walk_speeds) {
    motion::WalkParams wp;
    wp.speed_mps = v;
    wp.arm_abduction_rad = out.walk_arm_abduction_rad;
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
