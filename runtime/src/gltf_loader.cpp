// glTF -> Model. tinygltf parses (Debian ships it as libtinygltf.so, so no implementation is
// compiled here); everything it hands back is validated before use: indices, accessor bounds,
// counts, finiteness, hierarchy loops.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <glm/gtc/type_ptr.hpp>
#define GLM_ENABLE_EXPERIMENTAL
#include <glm/gtx/matrix_decompose.hpp>
#include <tiny_gltf.h>

#include "bb/runtime/model.h"

namespace bb::runtime {

namespace tg = tinygltf;

namespace {

std::string idx(const char* array, int i) { return std::string("$.") + array + "[" + std::to_string(i) + "]"; }

struct Ctx {
  const tg::Model& m;
  std::string file;
  Error err(const std::string& where, const std::string& reason) const { return Error{file, where, reason}; }
};

int component_size(int ct) {
  switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
    case TINYGLTF_COMPONENT_TYPE_INT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
    default: return 0;
  }
}

int type_components(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR: return 1;
    case TINYGLTF_TYPE_VEC2: return 2;
    case TINYGLTF_TYPE_VEC3: return 3;
    case TINYGLTF_TYPE_VEC4: return 4;
    case TINYGLTF_TYPE_MAT2: return 4;
    case TINYGLTF_TYPE_MAT3: return 9;
    case TINYGLTF_TYPE_MAT4: return 16;
    default: return 0;
  }
}

// Reads accessor `ai` as `want_components` values per element, converting every component to
// double (normalized integers mapped to [0,1] or [-1,1] when the accessor says so or `normalize`).
// `allowed` lists the accepted component types. Checks every byte range.
Result<std::vector<double>> read_accessor(const Ctx& c, int ai, int want_type, std::initializer_list<int> allowed,
                                          bool force_normalize, const std::string& user) {
  const auto& m = c.m;
  if (ai < 0 || ai >= static_cast<int>(m.accessors.size()))
    return c.err(user, "accessor index " + std::to_string(ai) + " does not exist");
  const tg::Accessor& a = m.accessors[ai];
  std::string where = idx("accessors", ai);
  if (a.type != want_type)
    return c.err(where + ".type", "has " + std::to_string(type_components(a.type)) + " components, " + user +
                                      " needs " + std::to_string(type_components(want_type)));
  if (std::find(allowed.begin(), allowed.end(), a.componentType) == allowed.end())
    return c.err(where + ".componentType", "component type " + std::to_string(a.componentType) + " is not allowed for " + user);
  if (a.sparse.isSparse) return c.err(where + ".sparse", "sparse accessors are not supported");
  const int nc = type_components(a.type);
  const int cs = component_size(a.componentType);
  if (a.count == 0) return c.err(where + ".count", "accessor is empty");
  if (a.count > (1u << 26)) return c.err(where + ".count", "accessor is implausibly large");
  std::vector<double> out(a.count * nc, 0.0);
  if (a.bufferView < 0) return out;  // all zeros, as glTF says
  if (a.bufferView >= static_cast<int>(m.bufferViews.size()))
    return c.err(where + ".bufferView", "buffer view " + std::to_string(a.bufferView) + " does not exist");
  const tg::BufferView& bv = m.bufferViews[a.bufferView];
  std::string bvw = idx("bufferViews", a.bufferView);
  if (bv.buffer < 0 || bv.buffer >= static_cast<int>(m.buffers.size()))
    return c.err(bvw + ".buffer", "buffer " + std::to_string(bv.buffer) + " does not exist");
  const auto& data = m.buffers[bv.buffer].data;
  if (bv.byteOffset > data.size() || bv.byteLength > data.size() - bv.byteOffset)
    return c.err(bvw, "byte range [" + std::to_string(bv.byteOffset) + ", " + std::to_string(bv.byteOffset + bv.byteLength) +
                          ") lies outside its buffer of " + std::to_string(data.size()) + " bytes");
  // Matrices of 1- and 2-byte components have column padding; we only read float matrices.
  const std::size_t elem = static_cast<std::size_t>(nc) * cs;
  const std::size_t stride = bv.byteStride ? bv.byteStride : elem;
  if (stride < elem) return c.err(bvw + ".byteStride", "stride " + std::to_string(stride) + " is smaller than an element");
  const std::size_t need = a.byteOffset + stride * (a.count - 1) + elem;
  if (a.byteOffset > bv.byteLength || need > bv.byteLength)
    return c.err(where, "accessor needs " + std::to_string(need) + " bytes, its buffer view has " +
                            std::to_string(bv.byteLength));
  const unsigned char* base = data.data() + bv.byteOffset + a.byteOffset;
  const bool norm = a.normalized || force_normalize;
  for (std::size_t i = 0; i < a.count; ++i) {
    const unsigned char* e = base + i * stride;
    for (int k = 0; k < nc; ++k) {
      const unsigned char* p = e + k * cs;
      double v = 0;
      switch (a.componentType) {
        case TINYGLTF_COMPONENT_TYPE_FLOAT: { float f; std::memcpy(&f, p, 4); v = f; break; }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: v = *p; if (norm) v /= 255.0; break;
        case TINYGLTF_COMPONENT_TYPE_BYTE: v = static_cast<signed char>(*p); if (norm) v = std::max(v / 127.0, -1.0); break;
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: { std::uint16_t s; std::memcpy(&s, p, 2); v = s; if (norm) v /= 65535.0; break; }
        case TINYGLTF_COMPONENT_TYPE_SHORT: { std::int16_t s; std::memcpy(&s, p, 2); v = s; if (norm) v = std::max(v / 32767.0, -1.0); break; }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: { std::uint32_t s; std::memcpy(&s, p, 4); v = s; break; }
        default: break;
      }
      if (!std::isfinite(v)) return c.err(where, "element " + std::to_string(i) + " is not a finite number");
      out[i * nc + k] = v;
    }
  }
  return out;
}

constexpr int kF = TINYGLTF_COMPONENT_TYPE_FLOAT;
constexpr int kUB = TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE;
constexpr int kUS = TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT;
constexpr int kUI = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
constexpr int kB = TINYGLTF_COMPONENT_TYPE_BYTE;
constexpr int kS = TINYGLTF_COMPONENT_TYPE_SHORT;

bool finite_all(const std::vector<double>& v) {
  return std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
}

Result<Transform> node_local(const Ctx& c, int ni) {
  const tg::Node& n = c.m.nodes[ni];
  std::string w = idx("nodes", ni);
  Transform t;
  if (!n.matrix.empty()) {
    if (n.matrix.size() != 16 || !finite_all(n.matrix)) return c.err(w + ".matrix", "needs 16 finite numbers");
    glm::mat4 m;
    for (int i = 0; i < 16; ++i) glm::value_ptr(m)[i] = static_cast<float>(n.matrix[i]);
    glm::vec3 skew;
    glm::vec4 persp;
    if (!glm::decompose(m, t.scale, t.rotation, t.translation, skew, persp))
      return c.err(w + ".matrix", "is not a translation-rotation-scale transform");
    t.rotation = glm::normalize(t.rotation);
    return t;
  }
  if (!n.translation.empty()) {
    if (n.translation.size() != 3 || !finite_all(n.translation)) return c.err(w + ".translation", "needs 3 finite numbers");
    t.translation = glm::vec3(n.translation[0], n.translation[1], n.translation[2]);
  }
  if (!n.rotation.empty()) {
    if (n.rotation.size() != 4 || !finite_all(n.rotation)) return c.err(w + ".rotation", "needs 4 finite numbers");
    glm::quat q(static_cast<float>(n.rotation[3]), static_cast<float>(n.rotation[0]), static_cast<float>(n.rotation[1]),
                static_cast<float>(n.rotation[2]));
    float l = glm::length(q);
    if (!(l > 1e-6f)) return c.err(w + ".rotation", "is not a rotation (zero quaternion)");
    t.rotation = q / l;
  }
  if (!n.scale.empty()) {
    if (n.scale.size() != 3 || !finite_all(n.scale)) return c.err(w + ".scale", "needs 3 finite numbers");
    t.scale = glm::vec3(n.scale[0], n.scale[1], n.scale[2]);
  }
  return t;
}

std::vector<double> number_array(const tg::Value& v) {
  std::vector<double> r;
  if (!v.IsArray()) return r;
  for (std::size_t i = 0; i < v.ArrayLen(); ++i)
    if (v.Get(static_cast<int>(i)).IsNumber()) r.push_back(v.Get(static_cast<int>(i)).GetNumberAsDouble());
  return r;
}

struct Builder {
  const Ctx& c;
  Model& out;
  std::vector<int> remap;  // glTF node -> runtime node
  std::map<int, int> skin_offset, rigid_slot, image_texture, material_index;
  int default_material = -1;

  Status hierarchy() {
    const auto& nodes = c.m.nodes;
    const int n = static_cast<int>(nodes.size());
    std::vector<int> parent(n, -1);
    for (int i = 0; i < n; ++i)
      for (std::size_t k = 0; k < nodes[i].children.size(); ++k) {
        int ch = nodes[i].children[k];
        std::string w = idx("nodes", i) + ".children[" + std::to_string(k) + "]";
        if (ch < 0 || ch >= n) return c.err(w, "node " + std::to_string(ch) + " does not exist");
        if (ch == i) return c.err(w, "a node cannot be its own child");
        if (parent[ch] >= 0) return c.err(w, "node " + std::to_string(ch) + " has more than one parent");
        parent[ch] = i;
      }
    remap.assign(n, -1);
    std::vector<int> stack;
    for (int r = 0; r < n; ++r) {
      if (parent[r] >= 0) continue;
      stack.push_back(r);
      while (!stack.empty()) {
        int g = stack.back();
        stack.pop_back();
        remap[g] = static_cast<int>(out.nodes.size());
        Node node;
        node.name = nodes[g].name;
        node.parent = parent[g] >= 0 ? remap[parent[g]] : -1;
        auto local = node_local(c, g);
        if (!local) return local.error();
        node.rest = *local;
        out.nodes.push_back(std::move(node));
        for (auto it = nodes[g].children.rbegin(); it != nodes[g].children.rend(); ++it) stack.push_back(*it);
      }
    }
    for (int i = 0; i < n; ++i)
      if (remap[i] < 0) return c.err(idx("nodes", i), "the node hierarchy has a loop");
    return Ok{};
  }

  Result<int> skin_palette(int si) {
    if (auto it = skin_offset.find(si); it != skin_offset.end()) return it->second;
    const tg::Skin& s = c.m.skins[si];
    std::string w = idx("skins", si);
    if (s.joints.empty()) return c.err(w + ".joints", "skin has no joints");
    std::vector<double> ibm;
    if (s.inverseBindMatrices >= 0) {
      auto r = read_accessor(c, s.inverseBindMatrices, TINYGLTF_TYPE_MAT4, {kF}, false, w + ".inverseBindMatrices");
      if (!r) return r.error();
      ibm = std::move(*r);
      if (ibm.size() / 16 < s.joints.size())
        return c.err(w + ".inverseBindMatrices", "has " + std::to_string(ibm.size() / 16) + " matrices for " +
                                                     std::to_string(s.joints.size()) + " joints");
    }
    int offset = static_cast<int>(out.palette.size());
    for (std::size_t j = 0; j < s.joints.size(); ++j) {
      int jn = s.joints[j];
      if (jn < 0 || jn >= static_cast<int>(remap.size()))
        return c.err(w + ".joints[" + std::to_string(j) + "]", "node " + std::to_string(jn) + " does not exist");
      PaletteEntry e;
      e.node = remap[jn];
      if (!ibm.empty())
        for (int k = 0; k < 16; ++k) glm::value_ptr(e.inverse_bind)[k] = static_cast<float>(ibm[j * 16 + k]);
      out.palette.push_back(e);
    }
    if (out.palette.size() > 65535) return c.err(w, "more than 65535 skinning matrices");
    skin_offset[si] = offset;
    return offset;
  }

  int rigid(int runtime_node) {
    if (auto it = rigid_slot.find(runtime_node); it != rigid_slot.end()) return it->second;
    int slot = static_cast<int>(out.palette.size());
    out.palette.push_back(PaletteEntry{runtime_node, glm::mat4(1.0f)});
    rigid_slot[runtime_node] = slot;
    return slot;
  }

  int texture_for_image(int image) {
    if (auto it = image_texture.find(image); it != image_texture.end()) return it->second;
    int result = -1;
    if (image >= 0 && image < static_cast<int>(c.m.images.size())) {
      const tg::Image& im = c.m.images[image];
      const std::size_t px = static_cast<std::size_t>(std::max(im.width, 0)) * std::max(im.height, 0);
      const int comp = im.component, bytes = im.bits == 16 ? 2 : 1;
      if (px > 0 && comp >= 1 && comp <= 4 && (im.bits == 8 || im.bits == 16) &&
          im.image.size() >= px * comp * bytes) {
        Texture t;
        t.width = im.width;
        t.height = im.height;
        t.rgba.resize(px * 4);
        for (std::size_t p = 0; p < px; ++p) {
          unsigned char ch[4] = {0, 0, 0, 255};
          for (int k = 0; k < comp; ++k) ch[k] = im.image[(p * comp + k) * bytes + (bytes - 1)];  // high byte
          if (comp == 1 || comp == 2) {  // grey (+ alpha)
            ch[3] = comp == 2 ? ch[1] : 255;
            ch[1] = ch[2] = ch[0];
          }
          std::memcpy(&t.rgba[p * 4], ch, 4);
        }
        result = static_cast<int>(out.textures.size());
        out.textures.push_back(std::move(t));
      }
    }
    image_texture[image] = result;
    return result;
  }

  int material(int mi) {
    if (mi < 0 || mi >= static_cast<int>(c.m.materials.size())) {
      if (default_material < 0) {
        default_material = static_cast<int>(out.materials.size());
        out.materials.push_back(Material{glm::vec4(0.8f, 0.8f, 0.8f, 1.0f)});
      }
      return default_material;
    }
    if (auto it = material_index.find(mi); it != material_index.end()) return it->second;
    const tg::Material& gm = c.m.materials[mi];
    Material mat;
    const auto& f = gm.pbrMetallicRoughness.baseColorFactor;
    if (f.size() == 4 && finite_all(f)) mat.base_color = glm::vec4(f[0], f[1], f[2], f[3]);
    int ti = gm.pbrMetallicRoughness.baseColorTexture.index;
    if (ti >= 0 && ti < static_cast<int>(c.m.textures.size())) mat.texture = texture_for_image(c.m.textures[ti].source);
    if (gm.alphaMode == "MASK" || gm.alphaMode == "BLEND") {
      mat.alpha_mask = true;
      mat.alpha_cutoff = gm.alphaMode == "MASK" ? static_cast<float>(gm.alphaCutoff) : 0.5f;
    }
    int r = static_cast<int>(out.materials.size());
    out.materials.push_back(mat);
    material_index[mi] = r;
    return r;
  }

  // Appends mesh `mi` drawn by glTF node `gn` to `lod`.
  Status add_mesh(MeshLod& lod, int gn, int mi, int si) {
    std::string mw = idx("meshes", mi);
    if (mi < 0 || mi >= static_cast<int>(c.m.meshes.size()))
      return c.err(idx("nodes", gn) + ".mesh", "mesh " + std::to_string(mi) + " does not exist");
    int palette_offset = 0, slot = 0;
    bool skinned = si >= 0;
    if (skinned) {
      if (si >= static_cast<int>(c.m.skins.size()))
        return c.err(idx("nodes", gn) + ".skin", "skin " + std::to_string(si) + " does not exist");
      auto off = skin_palette(si);
      if (!off) return off.error();
      palette_offset = *off;
    } else {
      slot = rigid(remap[gn]);
    }
    const int joint_count = skinned ? static_cast<int>(c.m.skins[si].joints.size()) : 1;
    const auto& prims = c.m.meshes[mi].primitives;
    for (std::size_t pi = 0; pi < prims.size(); ++pi) {
      const tg::Primitive& p = prims[pi];
      std::string pw = mw + ".primitives[" + std::to_string(pi) + "]";
      if (p.mode != -1 && p.mode != TINYGLTF_MODE_TRIANGLES) continue;  // points, lines, strips: not a skin
      auto attr = [&](const char* name) { auto it = p.attributes.find(name); return it == p.attributes.end() ? -1 : it->second; };
      int ap = attr("POSITION");
      if (ap < 0) return c.err(pw + ".attributes", "has no POSITION");
      auto pos = read_accessor(c, ap, TINYGLTF_TYPE_VEC3, {kF}, false, pw + ".attributes.POSITION");
      if (!pos) return pos.error();
      const std::size_t nv = pos->size() / 3;
      auto same_count = [&](const std::vector<double>& v, int comps, const char* what) -> Status {
        if (v.size() / comps != nv)
          return c.err(pw + ".attributes." + what, "has " + std::to_string(v.size() / comps) + " elements, POSITION has " + std::to_string(nv));
        return Ok{};
      };
      std::vector<double> nrm, uv, jnt, wgt;
      if (int a = attr("NORMAL"); a >= 0) {
        auto r = read_accessor(c, a, TINYGLTF_TYPE_VEC3, {kF}, false, pw + ".attributes.NORMAL");
        if (!r) return r.error();
        nrm = std::move(*r);
        if (auto s = same_count(nrm, 3, "NORMAL"); !s) return s;
      }
      if (int a = attr("TEXCOORD_0"); a >= 0) {
        auto r = read_accessor(c, a, TINYGLTF_TYPE_VEC2, {kF, kUB, kUS}, true, pw + ".attributes.TEXCOORD_0");
        if (!r) return r.error();
        uv = std::move(*r);
        if (auto s = same_count(uv, 2, "TEXCOORD_0"); !s) return s;
      }
      if (skinned) {
        int aj = attr("JOINTS_0"), aw = attr("WEIGHTS_0");
        if (aj < 0 || aw < 0) return c.err(pw + ".attributes", "a skinned mesh needs JOINTS_0 and WEIGHTS_0");
        auto rj = read_accessor(c, aj, TINYGLTF_TYPE_VEC4, {kUB, kUS}, false, pw + ".attributes.JOINTS_0");
        if (!rj) return rj.error();
        auto rw = read_accessor(c, aw, TINYGLTF_TYPE_VEC4, {kF, kUB, kUS}, true, pw + ".attributes.WEIGHTS_0");
        if (!rw) return rw.error();
        jnt = std::move(*rj);
        wgt = std::move(*rw);
        if (auto s = same_count(jnt, 4, "JOINTS_0"); !s) return s;
        if (auto s = same_count(wgt, 4, "WEIGHTS_0"); !s) return s;
      }
      std::vector<std::uint32_t> ind;
      if (p.indices >= 0) {
        auto r = read_accessor(c, p.indices, TINYGLTF_TYPE_SCALAR, {kUB, kUS, kUI}, false, pw + ".indices");
        if (!r) return r.error();
        ind.reserve(r->size());
        for (std::size_t k = 0; k < r->size(); ++k) {
          double v = (*r)[k];
          if (v >= static_cast<double>(nv))
            return c.err(idx("accessors", p.indices), "index " + std::to_string(static_cast<long long>(v)) + " at element " +
                                                          std::to_string(k) + " is past the " + std::to_string(nv) + " vertices");
          ind.push_back(static_cast<std::uint32_t>(v));
        }
      } else {
        ind.resize(nv);
        for (std::size_t k = 0; k < nv; ++k) ind[k] = static_cast<std::uint32_t>(k);
      }
      ind.resize(ind.size() / 3 * 3);
      if (ind.empty()) continue;
      const std::uint32_t base = static_cast<std::uint32_t>(lod.vertices.size());
      for (std::size_t v = 0; v < nv; ++v) {
        Vertex vx;
        vx.position = glm::vec3(pos->at(3 * v), pos->at(3 * v + 1), pos->at(3 * v + 2));
        if (!nrm.empty()) vx.normal = glm::vec3(nrm[3 * v], nrm[3 * v + 1], nrm[3 * v + 2]);
        if (!uv.empty()) vx.uv = glm::vec2(uv[2 * v], uv[2 * v + 1]);
        if (skinned) {
          glm::vec4 w(0.0f);
          for (int k = 0; k < 4; ++k) {
            double j = jnt[4 * v + k];
            double wk = std::max(0.0, wgt[4 * v + k]);
            if (wk > 0.0 && j >= joint_count)
              return c.err(pw + ".attributes.JOINTS_0", "vertex " + std::to_string(v) + " uses joint " +
                                                            std::to_string(static_cast<long long>(j)) + " of a skin with " +
                                                            std::to_string(joint_count));
            if (j >= joint_count) wk = 0.0, j = 0;
            vx.joints[k] = static_cast<std::uint16_t>(palette_offset + static_cast<int>(j));
            w[k] = static_cast<float>(wk);
          }
          float sum = w.x + w.y + w.z + w.w;
          if (sum > 0.0f) {
            vx.weights = w / sum;
          } else {
            vx.weights = glm::vec4(1, 0, 0, 0);
          }
        } else {
          vx.joints = glm::u16vec4(static_cast<std::uint16_t>(slot));
          vx.weights = glm::vec4(1, 0, 0, 0);
        }
        lod.vertices.push_back(vx);
      }
      if (nrm.empty()) {  // smooth (indexed) or flat (unindexed) normals from the triangles
        std::vector<glm::vec3> acc(nv, glm::vec3(0.0f));
        for (std::size_t t = 0; t < ind.size(); t += 3) {
          glm::vec3 a = lod.vertices[base + ind[t]].position, b = lod.vertices[base + ind[t + 1]].position,
                    d = lod.vertices[base + ind[t + 2]].position;
          glm::vec3 fnrm = glm::cross(b - a, d - a);
          for (int k = 0; k < 3; ++k) acc[ind[t + k]] += fnrm;
        }
        for (std::size_t v = 0; v < nv; ++v) {
          float l = glm::length(acc[v]);
          lod.vertices[base + v].normal = l > 0.0f ? acc[v] / l : glm::vec3(0, 1, 0);
        }
      }
      Primitive prim;
      prim.first_index = static_cast<std::uint32_t>(lod.indices.size());
      prim.index_count = static_cast<std::uint32_t>(ind.size());
      prim.material = material(p.material);
      for (auto i : ind) lod.indices.push_back(base + i);
      lod.primitives.push_back(prim);
    }
    return Ok{};
  }

  Status meshes() {
    const auto& m = c.m;
    // Mesh nodes reachable from the scene (its roots; every root node without scenes).
    std::vector<int> roots;
    int scene = m.defaultScene >= 0 ? m.defaultScene : (m.scenes.empty() ? -1 : 0);
    if (scene >= static_cast<int>(m.scenes.size())) return c.err("$.scene", "scene " + std::to_string(scene) + " does not exist");
    if (scene >= 0) {
      for (std::size_t k = 0; k < m.scenes[scene].nodes.size(); ++k) {
        int r = m.scenes[scene].nodes[k];
        if (r < 0 || r >= static_cast<int>(m.nodes.size()))
          return c.err(idx("scenes", scene) + ".nodes[" + std::to_string(k) + "]", "node " + std::to_string(r) + " does not exist");
        roots.push_back(r);
      }
    } else {
      std::vector<bool> child(m.nodes.size(), false);
      for (const auto& n : m.nodes)
        for (int ch : n.children) child[ch] = true;
      for (std::size_t i = 0; i < m.nodes.size(); ++i)
        if (!child[i]) roots.push_back(static_cast<int>(i));
    }
    struct Base { int node; std::vector<int> lod_nodes; std::vector<double> coverage; };
    std::vector<Base> bases;
    std::vector<int> stack(roots.rbegin(), roots.rend());
    std::vector<bool> seen(m.nodes.size(), false);
    while (!stack.empty()) {
      int g = stack.back();
      stack.pop_back();
      if (seen[g]) continue;
      seen[g] = true;
      const tg::Node& n = m.nodes[g];
      if (n.mesh >= 0) {
        Base b{g, {}, {}};
        if (auto it = n.extensions.find("MSFT_lod"); it != n.extensions.end()) {
          const tg::Value& ids = it->second.Get("ids");
          std::vector<double> v = number_array(ids);
          for (std::size_t k = 0; k < v.size(); ++k) {
            int id = static_cast<int>(v[k]);
            if (v[k] != id || id < 0 || id >= static_cast<int>(m.nodes.size()) || m.nodes[id].mesh < 0)
              return c.err(idx("nodes", g) + ".extensions.MSFT_lod.ids[" + std::to_string(k) + "]",
                           "is not a node with a mesh");
            b.lod_nodes.push_back(id);
          }
          if (n.extras.Has("MSFT_screencoverage")) b.coverage = number_array(n.extras.Get("MSFT_screencoverage"));
        }
        bases.push_back(std::move(b));
      }
      for (auto it = n.children.rbegin(); it != n.children.rend(); ++it) stack.push_back(*it);
    }
    if (bases.empty()) return c.err("$.nodes", "the scene has no mesh");
    std::size_t levels = 1;
    for (const auto& b : bases) levels = std::max(levels, b.lod_nodes.size() + 1);
    out.lods.resize(levels);
    for (std::size_t l = 0; l < levels; ++l) {
      for (const auto& b : bases) {
        int gn = b.node;
        if (l > 0 && !b.lod_nodes.empty()) gn = b.lod_nodes[std::min(l, b.lod_nodes.size()) - 1];
        const tg::Node& n = m.nodes[gn];
        // A lower level without its own skin uses the base node's skin.
        int skin = n.skin >= 0 ? n.skin : (n.mesh >= 0 && gn != b.node ? m.nodes[b.node].skin : n.skin);
        if (auto s = add_mesh(out.lods[l], gn, n.mesh, skin); !s) return s;
      }
      float cov = 0.0f;
      for (const auto& b : bases)
        if (l < b.coverage.size() && std::isfinite(b.coverage[l])) cov = std::max(cov, static_cast<float>(b.coverage[l]));
      if (l + 1 == levels && levels > 1 && cov == 0.0f) cov = 0.0f;
      if (cov == 0.0f && l + 1 < levels) cov = std::pow(0.5f, static_cast<float>(l + 1));  // no coverage given
      out.lods[l].screen_coverage = l + 1 == levels ? 0.0f : cov;
      if (out.lods[l].indices.empty())
        return c.err(idx("nodes", bases.front().node), "LOD level " + std::to_string(l) + " has no triangles");
    }
    if (out.materials.empty()) out.materials.push_back(Material{glm::vec4(0.8f, 0.8f, 0.8f, 1.0f)});
    return Ok{};
  }

  Status animations() {
    const auto& m = c.m;
    for (std::size_t ai = 0; ai < m.animations.size(); ++ai) {
      const tg::Animation& a = m.animations[ai];
      std::string aw = idx("animations", static_cast<int>(ai));
      Clip clip;
      clip.name = a.name.empty() ? "clip" + std::to_string(ai) : a.name;
      for (std::size_t ci = 0; ci < a.channels.size(); ++ci) {
        const tg::AnimationChannel& ch = a.channels[ci];
        std::string cw = aw + ".channels[" + std::to_string(ci) + "]";
        Channel out_ch;
        if (ch.target_path == "weights") continue;  // morph targets: not used by this runtime
        if (ch.target_path == "translation") out_ch.path = ChannelPath::kTranslation;
        else if (ch.target_path == "rotation") out_ch.path = ChannelPath::kRotation;
        else if (ch.target_path == "scale") out_ch.path = ChannelPath::kScale;
        else return c.err(cw + ".target.path", "unknown path \"" + ch.target_path + "\"");
        if (ch.target_node < 0 || ch.target_node >= static_cast<int>(m.nodes.size()))
          return c.err(cw + ".target.node", "node " + std::to_string(ch.target_node) + " does not exist");
        out_ch.node = remap[ch.target_node];
        if (ch.sampler < 0 || ch.sampler >= static_cast<int>(a.samplers.size()))
          return c.err(cw + ".sampler", "sampler " + std::to_string(ch.sampler) + " does not exist");
        const tg::AnimationSampler& s = a.samplers[ch.sampler];
        std::string sw = aw + ".samplers[" + std::to_string(ch.sampler) + "]";
        if (s.interpolation == "STEP") out_ch.interpolation = Interpolation::kStep;
        else if (s.interpolation == "CUBICSPLINE") out_ch.interpolation = Interpolation::kCubicSpline;
        else if (s.interpolation.empty() || s.interpolation == "LINEAR") out_ch.interpolation = Interpolation::kLinear;
        else return c.err(sw + ".interpolation", "unknown interpolation \"" + s.interpolation + "\"");
        auto in = read_accessor(c, s.input, TINYGLTF_TYPE_SCALAR, {kF}, false, sw + ".input");
        if (!in) return in.error();
        for (std::size_t k = 0; k < in->size(); ++k) {
          if ((*in)[k] < 0.0) return c.err(idx("accessors", s.input), "key time " + std::to_string(k) + " is negative");
          if (k > 0 && !((*in)[k] > (*in)[k - 1]))
            return c.err(idx("accessors", s.input), "key times are not strictly increasing at element " + std::to_string(k));
          out_ch.times.push_back(static_cast<float>((*in)[k]));
        }
        bool rot = out_ch.path == ChannelPath::kRotation;
        auto outv = rot ? read_accessor(c, s.output, TINYGLTF_TYPE_VEC4, {kF, kB, kUB, kS, kUS}, true, sw + ".output")
                        : read_accessor(c, s.output, TINYGLTF_TYPE_VEC3, {kF}, false, sw + ".output");
        if (!outv) return outv.error();
        const int comps = rot ? 4 : 3;
        const std::size_t per_key = out_ch.interpolation == Interpolation::kCubicSpline ? 3 : 1;
        if (outv->size() / comps != out_ch.times.size() * per_key)
          return c.err(idx("accessors", s.output), "has " + std::to_string(outv->size() / comps) + " values for " +
                                                       std::to_string(out_ch.times.size()) + " key times");
        for (std::size_t k = 0; k < outv->size() / comps; ++k) {
          glm::vec4 v(outv->at(k * comps), outv->at(k * comps + 1), outv->at(k * comps + 2), rot ? outv->at(k * comps + 3) : 0.0);
          if (rot && (out_ch.interpolation != Interpolation::kCubicSpline || k % 3 == 1)) {
            float l = glm::length(v);
            if (!(l > 1e-6f)) return c.err(idx("accessors", s.output), "rotation " + std::to_string(k) + " is a zero quaternion");
            v /= l;
          }
          out_ch.values.push_back(v);
        }
        clip.duration = std::max(clip.duration, out_ch.times.back());
        clip.channels.push_back(std::move(out_ch));
      }
      out.clips.push_back(std::move(clip));
    }
    return Ok{};
  }
};

}  // namespace

Result<Model> load_model(const std::string& path, const LoadOptions& options) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return Error{path, "", "no such file"};
  auto size = fs::file_size(path, ec);
  if (ec) return Error{path, "", "cannot read: " + ec.message()};
  if (size < 2) return Error{path, "", "file is empty or too short to be glTF"};
  tg::Model gm;
  tg::TinyGLTF loader;
  std::string err, warn;
  bool ok = false;
  const bool binary = fs::path(path).extension() == ".glb" || fs::path(path).extension() == ".GLB";
  try {
    ok = binary ? loader.LoadBinaryFromFile(&gm, &err, &warn, path) : loader.LoadASCIIFromFile(&gm, &err, &warn, path);
  } catch (const std::exception& e) {
    return Error{path, "", std::string("parse error: ") + e.what()};
  } catch (...) {
    return Error{path, "", "parse error"};
  }
  if (!ok) {
    while (!err.empty() && (err.back() == '\n' || err.back() == ' ')) err.pop_back();
    return Error{path, "", err.empty() ? "not a valid glTF file" : err};
  }
  Model model;
  model.name = fs::path(path).stem().string();
  Ctx c{gm, path};
  try {
    Builder b{c, model, {}, {}, {}, {}, {}};
    if (auto s = b.hierarchy(); !s) return s.error();
    if (auto s = b.meshes(); !s) return s.error();
    if (auto s = b.animations(); !s) return s.error();
  } catch (const std::exception& e) {
    return Error{path, "", std::string("cannot build the model: ") + e.what()};
  }
  model.bake(options.bake_rate);
  return model;
}

}  // namespace bb::runtime
