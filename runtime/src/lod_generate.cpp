// Levels of detail made at load for a model whose file has one level (LoadOptions::lod_levels), so
// that the geometry path can draw anyone's model as it draws ours: finer up close, coarser far away;
// and every level's triangles and vertices put in vertex cache order (LoadOptions::optimize_vertex_order).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include <meshoptimizer.h>

#include "bb/runtime/animation.h"
#include "bb/runtime/model.h"
#include "triangle_grid.h"

namespace bb::runtime {

namespace {

// One primitive of level 0, welded (bitwise-equal vertices shared: a non-indexed mesh becomes a
// connected one the simplifier can collapse) into its own vertex list. A flat-shaded primitive
// (every corner its own vertex, its normal its triangle's: what the loader makes of a file without
// normals, such as the Fox's) is welded without its normals, which would keep every triangle apart,
// and its levels get flat normals again. UV and colour seams stay: meshoptimizer keeps the vertices
// on either side of a seam together.
struct WeldedPrimitive {
  std::vector<Vertex> vertices;
  std::vector<std::uint32_t> indices;
  int material = 0;
  bool flat = false;
  std::vector<glm::vec3> normals;  // flat: each welded vertex's normal in its first triangle (for zero-area ones)
  float scale = 1.0f;  // meshopt_simplifyScale: the simplifier's relative errors times this are model units
};

// The unit normal of triangle abc, or `otherwise` where it has no area.
glm::vec3 face_normal(const Vertex& a, const Vertex& b, const Vertex& c, glm::vec3 otherwise) {
  const glm::vec3 n = glm::cross(b.position - a.position, c.position - a.position);
  const float l = glm::length(n);
  return l > 0.0f ? n / l : otherwise;
}

// Whether every corner of the primitive has a vertex of its own whose normal is its triangle's
// (within 1e-3; a degenerate triangle's corners may hold anything).
bool flat_shaded(const MeshLod& lod, const Primitive& p) {
  std::vector<std::uint32_t> used(p.index_count);
  for (std::uint32_t k = 0; k < p.index_count; ++k) used[k] = lod.indices[p.first_index + k];
  std::sort(used.begin(), used.end());
  if (std::adjacent_find(used.begin(), used.end()) != used.end()) return false;
  for (std::uint32_t t = 0; t + 2 < p.index_count; t += 3) {
    const Vertex* c[3];
    for (int k = 0; k < 3; ++k) c[k] = &lod.vertices[lod.indices[p.first_index + t + k]];
    const glm::vec3 n = face_normal(*c[0], *c[1], *c[2], glm::vec3(0.0f));
    if (n == glm::vec3(0.0f)) continue;
    for (int k = 0; k < 3; ++k)
      if (glm::length(c[k]->normal - n) > 1e-3f) return false;
  }
  return true;
}

WeldedPrimitive weld(const MeshLod& lod, const Primitive& p) {
  WeldedPrimitive w;
  w.material = p.material;
  w.flat = flat_shaded(lod, p);
  std::vector<Vertex> corners(p.index_count);
  for (std::uint32_t k = 0; k < p.index_count; ++k) {
    corners[k] = lod.vertices[lod.indices[p.first_index + k]];
    if (w.flat) corners[k].normal = glm::vec3(0.0f);  // set again per triangle of each level
  }
  std::vector<unsigned int> remap(corners.size());
  const std::size_t unique =
      meshopt_generateVertexRemap(remap.data(), nullptr, corners.size(), corners.data(), corners.size(), sizeof(Vertex));
  w.vertices.resize(unique);
  meshopt_remapVertexBuffer(w.vertices.data(), corners.data(), corners.size(), sizeof(Vertex), remap.data());
  w.indices.assign(remap.begin(), remap.end());
  if (w.flat) {
    w.normals.assign(unique, glm::vec3(0.0f, 1.0f, 0.0f));
    for (std::size_t k = corners.size(); k-- > 0;) w.normals[remap[k]] = lod.vertices[lod.indices[p.first_index + k]].normal;
  }
  if (!w.vertices.empty()) w.scale = meshopt_simplifyScale(&w.vertices[0].position.x, w.vertices.size(), sizeof(Vertex));
  return w;
}

// The skin's poses the made levels are checked in (palette matrices, model space): the rest pose
// and instants evenly spread over each clip, 12 in all (at least 2 a clip).
std::vector<std::vector<glm::mat4>> check_poses(const Model& model) {
  std::vector<std::vector<glm::mat4>> poses;
  std::vector<Transform> locals(model.nodes.size());
  std::vector<glm::mat4> world(model.nodes.size());
  auto add = [&](int clip, float t) {
    sample_clip(model, clip, t, locals);
    world_matrices(model, locals, world);
    poses.emplace_back(model.palette.size());
    palette_matrices(model, world, poses.back());
  };
  add(-1, 0.0f);
  const int clips = static_cast<int>(model.clips.size());
  const int instants = clips > 0 ? std::max(2, 12 / clips) : 0;
  for (int c = 0; c < clips; ++c)
    for (int k = 0; k < instants; ++k) add(c, model.clips[c].duration * static_cast<float>(k) / static_cast<float>(instants));
  return poses;
}

// A made level's error as drawn: the farthest a vertex of `base` lies from the surface of `lod`,
// both skinned, over `poses` (model units). The simplifier measures its error in the bind pose
// only and does not weigh the skin, so a vertex collapsed onto a neighbour that follows another bone
// drifts off the surface as the joint bends. Nearest triangles come from a grid of each posed level.
float skinned_error(const std::vector<Vertex>& base, const MeshLod& lod, const std::vector<std::vector<glm::mat4>>& poses) {
  if (lod.indices.empty()) return 0.0f;
  std::vector<glm::vec3> corners(lod.vertices.size());
  float worst = 0.0f;
  for (const auto& pose : poses) {
    for (std::size_t v = 0; v < lod.vertices.size(); ++v) corners[v] = skinned_position(lod.vertices[v], pose);
    const detail::TriangleGrid grid(corners, lod.indices);
    for (const Vertex& v : base) worst = std::max(worst, grid.distance(skinned_position(v, pose)));
  }
  return worst;
}

}  // namespace

int add_generated_lods(Model& model, const LoadOptions& options) {
  if (model.lods.size() != 1 || options.lod_levels <= 0 || !(options.lod_error_px > 0.0f) ||
      options.lod_reference_height_px <= 0)
    return 0;
  const MeshLod& base = model.lods[0];
  // Welding compares vertices bitwise: Vertex must hold no padding.
  static_assert(sizeof(Vertex) == 60, "Vertex must stay free of padding for meshopt_generateVertexRemap");
  float lo = std::numeric_limits<float>::max(), hi = -lo;
  for (const Vertex& v : base.vertices) lo = std::min(lo, v.position.y), hi = std::max(hi, v.position.y);
  const float height = hi - lo;
  if (!(height > 0.0f)) return 0;
  std::vector<WeldedPrimitive> welded;
  for (const Primitive& p : base.primitives) welded.push_back(weld(base, p));
  const std::vector<std::vector<glm::mat4>> poses = check_poses(model);
  const std::vector<Vertex> base_vertices = base.vertices;  // `base` moves as levels are added

  int added = 0;
  std::size_t previous = base.triangle_count();
  for (int l = 1; l <= options.lod_levels; ++l) {
    MeshLod lod;
    float error = 0.0f;  // the level's: the largest of its primitives'
    for (const WeldedPrimitive& w : welded) {
      if (w.indices.empty()) continue;
      const std::size_t target = std::max<std::size_t>(3, (w.indices.size() / 3 >> l) * 3);
      std::vector<std::uint32_t> out(w.indices.size());
      float rel = 0.0f;
      const std::size_t n = meshopt_simplify(out.data(), w.indices.data(), w.indices.size(), &w.vertices[0].position.x,
                                             w.vertices.size(), sizeof(Vertex), target, 1.0f, meshopt_SimplifyLockBorder, &rel);
      out.resize(n);
      error = std::max(error, rel * w.scale);
      if (n == 0) continue;  // simplified away (a primitive too small to keep at this level)
      Primitive prim{static_cast<std::uint32_t>(lod.indices.size()), static_cast<std::uint32_t>(n), w.material};
      if (w.flat) {
        // Flat shading again: every corner a vertex of its own with its triangle's normal.
        for (std::size_t t = 0; t < n; t += 3) {
          // (A triangle of no area, such as three border vertices on one line, draws nothing in
          // the bind pose but may once skinned: its first corner's normal in the file.)
          const glm::vec3 nrm = face_normal(w.vertices[out[t]], w.vertices[out[t + 1]], w.vertices[out[t + 2]], w.normals[out[t]]);
          for (int k = 0; k < 3; ++k) {
            lod.indices.push_back(static_cast<std::uint32_t>(lod.vertices.size()));
            lod.vertices.push_back(w.vertices[out[t + k]]);
            lod.vertices.back().normal = nrm;
          }
        }
      } else {
        // The vertices this primitive's triangles still use, in first-use order.
        std::vector<std::uint32_t> slot(w.vertices.size(), ~0u);
        for (std::uint32_t i : out) {
          if (slot[i] == ~0u) {
            slot[i] = static_cast<std::uint32_t>(lod.vertices.size());
            lod.vertices.push_back(w.vertices[i]);
          }
          lod.indices.push_back(slot[i]);
        }
      }
      lod.primitives.push_back(prim);
    }
    // Stop where the simplifier cannot take much more away (borders, seams, tiny primitives).
    if (lod.indices.empty() || 5 * lod.triangle_count() > 4 * previous) break;
    lod.made_at_load = true;
    lod.generated_error = error;
    lod.skinned_error = skinned_error(base_vertices, lod, poses);
    previous = lod.triangle_count();
    // The previous level is used while the character is tall enough on screen that this one's
    // error would show as more than lod_error_px pixels: the larger of the simplifier's and the
    // error as drawn (CesiumMan's first made level: 0.09 % of its height in the bind pose, 3 % as it
    // walks, where vertices collapsed across a joint drift off the arms' surface).
    const float shown = std::max(error, lod.skinned_error);
    MeshLod& finer = model.lods.back();
    // (An error of 0: the coarser level is as good, used up to the finer one's own bound.)
    const float bound = model.lods.size() > 1 ? model.lods[model.lods.size() - 2].screen_coverage : 1.0f;
    finer.screen_coverage =
        shown > 0.0f ? std::min(bound, options.lod_error_px * height / (shown * static_cast<float>(options.lod_reference_height_px)))
                     : bound;
    model.lods.push_back(std::move(lod));
    ++added;
  }
  model.lods.back().screen_coverage = 0.0f;
  return added;
}

void optimize_vertex_order(Model& model) {
  std::vector<std::uint32_t> out;
  std::vector<unsigned int> remap;
  std::vector<Vertex> moved;
  for (MeshLod& ml : model.lods) {
    if (ml.indices.empty() || ml.vertices.empty()) continue;
    for (const Primitive& p : ml.primitives) {
      // A blended primitive's triangles blend in the file's order, which its author may have chosen.
      if (model.materials[static_cast<std::size_t>(p.material)].alpha_blend || p.index_count < 6) continue;
      std::uint32_t* first = ml.indices.data() + p.first_index;
      out.resize(p.index_count);
      meshopt_optimizeVertexCache(out.data(), first, p.index_count, ml.vertices.size());
      std::copy(out.begin(), out.end(), first);
    }
    // The vertices in the order the triangles first use them (the level's primitives share them);
    // vertices no triangle uses are dropped.
    remap.assign(ml.vertices.size(), 0);
    const std::size_t used = meshopt_optimizeVertexFetchRemap(remap.data(), ml.indices.data(), ml.indices.size(),
                                                              ml.vertices.size());
    moved.assign(used, Vertex{});
    for (std::size_t k = 0; k < ml.vertices.size(); ++k)
      if (remap[k] != ~0u) moved[remap[k]] = ml.vertices[k];
    for (std::uint32_t& i : ml.indices) i = remap[i];
    ml.vertices.swap(moved);
  }
}

float vertices_shaded_per_triangle(const MeshLod& lod, unsigned cache_size) {
  if (lod.indices.size() < 3 || lod.vertices.empty()) return 0.0f;
  return meshopt_analyzeVertexCache(lod.indices.data(), lod.indices.size(), lod.vertices.size(), cache_size, 0, 0).acmr;
}

}  // namespace bb::runtime
