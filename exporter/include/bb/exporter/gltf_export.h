// The toolchain's product: one binary glTF (.glb) per body that a game or tool can load.
//
//  - the skeleton as nodes (H-Anim joint names), their rest transforms the bind posture;
//  - one skin shared by every LOD mesh, inverse bind matrices of the bind posture;
//  - per LOD a mesh (POSITION, NORMAL, JOINTS_0 u16, WEIGHTS_0 float, optional TEXCOORD_0), at
//    most 4 influences summing to 1, materials (skin colour; the lowest LOD's proxy texture);
//  - the LOD chain through MSFT_lod on the LOD 0 node, extras.MSFT_screencoverage one value per
//    level; lower-LOD nodes are not scene roots; per-LOD error and checks in the mesh's extras;
//  - every clip as a glTF animation (root translation, joint rotations; linear, strictly
//    increasing key times).
// Units: metres, seconds. The Khronos validator reports 0 errors and 0 warnings on the result.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "bb/mesher/skinned_mesh.h"
#include "bb/modeler/body.h"
#include "bb/motion/clip.h"
#include "bb/result.h"

namespace bb::exporter {

struct Image {
  int width = 0, height = 0;
  std::vector<uint8_t> rgba;  // width * height * 4, rows top to bottom
};

struct ExportLod {
  mesher::SkinnedMesh mesh;     // in the body's bind posture (Body::sample_posture)
  mesher::LodReport report;     // written to the mesh's extras
  float screen_coverage = 0;    // MSFT_screencoverage of this level
  int texture = -1;             // index into ExportInput::textures for a base-colour texture, or -1
};

struct ExportInput {
  const modeler::Body* body = nullptr;  // its skeleton and sample posture
  std::vector<ExportLod> lods;          // LOD 0 first; at least one
  std::vector<motion::Clip> clips;
  std::vector<Image> textures;
  glm::vec3 skin_colour{0.80f, 0.62f, 0.50f};  // linear base colour
};

// Encodes the input as GLB bytes. Errors name the LOD or clip that is inconsistent.
Result<std::vector<uint8_t>> encode_glb(const ExportInput& input);

// One file per LOD for tools that ignore MSFT_lod: the same model with only level `level`.
Result<std::vector<uint8_t>> encode_glb_level(const ExportInput& input, int level);

}  // namespace bb::exporter
