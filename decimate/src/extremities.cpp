#include "bb/decimate/extremities.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <memory>
#include <thread>
#include <unordered_map>

#include "triangle_grid.h"
#include "bb/mesher/mesh_check.h"
#include "bb/parallel.h"

namespace bb::decimate {

namespace {

// The border of each extremity part (1..7) of `m`: its edges used by one of the part's triangles,
// each as the bit patterns of its two end positions (smaller first), sorted.
using PositionEdge = std::array<uint32_t, 6>;
std::vector<std::vector<PositionEdge>> part_borders(const mesher::SkinnedMesh& m) {
  std::vector<std::vector<PositionEdge>> all(8);
  for (size_t t = 0; t < m.indices.size(); t += 3) {
    const uint8_t p = m.extremity_part(t);
    if (p == 0 || p >= 8) continue;
    for (int k = 0; k < 3; ++k) {
      std::array<uint32_t, 3> a, b;
      std::memcpy(a.data(), &m.positions[m.indices[t + k]], 12);
      std::memcpy(b.data(), &m.positions[m.indices[t + (k + 1) % 3]], 12);
      if (b < a) std::swap(a, b);
      all[p].push_back({a[0], a[1], a[2], b[0], b[1], b[2]});
    }
  }
  for (auto& e : all) {
    std::sort(e.begin(), e.end());
    std::vector<PositionEdge> border;
    for (size_t i = 0; i < e.size();) {
      size_t j = i;
      while (j < e.size() && e[j] == e[i]) ++j;
      if ((j - i) % 2 == 1) border.push_back(e[i]);
      i = j;
    }
    e = std::move(border);
  }
  return all;
}

}  // namespace

mesher::SkinnedMesh with_extremities_of(const mesher::SkinnedMesh& level, const mesher::SkinnedMesh& from) {
  // A part of `from` replaces `level`'s only where its border is `level`'s part's border: where
  // the union cut into an extremity (a wide shoulder's cap through the neck, which sends a level
  // to the full union) the cut part fits no other level's zipper, and `level` keeps its own.
  const auto level_borders = part_borders(level), from_borders = part_borders(from);
  std::array<bool, 8> take{};
  for (int p = 1; p < 8; ++p) take[p] = level_borders[p] == from_borders[p];
  mesher::SkinnedMesh out;
  auto key = [](const glm::vec3& p) {
    uint32_t b[3];
    std::memcpy(b, &p, 12);
    return (uint64_t(b[0]) * 0x9E3779B97F4A7C15ull) ^ (uint64_t(b[1]) * 0xC2B2AE3D27D4EB4Full) ^ b[2];
  };
  std::unordered_multimap<uint64_t, uint32_t> index;
  auto add = [&](const mesher::SkinnedMesh& m, uint32_t i) -> uint32_t {
    const glm::vec3& p = m.positions[i];
    auto range = index.equal_range(key(p));
    for (auto it = range.first; it != range.second; ++it)
      if (out.positions[it->second] == p) return it->second;
    uint32_t n = out.append_vertex(m, i);
    index.emplace(key(p), n);
    return n;
  };
  for (size_t t = 0; t < level.indices.size(); t += 3) {
    const uint8_t p = level.extremity_part(t);
    if (p == 0 || p >= 8 || !take[p])
      for (int k = 0; k < 3; ++k) out.indices.push_back(add(level, level.indices[t + k]));
  }
  for (size_t t = 0; t < from.indices.size(); t += 3) {
    const uint8_t p = from.extremity_part(t);
    if (p != 0 && p < 8 && take[p])
      for (int k = 0; k < 3; ++k) out.indices.push_back(add(from, from.indices[t + k]));
  }
  return out;
}

namespace {

// A part's own locked vertices: on its border (shared with the rest of the body) or seams.
std::vector<char> border_or_seam(const mesher::SkinnedMesh& m) {
  std::vector<char> locked(m.positions.size(), 0);
  std::unordered_map<uint64_t, int> edges;
  for (size_t t = 0; t < m.indices.size(); t += 3)
    for (int k = 0; k < 3; ++k) {
      uint32_t a = m.indices[t + k], b = m.indices[t + (k + 1) % 3];
      ++edges[(uint64_t(std::min(a, b)) << 32) | std::max(a, b)];
    }
  for (const auto& [e, n] : edges)
    if (n == 1) locked[e >> 32] = locked[e & 0xffffffffu] = 1;
  for (size_t i = 0; i < m.seam.size(); ++i)
    if (m.seam[i]) locked[i] = 1;
  return locked;
}

// Each extremity part of `mesh` as a sub-mesh (index: the part tag, 1..7), its vertices shared with
// any other triangle (seams, zippers) or tagged seam locked.
struct PartMesh {
  mesher::SkinnedMesh sub;
  std::vector<char> locked;
};
std::vector<PartMesh> split_parts(const mesher::SkinnedMesh& mesh) {
  const size_t nv = mesh.positions.size();
  std::vector<std::vector<size_t>> tris(8);
  std::vector<char> shared(nv, 0);
  for (size_t t = 0; t < mesh.indices.size(); t += 3) {
    uint8_t p = mesh.extremity_part(t);
    if (p != 0 && p < 8) tris[p].push_back(t);
    else
      for (int k = 0; k < 3; ++k) shared[mesh.indices[t + k]] = 1;
  }
  std::vector<PartMesh> parts(8);
  std::vector<int> map(nv, -1);
  for (int p = 1; p < 8; ++p) {
    PartMesh& pm = parts[p];
    auto add = [&](uint32_t i) {
      if (map[i] < 0) {
        map[i] = static_cast<int>(pm.sub.append_vertex(mesh, i));
        pm.locked.push_back(shared[i] || mesh.seam[i] != 0);  // border vertices: below
      }
      return static_cast<uint32_t>(map[i]);
    };
    for (size_t t : tris[p])
      for (int k = 0; k < 3; ++k) pm.sub.indices.push_back(add(mesh.indices[t + k]));
    for (size_t t : tris[p])
      for (int k = 0; k < 3; ++k) map[mesh.indices[t + k]] = -1;
    std::vector<char> own = border_or_seam(pm.sub);
    for (size_t i = 0; i < own.size(); ++i) pm.locked[i] |= own[i];
  }
  return parts;
}

}  // namespace

struct ReferenceCache {
  const mesher::SkinnedMesh* reference = nullptr;
  size_t vertices = 0, triangles = 0;  // of the reference it was built from
  std::vector<PartMesh> parts;
  std::vector<std::unique_ptr<ReferenceDistance>> distance;  // per part, built on first use
};

std::shared_ptr<ReferenceCache> new_reference_cache() { return std::make_shared<ReferenceCache>(); }

Result<mesher::SkinnedMesh> decimate_extremities(const mesher::SkinnedMesh& mesh, size_t budget, Report* report,
                                                 unsigned threads) {
  ExtremityOptions o;
  o.budget = budget;
  o.threads = threads;
  ExtremityReport er;
  auto r = decimate_extremities(mesh, o, report ? &er : nullptr);
  if (r && report) *report = er.report;
  return r;
}

Result<mesher::SkinnedMesh> decimate_extremities(const mesher::SkinnedMesh& mesh, const ExtremityOptions& opt,
                                                 ExtremityReport* report, mesher::SkinnedMesh* snapshot) {
  const size_t nv = mesh.positions.size();
  if (mesh.part.size() != nv || mesh.seam.size() != nv)
    return Error{"", "", "the mesh has no part/seam tags: cannot tell extremities from the body"};
  if (opt.candidates.empty()) return Error{"", "candidates", "at least one candidate expected"};
  const mesher::SkinnedMesh* reference = opt.reference;
  const mesher::SkinnedMesh* restart = opt.restart ? opt.restart : opt.reference;
  for (const mesher::SkinnedMesh* m : {reference, restart})
    if (m && (m->part.size() != m->positions.size() || m->seam.size() != m->positions.size()))
      return Error{"", "reference", "the reference or restart mesh has no part/seam tags"};
  const size_t total = mesh.indices.size() / 3;
  const size_t extremity = mesh.extremity_triangle_count();
  if (extremity <= opt.budget) {
    if (report) *report = ExtremityReport{Report{total, total, nv, 0, 0, 0, 0}, {}, {}, {}, {}, {}};
    if (snapshot) *snapshot = mesh;
    return mesh;
  }
  // One sub-mesh per part, decimated to its share of the budget once per candidate, parts in
  // parallel; the candidate nearest to the reference's part is kept.
  std::vector<PartMesh> own = split_parts(mesh);
  // The reference's parts and their measurements: from the cache when it was built from this
  // reference, else built here (and kept in the cache when there is one).
  std::shared_ptr<ReferenceCache> cache = opt.cache ? opt.cache : new_reference_cache();
  if (reference && (cache->reference != reference || cache->vertices != reference->positions.size() ||
                    cache->triangles != reference->indices.size())) {
    cache->reference = reference;
    cache->vertices = reference->positions.size();
    cache->triangles = reference->indices.size();
    cache->parts = split_parts(*reference);
    cache->distance.clear();
  }
  if (!reference) cache = new_reference_cache();  // measured against `mesh` itself, not kept
  cache->distance.resize(8);
  const std::vector<PartMesh>& ref = cache->parts;
  std::vector<PartMesh> restart_parts;
  if (restart && restart != reference) restart_parts = split_parts(*restart);
  const std::vector<PartMesh>& again = restart == reference ? ref : restart_parts;
  // A restart part replaces this mesh's only where it meets the same zipper (see
  // with_extremities_of: a part the union cut into fits only its own level).
  std::array<bool, 8> restart_fits{};
  if (restart) {
    const auto mine = part_borders(mesh), theirs = restart == &mesh ? mine : part_borders(*restart);
    for (int p = 1; p < 8; ++p) restart_fits[p] = mine[p] == theirs[p];
  }
  const bool measure = opt.candidates.size() > 1 || report;
  struct Job {
    uint8_t part = 0;
    size_t target = 0;
    Result<mesher::SkinnedMesh> result = Error{"", "", "not run"};
    size_t chosen = 0;
    Distance distance;
    size_t self_intersections = 0;  // of the kept candidate's part alone
    mesher::SkinnedMesh snapshot;
  };
  std::vector<Job> jobs;
  for (int p = 1; p < 8; ++p) {
    size_t n = own[p].sub.triangle_count();
    if (n == 0) continue;
    Job& j = jobs.emplace_back();
    j.part = static_cast<uint8_t>(p);
    j.target = std::min(n, std::max<size_t>(1, opt.budget * n / extremity));
  }
  auto run = [&](Job& j) {
    const PartMesh& mine = own[j.part];
    const bool has_ref = reference && ref[j.part].sub.triangle_count() > 0;
    const bool has_restart = restart && restart_fits[j.part] && again[j.part].sub.triangle_count() > 0;
    const PartMesh& against = has_ref ? ref[j.part] : mine;
    std::unique_ptr<ReferenceDistance>& rd = cache->distance[j.part];  // one job per part
    if (measure && !rd) rd = std::make_unique<ReferenceDistance>(against.sub.positions, against.sub.indices);
    // The nearest candidate without self-intersections is kept: the decimator's rules are local
    // (normals of the faces that move), so a collapse may still push a fingertip or a finger's side
    // through a neighbouring finger, and the candidate nearest by Hausdorff can be such a one. A
    // candidate is checked (CGAL, the part alone) only when it would be kept; `best` bounds the
    // measurements by the clean ones only. Where every candidate intersects, the one with the fewest
    // intersections (then the nearest) is kept.
    double best = 1e30;
    bool clean = false;
    size_t fewest = SIZE_MAX;
    double fallback = 1e30;
    PartMesh snap;
    for (size_t c = 0; c < opt.candidates.size(); ++c) {
      const Candidate& cand = opt.candidates[c];
      // Restart candidates start from this call's snapshot when the first candidate took one.
      const PartMesh& in = cand.restart && snap.sub.triangle_count() > 0 ? snap
                           : cand.restart && has_restart              ? again[j.part]
                                                                      : mine;
      Options o;
      o.target_triangles = j.target;
      o.locked = in.locked;
      o.member_k = cand.member_k;
      o.max_weight_difference = cand.max_weight_difference;
      if (c == 0 && snapshot && opt.snapshot_factor > 1) {
        o.snapshot_triangles = static_cast<size_t>(opt.snapshot_factor * static_cast<double>(j.target));
        j.snapshot = in.sub;  // kept when the part has no more than that
      }
      auto r = decimate(in.sub, o, nullptr, c == 0 && snapshot ? &j.snapshot : nullptr);
      if (c == 0 && snapshot && opt.snapshot_factor > 1 && opt.snapshot_restarts) {
        snap.sub = j.snapshot;
        snap.locked = border_or_seam(snap.sub);
      }
      if (!r) {
        j.result = r.error();
        return;
      }
      if (!measure) {
        j.result = std::move(r);
        return;
      }
      auto m = rd->measure(r->positions, r->indices, best, report != nullptr);
      if (!m.complete || !(m.distance.hausdorff_m < best || (c == 0 && !clean))) continue;
      const size_t crossings = mesher::check_mesh(r->positions, r->indices, true).self_intersections;
      if (crossings == 0) {
        clean = true;
        best = m.distance.hausdorff_m;
      } else if (clean || crossings > fewest || (crossings == fewest && !(m.distance.hausdorff_m < fallback))) {
        continue;
      } else {
        fewest = crossings;
        fallback = m.distance.hausdorff_m;
      }
      j.result = std::move(r);
      j.chosen = c;
      j.distance = m.distance;
      j.self_intersections = crossings;
    }
  };
  parallel_for(jobs.size(), opt.threads, [&](std::size_t i) { run(jobs[i]); });
  for (const Job& j : jobs)
    if (!j.result) return j.result.error();
  // Reassembly: the body and zipper triangles as they were, then the decimated parts.
  mesher::SkinnedMesh parts;
  for (const Job& j : jobs) {
    const mesher::SkinnedMesh& r = *j.result;
    const uint32_t base = static_cast<uint32_t>(parts.positions.size());
    for (uint32_t i = 0; i < r.positions.size(); ++i) parts.append_vertex(r, i);
    for (uint32_t i : r.indices) parts.indices.push_back(base + i);
  }
  mesher::SkinnedMesh out = with_extremities_of(mesh, parts);
  if (snapshot && !(opt.snapshot_factor > 1)) *snapshot = out;
  if (snapshot && opt.snapshot_factor > 1) {
    mesher::SkinnedMesh copies;
    for (const Job& j : jobs) {
      const uint32_t base = static_cast<uint32_t>(copies.positions.size());
      for (uint32_t i = 0; i < j.snapshot.positions.size(); ++i) copies.append_vertex(j.snapshot, i);
      for (uint32_t i : j.snapshot.indices) copies.indices.push_back(base + i);
    }
    *snapshot = with_extremities_of(mesh, copies);
  }
  if (report) {
    Report& rep = report->report;
    rep = Report{};
    rep.triangles_before = total;
    rep.triangles_after = out.indices.size() / 3;
    rep.vertices_after = out.positions.size();
    for (const Job& j : jobs) {
      for (char l : own[j.part].locked) rep.locked_vertices += l != 0;
      report->parts.push_back(j.part);
      report->chosen.push_back(j.chosen);
      report->hausdorff_m.push_back(j.distance.hausdorff_m);
      report->mean_m.push_back(j.distance.mean_m);
      report->self_intersections.push_back(j.self_intersections);
    }
    Distance d = mesh_distance(mesh.positions, mesh.indices, out.positions, out.indices);
    rep.hausdorff_m = d.hausdorff_m;
    rep.mean_m = d.mean_m;
  }
  return out;
}

ExtremityOptions extremity_level_options(int level, int levels) {
  ExtremityOptions o;
  const Candidate strict{false, 1.0, 0.6f};
  if (level == 0) {
    // From full resolution: the strict run (which also copies each part out after its first pass
    // at or below twice the target), then from that copy without, with a wider and with the same
    // member rule (the copy's quadrics start afresh).
    o.candidates = {strict, Candidate{true, 0.0, 0.6f}, Candidate{true, 2.0, 0.6f}, Candidate{true, 1.0, 0.6f}};
    o.snapshot_factor = 2;
    o.snapshot_restarts = true;
  } else if (level + 2 < levels) {
    // Middle levels: from the previous level, or from level 0's copy with the skin-weight rule
    // loosened to 1.0.
    o.candidates = {strict, Candidate{true, 1.0, 1.0f}, Candidate{true, 0.0, 1.0f}};
  } else {
    // The coarsest decimated level: also from the previous level with the loosened rule.
    o.candidates = {strict, Candidate{false, 1.0, 1.0f}, Candidate{true, 1.0, 1.0f}};
  }
  return o;
}

Result<Proxies> bake_proxies(const mesher::SkinnedMesh& coarse, const mesher::SkinnedMesh& detailed,
                             const ProxyOptions& o) {
  const size_t nv = coarse.positions.size();
  if (coarse.part.size() != nv || detailed.part.size() != detailed.positions.size())
    return Error{"", "", "meshes without part tags: cannot find the extremities"};
  if (o.texture_size < 16) return Error{"", "", "texture size must be at least 16 pixels"};
  // Detailed extremity triangles, per part, in nearest-point grids.
  std::vector<std::vector<uint32_t>> det_idx(8);
  for (size_t t = 0; t < detailed.indices.size(); t += 3) {
    uint8_t p = detailed.extremity_part(t);
    if (p && p < 8) det_idx[p].insert(det_idx[p].end(), {detailed.indices[t], detailed.indices[t + 1], detailed.indices[t + 2]});
  }
  std::vector<std::unique_ptr<runtime::detail::TriangleGrid>> grids(8);
  for (int p = 1; p < 8; ++p)
    if (!det_idx[p].empty()) grids[p] = std::make_unique<runtime::detail::TriangleGrid>(detailed.positions, det_idx[p]);

  std::vector<size_t> tris;
  for (size_t t = 0; t < coarse.indices.size(); t += 3) {
    uint8_t p = coarse.extremity_part(t);
    if (p && p < 8 && grids[p]) tris.push_back(t);
  }
  Proxies out;
  out.width = out.height = o.texture_size;
  out.rgba.assign(static_cast<size_t>(o.texture_size) * o.texture_size * 4, 0);
  out.mesh = coarse;
  out.proxy_triangles = tris.size();
  // Layout: two triangles per square cell (lower-left and upper-right halves), one more cell of
  // plain skin for the rest of the body.
  size_t cells = (tris.size() + 1) / 2 + 1;
  int per_row = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(cells))));
  int cell = o.texture_size / per_row;
  if (cell < 6) return Error{"", "", "too many proxy triangles for a " + std::to_string(o.texture_size) + " px texture"};
  const int gutter = 2;
  auto to_byte = [](float v) { return static_cast<uint8_t>(std::clamp(v, 0.0f, 1.0f) * 255.0f + 0.5f); };
  auto put = [&](int x, int y, glm::vec3 c) {
    if (x < 0 || y < 0 || x >= o.texture_size || y >= o.texture_size) return;
    uint8_t* px = &out.rgba[(static_cast<size_t>(y) * o.texture_size + x) * 4];
    px[0] = to_byte(c.r);
    px[1] = to_byte(c.g);
    px[2] = to_byte(c.b);
    px[3] = 255;
  };
  // The plain cell (last one) and the whole background in skin colour.
  for (int y = 0; y < o.texture_size; ++y)
    for (int x = 0; x < o.texture_size; ++x) put(x, y, o.skin);
  int plain = static_cast<int>(cells) - 1;
  glm::vec2 plain_uv((plain % per_row + 0.5f) * cell / o.texture_size, (plain / per_row + 0.5f) * cell / o.texture_size);
  out.mesh.uvs.assign(nv, plain_uv);

  glm::vec3 light = glm::normalize(o.light);
  auto shade = [&](const glm::vec3& n) { return 0.35f + 0.65f * std::max(0.0f, glm::dot(n, light)); };
  for (size_t k = 0; k < tris.size(); ++k) {
    bool has_last = false;  // the previous query in this triangle (same part, same grid)
    float last_d = 0;
    glm::vec3 last_p(0.0f);
    size_t t = tris[k];
    int c = static_cast<int>(k / 2), half = static_cast<int>(k % 2);
    int cx = (c % per_row) * cell, cy = (c / per_row) * cell;
    // Texel-space corners of this half cell (inset by the gutter).
    float lo = gutter, hi = cell - gutter;
    glm::vec2 corners[3];
    if (half == 0) {
      corners[0] = {lo, lo};
      corners[1] = {hi - 1, lo};
      corners[2] = {lo, hi - 1};
    } else {
      corners[0] = {hi, hi};
      corners[1] = {lo + 1, hi};
      corners[2] = {hi, lo + 1};
    }
    uint32_t vi[3] = {coarse.indices[t], coarse.indices[t + 1], coarse.indices[t + 2]};
    uint8_t part = coarse.part[vi[0]];
    // New vertices with this triangle's uvs.
    for (int j = 0; j < 3; ++j) {
      uint32_t nvi = static_cast<uint32_t>(out.mesh.positions.size());
      out.mesh.positions.push_back(coarse.positions[vi[j]]);
      if (!coarse.normals.empty()) out.mesh.normals.push_back(coarse.normals[vi[j]]);
      if (!coarse.joints.empty()) out.mesh.joints.push_back(coarse.joints[vi[j]]);
      if (!coarse.weights.empty()) out.mesh.weights.push_back(coarse.weights[vi[j]]);
      out.mesh.part.push_back(coarse.part[vi[j]]);
      if (!coarse.seam.empty()) out.mesh.seam.push_back(coarse.seam[vi[j]]);
      out.mesh.uvs.push_back((glm::vec2(cx, cy) + corners[j] + 0.5f) / static_cast<float>(o.texture_size));
      out.mesh.indices[t + j] = nvi;
    }
    // Fill the texels of the half cell (and its gutter) from the detailed extremity.
    glm::vec3 p0 = coarse.positions[vi[0]], p1 = coarse.positions[vi[1]], p2 = coarse.positions[vi[2]];
    glm::vec3 face_n = glm::normalize(glm::cross(p1 - p0, p2 - p0));
    glm::vec2 a = corners[0], b = corners[1], d = corners[2];
    float det = (b.x - a.x) * (d.y - a.y) - (d.x - a.x) * (b.y - a.y);
    if (std::abs(det) < 1e-6f) continue;
    // The detail is looked up once per 2x2 texel block (nearest-point queries dominate the cost).
    for (int y = 0; y < cell; y += 2)
      for (int x = 0; x < cell; x += 2) {
        glm::vec2 q(x + 0.5f, y + 0.5f);
        float u = ((q.x - a.x) * (d.y - a.y) - (d.x - a.x) * (q.y - a.y)) / det;
        float v = ((b.x - a.x) * (q.y - a.y) - (q.x - a.x) * (b.y - a.y)) / det;
        // Texels of this half (with a small margin that feeds the gutter).
        bool mine = half == 0 ? (x + y <= cell) : (x + y + 2 >= cell - 1);
        if (!mine) continue;
        u = std::clamp(u, 0.0f, 1.0f);
        v = std::clamp(v, 0.0f, 1.0f - u);
        glm::vec3 p = p0 + u * (p1 - p0) + v * (p2 - p0);
        glm::vec3 n = face_n;
        if (!coarse.normals.empty()) {
          glm::vec3 nn = (1 - u - v) * coarse.normals[vi[0]] + u * coarse.normals[vi[1]] + v * coarse.normals[vi[2]];
          if (glm::length(nn) > 1e-6f) n = glm::normalize(nn);
        }
        glm::vec3 cp;
        uint32_t dt = 0;
        // Queries move little from one block to the next: the last distance plus the move bounds
        // this one.
        float bound = has_last ? last_d + glm::distance(p, last_p) : 1e15f;
        last_d = grids[part]->closest(p, &cp, &dt, bound);
        last_p = p;
        has_last = true;
        const auto& di = det_idx[part];
        glm::vec3 q0 = detailed.positions[di[3 * dt]], q1 = detailed.positions[di[3 * dt + 1]],
                  q2 = detailed.positions[di[3 * dt + 2]];
        glm::vec3 dn = glm::normalize(glm::cross(q1 - q0, q2 - q0));
        float ratio = std::clamp(shade(dn) / std::max(0.2f, shade(n)), 0.35f, 1.25f);
        // Detail below the proxy surface (between fingers, under the chin) is darker.
        float depth = glm::dot(p - cp, n);
        float occlusion = 1.0f - 0.6f * std::clamp(depth / o.gap_depth_m, 0.0f, 1.0f);
        glm::vec3 colour = o.skin * (0.85f * ratio * occlusion);
        for (int j = 0; j < 2; ++j)
          for (int i = 0; i < 2; ++i)
            if (x + i < cell && y + j < cell) put(cx + x + i, cy + y + j, colour);
      }
  }
  // Drop vertices no triangle uses any more (extremity vertices replaced by their copies).
  std::vector<int> used(out.mesh.positions.size(), -1);
  mesher::SkinnedMesh compact;
  compact.indices.reserve(out.mesh.indices.size());
  for (uint32_t& i : out.mesh.indices) {
    if (used[i] < 0) used[i] = static_cast<int>(compact.append_vertex(out.mesh, i));
    compact.indices.push_back(static_cast<uint32_t>(used[i]));
  }
  out.mesh = std::move(compact);
  return out;
}

}  // namespace bb::decimate
