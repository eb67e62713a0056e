// bodybuilder inspect FILE.glb|FILE.gltf [--json]: any skinned glTF, ours or anyone's.
// Levels come from the runtime's loader (MSFT_lod or one level); each level is checked with
// CGAL (closed, manifold, self-intersections; vertices welded by position first, since uv seams
// split vertices) and compared with level 0 (symmetric Hausdorff over the model's height). The
// skin's influences are read raw with tinygltf (the runtime normalizes them on load).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <cstring>
#include <map>
#include <string>
#include <tuple>

#include <nlohmann/json.hpp>
#include <tiny_gltf.h>

#include "bb/mesher/mesh_check.h"
#include "bb/runtime/model.h"

namespace bb::cli {

namespace {

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

struct SkinStats {
  int max_influences = 0;
  bool normalized = true;
  size_t vertices = 0;
  double worst_sum_error = 0;
};

// Reads WEIGHTS_0 of every skinned primitive as stored.
SkinStats skin_stats(const tinygltf::Model& m) {
  SkinStats s;
  for (const auto& node : m.nodes) {
    if (node.skin < 0 || node.mesh < 0 || node.mesh >= static_cast<int>(m.meshes.size())) continue;
    for (const auto& prim : m.meshes[node.mesh].primitives) {
      auto it = prim.attributes.find("WEIGHTS_0");
      if (it == prim.attributes.end() || it->second < 0 || it->second >= static_cast<int>(m.accessors.size())) continue;
      const auto& a = m.accessors[it->second];
      if (a.bufferView < 0 || a.type != TINYGLTF_TYPE_VEC4) continue;
      const auto& v = m.bufferViews[a.bufferView];
      const auto& buf = m.buffers[v.buffer].data;
      int comp = tinygltf::GetComponentSizeInBytes(a.componentType);
      size_t stride = v.byteStride ? v.byteStride : 4 * comp;
      for (size_t i = 0; i < a.count; ++i) {
        size_t off = v.byteOffset + a.byteOffset + i * stride;
        if (off + 4 * comp > buf.size()) break;
        double sum = 0;
        int n = 0;
        for (int k = 0; k < 4; ++k) {
          const unsigned char* p = &buf[off + k * comp];
          double w = 0;
          if (a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT) { float f; std::memcpy(&f, p, 4); w = f; }
          else if (a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE) w = *p / 255.0;
          else if (a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT) { uint16_t u; std::memcpy(&u, p, 2); w = u / 65535.0; }
          sum += w;
          n += w > 0;
        }
        s.max_influences = std::max(s.max_influences, n);
        double tol = a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT ? 1e-5 : 2.0 / 255;
        s.worst_sum_error = std::max(s.worst_sum_error, std::abs(sum - 1));
        if (std::abs(sum - 1) > tol) s.normalized = false;
        ++s.vertices;
      }
    }
  }
  return s;
}

}  // namespace

int inspect_gltf(const std::string& path, bool as_json) {
  auto model = runtime::load_model(path);
  if (!model) {
    std::cerr << "bodybuilder inspect: " << model.error().message() << "\n";
    return 1;
  }
  tinygltf::Model raw;
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  bool binary = path.size() >= 4 && path.compare(path.size() - 4, 4, ".glb") == 0;
  bool ok = binary ? loader.LoadBinaryFromFile(&raw, &err, &warn, path) : loader.LoadASCIIFromFile(&raw, &err, &warn, path);
  SkinStats skin = ok ? skin_stats(raw) : SkinStats{};
  const runtime::Model& m = *model;
  // Model height: bind-space extent of level 0 along Y.
  float lo = 1e30f, hi = -1e30f;
  for (const auto& v : m.lods[0].vertices) { lo = std::min(lo, v.position.y); hi = std::max(hi, v.position.y); }
  double height = hi > lo ? hi - lo : 1.0;
  Welded w0 = weld(m.lods[0]);
  nlohmann::ordered_json lods = nlohmann::ordered_json::array();
  for (size_t l = 0; l < m.lods.size(); ++l) {
    const auto& lod = m.lods[l];
    Welded w = l == 0 ? w0 : weld(lod);
    auto check = mesher::check_mesh(w.positions, w.indices, true);
    double h = l == 0 ? 0.0 : mesher::hausdorff_distance(w.positions, w.indices, w0.positions, w0.indices);
    nlohmann::ordered_json j;
    j["level"] = l;
    j["triangles"] = lod.triangle_count();
    j["vertices"] = lod.vertices.size();
    j["screen_coverage"] = lod.screen_coverage;
    j["closed"] = check.closed;
    j["manifold"] = check.manifold;
    j["oriented"] = check.oriented;
    j["self_intersections"] = check.self_intersections;
    j["components"] = check.connected_components;
    j["hausdorff_m"] = h;
    j["hausdorff_rel"] = h / height;
    j["textured"] = std::any_of(lod.primitives.begin(), lod.primitives.end(),
                                [&](const runtime::Primitive& p) { return m.materials[p.material].texture >= 0; });
    lods.push_back(j);
  }
  nlohmann::ordered_json anims = nlohmann::ordered_json::array();
  for (const auto& c : m.clips) anims.push_back({{"name", c.name}, {"duration_s", c.duration}});
  int joints = 0;
  for (const auto& s : raw.skins) joints = std::max(joints, static_cast<int>(s.joints.size()));
  nlohmann::ordered_json j;
  j["kind"] = "gltf";
  j["file"] = path;
  j["joints"] = joints;
  j["nodes"] = m.nodes.size();
  j["height"] = height;
  j["lods"] = lods;
  j["animations"] = anims;
  j["skin"] = {{"max_influences", skin.max_influences}, {"weights_normalized", skin.normalized},
               {"worst_weight_sum_error", skin.worst_sum_error}, {"skinned_vertices", skin.vertices}};
  j["materials"] = m.materials.size();
  j["textures"] = m.textures.size();
  if (as_json) {
    std::cout << j.dump() << "\n";
    return 0;
  }
  std::printf("glTF %s: %d joints, %zu nodes, height %.3f (model units), %zu materials, %zu textures\n", path.c_str(),
              joints, m.nodes.size(), height, m.materials.size(), m.textures.size());
  std::printf("lod  triangles  vertices  coverage  closed manifold self-x  hausdorff/height  textured\n");
  for (const auto& l : lods)
    std::printf("%3d  %9zu  %8zu  %8.3f  %6s %8s %6zu  %16.4f  %s\n", l["level"].get<int>(), l["triangles"].get<size_t>(),
                l["vertices"].get<size_t>(), l["screen_coverage"].get<double>(), l["closed"].get<bool>() ? "yes" : "no",
                l["manifold"].get<bool>() ? "yes" : "no", l["self_intersections"].get<size_t>(),
                l["hausdorff_rel"].get<double>(), l["textured"].get<bool>() ? "yes" : "no");
  for (const auto& c : m.clips) std::printf("animation %s: %.3f s\n", c.name.c_str(), c.duration);
  std::printf("skin: at most %d influences per vertex, weights %s\n", skin.max_influences,
              skin.normalized ? "normalized" : "NOT normalized");
  return 0;
}

}  // namespace bb::cli
