// The whole pipeline on the default body: build_body -> GLB -> the Khronos validator and the
// runtime's loader; and `bodybuilder inspect` on the result.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "bb/exporter/build.h"
#include "bb/mesher/mesher.h"
#include "bb/modeler/body.h"
#include "bb/runtime/headless.h"
#include "bb/runtime/model.h"
#include "bb/runtime/portrait.h"

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
    // Every test of this file runs in its own process (CTest), several at once, and each reads
    // the file its own process built (a shared file is also overwritten by the other processes,
    // and by another checkout's tests on the same machine). Removed when the process exits.
    static std::string p = (dir / ("default." + std::to_string(::getpid()) + ".glb")).string();
    if (b) {
      std::ofstream(p, std::ios::binary).write(reinterpret_cast<const char*>(b->glb.data()), b->glb.size());
      std::atexit([] { std::filesystem::remove(p); });
    }
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
    // Written in vertex cache order (0.59-0.79 vertices shaded a triangle by a 32-entry FIFO; the
    // mesher's ring order gave 1.1-1.3), so the runtime's reorder has nothing left to gain.
    EXPECT_LT(l["vertex_cache"]["as_stored"].get<double>(), 0.85) << l.dump();
    EXPECT_NEAR(l["vertex_cache"]["as_drawn"].get<double>(), l["vertex_cache"]["as_stored"].get<double>(), 0.03) << l.dump();
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
  // Impostor part cards: the walk splits our body into pelvis, chest with head, and each limb's
  // segments (upper arm, forearm with hand, thigh, shin, foot), found from the skin and the clip.
  std::set<std::string> parts;
  for (const auto& p : m->body_parts()) parts.insert(m->nodes[m->palette[p.bone].node].name);
  const std::set<std::string> expected = {"HumanoidRoot", "vt10",     "l_shoulder", "l_elbow", "r_shoulder", "r_elbow",
                                          "l_hip",        "l_knee",   "l_ankle",    "r_hip",   "r_knee",     "r_ankle"};
  EXPECT_EQ(parts, expected);
}

// The walk's speed measured from its poses (BakedClip::ground_speed) comes within 10 % of the speed its
// name gives (measured: 1.26 against 1.20 m/s; our clip plants the ankle, and the toes roll about it).
TEST(Build, TheWalksMeasuredSpeedIsNearItsName) {
  auto m = runtime::load_model(built_glb());
  ASSERT_TRUE(m) << m.error().message();
  ASSERT_EQ(m->clips.size(), 1u);
  EXPECT_EQ(m->clips[0].name, "walk_1.20mps");
  EXPECT_NEAR(m->baked_clips()[0].ground_speed, 1.20f, 0.12f);
}

// Middle levels start from the previous level's decimated extremities: every extremity vertex of
// level l+1 is a vertex of level l (decimation only removes vertices, never moves them), and each
// level reports a measured distance to the skin that grows as the levels get coarser.
TEST(Build, LevelsDecimateTheirExtremitiesFromFullResolutionVertices) {
  auto b = exporter::build_body(modeler::default_body());
  ASSERT_TRUE(b) << b.error().message();
  const auto& lods = b->input.lods;
  ASSERT_GE(lods.size(), 4u);
  // The full-resolution level 0 (OpenVDB extremities) that every decimated level starts from,
  // directly or through the previous level or level 0's lightly decimated copy.
  mesher::MesherOptions mo;
  mo.error_samples = 0;
  mo.check_topology = false;
  auto full = mesher::build_lods(modeler::default_body(), mo);
  ASSERT_TRUE(full) << full.error().message();
  std::set<std::array<float, 3>> source;
  for (const auto& p : (*full)[0].mesh.positions) source.insert({p.x, p.y, p.z});
  for (size_t l = 0; l + 1 < lods.size(); ++l) {
    const auto& c = lods[l].mesh;
    ASSERT_EQ(c.part.size(), c.positions.size());
    size_t extremity = 0, found = 0;
    for (size_t i = 0; i < c.positions.size(); ++i) {
      if (c.part[i] == 0) continue;
      ++extremity;
      found += source.count({c.positions[i].x, c.positions[i].y, c.positions[i].z});
    }
    EXPECT_GT(extremity, 100u) << "level " << l;
    EXPECT_EQ(found, extremity) << "level " << l;
    if (l > 0) {
      EXPECT_LT(lods[l].report.triangles, lods[l - 1].report.triangles);
      EXPECT_LT(lods[l].report.extremity_triangles, lods[l - 1].report.extremity_triangles);
    }
  }
  for (const auto& l : lods) {
    EXPECT_GT(l.report.hausdorff_rel, 0.0);
    EXPECT_LT(l.report.hausdorff_rel, 0.05);
    EXPECT_GT(l.report.mean_rel, 0.0);
    EXPECT_LT(l.report.mean_rel, l.report.hausdorff_rel);
    EXPECT_TRUE(l.report.closed && l.report.manifold && !l.report.self_intersections);
  }
  EXPECT_LT(lods.front().report.hausdorff_rel, lods.back().report.hausdorff_rel);
  // Reproducible: the same body builds to the same bytes in one process (no timings in the file,
  // parallel parts reassembled in a fixed order). Across processes, two full-suite runs in the
  // thirty-first session read a file of the same size with other bytes, written by a concurrent
  // test process: not reproduced alone (40 runs under load, 12 CLI builds two at a time); see
  // docs/results.md.
  std::ifstream f(built_glb(), std::ios::binary);
  std::string again((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  ASSERT_EQ(again.size(), b->glb.size());
  EXPECT_TRUE(std::equal(again.begin(), again.end(), reinterpret_cast<const char*>(b->glb.data())));
}

// `render --lod K` draws one level (the picture of the proxies next to level 0); a level the file
// does not have is an error naming the file and the flag.
TEST(Build, RenderDrawsAChosenLevel) {
  auto png = (std::filesystem::temp_directory_path() / "bb_build_test" / "lod3.png").string();
  std::filesystem::remove(png);
  auto out = run(std::string(BB_BIN_DIR) + "/bodybuilder render " + built_glb() + " --lod 3 --size 64x128 -o " + png +
                 " --json");
  auto j = nlohmann::json::parse(out, nullptr, false);
  if (j.is_discarded() && out.find("EGL") != std::string::npos) GTEST_SKIP() << "no headless OpenGL: " << out;
  ASSERT_FALSE(j.is_discarded()) << out;
  EXPECT_GT(j["covered_pixels"].get<long>(), 500) << out;
  EXPECT_TRUE(std::filesystem::exists(png));
  out = run(std::string(BB_BIN_DIR) + "/bodybuilder render " + built_glb() + " --lod 9 -o " + png + " 2>&1; echo status=$?");
  EXPECT_NE(out.find(built_glb() + ": --lod 9: the model has 4 levels"), std::string::npos) << out;
  EXPECT_NE(out.find("status=1"), std::string::npos) << out;
}

// Our own LOD set through the runtime (a model outside ../shared/data): the impostor portrait
// agrees with the geometry portrait of the same instant (PSNR over covered pixels).
TEST(Build, ImpostorAndGeometryPortraitsOfOurModelAgree) {
  auto ctx = runtime::HeadlessContext::create();
  if (!ctx) GTEST_SKIP() << "no headless OpenGL: " << ctx.error().message();
  auto m = runtime::load_model(built_glb());
  ASSERT_TRUE(m) << m.error().message();
  for (float az : {0.0f, 120.0f}) {
    runtime::PortraitOptions o;
    o.width = o.height = 256;
    o.time = 0.4f;
    o.azimuth_deg = az;
    auto g = runtime::render_portrait(*m, o);
    o.mode = runtime::RenderMode::kImpostor;
    auto i = runtime::render_portrait(*m, o);
    ASSERT_TRUE(g && i);
    double se = 0;
    long n = 0;
    for (size_t k = 0; k < g->rgba.size(); k += 4) {
      if (g->rgba[k + 3] == 0 && i->rgba[k + 3] == 0) continue;
      ++n;
      for (int c = 0; c < 3; ++c) {
        double x = g->rgba[k + c] * (g->rgba[k + 3] / 255.0), y = i->rgba[k + c] * (i->rgba[k + 3] / 255.0);
        se += (x - y) * (x - y);
      }
    }
    ASSERT_GT(n, 3000);
    double psnr = se == 0 ? 99.0 : 10.0 * std::log10(255.0 * 255.0 * 3.0 * n / se);
    std::printf("azimuth %.0f: %ld covered pixels, PSNR %.2f dB\n", az, n, psnr);
    EXPECT_GT(psnr, 40.0);  // measured 49.7 and 99 (identical) dB
  }
}
