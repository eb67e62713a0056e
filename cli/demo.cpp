// bodybuilder demo [-o DIR]: the README's main job. It grows with the project: today it
// describes the built-in default body and writes a ray-cast picture of its skin.
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>

#include <nlohmann/json.hpp>

#include "bb/modeler/body.h"
#include "bb/modeler/implicit_surface.h"
#include "commands.h"
#include "io.h"

namespace bb::cli {

int run_inspect_body(const std::string& path, bool as_json, const std::string& preview_path,
                     const std::string& posture_name);  // inspect.cpp

namespace {

void add_demo_command(CLI::App& app, int* status) {
  auto* cmd = app.add_subcommand("demo", "The main job: describe and picture the built-in default body");
  auto dir = std::make_shared<std::string>("out/demo");
  cmd->add_option("-o,--output", *dir, "Output folder")->capture_default_str();
  cmd->callback([=] {
    std::string png = (std::filesystem::path(*dir) / "default_body.png").string();
    *status = run_inspect_body("default", false, png, "bind");
    if (*status == 0) std::printf("wrote %s (front and side views of the skin in the bind posture)\n", png.c_str());
  });
}

const Registrar registrar(10, add_demo_command);

}  // namespace
}  // namespace bb::cli
