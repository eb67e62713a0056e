// Head, hands and feet at the middle and lowest levels of detail (paper section 3.1, figure 3).
//
// decimate_extremities: the contour-sampled body keeps its rings; the OpenVDB extremities zipped
// to it are decimated (decimate.h) to a triangle budget, with every body and seam vertex locked,
// so the seams stay exactly where they were and no crack opens.
//
// bake_proxies: at the lowest level the extremities are simple geometry (the mesher's coarse,
// contour-sampled caps); their look comes from a texture baked from the full-resolution meshes:
// for every texel of a proxy triangle, the nearest point of the same extremity in the detailed
// mesh gives its normal, and the texel stores the skin colour scaled by how much that normal's
// lighting differs from the proxy's, darkened where the detail is far below the proxy (the gaps
// between fingers). Units: metres; colours linear RGB in [0, 1].
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "bb/decimate/decimate.h"
#include "bb/mesher/skinned_mesh.h"
#include "bb/result.h"

namespace bb::decimate {

// Decimates the extremity triangles (all three vertices of one non-body part) of `mesh` until
// the extremities hold about `extremity_triangles` triangles in all, each part its share in
// proportion with its triangles. Needs SkinnedMesh::part and ::seam. Parts are decimated in
// parallel on `threads` threads (0: one per core). The report's error is measured over the whole
// mesh (skipped, and the call cheaper, without a report).
Result<mesher::SkinnedMesh> decimate_extremities(const mesher::SkinnedMesh& mesh, size_t extremity_triangles,
                                                 Report* report = nullptr, unsigned threads = 0);

// `level`'s body and zipper triangles with the extremity triangles of `from` (the same head, hands
// and feet, e.g. decimated with their seam loops locked, so they meet `level`'s zippers exactly);
// vertices are welded by exact position, attributes from the mesh that brings the position first.
// Both meshes need SkinnedMesh::part and ::seam.
mesher::SkinnedMesh with_extremities_of(const mesher::SkinnedMesh& level, const mesher::SkinnedMesh& from);

struct ProxyOptions {
  int texture_size = 256;                      // square RGBA8 texture, pixels
  glm::vec3 skin{0.80f, 0.62f, 0.50f};         // base colour of the skin (linear)
  glm::vec3 light{0.3f, 0.8f, 0.5f};           // direction towards the light used for the ratio
  float gap_depth_m = 0.012f;                  // detail this far below the proxy is fully darkened
};

struct Proxies {
  mesher::SkinnedMesh mesh;          // `coarse` with uvs; extremity triangles get their own texels
  int width = 0, height = 0;
  std::vector<uint8_t> rgba;         // width * height * 4, rows top to bottom (glTF uv origin)
  size_t proxy_triangles = 0;        // extremity triangles textured
};

// `coarse`: the lowest LOD, its extremities tagged by part; `detailed`: a mesh whose extremities
// (same part tags) are at full resolution, in the same posture.
Result<Proxies> bake_proxies(const mesher::SkinnedMesh& coarse, const mesher::SkinnedMesh& detailed,
                             const ProxyOptions& options = {});

}  // namespace bb::decimate
