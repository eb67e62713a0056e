// `bodybuilder render`: both modes write an RGBA PNG, --frames an animated one; bad input fails with a
// message.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "run_cli.h"

namespace {

namespace fs = std::filesystem;

bool have_cli() { return fs::exists(std::string(BB_BIN_DIR) + "/bodybuilder"); }

// tests/support/run_cli.h, with the output appended to *out and the exit status returned.
int run_command(const std::string& command, std::string* out) {
  const bb::test::CliRun r = bb::test::run_command(command);
  *out += r.text;
  return r.status;
}

int run(const std::string& args, std::string* out) { return run_command(std::string(BB_BIN_DIR) + "/bodybuilder " + args, out); }

TEST(RenderCommand, BothModesWritePngs) {
  if (!have_cli()) GTEST_SKIP() << "bodybuilder not built in " << BB_BIN_DIR;
  std::string model = std::string(BB_SHARED_DATA_DIR) + "/gltf/CesiumMan.glb";
  if (!fs::exists(model)) GTEST_SKIP() << "shared data absent: " << model;
  fs::path dir = fs::temp_directory_path() / "bb_runtime_render_test";
  fs::create_directories(dir);
  for (const char* mode : {"geometry", "impostor"}) {
    fs::path png = dir / (std::string(mode) + ".png");
    std::string out;
    int rc = run("render " + model + " -o " + png.string() + " --mode " + mode +
                     " --time 0.5 --azimuth 30 --elevation 5 --size 128x96 --json",
                 &out);
    if (rc == 3 && out.find("no headless OpenGL") != std::string::npos) GTEST_SKIP() << out;
    ASSERT_EQ(rc, 0) << out;
    EXPECT_NE(out.find("\"covered_pixels\""), std::string::npos) << out;
    std::ifstream f(png, std::ios::binary);
    char sig[8] = {};
    f.read(sig, 8);
    EXPECT_EQ(std::string(sig + 1, 3), "PNG");
    // IHDR: width 128, height 96, 8 bits, colour type 6 (RGBA).
    unsigned char ihdr[18];  // length, "IHDR", width, height, depth, colour type
    f.read(reinterpret_cast<char*>(ihdr), 18);
    EXPECT_EQ(ihdr[11] | ihdr[10] << 8, 128);
    EXPECT_EQ(ihdr[15] | ihdr[14] << 8, 96);
    EXPECT_EQ(ihdr[16], 8);
    EXPECT_EQ(ihdr[17], 6);
  }
  fs::remove_all(dir);
}

// --frames: an animated PNG whose frame k is the still of --time + k / fps seen from --azimuth +
// spin * k / fps (played back by UPNG.js, tools/, npm). Steps exact in binary: 0.25 s and 10 degrees.
TEST(RenderCommand, FramesAreTheStillsOfTheClipPlayedOn) {
  if (!have_cli()) GTEST_SKIP() << "bodybuilder not built in " << BB_BIN_DIR;
  std::string model = std::string(BB_SHARED_DATA_DIR) + "/gltf/CesiumMan.glb";
  if (!fs::exists(model)) GTEST_SKIP() << "shared data absent: " << model;
  const std::string tool = std::string(BB_SOURCE_DIR) + "/tools/apng_frames.js";
  if (!fs::exists(std::string(BB_SOURCE_DIR) + "/tools/node_modules/upng-js/package.json"))
    GTEST_SKIP() << "upng-js not installed (run scripts/setup.sh)";
  fs::path dir = fs::temp_directory_path() / "bb_runtime_render_frames_test";
  fs::create_directories(dir);
  auto decode = [&](const fs::path& png) {
    std::string out;
    EXPECT_EQ(run_command("node " + tool + " " + png.string(), &out), 0) << out;
    return nlohmann::json::parse(out, nullptr, false);
  };
  const std::string common = " --mode impostor --elevation 5 --size 128x96";
  std::string out;
  int rc = run("render " + model + " -o " + (dir / "anim.png").string() + common +
                   " --time 0.5 --azimuth 30 --frames 4 --fps 4 --spin 40 --json",
               &out);
  if (rc == 3 && out.find("no headless OpenGL") != std::string::npos) GTEST_SKIP() << out;
  ASSERT_EQ(rc, 0) << out;
  auto anim = decode(dir / "anim.png");
  ASSERT_FALSE(anim.is_discarded());
  EXPECT_TRUE(anim["animated"].get<bool>());
  EXPECT_EQ(anim["ctype"], 6);  // RGBA: the background stays transparent
  ASSERT_EQ(anim["frames"], 4);
  for (const auto& f : anim["frame"]) EXPECT_EQ(f["delay_ms"], 250);
  // Frame 0 is the still at the start; frame 2 the still 0.5 s later, turned by 20 degrees.
  for (const auto& [k, args] : {std::pair<int, const char*>{0, " --time 0.5 --azimuth 30"}, {2, " --time 1 --azimuth 50"}}) {
    out.clear();
    const fs::path still = dir / ("still" + std::to_string(k) + ".png");
    ASSERT_EQ(run("render " + model + " -o " + still.string() + common + args, &out), 0) << out;
    auto j = decode(still);
    ASSERT_FALSE(j.is_discarded());
    EXPECT_FALSE(j["animated"].get<bool>());
    EXPECT_EQ(j["frame"][0]["fnv1a"], anim["frame"][k]["fnv1a"]) << "frame " << k;
  }
  EXPECT_NE(anim["frame"][0]["fnv1a"], anim["frame"][1]["fnv1a"]);
  fs::remove_all(dir);
}

TEST(RenderCommand, BadInputIsAnError) {
  if (!have_cli()) GTEST_SKIP() << "bodybuilder not built in " << BB_BIN_DIR;
  std::string out;
  EXPECT_NE(run("render /nonexistent/model.glb -o /tmp/bb_never.png", &out), 0);
  EXPECT_NE(out.find("/nonexistent/model.glb: no such file"), std::string::npos) << out;
  out.clear();
  EXPECT_NE(run("render x.glb -o /tmp/bb_never.png --mode wireframe", &out), 0);
  EXPECT_NE(out.find("--mode"), std::string::npos) << out;
  out.clear();
  EXPECT_NE(run("render x.glb -o /tmp/bb_never.png --size 12", &out), 0);
  EXPECT_NE(run("render x.glb -o /tmp/bb_never.png --size 64x64px", &out), 0);
  // Numbers that are not finite, or out of range, are named before anything is read.
  for (const char* bad : {"--time nan", "--azimuth inf", "--elevation -nan", "--distance -1", "--distance inf"}) {
    out.clear();
    EXPECT_NE(run(std::string("render x.glb -o /tmp/bb_never.png ") + bad, &out), 0) << bad;
    const std::string flag(bad, std::string(bad).find(' '));
    EXPECT_NE(out.find(flag + ": expected a "), std::string::npos) << bad << ": " << out;
  }
  EXPECT_FALSE(fs::exists("/tmp/bb_never.png"));
}

}  // namespace
