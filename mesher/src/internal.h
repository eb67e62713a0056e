// Internal pieces of the mesher shared between its translation units (not installed).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "bb/modeler/implicit_surface.h"
#include "bb/result.h"

namespace bb::mesher::detail {

// The skin field restricted to a subset of the placed primitives (one body piece), so that
// rays cast from a limb see that limb's skin and not a neighbour's.
class SubField {
 public:
  // The primitives listed (indices into surface.primitives()).
  SubField(const modeler::ImplicitSurface& surface, const std::vector<int>& primitive_indices);
  // The whole skin (uses the surface's own grid).
  explicit SubField(const modeler::ImplicitSurface& surface);
  float field(const glm::vec3& x) const;
  float field_gradient(const glm::vec3& x, glm::vec3* g) const;
  // Largest t in [0, max_t] where the field goes from inside (>= iso) to outside along
  // origin + t * dir (dir unit). Nothing when the ray never is inside.
  std::optional<float> outermost(const glm::vec3& origin, const glm::vec3& dir, float max_t) const;
  // Moves x onto the iso-surface along the gradient (Newton), at most `max_move` metres.
  glm::vec3 project(const glm::vec3& x, float max_move, int iterations = 8) const;
  const modeler::Aabb& bounds() const { return bounds_; }
  bool empty() const { return prims_.empty(); }

 private:
  const modeler::ImplicitSurface* whole_ = nullptr;  // set: delegate field queries to it
  std::vector<modeler::PlacedPrimitive> prims_;
  modeler::Aabb bounds_;
};

// One contour (paper 3.1): `points` rays cast star-shaped from `center` in the plane normal to
// `tangent` (first ray along the projection of `reference`), each sample the outermost crossing
// of `field`. Returns the samples in order around the tangent (counter-clockwise).
std::vector<glm::vec3> sample_contour(const SubField& field, const glm::vec3& center, const glm::vec3& tangent,
                                      const glm::vec3& reference, int points);

// An indexed triangle mesh with per-vertex tags, the unit the mesher assembles.
struct PieceMesh {
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;
  std::vector<uint8_t> part;   // MeshPart
  std::vector<uint8_t> seam;   // 1 on seam loops
  std::vector<int8_t> region;  // which skinning region (see mesher.cpp) a vertex belongs to
  uint32_t add(const glm::vec3& p, uint8_t part_, uint8_t seam_, int8_t region_) {
    positions.push_back(p);
    part.push_back(part_);
    seam.push_back(seam_);
    region.push_back(region_);
    return uint32_t(positions.size() - 1);
  }
  void append(const PieceMesh& o);
};

// OpenVDB: the iso-surface of `field` inside `box` at `voxel` metres, then the part on the
// positive side of the plane (point `plane_point`, unit normal `plane_normal`), with vertices
// projected onto the surface. The result has exactly one border loop, on the plane, returned in
// `loop` (vertex indices, in order). Errors when the cut is not a single loop.
struct Extremity {
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;
  std::vector<uint32_t> loop;
};
Result<Extremity> mesh_extremity(const SubField& field, const modeler::Aabb& box, float voxel,
                                 const glm::vec3& plane_point, const glm::vec3& plane_normal);

// OpenVDB: the whole skin's iso-surface at `voxel` metres, vertices projected onto the surface
// (the reference of the error report).
struct PlainMesh;
PlainMesh reference_mesh(const SubField& field, float voxel);

// CGAL: union of closed, oriented, self-intersection-free triangle meshes (corefinement).
struct PlainMesh {
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;
};
Result<PlainMesh> mesh_union(const std::vector<PlainMesh>& pieces);

// The union leaves the creases where pieces meet (armpit vault, groin) off the skin: a contour
// piece samples its own skin, the blend of two pieces is seen by neither at full resolution, and
// the union's intersection curves lie inside the blend. Fits the mesh there:
//  1. vertices farther than `tol` from the skin (first-order distance |F - iso| / |grad F|) move
//     onto it (Newton along the gradient, at most `max_move`);
//  2. up to `passes` times, every edge whose midpoint is farther than `tol` is split and the new
//     vertex put on the skin (at most half the edge's length away); a triangle with split edges
//     becomes 2, 3 or 4 triangles in its own orientation;
//  3. guard: the most displaced vertex of each triangle that now intersects another goes
//     half-way back to its chord position (on the unfitted surface), round after round, then all
//     the triangle's vertices go all the way back;
//     the last resort puts every vertex back. The chord surface is the joined mesh itself, free
//     of self-intersections, so the result is too.
// Edges with both ends in `frozen` are kept (extremities, seam rings); frozen vertices stay.
// Returns the number of vertices added.
size_t fit_creases(PlainMesh& m, const SubField& skin, float tol, float max_move, float min_edge, int passes,
                   const std::vector<char>& frozen);

}  // namespace bb::mesher::detail
