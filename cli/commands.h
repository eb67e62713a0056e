// The bodybuilder command line: one file per subcommand. Each file registers itself with a
// static Registrar, so adding a command touches no other file.
#pragma once

#include <algorithm>
#include <functional>
#include <iostream>
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

// Adds every registered command to `app` (in their --help order), parses the command line and
// returns the exit status: the command's, or CLI11's for a parse error (never 0 on an error).
inline int run_command_line(CLI::App& app, int argc, char** argv) {
  app.require_subcommand(1);
  int status = 0;
  auto entries = command_registry();
  std::sort(entries.begin(), entries.end(), [](auto& a, auto& b) { return a.order < b.order; });
  for (const auto& e : entries) e.add(app, &status);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e, std::cout, std::cerr);  // --help
    // Like the commands' own errors: the program and the command first, then the reason.
    std::string where = "bodybuilder";
    for (const CLI::App* sub : app.get_subcommands()) where += " " + sub->get_name();
    std::string reason = e.what();
    if (app.get_subcommands().empty() && argc > 1 && argv[1][0] != '-') {
      reason = std::string("unknown command \"") + argv[1] + "\" (commands:";
      for (const CLI::App* sub : app.get_subcommands({})) reason += " " + sub->get_name();
      reason += ")";
    }
    std::cerr << where << ": " << reason << "\nRun with --help for more information.\n";
    return e.get_exit_code();
  }
  return status;
}

}  // namespace bb::cli
