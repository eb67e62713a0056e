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
};

// What a LOD reached, measured against the implicit surface (metres and fractions of height).
struct LodReport {
  int level = 0;
  size_t triangles = 0, vertices = 0;
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
