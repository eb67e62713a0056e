// Head, hands and feet at the middle and lowest levels of detail (paper section 3.1, figure 3).
//
// decimate_extremities: the contour-sampled body keeps its rings; the OpenVDB extremities zipped
// to it are decimated (decimate.h) to a triangle budget, with every body and seam vertex locked,
// so the seams stay exactly where they were and no crack opens. With several candidates per part
// (rule settings, and where to start: the given mesh or a restart mesh), each result is measured
// against the full-resolution part and the nearest kept: a real optimisation by measured error
// (meshoptimizer is never used here; it is bench_decimate's yardstick only).
//
// bake_proxies: at the lowest level the extremities are simple geometry (the mesher's coarse,
// contour-sampled caps); their look comes from a texture baked from the full-resolution meshes:
// for every texel of a proxy triangle, the nearest point of the same extremity in the detailed
// mesh gives its normal, and the texel stores the skin colour scaled by how much that normal's
// lighting differs from the proxy's, darkened where the detail is far below the proxy (the gaps
// between fingers). Units: metres; colours linear RGB in [0, 1].
#pragma once

#include <cstdint>
#include <memory>
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

// One way to decimate a part: from which mesh and with which rules (decimate.h's Options).
struct Candidate {
  bool restart = false;               // from ExtremityOptions::restart's part instead of the mesh's own
  double member_k = 1;                // Options::member_k
  float max_weight_difference = 0.6f; // Options::max_weight_difference
};

// Best of several candidates per part: each part is decimated to its share of the budget (shares
// from `mesh`'s parts) once per candidate, each result's symmetric Hausdorff distance to the
// reference's part (or the mesh's own, without a reference) is measured (ReferenceDistance) and
// the nearest without self-intersections (check_mesh on the part alone) is kept (the first on
// ties); only where every candidate has some, the one with the fewest (then the nearest). `reference` and `restart`: meshes with the same head,
// hands and feet (same part tags, seam loops at the same positions), e.g. LOD 0 before decimation
// and a lightly decimated copy of it, so that a part decimated from them still meets `mesh`'s
// zippers. Locked vertices, the normal rules and skin-weight influences are decimate()'s; only the
// rules' settings vary.
// The reference's parts and their measurements (ReferenceDistance), built on first use and kept
// for later calls with the same reference (`build`'s levels): pass one cache to each call.
struct ReferenceCache;
std::shared_ptr<ReferenceCache> new_reference_cache();

struct ExtremityOptions {
  size_t budget = 0;                               // extremity triangles in all
  const mesher::SkinnedMesh* reference = nullptr;  // measured against; null: `mesh` itself
  const mesher::SkinnedMesh* restart = nullptr;    // restart candidates start here; null: the reference
  std::vector<Candidate> candidates{Candidate{}};  // at least one
  unsigned threads = 0;                            // parts in parallel; 0: one per core
  double snapshot_factor = 0;  // > 1, with a `snapshot` mesh given: the first candidate's passes copy
                               // each part out at this many times its target (Options::snapshot_triangles)
  bool snapshot_restarts = false;  // restart candidates after the first start from its snapshot
  std::shared_ptr<ReferenceCache> cache;  // optional, see new_reference_cache
};
struct ExtremityReport {
  Report report;                  // as decimate_extremities' report (whole mesh against `mesh`)
  std::vector<uint8_t> parts;     // per part decimated: its tag,
  std::vector<size_t> chosen;     // the candidate kept (index into ExtremityOptions::candidates),
  std::vector<double> hausdorff_m, mean_m;  // and its distance to the reference's part,
  std::vector<size_t> self_intersections;   // and its intersecting triangle pairs (the part alone;
                                            // 0 unless every candidate had some)
};
// `snapshot`: `mesh` with those copies as its extremities (a restart mesh for coarser levels).
// Each part's locked vertices: those shared with any other triangle, on the part's border, or
// tagged seam.
Result<mesher::SkinnedMesh> decimate_extremities(const mesher::SkinnedMesh& mesh, const ExtremityOptions& options,
                                                 ExtremityReport* report = nullptr,
                                                 mesher::SkinnedMesh* snapshot = nullptr);

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

// The candidates `bodybuilder build` runs at `level` of `levels` (the last one, contour-sampled
// proxies, is not decimated). Level 0, from full resolution: the strict run (member ratio 1, skin
// weights 0.6), which copies the parts out after its first pass at or below twice its target (the
// restart mesh of this level and of the coarser ones), then three restarts from that copy with
// member ratio 0, 2 and 1. Middle levels: from the previous level (strict), or from level 0's copy
// with the skin-weight threshold loosened to 1.0 (member ratio 1 and 0); the coarsest decimated
// level: from the previous level (strict and loosened) or from level 0's copy (loosened). At
// levels 1 and 2 a hand is tens of pixels tall; level 0 keeps the strict weight rule. Budget,
// reference, restart, cache and threads are left to the caller.
ExtremityOptions extremity_level_options(int level, int levels);

}  // namespace bb::decimate
