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
// with its position, normal, uv and skin weights. A collapse that would leave an absorbed input
// vertex farther than sqrt(member_k x the pass's error goal) waits for a later pass.
//
// One run's Hausdorff error is a lottery at coarse counts (one fingertip or ear decides it; another
// rule setting moves it by 10-30 %, a one-triangle change of target by several per cent), so
// callers that care (extremities.h) run a few candidates with different rule settings and keep
// the one measured nearest to the full resolution; ReferenceDistance makes those measurements
// cheap, and a snapshot (a lightly decimated copy taken between passes) gives them a cheaper start
// than full resolution.
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
  double member_k = 1;                  // a collapse that would leave an absorbed input vertex farther than
                                        // sqrt(member_k x the pass's error goal) waits for a later pass; 0: off
  std::vector<char> locked;             // empty, or one flag per vertex: 1 = seam, never touched
  size_t snapshot_triangles = 0;        // with a `snapshot` mesh given to decimate(): the mesh is copied
                                        // out after the first pass that leaves at most this many
                                        // triangles (a lightly decimated copy to restart from; the
                                        // passes are the same without it)
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
                                     Report* report = nullptr, mesher::SkinnedMesh* snapshot = nullptr);

// Symmetric Hausdorff and mean distance between two triangle meshes, sampled at the vertices and
// face centres of each against the triangles of the other (metres). Used to report decimation
// error and to compare with other simplifiers on the same terms.
struct Distance {
  double hausdorff_m = 0, mean_m = 0;
};
Distance mesh_distance(const std::vector<glm::vec3>& pa, const std::vector<uint32_t>& ia,
                       const std::vector<glm::vec3>& pb, const std::vector<uint32_t>& ib);

// mesh_distance from one reference mesh to many candidates (the reference's grid and samples are
// built once), for picking the nearest candidate: measure(..., give_up_above) stops as soon as a
// sample is farther than `give_up_above` (the candidate cannot beat the best so far) and then
// returns complete = false with a Hausdorff above that bound. The reference samples that were
// farthest in the last complete measurement are tried first, so a worse candidate usually fails
// within a few queries. A complete measurement equals mesh_distance(reference, candidate).
class ReferenceDistance {
 public:
  ReferenceDistance(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& indices);
  ~ReferenceDistance();
  ReferenceDistance(const ReferenceDistance&) = delete;
  ReferenceDistance& operator=(const ReferenceDistance&) = delete;
  struct Measured {
    Distance distance;      // complete: exact; otherwise hausdorff_m > give_up_above, mean_m unknown (0)
    bool complete = false;
  };
  // with_mean = false: the Hausdorff distance alone (mean_m 0), much cheaper: a sample is
  // searched for only when the triangle nearest to the previous one is farther than the largest
  // distance so far (the maximum is still exact).
  Measured measure(const std::vector<glm::vec3>& pb, const std::vector<uint32_t>& ib,
                   double give_up_above = 1e30, bool with_mean = true);

 private:
  struct Impl;
  Impl* impl_;
};

}  // namespace bb::decimate
