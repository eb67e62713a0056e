// `bodybuilder mesh`: one OBJ per level, report.json and the LOD-chain picture; errors name the file.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace {

std::string run(const std::string& args, int* status) {
  std::string cmd = std::string(BB_BIN_DIR) + "/bodybuilder " + args + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  std::string out;
  char buf[4096];
  while (size_t n = fread(buf, 1, sizeof buf, p)) out.append(buf, n);
  *status = pclose(p);
  return out;
}

TEST(CliMesh, WritesOneObjPerLevelReportAndPicture) {
  namespace fs = std::filesystem;
  if (!fs::exists(std::string(BB_BIN_DIR) + "/bodybuilder")) GTEST_SKIP() << "bodybuilder not built";
  fs::path dir = fs::temp_directory_path() / "bb_cli_mesh_test";
  fs::remove_all(dir);
  int status = 0;
  std::string out = run("mesh -o " + dir.string() + " --json --no-errors", &status);
  ASSERT_EQ(status, 0) << out;
  EXPECT_NE(out.find("\"kind\":\"lod_chain\""), std::string::npos) << out;
  for (int l = 0; l < 4; ++l) {
    fs::path obj = dir / ("lod" + std::to_string(l) + ".obj");
    ASSERT_TRUE(fs::exists(obj)) << obj;
    std::ifstream in(obj);
    std::string line;
    size_t faces = 0;
    while (std::getline(in, line)) faces += line.rfind("f ", 0) == 0;
    EXPECT_GT(faces, 400u);
  }
  EXPECT_TRUE(fs::exists(dir / "report.json"));
  EXPECT_TRUE(fs::exists(dir / "lods.png"));
  fs::remove_all(dir);
}

// The same body gives the same files in every process. CGAL's corefinement numbered the union's
// new vertices by where its boxes lay in memory, so level 1 of the built-in body came out in three
// vertex orders over four runs until the union was put in a canonical order (MeshUnion tests).
TEST(CliMesh, EveryProcessWritesTheSameFiles) {
  namespace fs = std::filesystem;
  if (!fs::exists(std::string(BB_BIN_DIR) + "/bodybuilder")) GTEST_SKIP() << "bodybuilder not built";
  auto read = [](const fs::path& f) {
    std::ifstream in(f, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  };
  std::vector<std::string> first;
  for (int run_k = 0; run_k < 4; ++run_k) {
    const fs::path dir = fs::temp_directory_path() / ("bb_cli_mesh_same_" + std::to_string(run_k));
    fs::remove_all(dir);
    int status = 0;
    const std::string out = run("mesh -o " + dir.string() + " --no-errors", &status);
    ASSERT_EQ(status, 0) << out;
    for (int level = 0; level < 4; ++level) {
      const std::string bytes = read(dir / ("lod" + std::to_string(level) + ".obj"));
      ASSERT_FALSE(bytes.empty()) << dir << " level " << level;
      if (run_k == 0) first.push_back(bytes);
      else EXPECT_TRUE(bytes == first[static_cast<size_t>(level)]) << "run " << run_k << ", level " << level;
    }
    if (run_k > 0) fs::remove_all(dir);
  }
  fs::remove_all(fs::temp_directory_path() / "bb_cli_mesh_same_0");
}

TEST(CliMesh, MissingBodyFileIsNamedInTheError) {
  if (!std::filesystem::exists(std::string(BB_BIN_DIR) + "/bodybuilder")) GTEST_SKIP() << "bodybuilder not built";
  int status = 0;
  std::string out = run("mesh /nonexistent/body.json -o /tmp/bb_never", &status);
  EXPECT_NE(status, 0);
  EXPECT_NE(out.find("/nonexistent/body.json"), std::string::npos) << out;
  out = run("mesh --seed -1 -o /tmp/bb_never", &status);
  EXPECT_NE(status, 0);
  EXPECT_NE(out.find("--seed: expected a whole number >= 0"), std::string::npos) << out;
  EXPECT_FALSE(std::filesystem::exists("/tmp/bb_never"));
}

}  // namespace
