// The bodybuilder command line: one file per subcommand. Each file registers itself with a
// static Registrar, so adding a command touches no other file.
#pragma once

#include <functional>
#include <vector>

#include <CLI/CLI.hpp>

namespace bb::cli {

// Adds a subcommand to `app`; when it runs, it stores its exit status in `*status`.
using AddCommand = void (*)(CLI::App& app, int* status);

struct CommandEntry {
  int order;  // position in --help
  AddCommand add;
};

inline std::vector<CommandEntry>& command_registry() {
  static std::vector<CommandEntry> r;
  return r;
}

struct Registrar {
  Registrar(int order, AddCommand add) { command_registry().push_back({order, add}); }
};

}  // namespace bb::cli
