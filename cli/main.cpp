// bodybuilder: build LOD glTF files of virtual humans, inspect them, render them, and run the
// paper's human flow test bed. See README.md.
#include "commands.h"

#ifndef BB_VERSION
#define BB_VERSION "0.0.0"
#endif

int main(int argc, char** argv) {
  CLI::App app{"bodybuilder " BB_VERSION
               ": animated impostors for numerous virtual humans (Aubel, Boulic, Thalmann)",
               "bodybuilder"};
  app.set_version_flag("--version", "bodybuilder " BB_VERSION);
  return bb::cli::run_command_line(app, argc, argv);
}
