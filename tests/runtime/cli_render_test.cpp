// `bodybuilder render`: both modes write an RGBA PNG; bad input fails with a message.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

namespace {

namespace fs = std::filesystem;

bool have_cli() { return fs::exists(std::string(BB_BIN_DIR) + "/bodybuilder"); }

int run(const std::string& args, std::string* out) {
  std::string cmd = std::string(BB_BIN_DIR) + "/bodybuilder " + args + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return -1;
  char buf[4096];
  std::size_t n;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0) out->append(buf, n);
  int rc = pclose(p);
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

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
    EXPECT_NE(out.find(flag + ": expected a finite number"), std::string::npos) << bad << ": " << out;
  }
  EXPECT_FALSE(fs::exists("/tmp/bb_never.png"));
}

}  // namespace
