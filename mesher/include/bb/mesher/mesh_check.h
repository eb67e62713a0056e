// CGAL-backed checks on any indexed triangle mesh (CGAL stays inside mesh_check.cpp).
//
// Positions in metres, 3 indices per triangle, counter-clockwise seen from outside. Empty spans
// are allowed (an empty mesh is reported as not closed, 0 components).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

namespace bb::mesher {

struct MeshCheck {
  bool closed = false;       // every edge has exactly two triangles (no border)
  bool manifold = false;     // no non-manifold edge or vertex, no degenerate triangle
  bool oriented = false;     // neighbours agree on orientation and the volume is positive
  size_t self_intersections = 0;  // pairs of intersecting triangles (not sharing an edge/vertex)
  size_t connected_components = 0;
  size_t border_edges = 0;         // edges with one triangle
  size_t non_manifold_edges = 0;   // edges with more than two triangles
  size_t non_manifold_vertices = 0;
  size_t degenerate_triangles = 0; // zero area or repeated index
  double area_m2 = 0;
  double volume_m3 = 0;            // signed; > 0 for a closed, outward-oriented mesh
  std::vector<std::pair<uint32_t, uint32_t>> intersecting;  // first (up to 64) intersecting triangle pairs
  bool ok() const { return closed && manifold && oriented && self_intersections == 0; }
};

// `find_self_intersections` = false skips the costly pairwise test (self_intersections = 0).
MeshCheck check_mesh(std::span<const glm::vec3> positions, std::span<const uint32_t> indices,
                     bool find_self_intersections = true);

// The triangles that take part in a self-intersection with at least one triangle of `subset`
// (indices of triangles; the same rules as check_mesh), sorted. Cheaper than check_mesh when the
// subset is small: only the subset's boxes are tested against the whole mesh.
std::vector<uint32_t> intersecting_triangles(std::span<const glm::vec3> positions, std::span<const uint32_t> indices,
                                             std::span<const uint32_t> subset);

// Approximate symmetric Hausdorff distance between two triangle meshes, metres: points are
// sampled on each mesh (about `samples_per_mesh`) and their distance to the other measured
// exactly (AABB tree). Returns -1 when either mesh is empty.
double hausdorff_distance(std::span<const glm::vec3> positions_a, std::span<const uint32_t> indices_a,
                          std::span<const glm::vec3> positions_b, std::span<const uint32_t> indices_b,
                          int samples_per_mesh = 20000);

// Distance from each point to the nearest point of the mesh, metres (AABB tree, exact).
// `out` gets points.size() values. Empty mesh: every distance is infinity.
void distances_to_mesh(std::span<const glm::vec3> positions, std::span<const uint32_t> indices,
                       std::span<const glm::vec3> points, std::span<double> out);

}  // namespace bb::mesher
