// The only translation unit of the exporter that includes tinygltf.
#include "bb/exporter/gltf_export.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <sstream>

#include <glm/gtc/quaternion.hpp>
#include <meshoptimizer.h>
#include <tiny_gltf.h>

#define STB_IMAGE_WRITE_STATIC
#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <stb/stb_image_write.h>

namespace bb::exporter {

namespace {

constexpr int kFloat = TINYGLTF_COMPONENT_TYPE_FLOAT;
constexpr int kU16 = TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT;
constexpr int kU32 = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;

class Builder {
 public:
  explicit Builder(tinygltf::Model& m) : m_(m) {
    m_.buffers.emplace_back();
  }
  int view(const void* data, size_t bytes, int target) {
    auto& buf = m_.buffers[0].data;
    while (buf.size() % 4) buf.push_back(0);
    tinygltf::BufferView v;
    v.buffer = 0;
    v.byteOffset = buf.size();
    v.byteLength = bytes;
    v.target = target;
    buf.insert(buf.end(), static_cast<const unsigned char*>(data), static_cast<const unsigned char*>(data) + bytes);
    m_.bufferViews.push_back(v);
    return static_cast<int>(m_.bufferViews.size() - 1);
  }
  int accessor(int view, int component, size_t count, int type, std::vector<double> min = {},
               std::vector<double> max = {}) {
    tinygltf::Accessor a;
    a.bufferView = view;
    a.componentType = component;
    a.count = count;
    a.type = type;
    a.minValues = std::move(min);
    a.maxValues = std::move(max);
    m_.accessors.push_back(a);
    return static_cast<int>(m_.accessors.size() - 1);
  }
  template <class T>
  int array(const std::vector<T>& v, int component, int type, int target = 0) {
    return accessor(this->view(v.data(), v.size() * sizeof(T), target), component, v.size(), type);
  }

 private:
  tinygltf::Model& m_;
};

tinygltf::Value to_value(const mesher::LodReport& r, int level) {
  tinygltf::Value::Object o;
  o["level"] = tinygltf::Value(level);
  o["triangles"] = tinygltf::Value(static_cast<int>(r.triangles));
  o["vertices"] = tinygltf::Value(static_cast<int>(r.vertices));
  if (r.errors_measured) {  // unmeasured (build --no-errors): left out rather than a perfect 0
    o["hausdorff_m"] = tinygltf::Value(r.hausdorff_m);
    o["mean_m"] = tinygltf::Value(r.mean_m);
    o["hausdorff_rel"] = tinygltf::Value(r.hausdorff_rel);
    o["mean_rel"] = tinygltf::Value(r.mean_rel);
  }
  o["closed"] = tinygltf::Value(r.closed);
  o["manifold"] = tinygltf::Value(r.manifold);
  o["self_intersections"] = tinygltf::Value(static_cast<int>(r.self_intersection_count));
  return tinygltf::Value(o);
}

// At most 4 influences, merged by joint, sorted by weight, summing to exactly 1 in float;
// zero-weight slots hold joint 0 (the validator warns otherwise).
void normalize_influences(glm::u16vec4& j, glm::vec4& w) {
  std::pair<int, double> inf[4];
  int n = 0;
  for (int k = 0; k < 4; ++k) {
    if (!(w[k] > 0)) continue;
    int found = -1;
    for (int q = 0; q < n; ++q) if (inf[q].first == j[k]) found = q;
    if (found >= 0) inf[found].second += w[k];
    else inf[n++] = {j[k], w[k]};
  }
  for (int a = 1; a < n; ++a)  // insertion sort, heaviest first
    for (int q = a; q > 0 && inf[q].second > inf[q - 1].second; --q) std::swap(inf[q], inf[q - 1]);
  double sum = 0;
  for (int k = 0; k < n; ++k) sum += inf[k].second;
  if (n == 0 || !(sum > 0)) { n = 1; inf[0] = {0, 1.0}; sum = 1; }
  j = glm::u16vec4(0);
  w = glm::vec4(0);
  float rest = 1.0f;
  for (int k = 1; k < n; ++k) {
    j[k] = static_cast<uint16_t>(inf[k].first);
    w[k] = static_cast<float>(inf[k].second / sum);
    rest -= w[k];
  }
  j[0] = static_cast<uint16_t>(inf[0].first);
  w[0] = rest;
}

std::vector<unsigned char> encode_png(const Image& img) {
  std::vector<unsigned char> bytes;
  auto sink = [](void* ctx, void* data, int size) {
    auto* v = static_cast<std::vector<unsigned char>*>(ctx);
    v->insert(v->end(), static_cast<unsigned char*>(data), static_cast<unsigned char*>(data) + size);
  };
  stbi_write_png_to_func(sink, &bytes, img.width, img.height, 4, img.rgba.data(), img.width * 4);
  return bytes;
}

Result<std::vector<uint8_t>> encode(const ExportInput& in, int only_level) {
  if (!in.body || !in.body->skeleton) return Error{"", "", "no body to export"};
  if (in.lods.empty()) return Error{"", "lods", "no level of detail to export"};
  const modeler::Skeleton& sk = *in.body->skeleton;
  const size_t nj = sk.joints().size();
  modeler::Posture bind = sk.posture(in.body->sample_posture);
  std::vector<glm::mat4> world = sk.world_transforms(bind);

  tinygltf::Model m;
  m.asset.version = "2.0";
  m.asset.generator = "bodybuilder";
  Builder b(m);

  // Skeleton nodes: index = skeleton joint index.
  for (size_t j = 0; j < nj; ++j) {
    tinygltf::Node n;
    n.name = sk.joints()[j].name;
    glm::mat4 l = sk.local_transform(static_cast<int>(j), bind);
    glm::quat q = glm::normalize(glm::quat_cast(glm::mat3(l)));
    n.translation = {l[3][0], l[3][1], l[3][2]};
    if (std::abs(q.w - 1.0f) > 1e-7f) n.rotation = {q.x, q.y, q.z, q.w};
    m.nodes.push_back(n);
  }
  for (size_t j = 0; j < nj; ++j) {
    int p = sk.joints()[j].parent;
    if (p >= 0) m.nodes[p].children.push_back(static_cast<int>(j));
  }
  // The skin.
  {
    std::vector<glm::mat4> ibm(nj);
    for (size_t j = 0; j < nj; ++j) {
      ibm[j] = glm::inverse(world[j]);
      ibm[j][0][3] = ibm[j][1][3] = ibm[j][2][3] = 0.0f;  // exact last row 0 0 0 1
      ibm[j][3][3] = 1.0f;
    }
    tinygltf::Skin s;
    s.name = in.body->name + "_skin";
    s.inverseBindMatrices = b.array(ibm, kFloat, TINYGLTF_TYPE_MAT4);
    s.skeleton = 0;
    for (size_t j = 0; j < nj; ++j) s.joints.push_back(static_cast<int>(j));
    m.skins.push_back(s);
  }
  // Materials and textures.
  {
    tinygltf::Material mat;
    mat.name = "skin";
    mat.pbrMetallicRoughness.baseColorFactor = {in.skin_colour.r, in.skin_colour.g, in.skin_colour.b, 1.0};
    mat.pbrMetallicRoughness.metallicFactor = 0.0;
    mat.pbrMetallicRoughness.roughnessFactor = 0.8;
    m.materials.push_back(mat);
  }
  std::vector<int> texture_material(in.textures.size(), -1);
  for (size_t t = 0; t < in.textures.size(); ++t) {
    bool used = false;
    for (size_t l = 0; l < in.lods.size(); ++l)
      used |= in.lods[l].texture == static_cast<int>(t) && (only_level < 0 || only_level == static_cast<int>(l));
    if (!used) continue;
    const Image& img = in.textures[t];
    if (img.width <= 0 || img.height <= 0 || img.rgba.size() != static_cast<size_t>(img.width) * img.height * 4)
      return Error{"", "textures[" + std::to_string(t) + "]", "image size does not match its pixels"};
    auto png = encode_png(img);
    tinygltf::Image gi;
    gi.name = "proxy_texture_" + std::to_string(t);
    gi.mimeType = "image/png";
    gi.bufferView = b.view(png.data(), png.size(), 0);
    m.images.push_back(gi);
    if (m.samplers.empty()) {
      tinygltf::Sampler s;
      s.magFilter = TINYGLTF_TEXTURE_FILTER_LINEAR;
      s.minFilter = TINYGLTF_TEXTURE_FILTER_LINEAR_MIPMAP_LINEAR;  // the proxies are seen small: mipmaps
      m.samplers.push_back(s);
    }
    tinygltf::Texture tex;
    tex.source = static_cast<int>(m.images.size() - 1);
    tex.sampler = 0;
    m.textures.push_back(tex);
    tinygltf::Material mat;
    mat.name = "skin_proxies";
    mat.pbrMetallicRoughness.baseColorFactor = {1, 1, 1, 1};
    mat.pbrMetallicRoughness.baseColorTexture.index = static_cast<int>(m.textures.size() - 1);
    mat.pbrMetallicRoughness.metallicFactor = 0.0;
    mat.pbrMetallicRoughness.roughnessFactor = 0.8;
    m.materials.push_back(mat);
    texture_material[t] = static_cast<int>(m.materials.size() - 1);
  }
  // One mesh and one node per level.
  std::vector<int> lod_nodes;
  std::vector<double> coverage;
  for (size_t l = 0; l < in.lods.size(); ++l) {
    if (only_level >= 0 && static_cast<int>(l) != only_level) continue;
    const ExportLod& lod = in.lods[l];
    const mesher::SkinnedMesh& sm = lod.mesh;
    const size_t nv = sm.positions.size();
    std::string where = "lods[" + std::to_string(l) + "]";
    if (nv == 0 || sm.indices.empty() || sm.indices.size() % 3) return Error{"", where, "empty mesh or bad index count"};
    if (sm.normals.size() != nv || sm.joints.size() != nv || sm.weights.size() != nv)
      return Error{"", where, "normals, joints and weights need one value per vertex"};
    for (uint32_t i : sm.indices)
      if (i >= nv) return Error{"", where, "vertex index out of range"};
    bool textured = lod.texture >= 0;
    if (textured && (lod.texture >= static_cast<int>(in.textures.size()) || sm.uvs.size() != nv))
      return Error{"", where, "a textured level needs a texture and one uv per vertex"};
    std::vector<glm::u16vec4> joints = sm.joints;
    std::vector<glm::vec4> weights = sm.weights;
    for (size_t i = 0; i < nv; ++i) {
      for (int k = 0; k < 4; ++k)
        if (weights[i][k] > 0 && joints[i][k] >= nj) return Error{"", where, "joint index out of range"};
      normalize_influences(joints[i], weights[i]);
    }
    std::vector<glm::vec3> normals(nv);
    for (size_t i = 0; i < nv; ++i) {
      float len = glm::length(sm.normals[i]);
      normals[i] = len > 0 ? sm.normals[i] / len : glm::vec3(0, 1, 0);
    }
    glm::vec3 lo(1e30f), hi(-1e30f);
    for (const auto& p : sm.positions) { lo = glm::min(lo, p); hi = glm::max(hi, p); }
    tinygltf::Primitive prim;
    prim.mode = TINYGLTF_MODE_TRIANGLES;
    prim.attributes["POSITION"] = b.accessor(
        b.view(sm.positions.data(), nv * sizeof(glm::vec3), TINYGLTF_TARGET_ARRAY_BUFFER), kFloat, nv,
        TINYGLTF_TYPE_VEC3, {lo.x, lo.y, lo.z}, {hi.x, hi.y, hi.z});
    prim.attributes["NORMAL"] = b.array(normals, kFloat, TINYGLTF_TYPE_VEC3, TINYGLTF_TARGET_ARRAY_BUFFER);
    if (textured) prim.attributes["TEXCOORD_0"] = b.array(sm.uvs, kFloat, TINYGLTF_TYPE_VEC2, TINYGLTF_TARGET_ARRAY_BUFFER);
    prim.attributes["JOINTS_0"] = b.array(joints, kU16, TINYGLTF_TYPE_VEC4, TINYGLTF_TARGET_ARRAY_BUFFER);
    prim.attributes["WEIGHTS_0"] = b.array(weights, kFloat, TINYGLTF_TYPE_VEC4, TINYGLTF_TARGET_ARRAY_BUFFER);
    // The triangles in vertex cache order (meshoptimizer), for whatever engine draws the file: the
    // same triangles, fewer vertices shaded (the vertices keep their numbers).
    std::vector<uint32_t> indices(sm.indices.size());
    meshopt_optimizeVertexCache(indices.data(), sm.indices.data(), sm.indices.size(), nv);
    prim.indices = b.array(indices, kU32, TINYGLTF_TYPE_SCALAR, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    prim.material = textured ? texture_material[lod.texture] : 0;
    tinygltf::Mesh mesh;
    mesh.name = in.body->name + "_lod" + std::to_string(l);
    mesh.primitives.push_back(prim);
    mesh.extras = to_value(lod.report, static_cast<int>(l));
    m.meshes.push_back(mesh);
    tinygltf::Node n;
    n.name = mesh.name;
    n.mesh = static_cast<int>(m.meshes.size() - 1);
    n.skin = 0;
    m.nodes.push_back(n);
    lod_nodes.push_back(static_cast<int>(m.nodes.size() - 1));
    coverage.push_back(lod.screen_coverage);
  }
  if (lod_nodes.size() > 1) {
    tinygltf::Value::Array ids;
    for (size_t k = 1; k < lod_nodes.size(); ++k) ids.push_back(tinygltf::Value(lod_nodes[k]));
    tinygltf::Value::Object ext;
    ext["ids"] = tinygltf::Value(ids);
    m.nodes[lod_nodes[0]].extensions["MSFT_lod"] = tinygltf::Value(ext);
    tinygltf::Value::Array cov;
    for (double c : coverage) cov.push_back(tinygltf::Value(c));
    tinygltf::Value::Object extras;
    extras["MSFT_screencoverage"] = tinygltf::Value(cov);
    m.nodes[lod_nodes[0]].extras = tinygltf::Value(extras);
    m.extensionsUsed.push_back("MSFT_lod");
  }
  // Animations.
  for (size_t c = 0; c < in.clips.size(); ++c) {
    const motion::Clip& clip = in.clips[c];
    std::string where = "clips[" + std::to_string(c) + "]";
    if (clip.frames.size() < 2 || !(clip.fps > 0)) return Error{"", where, "a clip needs at least 2 frames and fps > 0"};
    for (const auto& f : clip.frames)
      if (static_cast<int>(f.size()) != sk.dof_count()) return Error{"", where, "a frame has the wrong number of DOFs"};
    std::vector<float> times(clip.frames.size());
    for (size_t f = 0; f < times.size(); ++f) times[f] = static_cast<float>(f / static_cast<double>(clip.fps));
    tinygltf::Animation anim;
    anim.name = clip.name.empty() ? "clip" + std::to_string(c) : clip.name;
    int input = b.accessor(b.view(times.data(), times.size() * sizeof(float), 0), kFloat, times.size(),
                           TINYGLTF_TYPE_SCALAR, {times.front()}, {times.back()});
    for (size_t j = 0; j < nj; ++j) {
      const modeler::Joint& joint = sk.joints()[j];
      bool rot = false, trans = false;
      for (const auto& d : joint.dofs) (d.type == modeler::DofType::kRotation ? rot : trans) = true;
      if (!rot && !trans) continue;
      std::vector<glm::vec4> rotations;
      std::vector<glm::vec3> translations;
      glm::quat prev(1, 0, 0, 0);
      for (const auto& f : clip.frames) {
        glm::mat4 l = sk.local_transform(static_cast<int>(j), f);
        glm::quat q = glm::normalize(glm::quat_cast(glm::mat3(l)));
        if (glm::dot(q, prev) < 0) q = -q;  // keep neighbouring keys on one hemisphere
        prev = q;
        rotations.push_back({q.x, q.y, q.z, q.w});
        translations.push_back(glm::vec3(l[3]));
      }
      auto add_channel = [&](int output, const char* path) {
        tinygltf::AnimationSampler s;
        s.input = input;
        s.output = output;
        s.interpolation = "LINEAR";
        anim.samplers.push_back(s);
        tinygltf::AnimationChannel ch;
        ch.sampler = static_cast<int>(anim.samplers.size() - 1);
        ch.target_node = static_cast<int>(j);
        ch.target_path = path;
        anim.channels.push_back(ch);
      };
      if (rot) add_channel(b.array(rotations, kFloat, TINYGLTF_TYPE_VEC4), "rotation");
      if (trans) add_channel(b.array(translations, kFloat, TINYGLTF_TYPE_VEC3), "translation");
    }
    tinygltf::Value::Object extras;
    extras["fps"] = tinygltf::Value(static_cast<double>(clip.fps));
    extras["loops"] = tinygltf::Value(clip.loops);
    extras["speed_mps"] = tinygltf::Value(static_cast<double>(clip.speed_mps));
    anim.extras = tinygltf::Value(extras);
    m.animations.push_back(anim);
  }
  tinygltf::Scene scene;
  scene.name = in.body->name;
  scene.nodes = {0, lod_nodes[0]};
  m.scenes.push_back(scene);
  m.defaultScene = 0;
  m.buffers[0].name = "";
  {
    tinygltf::Value::Object extras;
    extras["generator"] = tinygltf::Value(std::string("bodybuilder"));
    extras["body"] = tinygltf::Value(in.body->name);
    extras["ta"] = tinygltf::Value(tinygltf::Value::Array{tinygltf::Value(static_cast<double>(sk.ta().x)),
                                                           tinygltf::Value(static_cast<double>(sk.ta().y)),
                                                           tinygltf::Value(static_cast<double>(sk.ta().z))});
    m.asset.extras = tinygltf::Value(extras);
  }

  tinygltf::TinyGLTF writer;
  std::ostringstream out;
  if (!writer.WriteGltfSceneToStream(&m, out, false, true)) return Error{"", "", "tinygltf could not write the GLB"};
  std::string s = out.str();
  return std::vector<uint8_t>(s.begin(), s.end());
}

}  // namespace

Result<std::vector<uint8_t>> encode_glb(const ExportInput& input) { return encode(input, -1); }

Result<std::vector<uint8_t>> encode_glb_level(const ExportInput& input, int level) {
  if (level < 0 || level >= static_cast<int>(input.lods.size()))
    return Error{"", "", "no level " + std::to_string(level)};
  return encode(input, level);
}

}  // namespace bb::exporter
