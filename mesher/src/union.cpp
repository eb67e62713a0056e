// CGAL corefinement: union of the closed body pieces (torso, arms, legs) into one closed,
// oriented 2-manifold. Corefinement computes the exact intersection curves of the pieces and
// keeps the outer parts, so the joined mesh has no cracks and no self-intersections provided
// each piece has none (contour pieces are radial graphs around their axis, which cannot fold).
#include <algorithm>
#include <array>
#include <exception>
#include <limits>
#include <numeric>
#include <vector>

#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/corefinement.h>
#include <CGAL/Surface_mesh.h>

#include "internal.h"

namespace bb::mesher::detail {

namespace {
using K = CGAL::Exact_predicates_exact_constructions_kernel;
using Mesh = CGAL::Surface_mesh<K::Point_3>;
namespace PMP = CGAL::Polygon_mesh_processing;

bool to_surface_mesh(const PlainMesh& in, Mesh& out) {
  out.clear();
  std::vector<Mesh::Vertex_index> v;
  v.reserve(in.positions.size());
  for (const glm::vec3& p : in.positions) v.push_back(out.add_vertex(K::Point_3(p.x, p.y, p.z)));
  for (size_t i = 0; i + 2 < in.indices.size(); i += 3) {
    auto f = out.add_face(v[in.indices[i]], v[in.indices[i + 1]], v[in.indices[i + 2]]);
    if (f == Mesh::null_face()) return false;
  }
  return true;
}
// The same mesh with its vertices sorted by position (x, then y, then z; where two share one, by
// the smallest position next to them) and its triangles, each turned to start at its smallest
// index, sorted by their indices. Corefinement numbers the vertices it creates on the
// intersection curves in an order that depends on where its boxes lie in memory, so the same
// pieces gave unions numbered differently from one process to the next (the default body's level
// 1: three orders in four runs of `bodybuilder mesh`), and every later step followed that order
// into the files written. The union's vertices have distinct positions (every level of the
// default body and its seeded variants), so this order is the mesh's own.
PlainMesh canonical_order(PlainMesh m) {
  const size_t n = m.positions.size();
  auto less = [](const glm::vec3& a, const glm::vec3& b) {
    return a.x != b.x ? a.x < b.x : a.y != b.y ? a.y < b.y : a.z < b.z;
  };
  // The smallest neighbour position of each vertex: the tie-break.
  std::vector<glm::vec3> nearest(n, glm::vec3(std::numeric_limits<float>::max()));
  for (size_t t = 0; t + 2 < m.indices.size(); t += 3)
    for (int k = 0; k < 3; ++k)
      for (int j = 1; j < 3; ++j) {
        const glm::vec3& q = m.positions[m.indices[t + (k + j) % 3]];
        if (less(q, nearest[m.indices[t + k]])) nearest[m.indices[t + k]] = q;
      }
  std::vector<uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
    if (m.positions[a] != m.positions[b]) return less(m.positions[a], m.positions[b]);
    return less(nearest[a], nearest[b]);
  });
  std::vector<uint32_t> rank(n);
  PlainMesh out;
  out.positions.reserve(n);
  for (uint32_t r = 0; r < n; ++r) {
    rank[order[r]] = r;
    out.positions.push_back(m.positions[order[r]]);
  }
  std::vector<std::array<uint32_t, 3>> tris;
  tris.reserve(m.indices.size() / 3);
  for (size_t t = 0; t + 2 < m.indices.size(); t += 3) {
    std::array<uint32_t, 3> f{rank[m.indices[t]], rank[m.indices[t + 1]], rank[m.indices[t + 2]]};
    // Turned, not reordered: the winding stays.
    while (f[0] > f[1] || f[0] > f[2]) f = {f[1], f[2], f[0]};
    tris.push_back(f);
  }
  std::sort(tris.begin(), tris.end());
  out.indices.reserve(m.indices.size());
  for (const auto& f : tris) out.indices.insert(out.indices.end(), f.begin(), f.end());
  return out;
}

}  // namespace

Result<PlainMesh> mesh_union(const std::vector<PlainMesh>& pieces) {
  if (pieces.empty()) return PlainMesh{};
  try {
    Mesh acc;
    if (!to_surface_mesh(pieces[0], acc)) return Error{"", "piece 0", "not a manifold triangle mesh"};
    for (size_t i = 1; i < pieces.size(); ++i) {
      Mesh other;
      if (!to_surface_mesh(pieces[i], other))
        return Error{"", "piece " + std::to_string(i), "not a manifold triangle mesh"};
      if (!PMP::corefine_and_compute_union(acc, other, acc))
        return Error{"", "piece " + std::to_string(i), "union failed (non-manifold result)"};
    }
    PlainMesh out;
    std::vector<uint32_t> id(acc.num_vertices(), 0);
    out.positions.reserve(acc.number_of_vertices());
    for (auto v : acc.vertices()) {
      const auto& p = acc.point(v);
      id[v.idx()] = uint32_t(out.positions.size());
      out.positions.emplace_back(float(CGAL::to_double(p.x())), float(CGAL::to_double(p.y())), float(CGAL::to_double(p.z())));
    }
    for (auto f : acc.faces()) {
      auto h = acc.halfedge(f);
      for (int k = 0; k < 3; ++k, h = acc.next(h)) out.indices.push_back(id[acc.target(h).idx()]);
    }
    return canonical_order(std::move(out));
  } catch (const std::exception& e) {
    return Error{"", "union", std::string("CGAL: ") + e.what()};
  }
}

}  // namespace bb::mesher::detail
