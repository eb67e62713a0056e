// The whole offline pipeline for one body: modeler -> mesher -> decimate -> glTF.
//
//   LOD 0      contour-sampled body + OpenVDB head, hands and feet decimated to a budget
//   LOD 1..K-2 coarser contours + the previous level's extremities decimated further (seams locked)
//   LOD K-1    coarsest contours + simple contour-sampled extremities textured from LOD 0 (proxies)
// plus a procedural walk clip and any imported clips, written as one GLB (and optionally one
// GLB per level).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "bb/exporter/gltf_export.h"
#include "bb/mesher/mesher.h"
#include "bb/modeler/body.h"
#include "bb/motion/clip.h"
#include "bb/result.h"

namespace bb::exporter {

struct BuildOptions {
  int lods = 4;                              // levels, 2..8 (the default chain has 4)
  std::vector<float> walk_speeds = {1.2f};   // one baked walk clip per speed, m/s
  // Air the walk keeps between the hanging upper arms and the torso, metres for a body 1.75 m tall
  // (scaled by the body's height): the arms hang the walk's 9 degrees out, or further where a heavy
  // body needs it (modeler::walk_arm_abduction; at most 30 degrees). Negative: 9 degrees for every
  // body.
  float walk_arm_clearance_m = 0.01f;
  std::vector<motion::Clip> extra_clips;     // imported clips (already retargeted)
  bool proxies = true;                       // textured proxies at the lowest level
  size_t lod0_extremity_triangles = 4000;    // head, hands and feet of LOD 0 (0: full resolution)
  // Per final level: Hausdorff and mean distance to the skin (from mesh samples, the distance to the
  // skin along the field's gradient line; LOD 0's full-resolution vertices, which lie on the skin,
  // to the mesh). Closed/manifold/self-intersection checks run either way.
  bool measure_errors = true;
  // Threads for the parallel stages (extremity parts, per-level checks); 0: one per core. A batch
  // that runs several bodies at once gives each 1.
  unsigned threads = 0;
};

struct BuildTimes {
  double mesh = 0, decimate = 0, checks = 0, proxies = 0, clips = 0, encode = 0, total = 0;  // seconds
};

struct BuildOutput {
  ExportInput input;               // what was written (meshes, reports, clips, textures)
  float walk_arm_abduction_rad = 0;  // how far out the walk's arms hang
  std::vector<uint8_t> glb;        // the whole LOD set
  BuildTimes times;
};

Result<BuildOutput> build_body(const modeler::Body& body, const BuildOptions& options = {});

}  // namespace bb::exporter
