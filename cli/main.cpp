// bodybuilder: build LOD glTF files of virtual humans, inspect them, render them, and run the
// paper's human flow test bed. See README.md.
#include <algorithm>
#include <iostream>

#include "commands.h"

#ifndef BB_VERSION
#define BB_VERSION "0.0.0"
#endif

int main(int argc, char** argv) {
  CLI::App app{"bodybuilder " BB_VERSION
               ": animated impostors for numerous virtual humans (Aubel, Boulic, Thalmann)",
               "bodybuilder"};
  app.set_version_flag("--version", "bodybuilder " BB_VERSION);
  app.require_subcommand(1);
  int status = 0;
  auto entries = bb::cli::command_registry();
  std::sort(entries.begin(), entries.end(), [](auto& a, auto& b) { return a.order < b.order; });
  for (const auto& e : entries) e.add(app, &status);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    int rc = app.exit(e, std::cout, std::cerr);
    return e.get_exit_code() == 0 ? 0 : (rc == 0 ? 2 : rc);
  }
  return status;
}
