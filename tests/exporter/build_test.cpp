// The whole pipeline on the default body: build_body -> GLB -> the Khronos validator and the
// runtime's loader; and `bodybuilder inspect` on the result.
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "bb/exporter/build.h"
#include "bb/runtime/model.h"

using namespace bb;

namespace {

std::string run(const std::string& cmd) {
  FILE* p = popen((cmd + " 2>&1").c_str(), "r");
  std::string out;
  std::array<char, 4096> buf;
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) out.append(buf.data(), n);
  pclose(p);
  return out;
}

const std::string& built_glb() {
  static std::string path = [] {
    auto b = exporter::build_body(modeler::default_body());
    EXPECT_TRUE(b) << b.error().message();
    auto dir = std::filesystem::temp_directory_path() / "bb_build_test";
    std::filesystem::create_directories(dir);
    std::string p = (dir / "default.glb").string();
    if (b) std::ofstream(p, std::ios::binary).write(reinterpret_cast<const char*>(b->glb.data()), b->glb.size());
    return p;
  }();
  return path;
}

}  // namespace

TEST(Build, DefaultBodyPassesTheKhronosValidator) {
  if (!std::filesystem::exists(std::string(BB_SOURCE_DIR) + "/tools/node_modules/gltf-validator/package.json"))
    GTEST_SKIP() << "gltf-validator not installed (run scripts/setup.sh)";
  auto out = run("node " + std::string(BB_SOURCE_DIR) + "/tools/validate.js " + built_glb());
  auto j = nlohmann::json::parse(out, nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << out;
  EXPECT_EQ(j["issues"]["numErrors"], 0) << out;
  EXPECT_EQ(j["issues"]["numWarnings"], 0) << out;
}

TEST(Build, InspectShowsFallingClosedManifoldLevelsAndNormalizedSkin) {
  auto out = run(std::string(BB_BIN_DIR) + "/bodybuilder inspect " + built_glb() + " --json");
  auto j = nlohmann::json::parse(out, nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << out;
  EXPECT_EQ(j["kind"], "gltf");
  EXPECT_EQ(j["joints"], 49);
  ASSERT_GE(j["lods"].size(), 4u);
  size_t prev = SIZE_MAX;
  for (const auto& l : j["lods"]) {
    size_t t = l["triangles"].get<size_t>();
    EXPECT_LT(t, prev);
    prev = t;
    EXPECT_TRUE(l["closed"].get<bool>()) << l.dump();
    EXPECT_TRUE(l["manifold"].get<bool>()) << l.dump();
    EXPECT_EQ(l["self_intersections"], 0) << l.dump();
    EXPECT_LT(l["hausdorff_rel"].get<double>(), 0.05) << l.dump();
  }
  EXPECT_TRUE(j["lods"].back()["textured"].get<bool>());  // the proxies
  EXPECT_LE(j["skin"]["max_influences"].get<int>(), 4);
  EXPECT_TRUE(j["skin"]["weights_normalized"].get<bool>());
}

TEST(Build, RuntimeLoadsTheLodSet) {
  auto m = runtime::load_model(built_glb());
  ASSERT_TRUE(m) << m.error().message();
  EXPECT_GE(m->lods.size(), 4u);
  EXPECT_EQ(m->textures.size(), 1u);
  EXPECT_GT(m->radius, 0.8f);
  EXPECT_LT(m->radius, 2.0f);
}
