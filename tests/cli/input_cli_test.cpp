// The command line against input a user gets wrong: file names that are not UTF-8, numbers out of
// what their type holds, outputs that are not files, and files read whatever the case of their
// extension. Each is an error naming the option or file and the reason, before any work.
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "run_cli.h"

namespace fs = std::filesystem;
using Out = bb::test::CliRun;

namespace {

Out run(const std::string& args) { return bb::test::run_cli(args); }

fs::path fresh_dir(const char* name) {
  fs::path d = fs::temp_directory_path() / "bb_cli_input_test" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

}  // namespace

// A file name that is not UTF-8 stopped the program in nlohmann's dump() (exit 134) when it went
// into --json output; now it is written with U+FFFD where the bad byte was.
TEST(CliInput, FileNamesThatAreNotUtf8) {
  const fs::path d = fresh_dir("utf8");
  std::ofstream(d / "bad\xFF.json") << "{\"name\": ";
  Out o = run("inspect --json '" + (d / "bad\xFF.json").string() + "'");
  EXPECT_EQ(o.status, 1) << o.text;  // the body file's own error, not an abort
  EXPECT_NE(o.text.find("bad\xFF.json"), std::string::npos) << o.text;
  const std::string model = std::string(BB_SHARED_DATA_DIR) + "/gltf/RiggedSimple.gltf";
  if (!fs::exists(model)) GTEST_SKIP() << "../shared/data/gltf is absent: the render half skipped";
  Out r = run("render " + model + " --size 64x64 --json -o '" + (d / "pic\xFF.png").string() + "' 2>/dev/null");
  ASSERT_EQ(r.status, 0) << r.text;
  const auto j = nlohmann::json::parse(r.text);
  EXPECT_NE(j.dump().find("pic\xEF\xBF\xBD.png"), std::string::npos) << r.text;
  EXPECT_TRUE(fs::exists(d / "pic\xFF.png"));  // the file itself keeps its name
}

TEST(CliInput, NumbersAreCheckedAsTheirTypeHoldsThem) {
  struct Case {
    std::string args, says;
  };
  const Case cases[] = {
      {"render x.glb -o x.png --time 1e40", "--time: expected a number from -100000 to 100000 (got \"1e40\")"},
      {"render x.glb -o x.png --distance 1e38", "--distance: expected a number from 0 to 1000000"},
      {"render x.glb -o x.png --azimuth 1e39", "--azimuth: expected a number from -36000 to 36000"},
      {"render x.glb -o x.png --lod -1", "--lod: expected a whole number from 0 to 1000 (got \"-1\")"},
      {"flow --humans x", "--humans: expected a whole number from 1 to 100000 (got \"x\", not a whole number)"},
      {"flow --frames 1.5", "--frames: expected a whole number from 1 to 100000 (got \"1.5\", not a whole number)"},
      {"flow --humans 99999999999999999999", "--humans: expected a whole number from 1 to 100000"},
      {"flow --posture ''", "--posture: expected"},
      {"flow --view ' 8'", "--view: expected"},
      {"flow --size ' 320x240'", "--size: expected WxH"},
      {"flow --size +320x+240", "--size: expected WxH"},
      {"flow --window-sizes 64,32,", "--window-sizes: expected"},
      {"build --seed 99999999999999999999999", "--seed: expected a whole number from 0 to 18446744073709551615"},
  };
  for (const Case& c : cases) {
    Out o = run(c.args);
    EXPECT_NE(o.status, 0) << c.args;
    EXPECT_NE(o.text.find(c.says), std::string::npos) << c.args << ": " << o.text;
  }
}

// An output that is a folder (or no name at all) is named before the model is even read; the
// rename used to replace a device or fail with "Success".
TEST(CliInput, OutputsThatAreNoFilesAreRefusedFirst) {
  const fs::path d = fresh_dir("outputs");
  fs::create_directories(d / "taken");
  Out folder = run("render /nonexistent.glb -o " + (d / "taken").string());
  EXPECT_EQ(folder.status, 1);
  EXPECT_NE(folder.text.find((d / "taken").string() + ": cannot write: it is a folder"), std::string::npos) << folder.text;
  Out empty = run("render /nonexistent.glb -o ''");
  EXPECT_EQ(empty.status, 1);
  EXPECT_NE(empty.text.find("no file name given"), std::string::npos) << empty.text;
  Out preview = run("inspect default --preview " + (d / "taken").string());
  EXPECT_EQ(preview.status, 1);
  EXPECT_NE(preview.text.find("--preview: " + (d / "taken").string() + ": cannot write: it is a folder"), std::string::npos)
      << preview.text;
}

TEST(CliInput, InspectNamesFoldersAndTakesAnyCase) {
  const fs::path d = fresh_dir("inspect");
  fs::create_directories(d / "folder.glb");
  Out folder = run("inspect " + (d / "folder.glb").string());
  EXPECT_EQ(folder.status, 1);
  EXPECT_NE(folder.text.find("folder.glb: is a folder, not a file"), std::string::npos) << folder.text;
  Out empty = run("inspect ''");
  EXPECT_EQ(empty.status, 1);
  EXPECT_NE(empty.text.find("no file given"), std::string::npos) << empty.text;
  const std::string model = std::string(BB_SHARED_DATA_DIR) + "/gltf/Fox.glb";
  if (!fs::exists(model)) GTEST_SKIP() << "../shared/data/gltf is absent: the upper-case half skipped";
  fs::copy_file(model, d / "FOX.GLB");
  Out upper = run("inspect --json " + (d / "FOX.GLB").string());
  ASSERT_EQ(upper.status, 0) << upper.text;
  EXPECT_EQ(nlohmann::json::parse(upper.text)["kind"], "gltf");
}
