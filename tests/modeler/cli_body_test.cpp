// The bodybuilder executable on body files: the JSON report and the bad-input errors.
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "run_cli.h"

namespace {

using CmdResult = bb::test::CliRun;
CmdResult run(const std::string& args) {
  auto r = bb::test::run_cli(args);
  return r;
}

std::string temp_file(const std::string& name, const std::string& text) {
  auto dir = std::filesystem::temp_directory_path() / "bb_cli_body_test";
  std::filesystem::create_directories(dir);
  auto p = dir / name;
  std::ofstream(p) << text;
  return p.string();
}

}  // namespace

TEST(CliInspectBody, JsonReportOfTheDefaultBody) {
  CmdResult r = run("inspect " + std::string(BB_DATA_DIR) + "/bodies/default.json --json");
  ASSERT_EQ(r.status, 0) << r.text;
  auto j = nlohmann::json::parse(r.text);
  EXPECT_EQ(j["kind"], "body");
  EXPECT_EQ(j["name"], "default");
  EXPECT_EQ(j["dofs"], 74);
  EXPECT_EQ(j["dofs_with_limits"], 74);
  EXPECT_GT(j["joints"].get<int>(), 40);
  EXPECT_GT(j["primitives"]["ellipsoid"].get<int>(), 0);
  EXPECT_GT(j["primitives"]["metaball"].get<int>(), 0);
  EXPECT_NEAR(j["height_m"].get<double>(), 1.75, 0.03);
  ASSERT_EQ(j["ta"].size(), 3u);
  EXPECT_NEAR(j["ta"][1].get<double>(), 1.0, 0.1);
}

TEST(CliInspectBody, PreviewIsAPng) {
  auto out = (std::filesystem::temp_directory_path() / "bb_cli_body_test" / "preview.png").string();
  std::filesystem::remove(out);
  CmdResult r = run("inspect default --preview " + out);
  ASSERT_EQ(r.status, 0) << r.text;
  std::ifstream in(out, std::ios::binary);
  char sig[8] = {};
  in.read(sig, 8);
  EXPECT_EQ(std::string(sig + 1, 3), "PNG");
}

TEST(CliInspectBody, BadInputGivesFilePlaceReasonAndNonZeroExit) {
  struct Case {
    std::string file, expect;
  } cases[] = {
      {temp_file("syntax.json", "{\"name\": \"x\",\n  \"primitives\": [ }"), "syntax.json: line 2"},
      {temp_file("joint.json", R"({"name":"x","primitives":[{"type":"metaball","joint":"elbow",
        "center":[0,0,0],"radii":[1,1,1]}]})"),
       "joint.json: $.primitives[0].joint: unknown joint \"elbow\""},
      {temp_file("radius.json", R"({"name":"x","primitives":[{"type":"metaball","joint":"l_elbow",
        "center":[0,0,0],"radii":[1,-1,1]}]})"),
       "radius.json: $.primitives[0].radii[1]: radius must be positive"},
      {temp_file("limits.json", R"({"name":"x","skeleton":"limits_skel.json","primitives":[]})"),
       "limits_skel.json: $.joints[0].dofs[0]: limit min > max"},
      {temp_file("cycle.json", R"({"name":"x","skeleton":"cycle_skel.json","primitives":[]})"),
       "cycle_skel.json: $.joints[1].parent: joint cycle"},
      {"/nonexistent/body.json", "/nonexistent/body.json: cannot open file"},
  };
  temp_file("limits_skel.json", R"({"joints":[{"name":"a","parent":null,"offset":[0,0,0],
    "dofs":[{"name":"x","type":"rotation","axis":[1,0,0],"min_deg":30,"max_deg":10}]}]})");
  temp_file("cycle_skel.json", R"({"joints":[{"name":"a","parent":null,"offset":[0,0,0]},
    {"name":"b","parent":"c","offset":[0,0,0]},{"name":"c","parent":"b","offset":[0,0,0]}]})");
  for (const auto& c : cases) {
    CmdResult r = run("inspect " + c.file);
    EXPECT_NE(r.status, 0) << c.file;
    EXPECT_NE(r.text.find(c.expect), std::string::npos) << "expected '" << c.expect << "' in: " << r.text;
  }
}

TEST(CliInspectBody, WrongFlagIsAnError) {
  CmdResult r = run("inspect --no-such-flag");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.text.find("--no-such-flag"), std::string::npos) << r.text;
  EXPECT_NE(r.text.find("bodybuilder inspect:"), std::string::npos) << r.text;  // the command named
  // An unknown posture is an error even without --preview, and the known ones are listed.
  CmdResult p = run("inspect default --posture sitting");
  EXPECT_NE(p.status, 0);
  EXPECT_NE(p.text.find("unknown posture \"sitting\" (known: bind, max_extent, neutral)"), std::string::npos) << p.text;
  CmdResult c = run("no-such-command");
  EXPECT_NE(c.status, 0);
  EXPECT_NE(c.text.find("unknown command \"no-such-command\""), std::string::npos) << c.text;
  EXPECT_NE(c.text.find("flow"), std::string::npos) << c.text;  // the commands listed
  CmdResult v = run("--version");
  EXPECT_EQ(v.status, 0);
  EXPECT_NE(v.text.find("bodybuilder"), std::string::npos);
}
