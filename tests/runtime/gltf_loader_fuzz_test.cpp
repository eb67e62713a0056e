// Deterministic mutation fuzzing of load_model: a hand-made skinned, textured, animated model (as .gltf
// with an external .bin and as .glb) and the shared real models are mutated a few hundred times each
// (JSON edits that know the glTF structure, text and byte damage, GLB header and chunk lengths, binary
// payload damage), every mutant is written to a file and loaded. Each load must return: the model, or an
// error that names the file, a place in it (a byte, a line and column, a JSON path) and a reason. A
// crash, hang or sanitizer report fails the run (build with BB_SANITIZE to see the latter).
// BB_FUZZ_ITERATIONS=N sets the mutants per seed file (to look harder).
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "bb/runtime/model.h"
#include "fuzz.h"

namespace bb::runtime {
namespace {

namespace fs = std::filesystem;
namespace fuzz = bb::test::fuzz;
using json = nlohmann::json;
using Bytes = std::string;  // file contents, binary or text

// ---- base64, for the buffers of a .gltf that carries them in data: URIs -------------------------------

const char kB64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

std::string b64_encode(const Bytes& in) {
  std::string out;
  std::size_t i = 0;
  for (; i + 2 < in.size(); i += 3) {
    const std::uint32_t v = std::uint8_t(in[i]) << 16 | std::uint8_t(in[i + 1]) << 8 | std::uint8_t(in[i + 2]);
    for (int s = 18; s >= 0; s -= 6) out += kB64[(v >> s) & 63];
  }
  if (i + 1 == in.size()) {
    const std::uint32_t v = std::uint8_t(in[i]) << 16;
    out += std::string{kB64[v >> 18], kB64[(v >> 12) & 63], '=', '='};
  } else if (i + 2 == in.size()) {
    const std::uint32_t v = std::uint8_t(in[i]) << 16 | std::uint8_t(in[i + 1]) << 8;
    out += std::string{kB64[v >> 18], kB64[(v >> 12) & 63], kB64[(v >> 6) & 63], '='};
  }
  return out;
}

Bytes b64_decode(const std::string& in) {
  Bytes out;
  std::uint32_t v = 0;
  int bits = 0;
  for (char ch : in) {
    const char* p = std::strchr(kB64, ch);
    if (ch == '=' || !p || !ch) break;
    v = v << 6 | static_cast<std::uint32_t>(p - kB64);
    bits += 6;
    if (bits >= 8) bits -= 8, out += static_cast<char>((v >> bits) & 0xff);
  }
  return out;
}

// ---- mutations ----------------------------------------------------------------------------------------

// Numbers that trouble a glTF reader besides the common ones: small indices, 16-bit limits, a fraction.
const std::vector<const char*> kNumberTexts = fuzz::number_texts({"3", "65535", "65536", "0.5"});
// What byte damage writes half the time in place of a byte: JSON's punctuation, a NUL, 0xff.
constexpr std::string_view kSpecialBytes("\0\xff{}[]\",:-9 \n\\.e", 16);
const double kNumbers[] = {0,          -1,         1,           2,     3,     1e30,   -1e30, 4294967295.0, 4294967296.0,
                           2147483647, 2147483648, -2147483648, 65535, 65536, 1e-30, 0.5,   1.7e308,      -0.0,
                           9007199254740993.0, 16777217, 255, 256, 5121, 5126, 35};
// Keys whose values are counts, offsets, lengths or indices: the structure-aware edits prefer them.
const std::set<std::string> kHotKeys = {
    "count",   "byteOffset", "byteLength", "byteStride", "bufferView", "buffer",   "componentType", "type",
    "indices", "mesh",       "skin",       "joints",     "children",   "nodes",    "scene",         "inverseBindMatrices",
    "input",   "output",     "node",       "sampler",    "source",     "index",    "texCoord",      "material",
    "POSITION", "NORMAL",    "TEXCOORD_0", "JOINTS_0",   "WEIGHTS_0",  "COLOR_0",  "ids",           "weights",
    "mode",    "uri",        "path",       "interpolation", "values",  "targets",  "MSFT_screencoverage",
    "matrix",  "rotation",   "translation", "scale",     "min",        "max",      "normalized",    "sparse"};

class Mutator : public fuzz::Random {
 public:
  using Random::Random;

  // Byte-level damage anywhere in `b` (the shared kinds, or several bit flips at once).
  void bytes(Bytes& b) {
    if (!b.empty() && below(6) == 0) {
      for (int k = 0; k < 8; ++k) fuzz::flip_bit(*this, b);
    } else {
      fuzz::damage_bytes(*this, b, '{', kSpecialBytes);
    }
  }

  // Text-level damage of a JSON text that keeps the tokens apart: a number replaced, two tokens swapped.
  void json_text(std::string& t) {
    if (!fuzz::damage_json_tokens(*this, t, kNumberTexts)) bytes(t);
  }

  // One structure-aware edit of a parsed JSON document.
  void json_edit(json& doc) {
    const fuzz::Sites sites(doc, kHotKeys);
    if (sites.all.empty()) return;
    const json::json_pointer& ptr = sites.pick(*this);  // never the root
    json& v = doc[ptr];
    switch (below(10)) {
      case 0:
      case 1:
      case 2:  // a troublesome number
        v = pick(kNumbers);
        break;
      case 3:  // off by a little (an index one past the end, a count one too many)
        if (v.is_number()) v = v.get<double>() + static_cast<double>(static_cast<int>(below(5)) - 2);
        else v = static_cast<int>(below(8));
        break;
      case 4: {  // another type
        const json others[] = {nullptr, "x", true, json::array(), json::object(), json::array({1, 2, 3}), "-1", "",
                               ".", "..", "/", "data:", "data:application/octet-stream;base64,AAAA", "%zz",
                               "LINEAR", "CUBICSPLINE", "rotation", "weights", "MASK", "BLEND", "VEC4", "MAT4"};
        v = pick(others);
        break;
      }
      case 5:  // removed
        fuzz::erase_at(doc, ptr);
        break;
      case 6:  // an array grows by a copy of one of its elements (more indices, more keys)
        if (v.is_array() && !v.empty()) {
          const json copy = v[below(v.size())];
          v.insert(v.begin() + below(v.size() + 1), copy);
        } else if (doc[ptr.parent_pointer()].is_array()) {
          const json copy = v;
          doc[ptr.parent_pointer()].push_back(copy);
        }
        break;
      case 7:  // swapped with another place's value
        fuzz::swap_with_another(*this, doc, v, sites);
        break;
      case 8:  // an array shortened or extended
        if (v.is_array()) {
          if (!v.empty() && chance(50)) v.erase(v.begin() + below(v.size()));
          else v.push_back(chance(50) ? json(pick(kNumbers)) : json(static_cast<int>(below(4))));
        } else {
          v = json::array({v});
        }
        break;
      default:  // a huge count or index
        v = chance(50) ? json(std::numeric_limits<std::uint32_t>::max()) : json(std::numeric_limits<std::int32_t>::max());
    }
  }

};

// A deeply nested value put in the document's extras (kept by tinygltf), or where it breaks the document.
void deep_nesting(Mutator& m, std::string& text) {
  const std::string deep = fuzz::deep_value(m);
  const std::size_t brace = text.find('{');
  if (brace == std::string::npos) return;
  if (m.chance(70)) text.insert(brace + 1, "\"extras\": " + deep + ",");
  else text.insert(brace + 1 + m.below(text.size() - brace), deep);
}

// ---- GLB container ------------------------------------------------------------------------------------

std::uint32_t get_u32(const Bytes& b, std::size_t at) {
  std::uint32_t v = 0;
  if (at + 4 <= b.size()) std::memcpy(&v, b.data() + at, 4);
  return v;
}
void put_u32(Bytes& b, std::size_t at, std::uint32_t v) {
  if (at + 4 <= b.size()) std::memcpy(b.data() + at, &v, 4);
}

Bytes make_glb(std::string json_text, Bytes bin, bool with_bin = true) {
  while (json_text.size() % 4) json_text.push_back(' ');
  while (bin.size() % 4) bin.push_back('\0');
  Bytes out = "glTF";
  auto u32 = [&](std::uint32_t v) { out.append(reinterpret_cast<const char*>(&v), 4); };
  const std::size_t total = 12 + 8 + json_text.size() + (with_bin ? 8 + bin.size() : 0);
  u32(2);
  u32(static_cast<std::uint32_t>(total));
  u32(static_cast<std::uint32_t>(json_text.size()));
  out += "JSON";
  out += json_text;
  if (with_bin) {
    u32(static_cast<std::uint32_t>(bin.size()));
    out += std::string("BIN\0", 4);
    out += bin;
  }
  return out;
}

// A .glb split into its JSON and BIN chunks (well-formed seeds only).
struct Glb {
  std::string json_text;
  Bytes bin;
};
Glb split_glb(const Bytes& b) {
  Glb g;
  const std::uint32_t jl = get_u32(b, 12);
  g.json_text = b.substr(20, jl);
  if (20 + jl + 8 <= b.size()) g.bin = b.substr(20 + jl + 8, get_u32(b, 20 + jl));
  return g;
}

// A troublesome value in one element of an accessor whose data lie in buffer `buffer` of `doc` (a key time, an
// index, a joint, a weight, a matrix entry; often the last element). False when there is none.
bool damage_accessor(Mutator& m, Bytes& bin, const json& doc, int buffer) {
  std::vector<const json*> candidates;
  if (doc.contains("accessors") && doc["accessors"].is_array() && doc.contains("bufferViews"))
    for (const json& a : doc["accessors"]) {
      if (!a.is_object() || !a.contains("bufferView") || !a["bufferView"].is_number_unsigned()) continue;
      const std::size_t v = a["bufferView"];
      if (v < doc["bufferViews"].size() && doc["bufferViews"][v].value("buffer", -1) == buffer) candidates.push_back(&a);
    }
  if (candidates.empty()) return false;
  const json& a = *candidates[m.below(candidates.size())];
  const json& view = doc["bufferViews"][a["bufferView"].get<std::size_t>()];
  const int ct = a.value("componentType", 5126);
  const std::string type = a.value("type", "SCALAR");
  const std::size_t cs = ct == 5126 || ct == 5125 ? 4 : ct == 5122 || ct == 5123 ? 2 : 1;
  const std::size_t nc = type == "SCALAR" ? 1 : type == "VEC2" ? 2 : type == "VEC3" ? 3
                         : type == "VEC4" || type == "MAT2" ? 4 : type == "MAT3" ? 9 : 16;
  const std::size_t given_stride = view.value("byteStride", std::size_t{0});
  const std::size_t stride = given_stride ? given_stride : cs * nc;
  const std::size_t count = a.value("count", std::size_t{0});
  if (count == 0) return false;
  const std::size_t element = m.chance(50) ? count - 1 : m.below(count);
  const std::size_t at = view.value("byteOffset", std::size_t{0}) + a.value("byteOffset", std::size_t{0}) +
                         element * stride + m.below(nc) * cs;
  if (at + cs > bin.size()) return false;
  if (ct == 5126) {
    const float fs[] = {1e30f, -1e30f, std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(),
                        0.0f, -1.0f, 1e-40f, 3.4e38f, 1e5f, 3600.0f, 2.0f};
    const float f = m.pick(fs);
    std::memcpy(bin.data() + at, &f, 4);
  } else {
    const std::uint32_t us[] = {0xffffffffu, 0x7fffffffu, 65535u, 65536u, 255u, 256u, 0u, 1u, 2u, 3u};
    const std::uint32_t u = m.pick(us);
    std::memcpy(bin.data() + at, &u, cs);  // little-endian: the low bytes
  }
  return true;
}

// Damage to binary payload: an accessor's element (with `doc`), bit flips, or a troublesome float, integer or
// short at an aligned place.
void damage_payload(Mutator& m, Bytes& bin, const json* doc = nullptr, int buffer = 0) {
  if (doc && m.chance(50) && damage_accessor(m, bin, *doc, buffer)) return;
  if (bin.size() < 4) return m.bytes(bin);
  const int edits = 1 + static_cast<int>(m.below(3));
  for (int e = 0; e < edits; ++e) {
    const std::size_t at = m.below(bin.size() / 4) * 4;
    switch (m.below(4)) {
      case 0: {
        const float fs[] = {1e30f, -1e30f, std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(),
                            -std::numeric_limits<float>::infinity(), 0.0f, -0.0f, 1e-40f, 3.4e38f, -1.0f, 1e6f, 3600.0f};
        const float f = m.pick(fs);
        std::memcpy(bin.data() + at, &f, 4);
        break;
      }
      case 1: {
        const std::uint32_t us[] = {0xffffffffu, 0x7fffffffu, 0x80000000u, 65535u, 65536u, 255u, 256u, 0u, 1u};
        const std::uint32_t u = m.pick(us);
        std::memcpy(bin.data() + at, &u, 4);
        break;
      }
      case 2: {
        const std::uint16_t s = m.chance(50) ? 0xffff : static_cast<std::uint16_t>(m.below(64));
        std::memcpy(bin.data() + at + 2 * m.below(2), &s, 2);
        break;
      }
      default: fuzz::flip_bit(m, bin);
    }
  }
}

// A GLB header or chunk header field set to a troublesome length, type, magic or version.
void damage_glb_header(Mutator& m, Bytes& glb) {
  const std::uint32_t jl = get_u32(glb, 12);
  const std::size_t fields[] = {0, 4, 8, 12, 16, 20 + static_cast<std::size_t>(jl), 24 + static_cast<std::size_t>(jl)};
  const std::size_t at = m.pick(fields);
  const std::uint32_t orig = get_u32(glb, at), total = static_cast<std::uint32_t>(glb.size());
  const std::uint32_t values[] = {0,     1,         3,         4,           8,           12,          19,
                                  20,    total - 1, total + 1, total + 8,   orig + 4,    orig - 4,    orig + 8,
                                  orig - 8, orig + 1, orig - 1, 0x7fffffffu, 0x80000000u, 0xffffffffu, 0xfffffff0u,
                                  0x4E4F534Au, 0x004E4942u, static_cast<std::uint32_t>(m.below(1u << 20))};
  put_u32(glb, at, m.pick(values));
  if (m.chance(20)) glb += std::string(4 * (1 + m.below(4)), '\0');  // trailing bytes
}

// ---- the hand-made seed: two joints, a skinned strip, morph target, MSFT_lod, texture, three clips ----

// 2x2 RGBA PNG.
const unsigned char kPng[] = {
    0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52, 0x00, 0x00, 0x00,
    0x02, 0x00, 0x00, 0x00, 0x02, 0x08, 0x06, 0x00, 0x00, 0x00, 0x72, 0xb6, 0x0d, 0x24, 0x00, 0x00, 0x00, 0x13, 0x49,
    0x44, 0x41, 0x54, 0x78, 0x9c, 0x63, 0xf8, 0xcf, 0xc0, 0xf0, 0x1f, 0x0c, 0x81, 0x34, 0x08, 0x34, 0x00, 0x00, 0x49,
    0x49, 0x09, 0x78, 0x28, 0xa0, 0xdb, 0x77, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82};

struct Seed {
  json j;
  Bytes bin;
};

// `glb`: the image is a buffer view and the buffer has no uri; else the image is a data: URI.
Seed hand_made(bool glb) {
  Seed s;
  s.j = {{"asset", {{"version", "2.0"}}}, {"bufferViews", json::array()}, {"accessors", json::array()}};
  auto view = [&](const void* data, std::size_t n, int stride = 0) {
    while (s.bin.size() % 4) s.bin.push_back('\0');
    json v = {{"buffer", 0}, {"byteOffset", s.bin.size()}, {"byteLength", n}};
    if (stride) v["byteStride"] = stride;
    s.bin.append(static_cast<const char*>(data), n);
    s.j["bufferViews"].push_back(v);
    return static_cast<int>(s.j["bufferViews"].size()) - 1;
  };
  auto accessor = [&](int v, int ct, int count, const char* type, bool norm = false) {
    json a = {{"componentType", ct}, {"count", count}, {"type", type}};
    if (v >= 0) a["bufferView"] = v;
    if (norm) a["normalized"] = true;
    s.j["accessors"].push_back(a);
    return static_cast<int>(s.j["accessors"].size()) - 1;
  };
  const float pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 2, 0, 1, 2, 0};
  const float nrm[] = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};
  const float uv[] = {0, 0, 1, 0, 0, 0.5f, 1, 0.5f, 0, 1, 1, 1};
  const std::uint8_t col[] = {255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255,
                              255, 255, 0, 255, 0, 255, 255, 255, 255, 0, 255, 255};
  const std::uint8_t jnt[] = {0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};
  const float wgt[] = {1, 0, 0, 0, 1, 0, 0, 0, 0.5f, 0.5f, 0, 0, 0.5f, 0.5f, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};
  const std::uint16_t ind[] = {0, 1, 2, 2, 1, 3, 2, 3, 4, 4, 3, 5};
  const std::uint8_t ind_coarse[] = {0, 1, 4, 4, 1, 5};
  const float ibm[] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, -1, 0, 1};
  const float times[] = {0, 0.5f, 1};
  const float quats[] = {0, 0, 0, 1, 0, 0, 0.3826834f, 0.9238795f, 0, 0, 0, 1};
  const float moves[] = {0, 1, 0, 0, 1.1f, 0, 0, 1, 0};
  const float scales[] = {0, 0, 0, 1, 1, 1, 0, 0, 0, 0, 0, 0, 1.2f, 1.2f, 1.2f, 0, 0, 0, 0, 0, 0, 1, 1, 1, 0, 0, 0};
  const std::uint8_t sparse_idx[] = {4};
  const float sparse_val[] = {0.5f, 0, 0};

  const int a_pos = accessor(view(pos, sizeof pos, 12), 5126, 6, "VEC3");
  s.j["accessors"][a_pos]["min"] = {0, 0, 0};
  s.j["accessors"][a_pos]["max"] = {1, 2, 0};
  const int a_nrm = accessor(view(nrm, sizeof nrm), 5126, 6, "VEC3");
  const int a_uv = accessor(view(uv, sizeof uv), 5126, 6, "VEC2");
  const int a_col = accessor(view(col, sizeof col), 5121, 6, "VEC4", true);
  const int a_jnt = accessor(view(jnt, sizeof jnt), 5121, 6, "VEC4");
  const int a_wgt = accessor(view(wgt, sizeof wgt), 5126, 6, "VEC4");
  const int a_ind = accessor(view(ind, sizeof ind), 5123, 12, "SCALAR");
  const int a_ind2 = accessor(view(ind_coarse, sizeof ind_coarse), 5121, 6, "SCALAR");
  const int a_ibm = accessor(view(ibm, sizeof ibm), 5126, 2, "MAT4");
  const int a_t = accessor(view(times, sizeof times), 5126, 3, "SCALAR");
  s.j["accessors"][a_t]["min"] = {0};
  s.j["accessors"][a_t]["max"] = {1};
  const int a_q = accessor(view(quats, sizeof quats), 5126, 3, "VEC4");
  const int a_m = accessor(view(moves, sizeof moves), 5126, 3, "VEC3");
  const int a_s = accessor(view(scales, sizeof scales), 5126, 9, "VEC3");
  const int a_morph = accessor(-1, 5126, 6, "VEC3");  // sparse: one displaced vertex
  s.j["accessors"][a_morph]["sparse"] = {{"count", 1},
                                         {"indices", {{"bufferView", view(sparse_idx, 1)}, {"componentType", 5121}}},
                                         {"values", {{"bufferView", view(sparse_val, sizeof sparse_val)}}}};
  const json attributes = {{"POSITION", a_pos}, {"NORMAL", a_nrm},   {"TEXCOORD_0", a_uv},
                           {"COLOR_0", a_col},  {"JOINTS_0", a_jnt}, {"WEIGHTS_0", a_wgt}};
  s.j["meshes"] = json::array(
      {{{"primitives", json::array({{{"attributes", attributes}, {"indices", a_ind}, {"material", 0}, {"mode", 4},
                                     {"targets", json::array({{{"POSITION", a_morph}}})}}})},
        {"weights", {0.5}}},
       {{"primitives", json::array({{{"attributes", attributes}, {"indices", a_ind2}, {"material", 1}}})}}});
  s.j["nodes"] = json::array(
      {{{"name", "body"}, {"mesh", 0}, {"skin", 0},
        {"extensions", {{"MSFT_lod", {{"ids", {3}}}}}}, {"extras", {{"MSFT_screencoverage", {0.5, 0.1}}}}},
       {{"name", "hip"}, {"children", {2}}, {"translation", {0, 1, 0}}},
       {{"name", "knee"}, {"rotation", {0, 0, 0, 1}}, {"scale", {1, 1, 1}}},
       {{"name", "body_lod1"}, {"mesh", 1}, {"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}}}});
  s.j["skins"] = json::array({{{"joints", {1, 2}}, {"inverseBindMatrices", a_ibm}, {"skeleton", 1}}});
  s.j["scenes"] = json::array({{{"nodes", {0, 1}}}});
  s.j["scene"] = 0;
  s.j["materials"] = json::array(
      {{{"pbrMetallicRoughness",
         {{"baseColorFactor", {1, 0.5, 0.5, 1}},
          {"baseColorTexture",
           {{"index", 0}, {"texCoord", 0},
            {"extensions", {{"KHR_texture_transform", {{"offset", {0.1, 0}}, {"scale", {2, 2}}, {"rotation", 0.5}}}}}}}}},
        {"alphaMode", "MASK"}, {"alphaCutoff", 0.4}},
       {{"alphaMode", "BLEND"}, {"extensions", {{"KHR_materials_unlit", json::object()}}}}});
  s.j["samplers"] = json::array({{{"magFilter", 9728}, {"minFilter", 9987}, {"wrapS", 33071}, {"wrapT", 33648}}});
  s.j["textures"] = json::array({{{"sampler", 0}, {"source", 0}}});
  const std::string png(reinterpret_cast<const char*>(kPng), sizeof kPng);
  if (glb) s.j["images"] = json::array({{{"bufferView", view(png.data(), png.size())}, {"mimeType", "image/png"}}});
  else s.j["images"] = json::array({{{"uri", "data:image/png;base64," + b64_encode(png)}}});
  s.j["animations"] = json::array(
      {{{"name", "bend"},
        {"samplers", json::array({{{"input", a_t}, {"output", a_q}, {"interpolation", "LINEAR"}},
                                  {{"input", a_t}, {"output", a_m}, {"interpolation", "STEP"}},
                                  {{"input", a_t}, {"output", a_s}, {"interpolation", "CUBICSPLINE"}}})},
        {"channels", json::array({{{"sampler", 0}, {"target", {{"node", 2}, {"path", "rotation"}}}},
                                  {{"sampler", 1}, {"target", {{"node", 1}, {"path", "translation"}}}},
                                  {{"sampler", 2}, {"target", {{"node", 2}, {"path", "scale"}}}}})}}});
  s.j["extensionsUsed"] = {"KHR_texture_transform", "MSFT_lod", "KHR_materials_unlit"};
  while (s.bin.size() % 4) s.bin.push_back('\0');
  s.j["buffers"] = json::array({{{"byteLength", s.bin.size()}}});
  return s;
}

// ---- the run ------------------------------------------------------------------------------------------

// Each mutant must load, or fail with an error that names the file, a place and a reason (fuzz::run checks).
Result<Model> load(const std::string& path) { return load_model(path); }

// Mutants of a .gltf document. `bin`, when given, is the external buffer 0 (written as mutant.bin beside the
// mutant whenever a mutant damages it); buffers with data: URIs are decoded, damaged and encoded again.
void fuzz_gltf(const std::string& name, const json& seed, const Bytes* bin, std::uint32_t rng_seed, int count) {
  const fs::path dir = fuzz::fresh_dir("bb_gltf_fuzz_" + name);
  json base = seed;
  if (bin) {
    fuzz::write_file(dir / "seed.bin", *bin);
    base["buffers"][0]["uri"] = "seed.bin";
  }
  Mutator m(rng_seed);
  auto mutant = [&] {
    json j = base;
    std::string text;
    const std::size_t kind = m.below(10);
    if (kind < 5) {  // structure-aware edits
      const int edits = 1 + static_cast<int>(m.below(3));
      for (int e = 0; e < edits; ++e) m.json_edit(j);
      text = j.dump(1);
    } else if (kind < 7) {  // damaged buffer contents
      bool done = false;
      if (bin && m.chance(50)) {
        Bytes b = *bin;
        damage_payload(m, b, &j, 0);
        if (m.chance(10)) b.resize(m.below(b.size()));
        fuzz::write_file(dir / "mutant.bin", b);
        j["buffers"][0]["uri"] = "mutant.bin";
        done = true;
      } else if (j.contains("buffers") && j["buffers"].is_array() && !j["buffers"].empty()) {
        const std::size_t first = m.below(j["buffers"].size());  // the first data: URI buffer from here on
        for (std::size_t bi = first; bi < j["buffers"].size() && !done; ++bi) {
          json& buf = j["buffers"][bi];
          if (!buf.contains("uri") || !buf["uri"].is_string()) continue;
          std::string uri = buf["uri"];
          const auto comma = uri.find(";base64,");
          if (uri.rfind("data:", 0) != 0 || comma == std::string::npos) continue;
          Bytes data = b64_decode(uri.substr(comma + 8));
          damage_payload(m, data, &j, static_cast<int>(bi));
          buf["uri"] = uri.substr(0, comma + 8) + b64_encode(data);
          done = true;
        }
      }
      if (!done) m.json_edit(j);
      text = j.dump(1);
    } else if (kind < 9) {  // token-level text damage
      text = j.dump(1);
      m.json_text(text);
      if (m.chance(30)) m.json_text(text);
    } else if (m.chance(90)) {  // byte-level damage
      text = j.dump(1);
      m.bytes(text);
    } else {
      text = j.dump(1);
      deep_nesting(m, text);
    }
    return text;
  };
  if (fuzz::run(dir / (name + ".gltf"), base.dump(1), count, mutant, load)) fs::remove_all(dir);
}

void fuzz_glb(const std::string& name, const Bytes& seed, std::uint32_t rng_seed, int count) {
  const fs::path dir = fuzz::fresh_dir("bb_gltf_fuzz_" + name);
  const Glb parts = split_glb(seed);
  const json doc = json::parse(parts.json_text);
  Mutator m(rng_seed);
  auto mutant = [&] {
    Bytes out;
    const std::size_t kind = m.below(10);
    if (kind < 4) {  // structure-aware JSON edits, a well-formed container
      json j = doc;
      const int edits = 1 + static_cast<int>(m.below(3));
      for (int e = 0; e < edits; ++e) m.json_edit(j);
      out = make_glb(j.dump(), parts.bin);
    } else if (kind < 5) {  // token-level JSON damage or deep nesting, a well-formed container
      std::string t = parts.json_text;
      if (m.chance(90)) m.json_text(t);
      else deep_nesting(m, t);
      out = make_glb(t, parts.bin);
    } else if (kind < 7) {  // header and chunk lengths, types, magic, version (of an edited document now and then)
      if (m.chance(30)) {
        json j = doc;
        m.json_edit(j);
        out = make_glb(j.dump(), parts.bin);
      } else {
        out = seed;
      }
      damage_glb_header(m, out);
      if (m.chance(25)) damage_glb_header(m, out);
    } else if (kind < 9) {  // binary payload damage (the container's lengths kept, or the chunk cut short)
      Bytes b = parts.bin;
      damage_payload(m, b, &doc, 0);
      if (m.chance(15)) b.resize(m.below(b.size()) & ~std::size_t{3});
      out = make_glb(parts.json_text, b, !b.empty() || m.chance(50));
    } else {  // byte-level damage anywhere
      out = seed;
      m.bytes(out);
    }
    return out;
  };
  if (fuzz::run(dir / (name + ".glb"), seed, count, mutant, load)) fs::remove_all(dir);
}

TEST(GltfLoaderFuzz, HandMadeGltfAndGlb) {
  const Seed text = hand_made(false);
  fuzz_gltf("hand", text.j, &text.bin, 20240611u, fuzz::iterations(1500));
  const Seed bin = hand_made(true);
  fuzz_glb("hand", make_glb(bin.j.dump(), bin.bin), 20240612u, fuzz::iterations(1500));
}

TEST(GltfLoaderFuzz, SharedModels) {
  const fs::path dir = fuzz::shared_dir("gltf");
  if (!fs::exists(dir)) GTEST_SKIP() << "shared data absent: " << dir << " (only the hand-made seeds were fuzzed)";
  std::uint32_t rng_seed = 7001;
  for (const fs::path& p : fuzz::present(dir, {"SimpleSkin.gltf", "RiggedSimple.gltf"}))
    fuzz_gltf(p.stem().string(), json::parse(fuzz::read_file(p)), nullptr, rng_seed++, fuzz::iterations(400));
  for (const fs::path& p : fuzz::present(dir, {"CesiumMan.glb", "Fox.glb"}))
    fuzz_glb(p.stem().string(), fuzz::read_file(p), rng_seed++, fuzz::iterations(150));
}

}  // namespace
}  // namespace bb::runtime
