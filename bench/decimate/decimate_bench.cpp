// OpenMesh decimation (ours: quadrics + seams locked + skin-weight and normal rules, run as
// `build` runs level 0: decimate_extremities with extremity_level_options(0), i.e. the strict run
// and two restarts from its lightly decimated copy, the one measured nearest to the input kept)
// against meshoptimizer's meshopt_simplify (meshopt_SimplifyLockBorder: the same border vertices
// locked as ours) on the same meshes: the default body's full-resolution OpenVDB head, hands and
// feet, at equal triangle counts. Error is the symmetric Hausdorff and mean distance to the
// original (same sampling for both); time is the simplifier alone (ours: all its candidates and
// their measurements). Then the levels `bodybuilder build` ships: each decimated level's head, hand
// and foot as built (from the previous level or level 0's copy, by measured candidates), against
// meshoptimizer from the full-resolution part to the same triangle count. Prints tables and, with
// --json, one JSON object. --no-rules: ours is one decimate() run with quadrics alone.
// Run: build/bin/bench_decimate [--json] [--no-rules]
#include <chrono>
#include <cstdio>
#include <cstdint>
#include <cstring>
#include <map>
#include <string>

#include <meshoptimizer.h>

#include "bb/decimate/decimate.h"
#include "bb/decimate/extremities.h"
#include "bb/exporter/build.h"
#include "bb/mesher/mesher.h"
#include "bb/modeler/body.h"

using namespace bb;

namespace {

// The triangles whose vertices all belong to `part`, as a standalone mesh; seam = border.
mesher::SkinnedMesh extract(const mesher::SkinnedMesh& m, uint8_t part, std::vector<char>* locked) {
  mesher::SkinnedMesh out;
  std::map<uint32_t, uint32_t> remap;
  for (size_t t = 0; t < m.indices.size(); t += 3) {
    bool in = true;
    for (int k = 0; k < 3; ++k) in &= m.part[m.indices[t + k]] == part;
    if (!in) continue;
    for (int k = 0; k < 3; ++k) {
      uint32_t v = m.indices[t + k];
      auto it = remap.find(v);
      if (it == remap.end()) {
        it = remap.emplace(v, static_cast<uint32_t>(out.positions.size())).first;
        out.append_vertex(m, v);  // position, normal, skin weights, part and seam tags
      }
      out.indices.push_back(it->second);
    }
  }
  // Border vertices (edges used by one triangle) are the seam: locked.
  std::map<std::pair<uint32_t, uint32_t>, int> edges;
  for (size_t t = 0; t < out.indices.size(); t += 3)
    for (int k = 0; k < 3; ++k) {
      uint32_t a = out.indices[t + k], b = out.indices[t + (k + 1) % 3];
      ++edges[{std::min(a, b), std::max(a, b)}];
    }
  locked->assign(out.positions.size(), 0);
  for (const auto& [e, n] : edges)
    if (n == 1) (*locked)[e.first] = (*locked)[e.second] = 1;
  return out;
}

// meshopt_simplify (border locked) of `m` to `target` triangles, as a standalone mesh of the
// vertices it uses (its unused input vertices lie on the original surface and must not count as
// samples of the output).
struct Simplified {
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;
  double seconds = 0;
};
Simplified meshopt_to(const mesher::SkinnedMesh& m, size_t target) {
  std::vector<unsigned> dst(m.indices.size());
  auto t1 = std::chrono::steady_clock::now();
  size_t got = meshopt_simplify(dst.data(), m.indices.data(), m.indices.size(), &m.positions[0].x, m.positions.size(),
                                sizeof(glm::vec3), target * 3, 1.0f, meshopt_SimplifyLockBorder, nullptr);
  Simplified out;
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
  dst.resize(got);
  std::vector<uint32_t> used(m.positions.size(), UINT32_MAX);
  for (unsigned v : dst) {
    if (used[v] == UINT32_MAX) {
      used[v] = static_cast<uint32_t>(out.positions.size());
      out.positions.push_back(m.positions[v]);
    }
    out.indices.push_back(used[v]);
  }
  return out;
}


}  // namespace

int main(int argc, char** argv) {
  bool json = false, rules = true;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--json") == 0) json = true;
    if (std::strcmp(argv[i], "--no-rules") == 0) rules = false;  // quadrics alone, like meshoptimizer
  }
  mesher::MesherOptions mo;
  mo.error_samples = 0;
  mo.check_topology = false;
  auto lods = mesher::build_lods(modeler::default_body(), mo);
  if (!lods) {
    std::fprintf(stderr, "%s\n", lods.error().message().c_str());
    return 1;
  }
  const mesher::SkinnedMesh& full = (*lods)[0].mesh;
  const char* names[] = {"body", "head", "left_hand", "right_hand", "left_foot", "right_foot"};
  if (!json)
    std::printf("%-10s %7s %7s | %11s %11s %9s | %11s %11s %9s\n", "part", "tris", "target", "ours H (mm)",
                "mean (mm)", "ms", "meshopt H", "mean (mm)", "ms");
  std::string out = "{\"rows\":[";
  bool first = true;
  int ours_better_or_equal = 0, rows = 0;
  for (uint8_t part : {1, 2, 4}) {  // head, left hand, left foot (the right side mirrors the left)
    std::vector<char> locked;
    mesher::SkinnedMesh m = extract(full, part, &locked);
    size_t n = m.triangle_count();
    if (n == 0) continue;
    for (double frac : {0.5, 0.25, 0.1, 0.05}) {
      size_t target = static_cast<size_t>(n * frac);
      // Ours as `build` runs it on level 0 (decimate_extremities with level 0's candidates: the
      // part's border locked, a stop at 3 times the target to copy the part out), or with
      // --no-rules a single decimate() run with quadrics alone.
      auto t0 = std::chrono::steady_clock::now();
      Result<mesher::SkinnedMesh> ours = Error{"", "", ""};
      if (rules) {
        decimate::ExtremityOptions eo = decimate::extremity_level_options(0, 4);
        eo.budget = target;
        eo.threads = 1;
        mesher::SkinnedMesh copy;
        ours = decimate::decimate_extremities(m, eo, nullptr, &copy);
      } else {
        decimate::Options opt;
        opt.target_triangles = target;
        opt.locked = locked;
        opt.max_weight_difference = 2.0f;
        opt.max_original_normal_deviation_deg = 180.0f;
        opt.max_normal_deviation_deg = 90.0f;
        ours = decimate::decimate(m, opt);
      }
      double t_ours = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      if (!ours) {
        std::fprintf(stderr, "%s\n", ours.error().message().c_str());
        return 1;
      }
      // meshoptimizer at the triangle count ours reached (equal counts), border locked.
      Simplified mos = meshopt_to(m, ours->indices.size() / 3);
      size_t got = mos.indices.size();
      double t_mo = mos.seconds;
      auto d_ours = decimate::mesh_distance(m.positions, m.indices, ours->positions, ours->indices);
      auto d_mo = decimate::mesh_distance(m.positions, m.indices, mos.positions, mos.indices);
      ++rows;
      ours_better_or_equal += d_ours.hausdorff_m <= d_mo.hausdorff_m * 1.0001;
      if (!json)
        std::printf("%-10s %7zu %7zu | %11.3f %11.3f %9.2f | %11.3f %11.3f %9.2f   (meshopt tris %zu)\n", names[part],
                    n, ours->triangle_count(), d_ours.hausdorff_m * 1e3, d_ours.mean_m * 1e3, t_ours * 1e3,
                    d_mo.hausdorff_m * 1e3, d_mo.mean_m * 1e3, t_mo * 1e3, got / 3);
      char buf[512];
      std::snprintf(buf, sizeof buf,
                    "%s{\"part\":\"%s\",\"triangles\":%zu,\"target\":%zu,\"ours_triangles\":%zu,\"ours_hausdorff_m\":%g,"
                    "\"ours_mean_m\":%g,\"ours_ms\":%g,\"meshopt_triangles\":%zu,\"meshopt_hausdorff_m\":%g,"
                    "\"meshopt_mean_m\":%g,\"meshopt_ms\":%g}",
                    first ? "" : ",", names[part], n, target, ours->triangle_count(), d_ours.hausdorff_m,
                    d_ours.mean_m, t_ours * 1e3, got / 3, d_mo.hausdorff_m, d_mo.mean_m, t_mo * 1e3);
      out += buf;
      first = false;
    }
  }
  out += "],\"ours_hausdorff_no_worse\":" + std::to_string(ours_better_or_equal) + ",\"rows_total\":" + std::to_string(rows);
  if (!json) std::printf("ours no worse (Hausdorff) in %d of %d rows\n", ours_better_or_equal, rows);

  // The levels `bodybuilder build` ships.
  auto built = exporter::build_body(modeler::default_body());
  if (!built) {
    std::fprintf(stderr, "%s\n", built.error().message().c_str());
    return 1;
  }
  const auto& levels = built->input.lods;
  if (!json)
    std::printf("\nshipped levels (ours as built; meshopt from full resolution)\n%-6s %-10s %7s | %11s %11s | %11s %11s\n",
                "level", "part", "tris", "ours H (mm)", "mean (mm)", "meshopt H", "mean (mm)");
  out += ",\"levels\":[";
  int level_rows = 0, level_no_worse = 0, level_mean_no_worse = 0;
  for (size_t l = 0; l + 1 < levels.size(); ++l) {  // the last level has contour-sampled proxies
    for (uint8_t part : {1, 2, 4}) {
      std::vector<char> locked;
      mesher::SkinnedMesh m = extract(full, part, &locked);
      mesher::SkinnedMesh ours = extract(levels[l].mesh, part, &locked);
      if (m.triangle_count() == 0 || ours.triangle_count() == 0) continue;
      Simplified ms = meshopt_to(m, ours.triangle_count());
      auto d_ours = decimate::mesh_distance(m.positions, m.indices, ours.positions, ours.indices);
      auto d_mo = decimate::mesh_distance(m.positions, m.indices, ms.positions, ms.indices);
      ++level_rows;
      level_no_worse += d_ours.hausdorff_m <= d_mo.hausdorff_m * 1.0001;
      level_mean_no_worse += d_ours.mean_m <= d_mo.mean_m * 1.0001;
      if (!json)
        std::printf("%-6zu %-10s %7zu | %11.3f %11.3f | %11.3f %11.3f   (meshopt tris %zu)\n", l, names[part],
                    ours.triangle_count(), d_ours.hausdorff_m * 1e3, d_ours.mean_m * 1e3, d_mo.hausdorff_m * 1e3,
                    d_mo.mean_m * 1e3, ms.indices.size() / 3);
      char buf[400];
      std::snprintf(buf, sizeof buf,
                    "%s{\"level\":%zu,\"part\":\"%s\",\"triangles\":%zu,\"ours_hausdorff_m\":%g,\"ours_mean_m\":%g,"
                    "\"meshopt_triangles\":%zu,\"meshopt_hausdorff_m\":%g,\"meshopt_mean_m\":%g}",
                    level_rows > 1 ? "," : "", l, names[part], ours.triangle_count(), d_ours.hausdorff_m, d_ours.mean_m,
                    ms.indices.size() / 3, d_mo.hausdorff_m, d_mo.mean_m);
      out += buf;
    }
  }
  out += "],\"levels_hausdorff_no_worse\":" + std::to_string(level_no_worse) + ",\"levels_mean_no_worse\":" +
         std::to_string(level_mean_no_worse) + ",\"level_rows\":" + std::to_string(level_rows) + "}";
  if (json) std::printf("%s\n", out.c_str());
  else
    std::printf("shipped levels: ours no worse in %d of %d rows (Hausdorff), %d of %d (mean)\n", level_no_worse,
                level_rows, level_mean_no_worse, level_rows);
  return 0;
}
