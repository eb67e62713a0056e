// OpenVDB extremities (head, hands, feet): the skin field sampled on a voxel grid, meshed with
// volumeToMesh, cut at the seam plane, vertices projected back onto the skin. The only
// translation unit that includes OpenVDB.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cmath>
#include <thread>
#include <unordered_map>

#include <openvdb/openvdb.h>
#include <openvdb/tools/VolumeToMesh.h>

#include "internal.h"

namespace bb::mesher::detail {

namespace {

struct Grid {
  glm::vec3 origin;
  float voxel;
  glm::ivec3 dims;
  std::vector<float> values;  // iso - F: negative inside
};

// Samples iso - F on the grid nodes (two threads, z-slabs). Coarse to fine: the field is
// evaluated on every other node first; a 2x2x2-voxel cell whose eight corners are all far
// outside (F < 0.3) or deep inside (F > 3) gets its other nodes by trilinear interpolation, the
// rest is evaluated exactly. The surface (F = 1) only passes through exactly evaluated cells;
// features thinner than a cell (2 voxels) whose field stays under 0.3 at all its corners could
// be missed, which the smallest primitives (fingers, ears: 15 mm and more) never are.
Grid sample(const SubField& field, const modeler::Aabb& box, float voxel) {
  Grid g;
  g.voxel = voxel;
  g.origin = box.min - glm::vec3(2 * voxel);
  g.dims = glm::ivec3(glm::ceil((box.max - box.min) / voxel)) + 5;
  g.dims += (g.dims + 1) % 2;  // odd: the coarse lattice covers both ends
  g.values.resize(size_t(g.dims.x) * g.dims.y * g.dims.z);
  const glm::ivec3 D = g.dims, C = (D - 1) / 2;  // C: cells per axis
  auto at = [&](int x, int y, int z) -> float& { return g.values[(size_t(z) * D.y + y) * D.x + x]; };
  auto eval = [&](int x, int y, int z) { return modeler::kIso - field.field(g.origin + voxel * glm::vec3(x, y, z)); };
  std::vector<char> exact(size_t(C.x) * C.y * C.z, 0);
  auto cell = [&](int x, int y, int z) -> char& { return exact[(size_t(z) * C.y + y) * C.x + x]; };
  auto parallel = [&](int n, auto&& fn) {
    std::thread t([&] { for (int z = 0; z < n / 2; ++z) fn(z); });
    for (int z = n / 2; z < n; ++z) fn(z);
    t.join();
  };
  parallel(C.z + 1, [&](int cz) {
    for (int cy = 0; cy <= C.y; ++cy)
      for (int cx = 0; cx <= C.x; ++cx) at(2 * cx, 2 * cy, 2 * cz) = eval(2 * cx, 2 * cy, 2 * cz);
  });
  const float far_out = modeler::kIso - 0.3f, deep_in = modeler::kIso - 3.0f;
  parallel(C.z, [&](int cz) {
    for (int cy = 0; cy < C.y; ++cy)
      for (int cx = 0; cx < C.x; ++cx) {
        bool out = true, in = true;
        for (int k = 0; k < 8; ++k) {
          float v = at(2 * (cx + (k & 1)), 2 * (cy + ((k >> 1) & 1)), 2 * (cz + (k >> 2)));
          out &= v > far_out;
          in &= v < deep_in;
        }
        cell(cx, cy, cz) = !(out || in);
      }
  });
  parallel(D.z, [&](int z) {
    for (int y = 0; y < D.y; ++y)
      for (int x = 0; x < D.x; ++x) {
        if (x % 2 == 0 && y % 2 == 0 && z % 2 == 0) continue;
        // Cells containing this node: one per odd coordinate, up to two per even one.
        int lo[3], hi[3];
        const int p[3] = {x, y, z}, cmax[3] = {C.x - 1, C.y - 1, C.z - 1};
        for (int d = 0; d < 3; ++d) {
          if (p[d] % 2) lo[d] = hi[d] = (p[d] - 1) / 2;
          else { lo[d] = std::max(0, p[d] / 2 - 1); hi[d] = std::min(cmax[d], p[d] / 2); }
        }
        bool need = false;
        for (int cz = lo[2]; cz <= hi[2] && !need; ++cz)
          for (int cy = lo[1]; cy <= hi[1] && !need; ++cy)
            for (int cx = lo[0]; cx <= hi[0] && !need; ++cx) need = cell(cx, cy, cz);
        if (need) { at(x, y, z) = eval(x, y, z); continue; }
        // Trilinear in cell (lo): fractions 0, 0.5 or 1 per axis.
        float v = 0;
        for (int k = 0; k < 8; ++k) {
          float w = 1;
          int q[3];
          for (int d = 0; d < 3; ++d) {
            int bit = (k >> d) & 1;
            float f = float(p[d] - 2 * lo[d]) * 0.5f;
            w *= bit ? f : 1 - f;
            q[d] = 2 * (lo[d] + bit);
          }
          if (w > 0) v += w * at(q[0], q[1], q[2]);
        }
        at(x, y, z) = v;
      }
  });
  return g;
}

// volumeToMesh on the sampled grid; triangles oriented outwards.
void mesh_grid(const Grid& g, std::vector<glm::vec3>& pos, std::vector<uint32_t>& idx) {
  openvdb::initialize();
  const float background = 1.0f;
  auto grid = openvdb::FloatGrid::create(background);
  grid->setTransform(openvdb::math::Transform::createLinearTransform(g.voxel));
  auto acc = grid->getAccessor();
  for (int z = 0; z < g.dims.z; ++z)
    for (int y = 0; y < g.dims.y; ++y)
      for (int x = 0; x < g.dims.x; ++x) {
        float v = g.values[(size_t(z) * g.dims.y + y) * g.dims.x + x];
        // Voxels far outside stay background (inactive), which reads the same.
        if (v < background) acc.setValue(openvdb::Coord(x, y, z), v);
      }
  std::vector<openvdb::Vec3s> points;
  std::vector<openvdb::Vec3I> tris;
  std::vector<openvdb::Vec4I> quads;
  openvdb::tools::volumeToMesh(*grid, points, tris, quads, 0.0, 0.0);
  pos.resize(points.size());
  for (size_t i = 0; i < points.size(); ++i)
    pos[i] = g.origin + glm::vec3(points[i].x(), points[i].y(), points[i].z());
  idx.clear();
  for (const auto& t : tris) idx.insert(idx.end(), {t[0], t[1], t[2]});
  for (const auto& q : quads) {
    // Split along the shorter diagonal.
    float d02 = glm::distance(pos[q[0]], pos[q[2]]), d13 = glm::distance(pos[q[1]], pos[q[3]]);
    if (d02 <= d13) idx.insert(idx.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
    else idx.insert(idx.end(), {q[0], q[1], q[3], q[1], q[2], q[3]});
  }
  double vol = 0;
  for (size_t i = 0; i < idx.size(); i += 3)
    vol += glm::dot(glm::dvec3(pos[idx[i]]), glm::cross(glm::dvec3(pos[idx[i + 1]]), glm::dvec3(pos[idx[i + 2]])));
  if (vol < 0)
    for (size_t i = 0; i < idx.size(); i += 3) std::swap(idx[i + 1], idx[i + 2]);
}

}  // namespace

Result<Extremity> mesh_extremity(const SubField& field, const modeler::Aabb& box, float voxel,
                                 const glm::vec3& plane_point, const glm::vec3& n) {
  auto t0 = std::chrono::steady_clock::now();
  Grid g = sample(field, box, voxel);
  auto t1 = std::chrono::steady_clock::now();
  std::vector<glm::vec3> pos;
  std::vector<uint32_t> idx;
  mesh_grid(g, pos, idx);
  auto t2 = std::chrono::steady_clock::now();
  if (std::getenv("BB_MESHER_DEBUG"))
    std::fprintf(stderr, "extremity: %d x %d x %d nodes, sample %.1f ms, volumeToMesh %.1f ms, %zu triangles\n",
                 g.dims.x, g.dims.y, g.dims.z, std::chrono::duration<double, std::milli>(t1 - t0).count(),
                 std::chrono::duration<double, std::milli>(t2 - t1).count(), idx.size() / 3);
  if (idx.empty()) return Error{"", "extremity", "OpenVDB found no surface"};
  // Signed distances to the plane; keep s > 0. Nudge vertices off the plane.
  const float eps = 1e-5f * voxel;
  std::vector<float> s(pos.size());
  for (size_t i = 0; i < pos.size(); ++i) {
    s[i] = glm::dot(pos[i] - plane_point, n);
    if (std::abs(s[i]) < eps) s[i] = -eps;
  }
  Extremity out;
  std::vector<int64_t> remap(pos.size(), -1);
  auto keep = [&](uint32_t v) {
    if (remap[v] < 0) { remap[v] = int64_t(out.positions.size()); out.positions.push_back(pos[v]); }
    return uint32_t(remap[v]);
  };
  std::unordered_map<uint64_t, uint32_t> cut;  // undirected edge -> vertex on the plane
  std::vector<char> on_plane;
  auto cut_vertex = [&](uint32_t a, uint32_t b) {
    uint64_t k = (uint64_t(std::min(a, b)) << 32) | std::max(a, b);
    auto it = cut.find(k);
    if (it != cut.end()) return it->second;
    float t = s[a] / (s[a] - s[b]);
    glm::vec3 p = pos[a] + t * (pos[b] - pos[a]);
    uint32_t id = uint32_t(out.positions.size());
    out.positions.push_back(p);
    cut.emplace(k, id);
    return id;
  };
  for (size_t i = 0; i < idx.size(); i += 3) {
    uint32_t v[3] = {idx[i], idx[i + 1], idx[i + 2]};
    int inside = (s[v[0]] > 0) + (s[v[1]] > 0) + (s[v[2]] > 0);
    if (inside == 0) continue;
    if (inside == 3) { out.indices.insert(out.indices.end(), {keep(v[0]), keep(v[1]), keep(v[2])}); continue; }
    // Rotate so that v[0] is the odd one out.
    for (int r = 0; r < 3; ++r) {
      bool a = s[v[0]] > 0, b = s[v[1]] > 0, c = s[v[2]] > 0;
      if ((inside == 1 && a && !b && !c) || (inside == 2 && !a && b && c)) break;
      std::rotate(v, v + 1, v + 3);
    }
    uint32_t p01 = cut_vertex(v[0], v[1]), p02 = cut_vertex(v[0], v[2]);
    if (inside == 1) {
      out.indices.insert(out.indices.end(), {keep(v[0]), p01, p02});
    } else {
      uint32_t k1 = keep(v[1]), k2 = keep(v[2]);
      out.indices.insert(out.indices.end(), {p01, k1, k2, p01, k2, p02});
    }
  }
  on_plane.assign(out.positions.size(), 0);
  for (const auto& [k, id] : cut) on_plane[id] = 1;
  // Border loops: directed edges without a twin.
  std::unordered_map<uint64_t, int> directed;
  for (size_t i = 0; i < out.indices.size(); i += 3)
    for (int e = 0; e < 3; ++e)
      ++directed[(uint64_t(out.indices[i + e]) << 32) | out.indices[i + (e + 1) % 3]];
  std::unordered_map<uint32_t, uint32_t> next;
  for (const auto& [k, c] : directed) {
    uint32_t a = uint32_t(k >> 32), b = uint32_t(k & 0xffffffffu);
    if (!directed.count((uint64_t(b) << 32) | a)) next[a] = b;
  }
  std::vector<std::vector<uint32_t>> loops;
  std::unordered_map<uint32_t, char> done;
  for (const auto& [a, b] : next) {
    if (done[a]) continue;
    std::vector<uint32_t> loop;
    uint32_t v = a;
    while (!done[v]) {
      done[v] = 1;
      loop.push_back(v);
      auto it = next.find(v);
      if (it == next.end()) break;
      v = it->second;
    }
    loops.push_back(std::move(loop));
  }
  if (loops.empty()) return Error{"", "extremity", "the seam plane does not cut the extremity"};
  std::sort(loops.begin(), loops.end(), [](const auto& x, const auto& y) { return x.size() > y.size(); });
  // Keep the triangles connected to the main loop.
  {
    const size_t nv = out.positions.size();
    std::vector<int> parent(nv);
    for (size_t i = 0; i < nv; ++i) parent[i] = int(i);
    auto find = [&](int x) { while (parent[x] != x) x = parent[x] = parent[parent[x]]; return x; };
    for (size_t i = 0; i < out.indices.size(); i += 3) {
      parent[find(int(out.indices[i + 1]))] = find(int(out.indices[i]));
      parent[find(int(out.indices[i + 2]))] = find(int(out.indices[i]));
    }
    int root = find(int(loops[0][0]));
    for (size_t l = 1; l < loops.size(); ++l)
      if (find(int(loops[l][0])) == root)
        return Error{"", "extremity", "the seam plane cuts the extremity in more than one loop"};
    std::vector<int64_t> map(nv, -1);
    Extremity kept;
    std::vector<char> kept_on_plane;
    for (size_t i = 0; i < out.indices.size(); i += 3) {
      if (find(int(out.indices[i])) != root) continue;
      for (int k = 0; k < 3; ++k) {
        uint32_t v = out.indices[i + k];
        if (map[v] < 0) {
          map[v] = int64_t(kept.positions.size());
          kept.positions.push_back(out.positions[v]);
          kept_on_plane.push_back(on_plane[v]);
        }
        kept.indices.push_back(uint32_t(map[v]));
      }
    }
    for (uint32_t v : loops[0]) kept.loop.push_back(uint32_t(map[v]));
    out = std::move(kept);
    on_plane = std::move(kept_on_plane);
  }
  // No projection onto the skin: volumeToMesh's vertices are already within a small fraction of
  // a voxel of it, and moving them along the gradient folded triangles between the fingers.
  return out;
}

PlainMesh reference_mesh(const SubField& field, float voxel) {
  Grid g = sample(field, field.bounds(), voxel);
  PlainMesh m;
  mesh_grid(g, m.positions, m.indices);
  for (glm::vec3& p : m.positions) p = field.project(p, voxel, 12);
  return m;
}

}  // namespace bb::mesher::detail
