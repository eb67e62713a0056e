// A compact, immutable runtime asset built from a skinned glTF file: node hierarchy, skin
// palette (node + inverse bind matrix), mesh LOD levels, base-colour textures, clips, and the
// data the impostor path needs (Ta, the snapshot radius, posture-test distances).
//
// Units: metres, seconds, radians. Model space is the glTF scene's space (Y up, +Z forward).
// No GL or tinygltf type appears here.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include "bb/result.h"

namespace bb::runtime {

struct Transform {
  glm::vec3 translation{0.0f};
  glm::quat rotation{1.0f, 0.0f, 0.0f, 0.0f};  // unit
  glm::vec3 scale{1.0f};
  glm::mat4 matrix() const;
};

struct Node {
  std::string name;
  int parent = -1;  // index into Model::nodes, always < this node's index; -1 for a root
  Transform rest;   // local transform when no clip animates it
};

// One skinning matrix slot: palette matrix = world(node) * inverse_bind. Rigid (unskinned)
// meshes get a slot with their own node and an identity inverse bind.
struct PaletteEntry {
  int node = 0;
  glm::mat4 inverse_bind{1.0f};
};

struct Vertex {
  glm::vec3 position{0.0f};  // bind space
  glm::vec3 normal{0.0f, 1.0f, 0.0f};
  glm::vec2 uv{0.0f};
  glm::u16vec4 joints{0};    // indices into Model::palette
  glm::vec4 weights{1.0f, 0.0f, 0.0f, 0.0f};  // sum to 1
  glm::u8vec4 color{255};    // COLOR_0 (linear, RGBA): multiplies the base colour where the material says so
};

struct Primitive {
  std::uint32_t first_index = 0;  // into MeshLod::indices
  std::uint32_t index_count = 0;  // a multiple of 3 (triangles)
  int material = 0;               // into Model::materials (a default one is always present)
};

struct MeshLod {
  std::vector<Vertex> vertices;
  std::vector<std::uint32_t> indices;
  std::vector<Primitive> primitives;
  // MSFT_screencoverage: use this level while the character's on-screen height divided by
  // the viewport height is >= this value (level 0: the finest). 0 for the last level.
  float screen_coverage = 0.0f;
  // A level made at load (LoadOptions::lod_levels), not read from the file, and its simplification
  // error as meshoptimizer reports it (bind pose, model units: about the farthest a surface point
  // moved; 0 for the file's levels).
  bool made_at_load = false;
  float generated_error = 0.0f;
  // A made level's error as drawn: the farthest a vertex of level 0 lies from this level's surface,
  // both skinned, over the rest pose and 12 instants of the clips (model units; a sampled estimate).
  // The simplifier does not weigh the skin, so this can be far above generated_error; the level's
  // switch takes the larger of the two.
  float skinned_error = 0.0f;
  std::size_t triangle_count() const { return indices.size() / 3; }
};

// How a material's texture is read: a glTF sampler (its defaults where the file gives none; the
// minification filter glTF leaves to the implementation is trilinear here).
enum class Wrap : std::uint8_t { kRepeat, kClampToEdge, kMirroredRepeat };
struct TextureSampler {
  Wrap wrap_s = Wrap::kRepeat, wrap_t = Wrap::kRepeat;  // s: u, t: v
  bool mag_nearest = false;  // magnified: the nearest texel, else bilinear
  bool min_nearest = false;  // minified: the nearest texel of a level, else bilinear
  bool mipmaps = true;       // minified: from the mip chain (glTF's *_MIPMAP_* filters), else level 0 only
  bool mip_nearest = false;  // with mipmaps: the nearest level, else a blend of the two nearest
  bool operator==(const TextureSampler&) const = default;
};

struct Material {
  glm::vec4 base_color{1.0f};  // linear factor
  int texture = -1;            // into Model::textures, or -1
  TextureSampler sampler;      // how `texture` is read
  float alpha_cutoff = 0.5f;   // used when alpha_mask
  bool alpha_mask = false;
  // glTF BLEND: drawn after the opaque surfaces, over them, without writing depth (premultiplied:
  // colour times alpha plus what lies behind times one minus alpha); in a snapshot the texel keeps
  // the blended colour and its accumulated alpha, so the impostor lets the background through alike.
  bool alpha_blend = false;
  bool vertex_colors = false;  // its primitives' vertices carry colours (Vertex::color)
  bool unlit = false;          // KHR_materials_unlit: drawn in its base colour, with no light
  // glTF doubleSided: both faces drawn, a back face lit with its normal reversed. Otherwise (glTF's
  // default) back faces are culled, in the scene and in snapshots alike: front faces wind
  // counter-clockwise in model space (a rigid mesh under a mirroring node has its triangles turned
  // at load, so this holds for every primitive).
  bool double_sided = false;
  // glTF emissiveFactor (linear), added to the shaded colour; emissiveTexture is not read.
  glm::vec3 emissive{0.0f};
};

struct Texture {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgba;  // width * height * 4, rows top to bottom (glTF uv origin)
};

enum class Interpolation { kStep, kLinear, kCubicSpline };
enum class ChannelPath { kTranslation, kRotation, kScale };

struct Channel {
  int node = 0;
  ChannelPath path = ChannelPath::kTranslation;
  Interpolation interpolation = Interpolation::kLinear;
  std::vector<float> times;         // strictly increasing, seconds
  std::vector<glm::vec4> values;    // xyz (or quaternion xyzw); cubic: 3 per key (in, value, out)
};

struct Clip {
  std::string name;
  float duration = 0.0f;  // seconds: the last key time (>= 0)
  std::vector<Channel> channels;
};

// Posture test (paper section 5.1): a point is a joint origin plus an offset in that joint's frame.
struct PosturePoint {
  int node = 0;
  glm::vec3 offset{0.0f};
};
struct PosturePair {
  PosturePoint a, b;
};
constexpr int kPosturePairs = 4;

// Where a clip time falls among a baked clip's frames: the per-frame paths show frame f0's pose
// blended towards frame f1's by `blend` (palette rows on the GPU and the CPU, posture distances,
// bounds and the root's travel alike).
struct BakedSample {
  int f0 = 0, f1 = 0;  // frames of the clip (add BakedClip::first_row for palette rows)
  float blend = 0.0f;  // [0, 1], f0 -> f1
};

// A clip resampled at a fixed rate for the per-frame paths (GPU skinning reads the palette
// rows; the cache tests read the posture distances and nothing else).
//
// A blend of two frames spreads a STEP channel's jump over the frame around its key (a held pose
// blended into the next for 1/60 s). So each key at which a STEP channel's value changes gets frames
// of its own at the key's time: where the clip mixes STEP with LINEAR or CUBICSPLINE channels, the
// pose just before the key (the STEP channels still at their previous key, the others at the key's
// time), then the pose at it (not where a grid frame falls on that very time). A time between frames
// blends the two around it, which then hold every STEP channel (both frames agree on it) and jump
// exactly at its key, while the other channels go on blending between frames. A clip whose channels
// are all STEP (`stepped`) never moves between keys: its blend is 0 (the frame at or before the
// time), and only a key between grid frames gets a frame, the pose at it.
struct BakedClip {
  int frame_count = 0;  // >= 1: the grid frames (grid.size()) and the step edges' frames
  float rate = 60.0f;   // grid frames per second: grid frame g is at time min(g / rate, duration)
  // Per frame, the clip time it shows (seconds, non-decreasing; the two frames of a step edge share
  // their key's time) and whether it shows the pose just before that time (sample_clip_before; the
  // first frame of an edge) rather than at it (sample_clip).
  std::vector<float> times;
  std::vector<std::uint8_t> before_step;
  std::vector<int> grid;  // frame index of each grid frame, increasing
  // Every channel of the clip is STEP: blend always 0.
  bool stepped = false;
  // The frames around clip time `time` (seconds, in [0, duration]; clip_time gives it; NaN or
  // negative: 0): f0 the last frame at or before it (of an edge, the pose at the key), f1 the next
  // (f0 at the last frame). A clip without edges takes the grid alone, blend = time * rate - f0 as
  // ever; with edges, a few comparisons more where they are near. Allocates nothing.
  BakedSample sample(float time) const {
    BakedSample s;
    if (frame_count <= 1) return s;
    if (!(time > 0.0f)) time = 0.0f;  // NaN too
    if (grid.size() != times.size()) return sample_edges(time);
    // No step edges: the grid alone, in frame units (inline: the planner calls this per character).
    const float fx = std::min(time * rate, static_cast<float>(grid.size() - 1));
    s.f0 = static_cast<int>(fx);
    s.f1 = std::min(s.f0 + 1, frame_count - 1);
    if (!stepped && s.f1 > s.f0) s.blend = fx - static_cast<float>(s.f0);
    return s;
  }
  BakedSample sample_edges(float time) const;  // sample() of a clip with step edges, time >= 0
  std::uint32_t first_row = 0;  // first row of this clip in Model::baked_palette()
  // kPosturePairs squared distances per frame (model space, m^2).
  std::vector<std::array<float, kPosturePairs>> posture;
  // Bounding box of each frame's pose (model space, metres, with a 2 % of radius margin).
  std::vector<std::array<glm::vec3, 2>> bounds;
  // Horizontal (x, z) travel of the skeleton's root from its rest place, per frame (metres):
  // clips with root motion carry Ta (and the impostor) along.
  std::vector<glm::vec2> root_offset;
  // The speed the clip walks at (model units per second), measured from its poses: how fast the
  // body moves horizontally over its supporting foot (the lowest end joint, where it is within 15 %
  // of the height of the pose's lowest point), the median over the grid frames. An in-place walk's foot
  // slides back at that speed, a clip with root motion moves the body over a foot that stays put.
  // 0 where the clip does not walk (no supporting foot in a quarter of the frames, or the body
  // moving over it at under 5 % of the height per second).
  float ground_speed = 0.0f;
};

// A body part for impostor part cards (ImpostorConfig::part_cards, the paper's section 7 item 2):
// the skin joints that move together, carried by one bone. Found at bake time from the skin and
// the clips (Model::body_parts).
constexpr int kMaxBodyParts = 16;
struct BodyPart {
  int bone = 0;              // palette entry whose matrix carries the part (its top joint)
  std::vector<int> joints;   // palette entries of the part
  // The part's vertices (its own triangles and those it overlaps at its joints) in the bone's
  // palette space, i.e. inverse(palette matrix) * skinned position = the bind position for a
  // vertex skinned to the bone alone; over sampled frames of every clip, with a margin. Metres.
  glm::vec3 box_min{0.0f}, box_max{0.0f};
  glm::vec3 centre{0.0f};    // of the bounding sphere, same space
  float radius = 0.0f;       // metres
  float mass = 0.0f;         // share of the skin weight of the finest level (own joints only)
  // Principal axis of the part's vertices (same space, unit) and how elongated the part is along
  // it: the ratio of the standard deviations along the first and second principal axes (>= 1),
  // and how flat its cross-section is: the same ratio for the second and third (>= 1). A limb
  // (elongated, round across) looks nearly the same turned about this axis.
  glm::vec3 axis{0.0f, 1.0f, 0.0f};
  float elongation = 1.0f, flatness = 1.0f;
};

// Triangles of each body part, per mesh level: the level's index list regrouped, triangles at the
// joints repeated in every part they overlap (so cards do not crack where limbs bend).
struct PartIndices {
  std::vector<std::uint32_t> indices;  // into the level's vertices, then cap_vertices
  struct Range {
    std::uint32_t first = 0, count = 0;  // into `indices`: the part's triangles
    // Then `caps` more indices: triangles that close the part's cuts (where its triangles end and
    // its neighbour's begin, not the mesh's own borders), a fan from each opening's centre, facing
    // out of the part. A part snapshot draws them with the part, culling back faces as its
    // material says: they stand where the neighbour's surface continues the part, which the
    // neighbour's card shows only where it has not moved since (without them the snapshot shows
    // the part's inside through the cut, or with back faces culled, the background).
    std::uint32_t caps = 0;
  };
  std::vector<Range> ranges;  // [primitive * part_count + part]
  // The caps' corners (index level vertex count + i): copies of the cut's vertices and of the
  // openings' centres (bind position the mean of the cut's, weights the cut's summed, four
  // heaviest kept; normal the mean of the cut's, not unit: across a round opening it interpolates
  // to the outward normal of the surface that would continue the part there).
  std::vector<Vertex> cap_vertices;
};

// The skin as the file stores it, before the loader fixed it up (each vertex keeps its four heaviest
// influences, weights renormalized to sum to 1): for `inspect`, and for anyone checking an asset.
struct SkinReport {
  std::size_t skinned_vertices = 0;   // over every level's skinned primitives
  int max_influences = 0;             // most non-zero weights on one vertex (JOINTS_0 and JOINTS_1: up to 8)
  double worst_weight_sum_error = 0;  // largest |sum of a vertex's stored weights - 1|
  bool weights_normalized = true;     // every sum within 1e-5 of 1 (2/255 for integer weights)
  std::size_t vertices_over_four = 0; // vertices that lost their fifth to eighth influences
  double worst_dropped_weight = 0;    // the largest share of one vertex's weight lost that way
  int skin_joints = 0;                // joints of the largest skin used
};

// Morph targets as the loader found them. This runtime draws every mesh at its default weights (the
// node's `weights`, else the mesh's), baked into the vertices at load; animated weights are not played.
struct MorphReport {
  std::size_t primitives = 0;      // primitives with targets, over every level
  int most_targets = 0;            // on one primitive
  std::size_t weighted_targets = 0;  // targets with a non-zero default weight, baked in
  int weight_channels = 0;         // animation channels on "weights" (not played)
};

class Model {
 public:
  std::string name;  // file stem
  std::vector<Node> nodes;           // parents before children
  std::vector<PaletteEntry> palette; // at most 65535
  std::vector<MeshLod> lods;         // >= 1 level, finest first
  std::vector<Material> materials;   // >= 1
  std::vector<Texture> textures;
  std::vector<Clip> clips;           // may be empty (then the rest pose is a 0 s clip)
  SkinReport skin_report;            // set by load_model
  MorphReport morph_report;          // set by load_model

  // Section 4.2: Ta, the centre of the bounds of every pose of every clip (model space, measured
  // relative to the root's horizontal travel, see BakedClip::root_offset, so a clip that walks
  // away does not inflate it), and the radius around Ta (+ that travel) containing every vertex of
  // every pose: the snapshot frustum's half size.
  glm::vec3 ta{0.0f};
  float radius = 1.0f;
  glm::vec3 bounds_min{0.0f}, bounds_max{0.0f};  // of all poses, model space (travel included)

  // Index of the clip named `name`, or -1.
  int find_clip(std::string_view clip_name) const;
  int find_node(std::string_view node_name) const;
  // Duration of clip `clip` (0 when there are no clips).
  float clip_duration(int clip) const;

  // Posture pairs used by the cache test; chosen automatically at load (the widest-spanning
  // pairs of end-effector points whose distance varies in the clips). Replace them with
  // set_posture_pairs (re-bakes the distances; not for the per-frame path).
  std::span<const PosturePair> posture_pairs() const { return posture_pairs_; }
  void set_posture_pairs(std::span<const PosturePair> pairs);
  // Same, by joint names; an error names the unknown joint.
  Status set_posture_pairs(std::span<const std::pair<std::string, std::string>> joint_names);

  // Baked clips (one per clip, or one 1-frame rest pose when there are no clips).
  std::span<const BakedClip> baked_clips() const { return baked_; }
  // Palette rows: palette.size() * 3 vec4 per frame (the transposed top 3 rows of each
  // palette matrix), frames of all clips one after the other.
  std::span<const glm::vec4> baked_palette() const { return baked_palette_; }

  // Rebuilds the baked data at `rate` frames per second (load does this at 60), and the body parts.
  void bake(float rate = 60.0f);

  // Body parts (at least one; one = the whole body; at most kMaxBodyParts) and their triangles
  // per level. Automatic: a skin joint starts a new part when its subtree holds at least 1.5 % of
  // the skin weight and it turns more than 12 degrees relative to its parent's part over the clips
  // (our walking body: root (pelvis), chest, thighs, shins, feet, upper arms, forearms+hands; the
  // neck and head stay with the chest). Parts with under 0.5 % of the weight of their own join
  // their parent's. A triangle belongs to the part with most of its vertices' weight, and also to
  // every part that weighs 0.7 or more on one of its vertices (so cards overlap a little at the
  // joints). A model with no clip, or where nothing turns, has one part.
  std::span<const BodyPart> body_parts() const { return parts_; }
  const PartIndices& part_indices(int lod) const { return part_indices_[lod]; }
  // Replaces the automatic parts: `bones[k]` are the palette entries that start part k (the first
  // is the root part); every other joint joins the part of its nearest ancestor. Recomputes the
  // triangles and bounds (not for the per-frame path).
  void set_body_parts(std::span<const int> bones);

 private:
  std::vector<BodyPart> parts_;
  std::vector<PartIndices> part_indices_;
  void split_parts(std::span<const int> bones);
  std::vector<PosturePair> posture_pairs_;
  std::vector<BakedClip> baked_;
  std::vector<glm::vec4> baked_palette_;
  void bake_posture();
};

struct LoadOptions {
  float bake_rate = 60.0f;  // frames per second for the baked clips
  // Levels of detail for a file that has one level only (no MSFT_lod): up to this many coarser
  // levels are made at load, each with about half the triangles of the one before (meshoptimizer's
  // simplifier on the welded bind-pose mesh, each primitive on its own, borders kept; a flat-shaded
  // primitive welded without its normals and flat-shaded again), until a level would keep more than
  // 80 % of the one before. Each is used where its error (the larger of the simplifier's and the
  // skinned one, MeshLod::skinned_error) projects under lod_error_px pixels on a viewport
  // lod_reference_height_px high (MeshLod::screen_coverage).
  // 0: none (the file's levels only).
  int lod_levels = 0;
  float lod_error_px = 1.0f;
  int lod_reference_height_px = 1080;
  // optimize_vertex_order() on every level, the file's and the made ones. Off: the file's triangle
  // and vertex order, vertex i of a level being the loader's vertex i (its own numbering over the
  // level's primitives). Flow test bed on llvmpipe, CesiumMan (a file in no cache order: 2.07
  // vertices shaded a triangle under a 32-entry FIFO, 0.79 in this order): 200 walkers' geometry
  // frame 223-228 ms against 251-288 ms; 20 walkers, three alternated runs, geometry 38-41 against
  // 42-51 ms, impostors 5.8-6.2 against 7.2-8.3 ms (their snapshots shade fewer vertices too).
  bool optimize_vertex_order = true;
};

// Loads a .gltf or .glb file. The character is every mesh reachable from the default scene
// (or scene 0, or every root node): skinned meshes use their skin (their node's own transform is
// ignored, as glTF says), unskinned ones follow their node rigidly. MSFT_lod on a mesh node adds
// levels; extras.MSFT_screencoverage gives their switch values. Errors name the file, a JSON
// path and the reason; malformed files never crash.
Result<Model> load_model(const std::string& path, const LoadOptions& options = {});

// The coarser levels of LoadOptions::lod_levels (its three fields), added to a model that has one
// level (none otherwise); returns how many. load_model does this before baking; on a model already
// loaded, call Model::bake() afterwards (body parts and their triangles are made per level there).
int add_generated_lods(Model& model, const LoadOptions& options);

// Each level's triangles reordered for the post-transform vertex cache (meshoptimizer's
// optimizeVertexCache, each opaque or alpha-tested primitive on its own; alpha-blended ones keep
// the file's order), then its vertices renumbered in the order the triangles first use them
// (optimizeVertexFetchRemap; vertices no triangle uses are dropped). The same triangles and
// pictures, less vertex work: skinning every vertex a triangle uses, on llvmpipe as on a GPU.
// load_model does this (LoadOptions::optimize_vertex_order) before baking; on a model already
// loaded, call Model::bake() afterwards.
void optimize_vertex_order(Model& model);

// Vertices a level's triangles shade per triangle, in their order, under a post-transform cache of
// `cache_size` entries that keeps the most recent vertices (FIFO; meshoptimizer's analyzer). 0.5 is a
// closed mesh's best, 3 no reuse at all; what a GPU's cache does, roughly, and llvmpipe's (which keeps
// 256 entries per 1,024 indices, direct-mapped by index: vertices numbered in first use fill it well).
float vertices_shaded_per_triangle(const MeshLod& lod, unsigned cache_size = 32);

}  // namespace bb::runtime
