// The mesher's product and the exporter's input: one skinned triangle mesh per level of
// detail, with the error it reached (a lossy step reports its error).
//
// Units: metres, in the bind posture (Body::sample_posture) of the body's skeleton. Joint
// indices are skeleton joint indices. Triangles are counter-clockwise seen from outside.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/type_precision.hpp>

namespace bb::mesher {

// Which piece of the body a vertex belongs to (SkinnedMesh::part). Extremities are the
// full-resolution OpenVDB meshes that decimation may simplify; kBody is contour-sampled.
enum class MeshPart : uint8_t {
  kBody = 0,
  kHead = 1,
  kLeftHand = 2,
  kRightHand = 3,
  kLeftFoot = 4,
  kRightFoot = 5,
};

struct SkinnedMesh {
  std::vector<glm::vec3> positions;   // metres
  std::vector<glm::vec3> normals;     // unit, outward
  std::vector<glm::vec2> uvs;         // empty, or one per vertex (textured proxies)
  std::vector<glm::u16vec4> joints;   // up to 4 influences; unused slots hold 0
  std::vector<glm::vec4> weights;     // sum to 1; unused slots hold 0
  std::vector<uint32_t> indices;      // 3 per triangle
  // Optional tags, empty or one per vertex. part: a MeshPart value. seam: 1 on a seam loop where
  // an extremity is zipped to the limb contours (both the extremity's border loop and the
  // contour ring it is joined to); decimation must keep these vertices and the edges between
  // them so that the seam stays crack-free. A triangle is an extremity triangle when all three
  // vertices have the same extremity part (zipper triangles mix kBody and the extremity).
  std::vector<uint8_t> part;
  std::vector<uint8_t> seam;
  size_t triangle_count() const { return indices.size() / 3; }

  // The extremity part of the triangle whose indices start at `first_index` when all three of its
  // vertices carry that one non-body part, else 0 (kBody). Needs `part`.
  uint8_t extremity_part(size_t first_index) const {
    uint8_t p = part[indices[first_index]];
    return p != 0 && part[indices[first_index + 1]] == p && part[indices[first_index + 2]] == p ? p : 0;
  }
  size_t extremity_triangle_count() const {
    if (part.size() != positions.size()) return 0;
    size_t n = 0;
    for (size_t t = 0; t < indices.size(); t += 3) n += extremity_part(t) != 0;
    return n;
  }
  // Appends vertex `i` of `from` with every per-vertex attribute `from` carries (this mesh must
  // carry the same ones); returns its index here.
  uint32_t append_vertex(const SkinnedMesh& from, uint32_t i) {
    positions.push_back(from.positions[i]);
    if (!from.normals.empty()) normals.push_back(from.normals[i]);
    if (!from.uvs.empty()) uvs.push_back(from.uvs[i]);
    if (!from.joints.empty()) joints.push_back(from.joints[i]);
    if (!from.weights.empty()) weights.push_back(from.weights[i]);
    if (!from.part.empty()) part.push_back(from.part[i]);
    if (!from.seam.empty()) seam.push_back(from.seam[i]);
    return static_cast<uint32_t>(positions.size() - 1);
  }
};

// What a LOD reached, measured against the implicit surface (metres and fractions of height).
struct LodReport {
  int level = 0;
  size_t triangles = 0, vertices = 0;
  bool errors_measured = false;              // false: the distances below were not measured (0)
  double hausdorff_m = 0, mean_m = 0;        // symmetric Hausdorff and mean distance to the skin
  double hausdorff_rel = 0, mean_rel = 0;    // the same over body height
  bool closed = false, manifold = false, oriented = false, self_intersections = true;
  double seconds = 0;                        // time to build this LOD
  bool vdb_extremities = false;              // head, hands, feet are full-resolution OpenVDB meshes
  size_t extremity_triangles = 0;            // triangles whose vertices are all one extremity part
  size_t self_intersection_count = 0;        // pairs of intersecting triangles (0 when clean)
  double extremity_hausdorff_m = 0;          // the same Hausdorff restricted to head, hands, feet
};

struct Lod {
  SkinnedMesh mesh;
  LodReport report;
  float screen_coverage = 0;  // MSFT_screencoverage: switch to the next LOD below this fraction
};

}  // namespace bb::mesher
