// bodybuilder inspect FILE.glb|FILE.gltf [--json]: any skinned glTF, ours or anyone's.
// Levels come from the runtime's loader (MSFT_lod or one level); each level is checked with
// CGAL (closed, manifold, self-intersections; vertices welded by position first, since uv seams
// split vertices) and compared with level 0 (symmetric Hausdorff over the model's height). The
// skin's influences as stored come from the loader's SkinReport (the runtime normalizes them on load).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <cstring>
#include <map>
#include <string>
#include <tuple>

#include <nlohmann/json.hpp>

#include "bb/mesher/mesh_check.h"
#include "bb/runtime/animation.h"
#include "bb/runtime/model.h"
#include "flow.h"
#include "io.h"

namespace bb::cli {

namespace {

// "1.23 units/s (0.70 heights/s)"
std::string fmt_speed(float v, double height) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%.3g units/s (%.2f heights/s)", v, height > 0 ? v / height : 0.0);
  return buf;
}

struct Welded {
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;
};

Welded weld(const runtime::MeshLod& lod) {
  Welded w;
  std::map<std::tuple<float, float, float>, uint32_t> index;
  std::vector<uint32_t> remap(lod.vertices.size());
  for (size_t i = 0; i < lod.vertices.size(); ++i) {
    const glm::vec3& p = lod.vertices[i].position;
    auto [it, fresh] = index.emplace(std::make_tuple(p.x, p.y, p.z), static_cast<uint32_t>(w.positions.size()));
    if (fresh) w.positions.push_back(p);
    remap[i] = it->second;
  }
  w.indices.reserve(lod.indices.size());
  for (uint32_t i : lod.indices) w.indices.push_back(remap[i]);
  return w;
}

// Level 0 skinned in the rest pose (model space: the file's units and axes, whatever its bind space
// is, e.g. the integer grid of a quantized mesh whose inverse bind matrices scale it back).
std::vector<glm::vec3> rest_positions(const runtime::Model& m) {
  std::vector<runtime::Transform> locals(m.nodes.size());
  runtime::sample_clip(m, -1, 0.0f, locals);
  std::vector<glm::mat4> world(m.nodes.size()), pal(m.palette.size());
  runtime::world_matrices(m, locals, world);
  runtime::palette_matrices(m, world, pal);
  std::vector<glm::vec3> out;
  out.reserve(m.lods[0].vertices.size());
  for (const auto& v : m.lods[0].vertices) out.push_back(runtime::skinned_position(v, pal));
  return out;
}

}  // namespace

int inspect_gltf(const std::string& path, bool as_json, int lod_levels) {
  runtime::LoadOptions options;
  options.lod_levels = lod_levels;
  // The levels in the file's order (and the simplifier's, for those made at load), so that the
  // vertex cache's figure can be given both as stored and as the runtime draws them (`drawn`).
  options.optimize_vertex_order = false;
  auto model = runtime::load_model(path, options);
  if (!model) {
    std::cerr << "bodybuilder inspect: " << model.error().message() << "\n";
    return 1;
  }
  const runtime::Model& m = *model;
  const runtime::SkinReport& skin = m.skin_report;
  runtime::Model drawn;  // its levels as load_model orders them by default (LoadOptions::optimize_vertex_order)
  drawn.materials = m.materials;
  drawn.lods = m.lods;
  runtime::optimize_vertex_order(drawn);
  // Model height: the rest pose's extent along Y. The Hausdorff distances are measured between the
  // levels' bind-space vertices and scaled by the ratio of the two extents (a similarity, such as a
  // quantized mesh's, keeps that ratio).
  float lo = 1e30f, hi = -1e30f, blo = 1e30f, bhi = -1e30f;
  for (const glm::vec3& p : rest_positions(m)) lo = std::min(lo, p.y), hi = std::max(hi, p.y);
  for (const auto& v : m.lods[0].vertices) blo = std::min(blo, v.position.y), bhi = std::max(bhi, v.position.y);
  const double height = hi > lo ? hi - lo : 1.0, bind_height = bhi > blo ? bhi - blo : 1.0;
  Welded w0 = weld(m.lods[0]);
  nlohmann::ordered_json lods = nlohmann::ordered_json::array();
  for (size_t l = 0; l < m.lods.size(); ++l) {
    const auto& lod = m.lods[l];
    Welded w = l == 0 ? w0 : weld(lod);
    auto check = mesher::check_mesh(w.positions, w.indices, true);
    double h = l == 0 ? 0.0 : mesher::hausdorff_distance(w.positions, w.indices, w0.positions, w0.indices) / bind_height;
    nlohmann::ordered_json j;
    j["level"] = l;
    j["triangles"] = lod.triangle_count();
    j["vertices"] = lod.vertices.size();
    j["screen_coverage"] = lod.screen_coverage;
    if (lod.made_at_load) {
      j["generated_error_rel"] = lod.generated_error / bind_height;
      j["skinned_error_rel"] = lod.skinned_error / bind_height;
    }
    j["closed"] = check.closed;
    j["manifold"] = check.manifold;
    j["oriented"] = check.oriented;
    j["self_intersections"] = check.self_intersections;
    j["components"] = check.connected_components;
    j["hausdorff_m"] = h * height;
    j["hausdorff_rel"] = h;
    j["textured"] = std::any_of(lod.primitives.begin(), lod.primitives.end(),
                                [&](const runtime::Primitive& p) { return m.materials[p.material].texture >= 0; });
    // Vertices shaded per triangle by a 32-entry FIFO cache, as stored and as the runtime draws them.
    j["vertex_cache"] = {{"as_stored", runtime::vertices_shaded_per_triangle(lod)},
                         {"as_drawn", runtime::vertices_shaded_per_triangle(drawn.lods[l])}};
    lods.push_back(j);
  }
  nlohmann::ordered_json anims = nlohmann::ordered_json::array();
  for (std::size_t k = 0; k < m.clips.size(); ++k)
    anims.push_back({{"name", m.clips[k].name}, {"duration_s", m.clips[k].duration},
                     {"ground_speed", m.baked_clips()[k].ground_speed}});  // model units per second, 0: does not walk
  const int joints = skin.skin_joints;
  nlohmann::ordered_json j;
  j["kind"] = "gltf";
  j["file"] = path;
  j["joints"] = joints;
  j["nodes"] = m.nodes.size();
  j["height"] = height;
  j["lods"] = lods;
  j["animations"] = anims;
  j["skin"] = {{"max_influences", skin.max_influences}, {"weights_normalized", skin.weights_normalized},
               {"worst_weight_sum_error", skin.worst_weight_sum_error}, {"skinned_vertices", skin.skinned_vertices},
               {"vertices_over_four", skin.vertices_over_four}, {"worst_dropped_weight", skin.worst_dropped_weight}};
  const runtime::MorphReport& morph = m.morph_report;
  j["morph"] = {{"primitives", morph.primitives}, {"most_targets", morph.most_targets},
                {"weighted_targets", morph.weighted_targets}, {"weight_channels", morph.weight_channels}};
  j["materials"] = m.materials.size();
  const auto unlit = static_cast<std::size_t>(
      std::count_if(m.materials.begin(), m.materials.end(), [](const runtime::Material& mat) { return mat.unlit; }));
  j["unlit_materials"] = unlit;  // KHR_materials_unlit
  const auto blended = static_cast<std::size_t>(
      std::count_if(m.materials.begin(), m.materials.end(), [](const runtime::Material& mat) { return mat.alpha_blend; }));
  j["blend_materials"] = blended;  // alphaMode BLEND
  j["textures"] = m.textures.size();
  // The body parts impostor part cards would carry (Model::body_parts): each part's bone, joints, share
  // of the skin weight and triangles at the finest level (a part's own, and those it overlaps at its
  // joints; cap_triangles: those that close its cuts, PartIndices::Range::caps); under
  // kFewTrianglesPerPart triangles a part on average (part_triangles), the text says part cards gain
  // little there, as flow --impostor-parts does.
  nlohmann::ordered_json parts = nlohmann::ordered_json::array();
  if (!m.lods.empty()) {
    const runtime::PartIndices& pi = m.part_indices(0);
    const std::size_t np = m.body_parts().size(), nprim = m.lods.front().primitives.size();
    for (std::size_t p = 0; p < np; ++p) {
      const runtime::BodyPart& bp = m.body_parts()[p];
      std::size_t triangles = 0, caps = 0;
      for (std::size_t k = 0; k < nprim && k * np + p < pi.ranges.size(); ++k) {
        triangles += pi.ranges[k * np + p].count / 3;
        caps += pi.ranges[k * np + p].caps / 3;
      }
      const std::size_t node = static_cast<std::size_t>(m.palette[static_cast<std::size_t>(bp.bone)].node);
      const std::string& name = m.nodes[node].name;
      parts.push_back({{"bone", name.empty() ? "node " + std::to_string(node) : name},
                       {"joints", bp.joints.size()},
                       {"skin_share", bp.mass},
                       {"triangles", triangles},
                       {"cap_triangles", caps}});
    }
  }
  j["body_parts"] = parts;
  if (as_json) {
    std::cout << json_text(j) << "\n";
    return 0;
  }
  std::string kinds;
  if (unlit > 0) kinds += std::to_string(unlit) + " unlit";
  if (blended > 0) kinds += (kinds.empty() ? "" : ", ") + std::to_string(blended) + " blended";
  std::printf("glTF %s: %d joints, %zu nodes, height %.3f (model units), %zu materials%s, %zu textures\n", path.c_str(),
              joints, m.nodes.size(), height, m.materials.size(), kinds.empty() ? "" : (" (" + kinds + ")").c_str(),
              m.textures.size());
  std::printf("lod  triangles  vertices  coverage  closed manifold self-x  hausdorff/height  textured\n");
  for (const auto& l : lods)
    std::printf("%3d  %9zu  %8zu  %8.3f  %6s %8s %6zu  %16.4f  %s\n", l["level"].get<int>(), l["triangles"].get<size_t>(),
                l["vertices"].get<size_t>(), l["screen_coverage"].get<double>(), l["closed"].get<bool>() ? "yes" : "no",
                l["manifold"].get<bool>() ? "yes" : "no", l["self_intersections"].get<size_t>(),
                l["hausdorff_rel"].get<double>(), l["textured"].get<bool>() ? "yes" : "no");
  std::string cache;
  for (const auto& l : lods) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%s%.2f -> %.2f", cache.empty() ? "" : ", ", l["vertex_cache"]["as_stored"].get<double>(),
                  l["vertex_cache"]["as_drawn"].get<double>());
    cache += buf;
  }
  std::printf("vertex cache, vertices shaded a triangle (32-entry FIFO), as stored -> as drawn, level by level: %s\n",
              cache.c_str());
  for (std::size_t k = 0; k < m.clips.size(); ++k) {
    const float v = m.baked_clips()[k].ground_speed;
    std::printf("animation %s: %.3f s, %s\n", m.clips[k].name.c_str(), m.clips[k].duration,
                v > 0.0f ? ("walks at " + fmt_speed(v, height)).c_str() : "does not walk");
  }
  if (const std::size_t each = part_triangles(m); each > 0) {
    std::string names;
    for (const auto& p : parts) names += (names.empty() ? "" : ", ") + p["bone"].get<std::string>();
    std::printf("body parts (flow --impostor-parts): %zu, %zu triangles each on average at level 0%s: %s\n", parts.size(), each,
                each < kFewTrianglesPerPart ? " (few: part cards gain little over geometry on this model)" : "",
                names.c_str());
  }
  std::printf("skin: at most %d influences per vertex, weights %s\n", skin.max_influences,
              skin.weights_normalized ? "normalized" : "NOT normalized");
  if (skin.vertices_over_four > 0)
    std::printf("skin: %zu vertices have more than 4 influences; the runtime keeps the 4 heaviest (at most %.1f %% of a "
                "vertex's weight dropped)\n", skin.vertices_over_four, 100.0 * skin.worst_dropped_weight);
  if (morph.primitives > 0)
    std::printf("morph targets: %zu primitives with up to %d; drawn at their default weights (%zu targets weighted)%s\n",
                morph.primitives, morph.most_targets, morph.weighted_targets,
                morph.weight_channels > 0 ? (", " + std::to_string(morph.weight_channels) +
                                             " animated weight channels not played").c_str()
                                          : "");
  return 0;
}

}  // namespace bb::cli
