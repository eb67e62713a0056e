// The checks made on a glTF file's container and JSON before tinygltf reads it
// (runtime/src/gltf_document.cpp): each damaged copy of a one-triangle file is refused with an
// error naming the file, the place and the reason, where tinygltf 2.7 alone said "Invalid glTF
// binary." or "'componentType' property is missing in Accessor." without a place, or silently
// ignored the property (an index written 1.0).
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bb/runtime/model.h"

namespace bb::runtime {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

const std::vector<float> kTriangle{0, 0, 0, 1, 0, 0, 0, 1, 0};

std::string triangle_bytes() {
  return std::string(reinterpret_cast<const char*>(kTriangle.data()), 36);
}

// The smallest document the loader takes: one triangle on node 0, its 36 bytes in buffer 0 (a file
// named by `uri`, or a .glb's BIN chunk when `uri` is empty).
json triangle(const std::string& uri) {
  json buffer = {{"byteLength", 36}};
  if (!uri.empty()) buffer["uri"] = uri;
  return {
      {"asset", {{"version", "2.0"}}},
      {"buffers", json::array({buffer})},
      {"bufferViews", json::array({{{"buffer", 0}, {"byteLength", 36}}})},
      {"accessors",
       json::array({{{"bufferView", 0}, {"componentType", 5126}, {"count", 3}, {"type", "VEC3"}}})},
      {"meshes",
       json::array({{{"primitives", json::array({{{"attributes", {{"POSITION", 0}}}}})}}})},
      {"nodes", json::array({{{"mesh", 0}}})},
      {"scenes", json::array({{{"nodes", json::array({0})}}})},
      {"scene", 0}};
}

// A folder of the running test's own: CTest runs each test in a process of its own, several at
// once, and every test here writes t.bin (a shared folder let one test read another's half-written
// t.bin: "TheTriangleLoadsAsGltfAndGlb" failed once in a run with -j2).
fs::path dir() {
  fs::path d = fs::temp_directory_path() / "bb_gltf_document_test" /
               ::testing::UnitTest::GetInstance()->current_test_info()->name();
  fs::create_directories(d);
  return d;
}

// `text` as name.gltf, with the triangle's bytes as t.bin beside it.
std::string write_gltf(const std::string& name, const std::string& text) {
  std::ofstream(dir() / "t.bin", std::ios::binary) << triangle_bytes();
  std::ofstream(dir() / (name + ".gltf"), std::ios::binary) << text;
  return (dir() / (name + ".gltf")).string();
}

void put_u32(std::string& s, std::uint32_t v) {
  for (int k = 0; k < 4; ++k) s += static_cast<char>((v >> (8 * k)) & 0xff);
}

// A .glb of `text` (padded to 4 bytes) and, unless `bin` is empty, a BIN chunk of `bin`.
std::string glb_bytes(std::string text, const std::string& bin) {
  while (text.size() % 4) text += ' ';
  std::string out = "glTF";
  put_u32(out, 2);
  put_u32(out,
          static_cast<std::uint32_t>(12 + 8 + text.size() + (bin.empty() ? 0 : 8 + bin.size())));
  put_u32(out, static_cast<std::uint32_t>(text.size()));
  out += "JSON" + text;
  if (!bin.empty()) {
    put_u32(out, static_cast<std::uint32_t>(bin.size()));
    out += std::string("BIN\0", 4) + bin;
  }
  return out;
}

std::string write_glb(const std::string& name, const std::string& bytes) {
  std::ofstream(dir() / (name + ".glb"), std::ios::binary) << bytes;
  return (dir() / (name + ".glb")).string();
}

void expect_error(const std::string& path, const std::string& where,
                  const std::string& reason_part) {
  auto m = load_model(path);
  ASSERT_FALSE(m.ok()) << path << " loaded";
  EXPECT_EQ(m.error().file, path);
  EXPECT_EQ(m.error().where, where) << m.error().message();
  EXPECT_NE(m.error().reason.find(reason_part), std::string::npos) << m.error().message();
}

TEST(GltfDocument, TheTriangleLoadsAsGltfAndGlb) {
  auto a = load_model(write_gltf("ok", triangle("t.bin").dump(1)));
  ASSERT_TRUE(a.ok()) << a.error().message();
  auto b = load_model(write_glb("ok", glb_bytes(triangle("").dump(), triangle_bytes())));
  ASSERT_TRUE(b.ok()) << b.error().message();
  EXPECT_EQ(a->lods[0].triangle_count(), 1u);
  EXPECT_EQ(b->lods[0].triangle_count(), 1u);
}

// Syntax errors and numbers out of range: a line and column in a .gltf, a byte of the file in a
// .glb.
TEST(GltfDocument, JsonErrorsNameTheirLineOrByte) {
  expect_error(write_gltf("syntax", "{\n  \"asset\": {\"version\": \"2.0\"},\n  \"nodes\": [}\n"),
               "line 3, column 13", "invalid JSON: syntax error");
  expect_error(
      write_gltf(
          "overflow",
          "{\"asset\": {\"version\": \"2.0\"},\n\"nodes\": [{\"translation\": [1e400, 0, 0]}]}"),
      "line 2, column 32", "number overflow");  // the number's last digit
  expect_error(write_gltf("empty", ""), "line 1, column 1", "unexpected end of input");
  // In a .glb: 20 bytes of header, then the text; its "]" is at offset 10.
  expect_error(write_glb("syntax", glb_bytes("{\"nodes\": ]}", "")), "byte 30", "invalid JSON");
}

// The .glb container, each damage at the byte that holds it.
TEST(GltfDocument, GlbContainerErrorsNameTheirByte) {
  const std::string text = triangle("").dump();
  const std::string good = glb_bytes(text, triangle_bytes());
  const std::size_t padded = (text.size() + 3) / 4 * 4, bin_at = 20 + padded;
  struct Case {
    const char* name;
    std::function<void(std::string&)> damage;
    std::string where, reason;
  };
  const std::vector<Case> cases = {
      {"short", [](std::string& b) { b.resize(7); }, "byte 0",
       "the 12-byte GLB header is cut short: the file has 7 bytes"},
      {"magic", [](std::string& b) { b[0] = 'G'; }, "byte 0",
       "not a GLB file: it starts with \"GlTF\", not \"glTF\""},
      {"version", [](std::string& b) { b[4] = 1; }, "byte 4",
       "GLB version 1; this loader reads version 2"},
      {"length", [](std::string& b) { b.pop_back(); }, "byte 8",
       "the header gives the file's length as " + std::to_string(good.size()) + " bytes; it has " +
           std::to_string(good.size() - 1)},
      {"first_chunk", [](std::string& b) { b.replace(16, 4, std::string("BIN\0", 4)); }, "byte 16",
       "the first chunk's type is bytes 42 49 4e 00, not \"JSON\""},
      {"json_empty", [](std::string& b) { b.replace(12, 4, std::string(4, '\0')); }, "byte 12",
       "the JSON chunk is empty"},
      {"json_long", [](std::string& b) { b[13] = 0x70; }, "byte 12", "the JSON chunk's length"},
      {"second_json", [&](std::string& b) { b.replace(bin_at + 4, 4, "JSON"); },
       "byte " + std::to_string(bin_at + 4), "a second JSON chunk"},
      {"bin_unaligned", [&](std::string& b) { b[bin_at] = 35; }, "byte " + std::to_string(bin_at),
       "the BIN chunk's length 35 is not a multiple of 4"},
      {"bin_long", [&](std::string& b) { b[bin_at] = 40; }, "byte " + std::to_string(bin_at),
       "the BIN chunk's length 40 runs past the end of the file"},
  };
  for (const Case& c : cases) {
    std::string bytes = good;
    c.damage(bytes);
    expect_error(write_glb(c.name, bytes), c.where, c.reason);
  }
  // A buffer without a uri and no BIN chunk, or a shorter one.
  expect_error(write_glb("no_bin", glb_bytes(text, "")), "$.buffers[0]",
               "has no uri, and the .glb has no BIN chunk");
  expect_error(write_glb("short_bin", glb_bytes(text, triangle_bytes().substr(0, 32))),
               "$.buffers[0].byteLength", "36 is more than the BIN chunk's 32 bytes");
}

// What tinygltf requires, and each reference within its array, named by JSON path.
TEST(GltfDocument, DocumentErrorsNameTheirJsonPath) {
  struct Case {
    const char* name;
    std::function<void(json&)> damage;
    const char* where;
    const char* reason;
  };
  const std::vector<Case> cases = {
      {"root", [](json& j) { j = json::array(); }, "$", "expected an object, got array"},
      {"asset", [](json& j) { j.erase("asset"); }, "$", "missing required property \"asset\""},
      {"version", [](json& j) { j["asset"]["version"] = 2; }, "$.asset.version",
       "expected a string, got number"},
      {"dictionary", [](json& j) { j["nodes"] = json::object(); }, "$.nodes",
       "expected an array, got object"},
      {"element", [](json& j) { j["meshes"].push_back(3); }, "$.meshes[1]",
       "expected an object, got number"},
      {"component_type", [](json& j) { j["accessors"][0].erase("componentType"); },
       "$.accessors[0]", "missing required property \"componentType\""},
      {"count_float", [](json& j) { j["accessors"][0]["count"] = 3.0; }, "$.accessors[0].count",
       "is written 3.0: this loader (tinygltf 2.7) reads integers written without a fraction or "
       "exponent"},
      {"count_huge", [](json& j) { j["accessors"][0]["count"] = 1e30; }, "$.accessors[0].count",
       "is 1e+30, not a whole number from 0 to 2^53"},
      {"count_fraction", [](json& j) { j["accessors"][0]["count"] = 2.5; }, "$.accessors[0].count",
       "is 2.5, not a whole number from 0 to 2^53"},
      {"count_negative", [](json& j) { j["accessors"][0]["count"] = -3; }, "$.accessors[0].count",
       "is -3; it must be 0 or more"},
      {"type", [](json& j) { j["accessors"][0]["type"] = "VEC5"; }, "$.accessors[0].type",
       "\"VEC5\" is not an accessor type"},
      {"view_missing", [](json& j) { j["accessors"][0]["bufferView"] = 1; },
       "$.accessors[0].bufferView", "bufferViews[1] does not exist (the file has 1)"},
      {"stride", [](json& j) { j["bufferViews"][0]["byteStride"] = 6; },
       "$.bufferViews[0].byteStride", "6 is not a multiple of 4 up to 252"},
      {"attributes", [](json& j) { j["meshes"][0]["primitives"][0].erase("attributes"); },
       "$.meshes[0].primitives[0]", "missing required property \"attributes\""},
      {"position", [](json& j) { j["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 1.0; },
       "$.meshes[0].primitives[0].attributes.POSITION", "is written 1.0"},
      {"indices", [](json& j) { j["meshes"][0]["primitives"][0]["indices"] = 4; },
       "$.meshes[0].primitives[0].indices", "accessors[4] does not exist (the file has 1)"},
      {"indices_without_view",
       [](json& j) {
         j["accessors"].push_back({{"componentType", 5123}, {"count", 3}, {"type", "SCALAR"}});
         j["meshes"][0]["primitives"][0]["indices"] = 1;
       },
       "$.meshes[0].primitives[0].indices", "accessors[1] has no bufferView"},
      {"texture",
       [](json& j) {
         j["materials"] =
             json::array({{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}}});
       },
       "$.materials[0].pbrMetallicRoughness.baseColorTexture.index",
       "textures[0] does not exist (the file has 0)"},
      // tinygltf refused these with "Array length of `emissiveFactor` parameter in material must
      // be 3, but got 2" and no place (found by the fuzz test with 15,000 mutants a seed).
      {"emissive_factor", [](json& j) { j["materials"] = json::array({{{"emissiveFactor", {1, 0}}}}); },
       "$.materials[0].emissiveFactor", "has 2 numbers; it must have 3"},
      {"base_color_factor",
       [](json& j) {
         j["materials"] = json::array({{{"pbrMetallicRoughness", {{"baseColorFactor", {1, 1, 1, 1, 1}}}}}});
       },
       "$.materials[0].pbrMetallicRoughness.baseColorFactor", "has 5 numbers; it must have 4"},
      {"base_color_factor_text",
       [](json& j) {
         j["materials"] = json::array({{{"pbrMetallicRoughness", {{"baseColorFactor", {1, "1", 1, 1}}}}}});
       },
       "$.materials[0].pbrMetallicRoughness.baseColorFactor[1]", "expected a number, got string"},
      {"image", [](json& j) { j["images"] = json::array({json::object()}); }, "$.images[0]",
       "has neither a uri nor a bufferView"},
      {"child",
       [](json& j) {
         j["nodes"][0]["children"] = {0, 7};
       },
       "$.nodes[0].children[1]", "nodes[7] does not exist"},
      {"scene", [](json& j) { j["scene"] = 1; }, "$.scene",
       "scenes[1] does not exist (the file has 1)"},
      {"joints", [](json& j) { j["skins"] = json::array({json::object()}); }, "$.skins[0]",
       "missing required property \"joints\""},
      {"channel",
       [](json& j) {
         j["animations"] = json::array(
             {{{"samplers", json::array({{{"input", 0}, {"output", 0}}})},
               {"channels",
                json::array({{{"sampler", 1}, {"target", {{"node", 0}, {"path", "scale"}}}}})}}});
       },
       "$.animations[0].channels[0].sampler", "sampler 1 does not exist (the animation has 1)"},
      {"camera",
       [](json& j) {
         j["cameras"] = json::array({{{"type", "perspective"}, {"perspective", {{"znear", 0.1}}}}});
       },
       "$.cameras[0].perspective", "missing required property \"yfov\""},
      {"byte_length", [](json& j) { j["buffers"][0].erase("byteLength"); }, "$.buffers[0]",
       "missing required property \"byteLength\""},
      {"byte_length_0", [](json& j) { j["buffers"][0]["byteLength"] = 0; },
       "$.buffers[0].byteLength", "is 0; it must be 1 or more"},
      {"no_uri", [](json& j) { j["buffers"][0].erase("uri"); }, "$.buffers[0]",
       "has no uri: a .gltf file's buffer must name its data"},
      {"uri_missing_file", [](json& j) { j["buffers"][0]["uri"] = "nowhere.bin"; },
       "$.buffers[0].uri", "names \"nowhere.bin\", which is not a file beside"},
      {"uri_empty", [](json& j) { j["buffers"][0]["uri"] = ""; }, "$.buffers[0].uri",
       "is empty; it must name a file beside"},
      // tinygltf cannot join an absolute path to the folder (it said "File not found" of a file
      // that is there); a URI with a scheme is not fetched.
      {"uri_absolute", [](json& j) { j["buffers"][0]["uri"] = (dir() / "t.bin").string(); },
       "$.buffers[0].uri", "names the absolute path \""},
      {"uri_windows_drive", [](json& j) { j["buffers"][0]["uri"] = "C:\\assets\\t.bin"; },
       "$.buffers[0].uri", "names the absolute path \"C:\\assets\\t.bin\""},
      {"uri_http", [](json& j) { j["buffers"][0]["uri"] = "http://example.com/t.bin"; },
       "$.buffers[0].uri", "a URI with the scheme http:, which is not fetched"},
      {"uri_file", [](json& j) { j["buffers"][0]["uri"] = "file:t.bin"; }, "$.buffers[0].uri",
       "a URI with the scheme file:, which is not fetched"},
      {"uri_size", [](json& j) { j["buffers"][0]["byteLength"] = 40; }, "$.buffers[0].uri",
       "holds 36 bytes; byteLength says 40"},
      {"data_uri_size",
       [](json& j) { j["buffers"][0]["uri"] = "data:application/octet-stream;base64,AAAA"; },
       "$.buffers[0].uri", "the data: URI holds 3 bytes; byteLength says 36"},
      {"data_uri_type", [](json& j) { j["buffers"][0]["uri"] = "data:application/gltf-buffer,0"; },
       "$.buffers[0].uri", "a data: URI this loader does not read"},
  };
  for (const Case& c : cases) {
    json j = triangle("t.bin");
    c.damage(j);
    expect_error(write_gltf(c.name, j.dump(1)), c.where, c.reason);
  }
}

// An image file is read as a buffer's is: beside the glTF, named relative to it (%XX escapes
// decoded). A missing one left the material untextured without a word.
TEST(GltfDocument, ImageFilesAreFoundBesideTheGltfOrRefused) {
  const std::string png(
      "\x89\x50\x4e\x47\x0d\x0a\x1a\x0a\x00\x00\x00\x0d\x49\x48\x44\x52\x00\x00\x00\x01\x00\x00"
      "\x00\x01\x08\x06\x00\x00\x00\x1f\x15\xc4\x89\x00\x00\x00\x0d\x49\x44\x41\x54\x78\x9c\x63"
      "\xf8\xcf\xc0\xf0\x1f\x00\x05\x00\x01\xff\x89\x99\x3d\x1d\x00\x00\x00\x00\x49\x45\x4e\x44"
      "\xae\x42\x60\x82",
      70);  // 1 x 1, opaque red
  std::ofstream(dir() / "red dot.png", std::ios::binary) << png;
  auto textured = [](const std::string& uri) {
    json j = triangle("t.bin");
    j["images"] = json::array({{{"uri", uri}}});
    j["textures"] = json::array({{{"source", 0}}});
    j["materials"] =
        json::array({{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}}});
    j["meshes"][0]["primitives"][0]["material"] = 0;
    return j.dump(1);
  };
  auto m = load_model(write_gltf("image_beside", textured("red%20dot.png")));
  ASSERT_TRUE(m.ok()) << m.error().message();
  ASSERT_EQ(m->textures.size(), 1u);
  expect_error(write_gltf("image_missing", textured("red.png")), "$.images[0].uri",
               "names \"red.png\", which is not a file beside");
  expect_error(write_gltf("image_absolute", textured((dir() / "red dot.png").string())),
               "$.images[0].uri", "names the absolute path");
  expect_error(write_gltf("image_http", textured("https://example.com/red.png")), "$.images[0].uri",
               "a URI with the scheme https:");
}

// stb_image allocates what a PNG header asks before it reads a pixel: 20000 x 10 is refused from
// the header.
TEST(GltfDocument, ImagesLargerThanTheLoaderTakesAreRefusedFromTheirHeader) {
  std::string png("\x89PNG\r\n\x1a\n\0\0\0\x0dIHDR", 16);
  for (std::uint32_t v : {20000u, 10u})
    for (int k = 3; k >= 0; --k) png += static_cast<char>((v >> (8 * k)) & 0xff);
  png += std::string("\x08\x06\0\0\0", 5);  // 8-bit RGBA; the CRC and the data are never read
  std::string bin = triangle_bytes() + png;
  while (bin.size() % 4) bin += '\0';
  json j = triangle("");
  j["buffers"][0]["byteLength"] = bin.size();
  j["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", 36}, {"byteLength", png.size()}});
  j["images"] = json::array({{{"bufferView", 1}, {"mimeType", "image/png"}}});
  j["textures"] = json::array({{{"source", 0}}});
  j["materials"] =
      json::array({{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}}});
  j["meshes"][0]["primitives"][0]["material"] = 0;
  expect_error(write_glb("huge_png", glb_bytes(j.dump(), bin)), "$.images[0]",
               "is 20000 x 10 pixels; this loader takes textures up to 16384 on a side");
}

}  // namespace
}  // namespace bb::runtime
