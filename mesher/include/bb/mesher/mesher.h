// Section 3.1 of the paper: multi-resolution modelling by sampling one implicit surface at
// several densities. Contours circle each limb link; rays are cast star-shaped from origins on
// the link; the outermost crossing with the skin is a sample. Head, hands and feet, which are
// not star-shaped around one link, come from OpenVDB (narrow-band level set of the same field,
// then volumeToMesh) and are zipped to the limb contours at the neck, wrist and ankle seams.
//
// Lifecycle:
//   const bb::modeler::Body& body = bb::modeler::default_body();
//   auto lods = bb::mesher::build_lods(body);          // LOD 0 first, falling triangle counts
//   if (!lods) { report(lods.error().message()); return; }
//   for (const bb::mesher::Lod& lod : *lods) export(lod.mesh, lod.report, lod.screen_coverage);
//
// Units: metres. Meshes are in the body's bind posture (Body::sample_posture); joint indices are
// skeleton joint indices; triangles are counter-clockwise seen from outside.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "bb/mesher/skinned_mesh.h"
#include "bb/modeler/body.h"
#include "bb/result.h"

namespace bb::mesher {

// Sample density of one limb or the torso: `contours` rings per skeleton link along the part's
// axis (the torso counts three links: lumbar, thoracic, cervical) and `points` samples per ring
// (rays around the axis). The closed start of a part (shoulder, hip, pelvis) gets a cap of about
// points / 4 latitude rings cast from the first ring's centre.
struct PartDensity {
  int contours = 8;   // rings per link, >= 1
  int points = 16;    // samples per ring, >= 4
};

// One level of detail.
struct LodDensity {
  PartDensity torso{12, 40};  // pelvis to the neck seam (3 links)
  PartDensity arm{12, 20};    // 2 links (upper arm, forearm), rings spread from the clavicle to the wrist seam
  PartDensity leg{12, 24};    // hip to the ankle seam (2 links)
  // Contour-sampled extremities (when !vdb_extremities): latitude rings of the star-shaped
  // "cup" cast from the centre of the hand, foot or head; each ring has as many points as the
  // limb ring it continues (arm, leg, torso points).
  int hand_rings = 8, foot_rings = 10, head_rings = 10;
  // Meridians of the cups; 0 (or fewer than the limb ring's points) keeps the limb ring's count.
  // The foot wants more than the ankle: it is long and the toes sit between meridians.
  int hand_points = 0, foot_points = 0, head_points = 0;
  // true: head, hands and feet are the full-resolution OpenVDB meshes, tagged in
  // SkinnedMesh::part and zipped along SkinnedMesh::seam loops (decimation works on them);
  // false: they are contour-sampled cups (self-contained coarse levels; part/seam still tagged).
  bool vdb_extremities = false;
  // Crease fitting after the union, as a fraction of the body height (0: off). Where pieces meet
  // (armpits, groin) the contour pieces miss the skin's blend and the union's intersection
  // curves lie inside it: vertices farther than this from the skin are moved onto it, then edges
  // whose midpoint is farther are split with the new vertex on the skin, up to `crease_passes`
  // times; moves that would make triangles intersect are taken back (see mesher.cpp).
  float crease_tolerance = 0;
  int crease_passes = 4;
  float screen_coverage = 0;  // MSFT_screencoverage of this level (fraction of screen height)
};

struct MesherOptions {
  // Levels, finest first. Empty: the default chain (default_lod_chain()).
  std::vector<LodDensity> lods;
  // OpenVDB voxel edge, metres on a 1.75 m body (scaled with the height), for the head/feet and
  // (finer) for the hands.
  float vdb_voxel_m = 0.006f;
  float vdb_hand_voxel_m = 0.003f;
  // Error report (LodReport): points sampled on the implicit surface and on each mesh; 0 skips
  // the distances (report left at 0) but still checks closed/manifold/self-intersections.
  int error_samples = 20000;
  bool check_topology = true;  // CGAL checks per LOD (self-intersection test is the costly one)
};

// The default chain, 4 levels (default body, measured): LOD 0 has ~9,300 contour triangles
// (crease fitting at 0.15 % of the height included) plus the full-resolution OpenVDB head, hands
// and feet (~46,000 triangles; decimation brings them down), within 0.15 % of the height
// (0.15-0.29 % on random variants), extremities within 0.15 %; then contour-only levels of
// ~4,600, ~2,000 and ~690 triangles with star-shaped cups for the extremities, within 2.1, 2.2
// and 2.4 % (coarsest 2.4-2.8 % on variants 1-3; the toes and the groin).
std::vector<LodDensity> default_lod_chain();

// Samples the body's skin in its bind posture (body.sample_posture) into one skinned mesh per
// level, LOD 0 first. Every mesh is one closed, consistently oriented 2-manifold (checked and
// reported in LodReport), vertices carry at most 4 normalized joint influences.
// Errors: an empty body, a skeleton without the joints the mesher needs (H-Anim names of
// data/skeleton.json), an invalid density, or a level whose mesh could not be joined.
Result<std::vector<Lod>> build_lods(const modeler::Body& body, const MesherOptions& options = {});

// Per-stage wall-clock seconds of the last build_lods call on this thread (for benchmarks and
// `bodybuilder mesh --json`).
struct StageTimes {
  double field = 0;       // ImplicitSurface construction
  double contours = 0;    // star-shaped contour sampling, all levels
  double extremities = 0; // OpenVDB field sampling + volumeToMesh + clipping
  double joining = 0;     // zipping seams and CGAL union of the pieces, all levels
  double refining = 0;    // crease refinement (LodDensity::crease_tolerance), all levels
  double skinning = 0;    // weights and normals, all levels
  double checks = 0;      // CGAL topology checks, all levels
  double errors = 0;      // distance measurements, all levels
};
const StageTimes& last_stage_times();

}  // namespace bb::mesher
