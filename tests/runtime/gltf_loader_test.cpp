// The loader on what other tools write: KHR_mesh_quantization, sparse accessors, KHR_texture_transform,
// EXT_meshopt_compression, eight influences, flat normals when a file has none, and required extensions
// it does not read. Tiny hand-made files with exact answers (the real models packed by gltfpack are in
// render_test.cpp).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <meshoptimizer.h>
#include <nlohmann/json.hpp>
#include <webp/encode.h>

#include "bb/runtime/model.h"
#include "bb/runtime/portrait.h"
#include "gl_context.h"

namespace bb::runtime {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

constexpr int kByte = 5120, kUByte = 5121, kShort = 5122, kUShort = 5123, kFloat = 5126;

// A .gltf with one external .bin, built a view and an accessor at a time.
struct GltfFile {
  json j = {{"asset", {{"version", "2.0"}}}, {"bufferViews", json::array()}, {"accessors", json::array()}};
  std::string bin;

  template <class T>
  int view(const std::vector<T>& data, int stride = 0) {
    while (bin.size() % 4) bin.push_back('\0');
    json v = {{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", data.size() * sizeof(T)}};
    if (stride) v["byteStride"] = stride;
    bin.append(reinterpret_cast<const char*>(data.data()), data.size() * sizeof(T));
    j["bufferViews"].push_back(v);
    return static_cast<int>(j["bufferViews"].size()) - 1;
  }
  int accessor(int view, int component_type, int count, const char* type, bool normalized = false) {
    json a = {{"componentType", component_type}, {"count", count}, {"type", type}};
    if (view >= 0) a["bufferView"] = view;
    if (normalized) a["normalized"] = true;
    j["accessors"].push_back(a);
    return static_cast<int>(j["accessors"].size()) - 1;
  }
  json& last_accessor() { return j["accessors"].back(); }
  // One mesh of one primitive on node 0 of scene 0.
  void mesh(const json& attributes, int indices = -1, int material = -1) {
    json prim = {{"attributes", attributes}};
    if (indices >= 0) prim["indices"] = indices;
    if (material >= 0) prim["material"] = material;
    j["meshes"] = json::array({{{"primitives", json::array({prim})}}});
    if (!j.contains("nodes")) j["nodes"] = json::array({{{"mesh", 0}}});
    j["scenes"] = json::array({{{"nodes", json::array({0})}}});
    j["scene"] = 0;
  }
  // One triangle drawn `n` times, primitive k with material k (the materials are the caller's).
  void triangle_per_material(int n) {
    mesh({{"POSITION", accessor(view(std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0}), kFloat, 3, "VEC3")}}, -1, 0);
    json prim = j["meshes"][0]["primitives"][0];
    for (int k = 1; k < n; ++k) {
      prim["material"] = k;
      j["meshes"][0]["primitives"].push_back(prim);
    }
  }
  std::string write(const std::string& name) {
    // A folder of the running test's own (CTest runs the tests in processes of their own, at once).
    fs::path dir = fs::temp_directory_path() / "bb_gltf_loader_test" / ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::create_directories(dir);
    j["buffers"] = json::array({{{"uri", name + ".bin"}, {"byteLength", bin.size()}}});
    std::ofstream(dir / (name + ".bin"), std::ios::binary) << bin;
    std::ofstream(dir / (name + ".gltf")) << j.dump(1);
    return (dir / (name + ".gltf")).string();
  }
};

void expect_vec(glm::vec3 got, glm::vec3 want, float tol = 0.0f) {
  EXPECT_NEAR(got.x, want.x, tol);
  EXPECT_NEAR(got.y, want.y, tol);
  EXPECT_NEAR(got.z, want.z, tol);
}

// KHR_mesh_quantization: positions as normalized shorts, normals as normalized bytes, texture coordinates as
// plain (not normalized) unsigned shorts in set 1, which the material's KHR_texture_transform picks and
// scales back. A sparse accessor replaces the third position.
TEST(GltfLoader, QuantizedAttributesSparseAndTextureTransform) {
  GltfFile f;
  int pos = f.accessor(f.view(std::vector<std::int16_t>{32767, 0, 0, 0, 32767, 0, 0, 0, -32767}), kShort, 3, "VEC3", true);
  // Sparse: element 2 becomes (16384, -32767, 0) (normalized: 16384 / 32767, -1, 0).
  int sidx = f.view(std::vector<std::uint8_t>{2, 0, 0, 0});
  int sval = f.view(std::vector<std::int16_t>{16384, -32767, 0});
  f.last_accessor()["sparse"] = {{"count", 1},
                                  {"indices", {{"bufferView", sidx}, {"componentType", kUByte}}},
                                  {"values", {{"bufferView", sval}}}};
  int nrm = f.accessor(f.view(std::vector<std::int8_t>{0, 0, 127, 0, 0, 0, 127, 0, 0, 0, 127, 0}, 4), kByte, 3, "VEC3", true);
  int uv0 = f.accessor(f.view(std::vector<float>{0.9f, 0.9f, 0.9f, 0.9f, 0.9f, 0.9f}), kFloat, 3, "VEC2");
  int uv1 = f.accessor(f.view(std::vector<std::uint16_t>{0, 0, 1024, 0, 0, 2048}), kUShort, 3, "VEC2");
  f.mesh({{"POSITION", pos}, {"NORMAL", nrm}, {"TEXCOORD_0", uv0}, {"TEXCOORD_1", uv1}}, -1, 0);
  f.j["materials"] = json::array(
      {{{"pbrMetallicRoughness",
         {{"baseColorTexture",
           {{"index", 0},
            {"texCoord", 0},
            {"extensions",
             {{"KHR_texture_transform", {{"offset", {0.5, 0.25}}, {"scale", {1.0 / 4096, 1.0 / 4096}}, {"texCoord", 1}}}}}}}}}}});
  f.j["textures"] = json::array({json::object()});
  f.j["extensionsUsed"] = {"KHR_mesh_quantization", "KHR_texture_transform"};
  f.j["extensionsRequired"] = {"KHR_mesh_quantization"};
  auto m = load_model(f.write("quantized"));
  ASSERT_TRUE(m.ok()) << m.error().message();
  const auto& v = m->lods[0].vertices;
  ASSERT_EQ(v.size(), 3u);
  expect_vec(v[0].position, {1, 0, 0});
  expect_vec(v[1].position, {0, 1, 0});
  expect_vec(v[2].position, {static_cast<float>(16384 / 32767.0), -1, 0});
  for (const auto& x : v) expect_vec(x.normal, {0, 0, 1});
  EXPECT_EQ(v[0].uv, glm::vec2(0.5f, 0.25f));
  EXPECT_EQ(v[1].uv, glm::vec2(0.75f, 0.25f));
  EXPECT_EQ(v[2].uv, glm::vec2(0.5f, 0.75f));
}

// The transform's rotation turns the coordinates counter-clockwise, as the extension's matrix says.
TEST(GltfLoader, TextureTransformRotation) {
  GltfFile f;
  int pos = f.accessor(f.view(std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0}), kFloat, 3, "VEC3");
  int uv = f.accessor(f.view(std::vector<float>{0, 0, 1, 0, 0, 1}), kFloat, 3, "VEC2");
  f.mesh({{"POSITION", pos}, {"TEXCOORD_0", uv}}, -1, 0);
  f.j["materials"] = json::array({{{"pbrMetallicRoughness",
                                     {{"baseColorTexture",
                                       {{"index", 0},
                                        {"extensions", {{"KHR_texture_transform", {{"rotation", std::acos(-1.0) / 2}, {"offset", {0, 1}}}}}}}}}}}});
  f.j["textures"] = json::array({json::object()});
  auto m = load_model(f.write("rotation"));
  ASSERT_TRUE(m.ok()) << m.error().message();
  const auto& v = m->lods[0].vertices;
  EXPECT_NEAR(v[1].uv.x, 0.0f, 1e-6f);  // (1, 0) turned a quarter turn is (0, 1), then offset by (0, 1)
  EXPECT_NEAR(v[1].uv.y, 2.0f, 1e-6f);
  EXPECT_NEAR(v[2].uv.x, -1.0f, 1e-6f);  // (0, 1) -> (-1, 0) -> (-1, 1)
  EXPECT_NEAR(v[2].uv.y, 1.0f, 1e-6f);
}

// A skin with JOINTS_1 / WEIGHTS_1: the four heaviest of eight influences are kept, renormalized, and the
// skin report says what was dropped.
TEST(GltfLoader, EightInfluencesKeepTheFourHeaviest) {
  GltfFile f;
  int pos = f.accessor(f.view(std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0}), kFloat, 3, "VEC3");
  int j0 = f.accessor(f.view(std::vector<std::uint8_t>{0, 1, 2, 3, 0, 0, 0, 0, 0, 0, 0, 0}), kUByte, 3, "VEC4");
  int w0 = f.accessor(f.view(std::vector<float>{0.05f, 0.3f, 0.05f, 0.1f, 1, 0, 0, 0, 1, 0, 0, 0}), kFloat, 3, "VEC4");
  int j1 = f.accessor(f.view(std::vector<std::uint8_t>{4, 5, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0}), kUByte, 3, "VEC4");
  int w1 = f.accessor(f.view(std::vector<float>{0.4f, 0.1f, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0}), kFloat, 3, "VEC4");
  f.j["nodes"] = json::array({{{"mesh", 0}, {"skin", 0}}, {{"children", {2, 3, 4, 5, 6, 7}}}, json::object(),
                              json::object(), json::object(), json::object(), json::object(), json::object()});
  f.j["skins"] = json::array({{{"joints", {2, 3, 4, 5, 6, 7}}}});
  f.mesh({{"POSITION", pos}, {"JOINTS_0", j0}, {"WEIGHTS_0", w0}, {"JOINTS_1", j1}, {"WEIGHTS_1", w1}});
  f.j["scenes"] = json::array({{{"nodes", {0, 1}}}});
  auto m = load_model(f.write("eight"));
  ASSERT_TRUE(m.ok()) << m.error().message();
  const Vertex& v = m->lods[0].vertices[0];
  ASSERT_EQ(m->palette.size(), 6u);  // the skin's joints, in its order: palette entry = joint index
  // Kept: joint 4 (0.4), 1 (0.3), then 3 and 5 (0.1 each, in the file's order); dropped 0 and 2 (0.05 each).
  EXPECT_EQ(v.joints, glm::u16vec4(4, 1, 3, 5));
  EXPECT_NEAR(v.weights.x, 0.4f / 0.9f, 1e-6f);
  EXPECT_NEAR(v.weights.y, 0.3f / 0.9f, 1e-6f);
  EXPECT_NEAR(v.weights.z, 0.1f / 0.9f, 1e-6f);
  EXPECT_NEAR(v.weights.w, 0.1f / 0.9f, 1e-6f);
  const SkinReport& r = m->skin_report;
  EXPECT_EQ(r.skinned_vertices, 3u);
  EXPECT_EQ(r.max_influences, 6);
  EXPECT_EQ(r.vertices_over_four, 1u);
  EXPECT_NEAR(r.worst_dropped_weight, 0.1, 1e-6);
  EXPECT_TRUE(r.weights_normalized);
  EXPECT_EQ(r.skin_joints, 6);
}

// COLOR_0, as normalized bytes (RGB) or floats (RGBA): kept per vertex as 8-bit RGBA, and the primitive gets a
// material that multiplies by it; a primitive without colours keeps the plain material.
TEST(GltfLoader, VertexColours) {
  for (bool rgb_bytes : {true, false}) {
    GltfFile f;
    int pos = f.accessor(f.view(std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0}), kFloat, 3, "VEC3");
    int col = rgb_bytes ? f.accessor(f.view(std::vector<std::uint8_t>{255, 0, 0, 0, 0, 128, 0, 0, 0, 0, 255, 0}, 4), kUByte,
                                     3, "VEC3", true)
                        : f.accessor(f.view(std::vector<float>{1, 0, 0, 0.5f, 0, 0.5f, 0, 1, 0, 0, 1, 0.25f}), kFloat, 3, "VEC4");
    f.mesh({{"POSITION", pos}, {"COLOR_0", col}});
    json plain = {{"attributes", {{"POSITION", pos}}}};
    f.j["meshes"][0]["primitives"].push_back(plain);
    auto m = load_model(f.write("colours"));
    ASSERT_TRUE(m.ok()) << m.error().message();
    const MeshLod& lod = m->lods[0];
    ASSERT_EQ(lod.vertices.size(), 6u);
    ASSERT_EQ(lod.primitives.size(), 2u);
    if (rgb_bytes) {
      EXPECT_EQ(lod.vertices[0].color, glm::u8vec4(255, 0, 0, 255));
      EXPECT_EQ(lod.vertices[1].color, glm::u8vec4(0, 128, 0, 255));
      EXPECT_EQ(lod.vertices[2].color, glm::u8vec4(0, 0, 255, 255));
    } else {
      EXPECT_EQ(lod.vertices[0].color, glm::u8vec4(255, 0, 0, 128));
      EXPECT_EQ(lod.vertices[2].color, glm::u8vec4(0, 0, 255, 64));
    }
    EXPECT_EQ(lod.vertices[3].color, glm::u8vec4(255));  // the second primitive has none
    EXPECT_TRUE(m->materials[lod.primitives[0].material].vertex_colors);
    EXPECT_FALSE(m->materials[lod.primitives[1].material].vertex_colors);
    EXPECT_EQ(m->materials[lod.primitives[0].material].base_color, glm::vec4(1.0f));  // glTF's default, white
  }
}

// glTF: a mesh without normals is drawn with flat ones, indexed or not.
TEST(GltfLoader, IndexedMeshWithoutNormalsIsFlatShaded) {
  GltfFile f;
  int pos = f.accessor(f.view(std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1}), kFloat, 4, "VEC3");
  int ind = f.accessor(f.view(std::vector<std::uint16_t>{0, 1, 2, 0, 3, 1}), kUShort, 6, "SCALAR");
  f.mesh({{"POSITION", pos}}, ind);
  auto m = load_model(f.write("flat"));
  ASSERT_TRUE(m.ok()) << m.error().message();
  const auto& v = m->lods[0].vertices;
  ASSERT_EQ(v.size(), 6u);
  for (int k = 0; k < 3; ++k) expect_vec(v[k].normal, {0, 0, 1});
  for (int k = 3; k < 6; ++k) expect_vec(v[k].normal, {0, 1, 0});
  expect_vec(v[4].position, {0, 0, 1});
}

// Triangle strips and fans (glTF modes 5 and 6) are triangles: each becomes a list in glTF's order,
// a strip's odd triangles with their first two corners swapped so that all keep the strip's winding,
// the degenerate triangles that join strips dropped. Points and lines (modes 0 to 3) are not a skin.
TEST(GltfLoader, StripsAndFansBecomeTriangleLists) {
  // A unit square's four corners and a fifth point; normals +Z so that nothing is made flat.
  const std::vector<float> corners{0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 2, 0, 0};
  const std::vector<float> normals{0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};
  auto indices_of = [&](int mode, const std::vector<std::uint16_t>& ind) {
    GltfFile f;
    const int pos = f.accessor(f.view(corners), kFloat, 5, "VEC3"), nrm = f.accessor(f.view(normals), kFloat, 5, "VEC3");
    const int ia = ind.empty() ? -1 : f.accessor(f.view(ind), kUShort, static_cast<int>(ind.size()), "SCALAR");
    f.mesh({{"POSITION", pos}, {"NORMAL", nrm}}, ia);
    f.j["meshes"][0]["primitives"][0]["mode"] = mode;
    LoadOptions in_file_order;  // the loader's lists as converted, not reordered for the vertex cache
    in_file_order.optimize_vertex_order = false;
    auto m = load_model(f.write("mode" + std::to_string(mode) + "_" + std::to_string(ind.size())), in_file_order);
    EXPECT_TRUE(m.ok()) << m.error().message();
    return m.ok() ? m->lods[0].indices : std::vector<std::uint32_t>{};
  };
  using V = std::vector<std::uint32_t>;
  // Non-indexed, the strip is the five vertices in order: 012, 213 (swapped), 234.
  EXPECT_EQ(indices_of(5, {}), (V{0, 1, 2, 2, 1, 3, 2, 3, 4}));
  EXPECT_EQ(indices_of(5, {0, 1, 2, 3}), (V{0, 1, 2, 2, 1, 3}));
  // Two strips joined by repeating 3 and 4: the four degenerate triangles go.
  EXPECT_EQ(indices_of(5, {0, 1, 2, 3, 3, 4, 4, 1, 2}), (V{0, 1, 2, 2, 1, 3, 4, 1, 2}));
  // Fan around 0: 1 2 0, 2 3 0 (glTF's corner order: v[i+1], v[i+2], v[0]).
  EXPECT_EQ(indices_of(6, {0, 1, 3, 2}), (V{1, 3, 0, 3, 2, 0}));
  // Every triangle of the strip faces +Z, as the list's would: the winding is kept.
  for (const V& ind : {indices_of(5, {1, 3, 0, 2})}) {
    ASSERT_EQ(ind.size(), 6u);
    for (std::size_t t = 0; t < ind.size(); t += 3) {
      auto p = [&](std::uint32_t k) { return glm::vec3(corners[3 * k], corners[3 * k + 1], corners[3 * k + 2]); };
      EXPECT_GT(glm::cross(p(ind[t + 1]) - p(ind[t]), p(ind[t + 2]) - p(ind[t])).z, 0.0f) << "triangle " << t / 3;
    }
  }
  // Too short a strip has no triangle, and a model of nothing else has no level to load: an error.
  GltfFile f;
  const int pos = f.accessor(f.view(corners), kFloat, 5, "VEC3");
  f.mesh({{"POSITION", pos}}, f.accessor(f.view(std::vector<std::uint16_t>{0, 1}), kUShort, 2, "SCALAR"));
  f.j["meshes"][0]["primitives"][0]["mode"] = 5;
  EXPECT_FALSE(load_model(f.write("short")).ok());
}

// glTF samplers: wrap modes and filters as the file gives them, glTF's defaults (repeat; trilinear where
// it leaves the filters to the implementation) where it gives none; values outside the enumerations and
// references to samplers that do not exist are errors naming the place.
TEST(GltfLoader, SamplersAreRead) {
  auto file = [](const json& samplers, const json& textures) {
    GltfFile f;
    f.triangle_per_material(4);
    f.j["materials"] = json::array();
    for (int mi = 0; mi < 3; ++mi)
      f.j["materials"].push_back({{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", mi}}}}}});
    f.j["materials"].push_back(json::object());  // untextured
    f.j["samplers"] = samplers;
    f.j["textures"] = textures;
    return f;
  };
  const json samplers = json::array({{{"wrapS", 33071}, {"wrapT", 33648}, {"magFilter", 9728}, {"minFilter", 9984}},
                                     json::object(),
                                     {{"minFilter", 9729}, {"magFilter", 9729}}});
  GltfFile f = file(samplers, json::array({{{"sampler", 0}}, {{"sampler", 1}}, {{"sampler", 2}}}));
  auto m = load_model(f.write("samplers"));
  ASSERT_TRUE(m.ok()) << m.error().message();
  const MeshLod& lod = m->lods[0];
  ASSERT_EQ(lod.primitives.size(), 4u);
  auto sampler = [&](int k) { return m->materials[lod.primitives[k].material].sampler; };
  const TextureSampler s0 = sampler(0), s1 = sampler(1), s2 = sampler(2), s3 = sampler(3);
  EXPECT_EQ(s0.wrap_s, Wrap::kClampToEdge);
  EXPECT_EQ(s0.wrap_t, Wrap::kMirroredRepeat);
  EXPECT_TRUE(s0.mag_nearest);
  EXPECT_TRUE(s0.min_nearest);
  EXPECT_TRUE(s0.mipmaps);
  EXPECT_TRUE(s0.mip_nearest);
  EXPECT_EQ(s1, TextureSampler{});  // nothing given: repeat, trilinear
  EXPECT_EQ(s1.wrap_s, Wrap::kRepeat);
  EXPECT_FALSE(s1.mag_nearest || s1.min_nearest || s1.mip_nearest);
  EXPECT_TRUE(s1.mipmaps);
  EXPECT_FALSE(s2.mipmaps);  // LINEAR: level 0 only
  EXPECT_FALSE(s2.min_nearest || s2.mag_nearest);
  EXPECT_EQ(s3, TextureSampler{});  // untextured

  struct Case {
    json samplers, textures;
    const char* where;
  };
  for (const Case& c : {Case{json::array({{{"wrapS", 1234}}}), json::array({{{"sampler", 0}}}), "$.samplers[0].wrapS"},
                        Case{json::array({{{"wrapT", 9729}}}), json::array({{{"sampler", 0}}}), "$.samplers[0].wrapT"},
                        Case{json::array({{{"magFilter", 9984}}}), json::array({{{"sampler", 0}}}), "$.samplers[0].magFilter"},
                        Case{json::array({{{"minFilter", 9730}}}), json::array({{{"sampler", 0}}}), "$.samplers[0].minFilter"},
                        Case{json::array({json::object()}), json::array({json::object(), {{"sampler", 3}}}), "$.textures[1].sampler"}}) {
    json textures = c.textures;  // the three textured materials name textures 0, 1 and 2
    while (textures.size() < 3) textures.push_back(json::object());
    GltfFile g = file(c.samplers, textures);
    auto bad = load_model(g.write("bad_sampler"));
    ASSERT_FALSE(bad.ok()) << c.where;
    EXPECT_EQ(bad.error().where, c.where) << bad.error().message();
  }
}

// KHR_materials_unlit marks its material unlit, also where a file requires the extension; other
// materials stay lit.
TEST(GltfLoader, UnlitMaterialsAreMarked) {
  GltfFile f;
  int pos = f.accessor(f.view(std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0}), kFloat, 3, "VEC3");
  f.mesh({{"POSITION", pos}}, -1, 0);
  json prim = f.j["meshes"][0]["primitives"][0];
  prim["material"] = 1;
  f.j["meshes"][0]["primitives"].push_back(prim);
  f.j["materials"] = json::array({{{"extensions", {{"KHR_materials_unlit", json::object()}}}}, json::object()});
  f.j["extensionsUsed"] = {"KHR_materials_unlit"};
  f.j["extensionsRequired"] = {"KHR_materials_unlit"};
  auto m = load_model(f.write("unlit"));
  ASSERT_TRUE(m.ok()) << m.error().message();
  const MeshLod& lod = m->lods[0];
  ASSERT_EQ(lod.primitives.size(), 2u);
  EXPECT_TRUE(m->materials[lod.primitives[0].material].unlit);
  EXPECT_FALSE(m->materials[lod.primitives[1].material].unlit);
}

// glTF's doubleSided is kept (default: single-sided, back faces culled), and a rigid mesh under a
// mirroring node (scale -1 along x: a negative determinant) has its triangles turned, so that its
// front faces wind counter-clockwise as drawn; the same mesh on an unmirrored node keeps the file's order.
TEST(GltfLoader, DoubleSidedMaterialsAndMirroredNodes) {
  for (bool mirrored : {false, true}) {
    GltfFile f;
    int pos = f.accessor(f.view(std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0}), kFloat, 3, "VEC3");
    int ind = f.accessor(f.view(std::vector<std::uint16_t>{0, 1, 2}), kUShort, 3, "SCALAR");
    f.mesh({{"POSITION", pos}}, ind, 0);
    json prim = f.j["meshes"][0]["primitives"][0];
    prim["material"] = 1;
    f.j["meshes"][0]["primitives"].push_back(prim);
    f.j["materials"] = json::array({{{"doubleSided", true}}, json::object()});
    if (mirrored) f.j["nodes"][0]["scale"] = {-1.0, 1.0, 1.0};
    LoadOptions in_file_order;  // the file's vertex numbers (not renumbered in first-use order)
    in_file_order.optimize_vertex_order = false;
    auto m = load_model(f.write(mirrored ? "mirrored" : "plain"), in_file_order);
    ASSERT_TRUE(m.ok()) << m.error().message();
    const MeshLod& lod = m->lods[0];
    ASSERT_EQ(lod.primitives.size(), 2u);
    EXPECT_TRUE(m->materials[lod.primitives[0].material].double_sided);
    EXPECT_FALSE(m->materials[lod.primitives[1].material].double_sided);
    for (const Primitive& p : lod.primitives) {
      ASSERT_EQ(p.index_count, 3u);
      const std::uint32_t* t = &lod.indices[p.first_index];  // corners relative to the first
      EXPECT_EQ(t[1] - t[0], mirrored ? 2u : 1u) << (mirrored ? "mirrored" : "plain");
      EXPECT_EQ(t[2] - t[0], mirrored ? 1u : 2u) << (mirrored ? "mirrored" : "plain");
    }
  }
}

// glTF's emissiveFactor is light of the surface's own, added after the shading: a black square that
// gives off orange is drawn orange, as geometry and as an impostor (lit as drawn too); without it, black.
TEST(GltfLoader, EmissiveColourIsDrawn) {
  auto square = [](const json& material) {
    GltfFile f;
    const int pos = f.accessor(f.view(std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0}), kFloat, 4, "VEC3");
    const int nrm = f.accessor(f.view(std::vector<float>{0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1}), kFloat, 4, "VEC3");
    const int ind = f.accessor(f.view(std::vector<std::uint16_t>{0, 1, 2, 2, 1, 3}), kUShort, 6, "SCALAR");
    f.mesh({{"POSITION", pos}, {"NORMAL", nrm}}, ind, 0);
    f.j["materials"] = json::array({material});
    return f;
  };
  const json black = {{"pbrMetallicRoughness", {{"baseColorFactor", {0, 0, 0, 1}}}}};
  json glowing = black;
  glowing["emissiveFactor"] = {1.0, 0.5, 0.0};
  auto lit = load_model(square(glowing).write("emissive"));
  ASSERT_TRUE(lit.ok()) << lit.error().message();
  EXPECT_EQ(lit->materials.at(0).emissive, glm::vec3(1.0f, 0.5f, 0.0f));
  auto dark = load_model(square(black).write("black"));
  ASSERT_TRUE(dark.ok()) << dark.error().message();
  EXPECT_EQ(dark->materials.at(0).emissive, glm::vec3(0.0f));
  REQUIRE_GL();
  for (const RenderMode mode : {RenderMode::kGeometry, RenderMode::kImpostor}) {
    PortraitOptions o;
    o.mode = mode;
    o.width = o.height = 64;
    o.elevation_deg = 0.0f;
    auto centre = [&](const Model& m) {
      auto img = render_portrait(m, o);
      EXPECT_TRUE(img.ok()) << img.error().message();
      const std::size_t at = 4 * (32 * 64 + 32);
      return img.ok() ? glm::ivec4(img->rgba[at], img->rgba[at + 1], img->rgba[at + 2], img->rgba[at + 3]) : glm::ivec4(-1);
    };
    const glm::ivec4 orange = centre(*lit), none = centre(*dark);
    EXPECT_EQ(orange.a, 255) << "mode " << static_cast<int>(mode);
    EXPECT_GE(orange.r, 250) << "mode " << static_cast<int>(mode);
    EXPECT_NEAR(orange.g, 128, 4) << "mode " << static_cast<int>(mode);
    EXPECT_LE(orange.b, 3) << "mode " << static_cast<int>(mode);
    EXPECT_EQ(none, glm::ivec4(0, 0, 0, 255)) << "mode " << static_cast<int>(mode);
  }
}

// EXT_texture_webp: a WebP image (lossless here, so exact) is decoded for the texture whose extension
// names it, whether the texture's own source is absent (the extension required) or a PNG fallback beside
// it (the extension used; the WebP is preferred). A WebP that does not decode is an error naming the file
// and the image.
TEST(GltfLoader, WebpTexturesAreDecoded) {
  const std::uint8_t rgba[16] = {255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255, 255, 255, 255, 128};
  std::uint8_t* webp = nullptr;
  const std::size_t webp_size = WebPEncodeLosslessRGBA(rgba, 2, 2, 8, &webp);
  ASSERT_GT(webp_size, 12u);
  const std::vector<std::uint8_t> webp_bytes(webp, webp + webp_size);
  WebPFree(webp);
  // A 1 x 1 PNG of (10, 20, 30, 255).
  const std::vector<std::uint8_t> png = {
      0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52, 0x00, 0x00,
      0x00, 0x01, 0x00, 0x00, 0x00, 0x01, 0x08, 0x06, 0x00, 0x00, 0x00, 0x1f, 0x15, 0xc4, 0x89, 0x00, 0x00, 0x00,
      0x0d, 0x49, 0x44, 0x41, 0x54, 0x78, 0x9c, 0x63, 0xe0, 0x12, 0x91, 0xfb, 0x0f, 0x00, 0x01, 0xa4, 0x01, 0x3c,
      0x93, 0x8b, 0x0e, 0xb7, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82};
  auto file = [&](bool fallback, const std::vector<std::uint8_t>& webp_image) {
    GltfFile f;
    int pos = f.accessor(f.view(std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0}), kFloat, 3, "VEC3");
    int uv = f.accessor(f.view(std::vector<float>{0, 0, 1, 0, 0, 1}), kFloat, 3, "VEC2");
    f.mesh({{"POSITION", pos}, {"TEXCOORD_0", uv}}, -1, 0);
    json images = json::array({{{"bufferView", f.view(webp_image)}, {"mimeType", "image/webp"}}});
    json texture = {{"extensions", {{"EXT_texture_webp", {{"source", 0}}}}}};
    if (fallback) {
      images.push_back({{"bufferView", f.view(png)}, {"mimeType", "image/png"}});
      texture["source"] = 1;
      f.j["extensionsUsed"] = {"EXT_texture_webp"};
    } else {
      f.j["extensionsUsed"] = {"EXT_texture_webp"};
      f.j["extensionsRequired"] = {"EXT_texture_webp"};
    }
    f.j["images"] = images;
    f.j["textures"] = json::array({texture});
    f.j["materials"] = json::array({{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}}});
    return f;
  };
  for (bool fallback : {false, true}) {
    GltfFile f = file(fallback, webp_bytes);
    auto m = load_model(f.write(fallback ? "webp_fallback" : "webp"));
    ASSERT_TRUE(m.ok()) << m.error().message();
    const Material& mat = m->materials[m->lods[0].primitives[0].material];
    ASSERT_GE(mat.texture, 0);
    const Texture& t = m->textures[mat.texture];
    EXPECT_EQ(t.width, 2);
    EXPECT_EQ(t.height, 2);
    ASSERT_EQ(t.rgba.size(), 16u);
    EXPECT_TRUE(std::equal(t.rgba.begin(), t.rgba.end(), rgba)) << "fallback " << fallback;
  }
  std::vector<std::uint8_t> corrupt = webp_bytes;
  for (std::size_t k = 12; k < corrupt.size(); ++k) corrupt[k] = 0x5a;
  GltfFile f = file(false, corrupt);
  const std::string path = f.write("webp_corrupt");
  auto m = load_model(path);
  ASSERT_FALSE(m.ok());
  const std::string msg = m.error().message();
  EXPECT_NE(msg.find(path), std::string::npos) << msg;
  EXPECT_NE(msg.find("$.images[0]: the WebP image does not decode"), std::string::npos) << msg;
}

// alphaMode: OPAQUE (the default) neither tests nor blends; MASK tests at alphaCutoff (default 0.5);
// BLEND blends and does not test.
TEST(GltfLoader, AlphaModesAreKept) {
  GltfFile f;
  f.triangle_per_material(4);
  f.j["materials"] = json::array({json::object(), {{"alphaMode", "MASK"}}, {{"alphaMode", "MASK"}, {"alphaCutoff", 0.25}},
                                  {{"alphaMode", "BLEND"}, {"alphaCutoff", 0.25}}});
  auto m = load_model(f.write("alpha_modes"));
  ASSERT_TRUE(m.ok()) << m.error().message();
  const MeshLod& lod = m->lods[0];
  ASSERT_EQ(lod.primitives.size(), 4u);
  const Material* mat[4];
  for (int k = 0; k < 4; ++k) mat[k] = &m->materials[lod.primitives[k].material];
  EXPECT_FALSE(mat[0]->alpha_mask || mat[0]->alpha_blend);
  EXPECT_TRUE(mat[1]->alpha_mask && !mat[1]->alpha_blend);
  EXPECT_EQ(mat[1]->alpha_cutoff, 0.5f);
  EXPECT_TRUE(mat[2]->alpha_mask && !mat[2]->alpha_blend);
  EXPECT_EQ(mat[2]->alpha_cutoff, 0.25f);
  EXPECT_TRUE(mat[3]->alpha_blend && !mat[3]->alpha_mask);
}

// Morph targets are drawn at their default weights, baked into the vertices: the node's weights where it
// gives them, else the mesh's. Normals move with their targets and are renormalized. Animated weights are
// counted, not played; weights that do not match the targets are an error.
TEST(GltfLoader, MorphTargetsAtTheirDefaultWeights) {
  auto file = [](const json& mesh_weights, const json& node_weights) {
    GltfFile f;
    int pos = f.accessor(f.view(std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0}), kFloat, 3, "VEC3");
    int nrm = f.accessor(f.view(std::vector<float>{0, 0, 1, 0, 0, 1, 0, 0, 1}), kFloat, 3, "VEC3");
    int up = f.accessor(f.view(std::vector<float>{0, 0, 2, 0, 0, 2, 0, 0, 2}), kFloat, 3, "VEC3");
    int right = f.accessor(f.view(std::vector<float>{4, 0, 0, 0, 0, 0, 0, 0, 0}), kFloat, 3, "VEC3");
    int tilt = f.accessor(f.view(std::vector<float>{1, 0, -1, 1, 0, -1, 1, 0, -1}), kFloat, 3, "VEC3");
    f.mesh({{"POSITION", pos}, {"NORMAL", nrm}});
    f.j["meshes"][0]["primitives"][0]["targets"] = json::array({{{"POSITION", up}}, {{"POSITION", right}, {"NORMAL", tilt}}});
    if (!mesh_weights.is_null()) f.j["meshes"][0]["weights"] = mesh_weights;
    if (!node_weights.is_null()) f.j["nodes"][0]["weights"] = node_weights;
    // A clip on the weights (input 0 and 1 s, outputs two weights per key) and one on the translation.
    int times = f.accessor(f.view(std::vector<float>{0, 1}), kFloat, 2, "SCALAR");
    f.last_accessor()["min"] = {0};
    f.last_accessor()["max"] = {1};
    int wv = f.accessor(f.view(std::vector<float>{0, 0, 1, 1}), kFloat, 4, "SCALAR");
    int tv = f.accessor(f.view(std::vector<float>{0, 0, 0, 0, 1, 0}), kFloat, 2, "VEC3");
    f.j["animations"] = json::array({{{"samplers", json::array({{{"input", times}, {"output", wv}}, {{"input", times}, {"output", tv}}})},
                                      {"channels", json::array({{{"sampler", 0}, {"target", {{"node", 0}, {"path", "weights"}}}},
                                                                {{"sampler", 1}, {"target", {{"node", 0}, {"path", "translation"}}}}})}}});
    return f;
  };
  {
    GltfFile f = file(json::array({0.5, 0.0}), nullptr);
    auto m = load_model(f.write("morph_mesh_weights"));
    ASSERT_TRUE(m.ok()) << m.error().message();
    const auto& v = m->lods[0].vertices;
    ASSERT_EQ(v.size(), 3u);
    expect_vec(v[0].position, {0, 0, 1});
    expect_vec(v[1].position, {1, 0, 1});
    expect_vec(v[0].normal, {0, 0, 1});
    EXPECT_EQ(m->morph_report.primitives, 1u);
    EXPECT_EQ(m->morph_report.most_targets, 2);
    EXPECT_EQ(m->morph_report.weighted_targets, 1u);
    EXPECT_EQ(m->morph_report.weight_channels, 1);
    ASSERT_EQ(m->clips.size(), 1u);
    EXPECT_EQ(m->clips[0].channels.size(), 1u);  // the translation
  }
  {
    GltfFile f = file(json::array({0.5, 0.0}), json::array({0.25, 1.0}));  // the node's weights win
    auto m = load_model(f.write("morph_node_weights"));
    ASSERT_TRUE(m.ok()) << m.error().message();
    const auto& v = m->lods[0].vertices;
    expect_vec(v[0].position, {4, 0, 0.5f});
    expect_vec(v[2].position, {0, 1, 0.5f});
    expect_vec(v[0].normal, {1, 0, 0}, 1e-6f);  // (0, 0, 1) + 1 * (1, 0, -1)
    EXPECT_EQ(m->morph_report.weighted_targets, 2u);
  }
  {
    GltfFile f = file(nullptr, nullptr);  // no weights: all 0
    auto m = load_model(f.write("morph_no_weights"));
    ASSERT_TRUE(m.ok()) << m.error().message();
    expect_vec(m->lods[0].vertices[1].position, {1, 0, 0});
    EXPECT_EQ(m->morph_report.weighted_targets, 0u);
  }
  {
    GltfFile f = file(json::array({0.5, 0.0, 1.0}), nullptr);
    auto m = load_model(f.write("morph_bad_weights"));
    ASSERT_FALSE(m.ok());
    EXPECT_EQ(m.error().where, "$.meshes[0].weights") << m.error().message();
  }
}

// EXT_meshopt_compression: positions (attributes), normals (octahedral filter) and indices (triangles)
// encoded with meshoptimizer decode to what was encoded. A damaged stream is an error naming the view.
TEST(GltfLoader, MeshoptCompressedViewsDecode) {
  const std::vector<float> positions{0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  const std::vector<float> normals{0, 0, 1, 0, 0.6f, 0, 0.8f, 0, -0.6f, 0, 0.8f, 0, 1, 0, 0, 0};  // xyz + pad
  const std::vector<std::uint16_t> indices{0, 1, 2, 0, 3, 1};
  std::vector<std::uint8_t> pos_enc(meshopt_encodeVertexBufferBound(4, 12));
  pos_enc.resize(meshopt_encodeVertexBuffer(pos_enc.data(), pos_enc.size(), positions.data(), 4, 12));
  std::vector<std::int8_t> oct(16);
  meshopt_encodeFilterOct(oct.data(), 4, 4, 8, normals.data());
  std::vector<std::uint8_t> nrm_enc(meshopt_encodeVertexBufferBound(4, 4));
  nrm_enc.resize(meshopt_encodeVertexBuffer(nrm_enc.data(), nrm_enc.size(), oct.data(), 4, 4));
  std::vector<std::uint8_t> ind_enc(meshopt_encodeIndexBufferBound(6, 4));
  ind_enc.resize(meshopt_encodeIndexBuffer(ind_enc.data(), ind_enc.size(), indices.data(), 6));

  for (bool damaged : {false, true}) {
    GltfFile f;
    // Buffer 0 holds the compressed streams; the views point at buffer 1, the fallback: zeros here (a .gltf
    // buffer needs a file; gltfpack's .glb files leave it without data).
    auto compressed = [&](const std::vector<std::uint8_t>& enc, std::size_t count, int stride, const char* mode,
                          const char* filter, bool vertex) {
      int v = f.view(enc);
      json& bv = f.j["bufferViews"][v];
      json ext = {{"buffer", 0}, {"byteOffset", bv["byteOffset"]}, {"byteLength", enc.size()}, {"byteStride", stride},
                  {"count", count}, {"mode", mode}};
      if (filter) ext["filter"] = filter;
      bv = {{"buffer", 1}, {"byteOffset", 0}, {"byteLength", count * stride}, {"extensions", {{"EXT_meshopt_compression", ext}}}};
      if (vertex) bv["byteStride"] = stride;
      return v;
    };
    std::vector<std::uint8_t> pe = pos_enc;
    if (damaged) pe.resize(pe.size() / 2);
    int pos = f.accessor(compressed(pe, 4, 12, "ATTRIBUTES", nullptr, true), kFloat, 4, "VEC3");
    int nrm = f.accessor(compressed(nrm_enc, 4, 4, "ATTRIBUTES", "OCTAHEDRAL", true), kByte, 4, "VEC3", true);
    int ind = f.accessor(compressed(ind_enc, 6, 2, "TRIANGLES", nullptr, false), kUShort, 6, "SCALAR");
    f.mesh({{"POSITION", pos}, {"NORMAL", nrm}}, ind);
    f.j["extensionsUsed"] = {"EXT_meshopt_compression"};
    f.j["extensionsRequired"] = {"EXT_meshopt_compression"};
    std::string path = f.write(damaged ? "meshopt_damaged" : "meshopt");
    f.j["buffers"].push_back(
        {{"uri", "zeros.bin"}, {"byteLength", 64}, {"extensions", {{"EXT_meshopt_compression", {{"fallback", true}}}}}});
    std::ofstream(path) << f.j.dump(1);
    std::ofstream(fs::path(path).parent_path() / "zeros.bin", std::ios::binary) << std::string(64, '\0');
    auto m = load_model(path);
    if (damaged) {
      ASSERT_FALSE(m.ok());
      EXPECT_EQ(m.error().where, "$.bufferViews[0].extensions.EXT_meshopt_compression") << m.error().message();
      EXPECT_NE(m.error().message().find("does not decode"), std::string::npos) << m.error().message();
      continue;
    }
    ASSERT_TRUE(m.ok()) << m.error().message();
    const MeshLod& lod = m->lods[0];
    ASSERT_EQ(lod.vertices.size(), 4u);
    for (int k = 0; k < 4; ++k) {
      expect_vec(lod.vertices[k].position, {positions[3 * k], positions[3 * k + 1], positions[3 * k + 2]});
      expect_vec(lod.vertices[k].normal, {normals[4 * k], normals[4 * k + 1], normals[4 * k + 2]}, 0.02f);
    }
    // The index codec may start a triangle at another corner; the winding stays.
    auto canonical = [](std::vector<std::uint32_t> t) {
      for (std::size_t k = 0; k + 2 < t.size(); k += 3)
        while (t[k] > t[k + 1] || t[k] > t[k + 2]) std::rotate(t.begin() + k, t.begin() + k + 1, t.begin() + k + 3);
      return t;
    };
    EXPECT_EQ(canonical(lod.indices), canonical({indices.begin(), indices.end()}));
  }
}

// A required extension the loader does not read, and broken sparse accessors, are errors naming the place.
TEST(GltfLoader, UnreadRequiredExtensionsAndBadSparseAccessorsAreErrors) {
  {
    GltfFile f;
    f.mesh({{"POSITION", f.accessor(f.view(std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0}), kFloat, 3, "VEC3")}});
    f.j["extensionsUsed"] = {"KHR_mesh_quantization", "KHR_draco_mesh_compression"};
    f.j["extensionsRequired"] = {"KHR_mesh_quantization", "KHR_draco_mesh_compression"};
    auto m = load_model(f.write("draco"));
    ASSERT_FALSE(m.ok());
    EXPECT_EQ(m.error().where, "$.extensionsRequired[1]");
    EXPECT_NE(m.error().message().find("KHR_draco_mesh_compression"), std::string::npos) << m.error().message();
  }
  struct Case {
    std::vector<std::uint8_t> indices;
    int count;
    const char* where;
  };
  for (const Case& c : {Case{{1, 1}, 2, "$.accessors[0].sparse.indices"}, Case{{0, 3}, 2, "$.accessors[0].sparse.indices"},
                        Case{{0, 1}, 4, "$.accessors[0].sparse.count"}}) {
    GltfFile f;
    int pos = f.accessor(f.view(std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0}), kFloat, 3, "VEC3");
    int si = f.view(c.indices);
    int sv = f.view(std::vector<float>{5, 5, 5, 6, 6, 6});
    f.j["accessors"][pos]["sparse"] = {{"count", c.count},
                                       {"indices", {{"bufferView", si}, {"componentType", kUByte}}},
                                       {"values", {{"bufferView", sv}}}};
    f.mesh({{"POSITION", pos}});
    auto m = load_model(f.write("sparse"));
    ASSERT_FALSE(m.ok());
    EXPECT_EQ(m.error().where, c.where) << m.error().message();
  }
}

// Found by gltf_loader_fuzz_test.cpp and in the code it pointed at: inputs that crashed, allocated 2^63 bytes
// or read past a buffer inside tinygltf 2.7 or the loader, or converted an out-of-range number to int (undefined
// behaviour). Each is now an error naming the file and the place (or, for the texture coordinate set, a clamp).
TEST(GltfLoader, FuzzFindingsAreErrors) {
  const std::vector<float> triangle{0, 0, 0, 1, 0, 0, 0, 1, 0};
  auto read = [](const std::string& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  {  // JSON nested 100000 deep (in extras): tinygltf walks it recursively and overflowed the stack (SIGSEGV).
    GltfFile f;
    f.mesh({{"POSITION", f.accessor(f.view(triangle), kFloat, 3, "VEC3")}});
    const std::string path = f.write("deep");
    std::string text = read(path);
    ASSERT_EQ(text[0], '{');
    text.insert(1, "\"extras\": " + std::string(100000, '[') + "0" + std::string(100000, ']') + ",");
    std::ofstream(path, std::ios::binary) << text;
    auto m = load_model(path);
    ASSERT_FALSE(m.ok());
    EXPECT_EQ(m.error().file, path);
    EXPECT_EQ(m.error().where, "line 1, column 267");  // level 257: the 256th '[' (after '{' and 10 bytes of "extras": )
    EXPECT_EQ(m.error().reason, "the JSON nests deeper than 256 levels");
  }
  {  // An image's buffer view past the end of its buffer: tinygltf hands its bytes over unchecked (SIGSEGV).
    GltfFile f;
    f.mesh({{"POSITION", f.accessor(f.view(triangle), kFloat, 3, "VEC3")}});
    const int iv = f.view(std::vector<std::uint8_t>(8, 0));
    f.j["bufferViews"][iv]["byteOffset"] = 1000000;
    f.j["images"] = json::array({{{"bufferView", iv}, {"mimeType", "image/png"}}});
    const std::string path = f.write("image_view_outside");
    auto m = load_model(path);
    ASSERT_FALSE(m.ok());
    EXPECT_EQ(m.error().message(), path + ": $.bufferViews[1]: byte range [1000000, 1000008) of image 0 lies outside its "
                                          "buffer of 44 bytes");
  }
  {  // A buffer uri naming a folder: tinygltf took it for a file of 2^63 - 1 bytes and allocated that.
    GltfFile f;
    f.mesh({{"POSITION", f.accessor(f.view(triangle), kFloat, 3, "VEC3")}});
    const std::string path = f.write("uri_folder");
    f.j["buffers"][0]["uri"] = ".";
    std::ofstream(path) << f.j.dump(1);
    auto m = load_model(path);
    ASSERT_FALSE(m.ok());
    EXPECT_EQ(m.error().file, path);
    EXPECT_EQ(m.error().where, "$.buffers[0].uri");
    EXPECT_NE(m.error().reason.find("not a file"), std::string::npos) << m.error().message();
  }
  {  // A .glb whose BIN chunk (and buffer) claim 8 bytes more than the file has: tinygltf forgets the chunk
     // header in its check and read 8 bytes past the end.
    json j = {{"asset", {{"version", "2.0"}}},
              {"buffers", json::array({{{"byteLength", 44}}})},
              {"bufferViews", json::array({{{"buffer", 0}, {"byteLength", 36}}})},
              {"accessors", json::array({{{"bufferView", 0}, {"componentType", kFloat}, {"count", 3}, {"type", "VEC3"}}})},
              {"meshes", json::array({{{"primitives", json::array({{{"attributes", {{"POSITION", 0}}}}})}}})},
              {"nodes", json::array({{{"mesh", 0}}})}};
    std::string text = j.dump();
    while (text.size() % 4) text += ' ';
    std::string glb = "glTF";
    auto u32 = [&](std::uint32_t v) { glb.append(reinterpret_cast<const char*>(&v), 4); };
    u32(2);
    u32(static_cast<std::uint32_t>(12 + 8 + text.size() + 8 + 36));
    u32(static_cast<std::uint32_t>(text.size()));
    glb += "JSON" + text;
    u32(44);  // 36 bytes follow
    glb += std::string("BIN\0", 4);
    glb.append(reinterpret_cast<const char*>(triangle.data()), 36);
    fs::create_directories(fs::temp_directory_path() / "bb_gltf_loader_test");
    const std::string path = (fs::temp_directory_path() / "bb_gltf_loader_test" / "bin_chunk_long.glb").string();
    std::ofstream(path, std::ios::binary) << glb;
    auto m = load_model(path);
    ASSERT_FALSE(m.ok());
    EXPECT_EQ(m.error().message(), path + ": byte " + std::to_string(20 + text.size()) +
                                       ": the BIN chunk's length 44 runs past the end of the file (" +
                                       std::to_string(glb.size()) + " bytes)");
  }
  {  // 1e30 as an MSFT_lod id and as KHR_texture_transform's texCoord: converted to int unchecked.
    GltfFile f;
    f.mesh({{"POSITION", f.accessor(f.view(triangle), kFloat, 3, "VEC3")}}, -1, 0);
    f.j["materials"] = json::array(
        {{{"pbrMetallicRoughness",
           {{"baseColorTexture", {{"index", 0}, {"extensions", {{"KHR_texture_transform", {{"texCoord", 1e30}}}}}}}}}}});
    f.j["textures"] = json::array({json::object()});  // no image: drawn untextured
    const std::string path = f.write("huge_tex_coord");
    auto m = load_model(path);
    ASSERT_TRUE(m.ok()) << m.error().message();  // set 7, which the primitive does not have
    f.j["nodes"][0]["extensions"] = {{"MSFT_lod", {{"ids", {1e30}}}}};
    std::ofstream(path) << f.j.dump(1);
    m = load_model(path);
    ASSERT_FALSE(m.ok());
    EXPECT_EQ(m.error().where, "$.nodes[0].extensions.MSFT_lod.ids[0]") << m.error().message();
  }
  // A damaged last key time: 1e30 s overflowed the baked frame count (undefined behaviour), 1e5 s baked six
  // million frames (seconds of work and hundreds of MB for a 4-byte change).
  for (const float last : {1e30f, 1e5f}) {
    GltfFile f;
    f.mesh({{"POSITION", f.accessor(f.view(triangle), kFloat, 3, "VEC3")}});
    const int in = f.accessor(f.view(std::vector<float>{0, last}), kFloat, 2, "SCALAR");
    const int out = f.accessor(f.view(std::vector<float>{0, 0, 0, 1, 0, 0}), kFloat, 2, "VEC3");
    f.j["animations"] = json::array({{{"samplers", json::array({{{"input", in}, {"output", out}}})},
                                      {"channels", json::array({{{"sampler", 0}, {"target", {{"node", 0}, {"path", "translation"}}}}})}}});
    const std::string path = f.write("long_clip");
    auto m = load_model(path);
    ASSERT_FALSE(m.ok());
    EXPECT_EQ(m.error().file, path);
    EXPECT_EQ(m.error().where, "$.animations[0]");
    EXPECT_NE(m.error().reason.find("frames"), std::string::npos) << m.error().message();
  }
}

}  // namespace
}  // namespace bb::runtime
