// CGAL corefinement: union of the closed body pieces (torso, arms, legs) into one closed,
// oriented 2-manifold. Corefinement computes the exact intersection curves of the pieces and
// keeps the outer parts, so the joined mesh has no cracks and no self-intersections provided
// each piece has none (contour pieces are radial graphs around their axis, which cannot fold).
#include <exception>
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
    return out;
  } catch (const std::exception& e) {
    return Error{"", "union", std::string("CGAL: ") + e.what()};
  }
}

}  // namespace bb::mesher::detail
