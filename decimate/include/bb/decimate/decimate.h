// Decimation of skinned meshes (paper section 3.1: head, hands and feet are simplified by
// decimation; the limbs and trunk get their LODs from contour sampling instead).
//
// Quadric-error halfedge collapses on an OpenMesh mesh, run in passes as meshoptimizer does (each
// pass ranks every edge by the removed vertex's plane quadric, weighted by the square root of the
// planes' area and normalized, at the survivor; collapses in that order up to 1.5 times the error at
// the rank that reaches the target, each vertex at most once per pass), with OpenMesh-style modules
// of ours (decimate/src/modules.h): ModQuadricNormalizedT (the priority and the normal rules: no
// face turns more than max_normal_deviation_deg in one collapse, nor away from the mean of its
// vertices' original normals by more than max_original_normal_deviation_deg, so flips cannot
// accumulate) and ModSkinWeightsT (no collapse between vertices whose skin weights differ by more
// than max_weight_difference: they would smear the skinning at joints). Vertices flagged `locked`
// (the seams where an extremity joins a limb) never move and are never removed, so a decimated
// extremity still meets its limb without cracks. After the passes each survivor may take the place
// of the absorbed input vertex that best fits its quadric: every output vertex is an input vertex
// with its position, normal, uv and skin weights.
//
// Units: metres. Lossy: the result carries the error it reached.
#pragma once

#include <cstddef>
#include <vector>

#include "bb/mesher/skinned_mesh.h"
#include "bb/result.h"

namespace bb::decimate {

struct Options {
  size_t target_triangles = 0;          // stop at (or just below) this many triangles; 0: error bound only
  double max_error_m = 0;               // quadric error bound, metres; 0: none
  float max_normal_deviation_deg = 60;  // no face normal turns more than this in one collapse
  float max_original_normal_deviation_deg = 80;  // nor this far from its vertices' original normals
  float max_weight_difference = 0.6f;   // L1 distance of two vertices' influences (0..2) above which they
                                        // may not be collapsed; >= 2 disables the rule
  std::vector<char> locked;             // empty, or one flag per vertex: 1 = seam, never touched
};

struct Report {
  size_t triangles_before = 0, triangles_after = 0, vertices_after = 0, locked_vertices = 0;
  double hausdorff_m = 0;  // symmetric Hausdorff distance, input vs output (vertex + face-centre samples)
  double mean_m = 0;       // mean of both one-sided sample distances
  double seconds = 0;      // decimation alone, without the error measurement
};

// Decimates `in` (closed or open, 2-manifold triangle mesh). Fails with a message on a mesh
// OpenMesh cannot represent (non-manifold edges) or an index out of range.
Result<mesher::SkinnedMesh> decimate(const mesher::SkinnedMesh& in, const Options& options,
                                     Report* report = nullptr);

// Symmetric Hausdorff and mean distance between two triangle meshes, sampled at the vertices and
// face centres of each against the triangles of the other (metres). Used to report decimation
// error and to compare with other simplifiers on the same terms.
struct Distance {
  double hausdorff_m = 0, mean_m = 0;
};
Distance mesh_distance(const std::vector<glm::vec3>& pa, const std::vector<uint32_t>& ia,
                       const std::vector<glm::vec3>& pb, const std::vector<uint32_t>& ib);

}  // namespace bb::decimate
