// The bodybuilder command line: one file per subcommand. Each file registers itself with a
// static Registrar, so adding a command touches no other file.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cerrno>
#include <cstdlib>
#include <functional>
#include <string>
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

// A number option's check: finite and within [lo, hi] (CLI::Range lets NaN through, and "inf" or
// "nan" would reach the camera or the clip time). Text that is not a number is left to the
// option's conversion, whose error names it.
inline CLI::Validator finite_number(double lo = -HUGE_VAL, double hi = HUGE_VAL) {
  return CLI::Validator(
      [lo, hi](std::string& text) -> std::string {
        char* end = nullptr;
        const double x = std::strtod(text.c_str(), &end);
        if (end == text.c_str() || *end != '\0') return {};
        if (std::isfinite(x) && x >= lo && x <= hi) return {};
        std::string want = "a finite number";
        auto num = [](double v) {
          std::string t = std::to_string(v);
          t.erase(t.find_last_not_of('0') + 1);
          if (!t.empty() && t.back() == '.') t.pop_back();
          return t;
        };
        if (std::isfinite(lo) && std::isfinite(hi)) want = "a number from " + num(lo) + " to " + num(hi);
        else if (std::isfinite(lo)) want = "a finite number >= " + num(lo);
        else if (std::isfinite(hi)) want = "a finite number <= " + num(hi);
        return "expected " + want + " (got \"" + text + "\")";
      },
      "NUMBER");
}

// An unsigned 64-bit option's check: digits only (CLI11 would wrap "-5" into 2^64 - 5) and no
// more than 2^64 - 1 (CLI11 would clamp a larger one without a word).
inline CLI::Validator whole_number() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        if (!text.empty() && text.find_first_not_of("0123456789") == std::string::npos) {
          errno = 0;
          std::strtoull(text.c_str(), nullptr, 10);
          if (errno != ERANGE) return {};
          return "expected a whole number from 0 to 18446744073709551615 (got \"" + text + "\")";
        }
        return "expected a whole number >= 0 (got \"" + text + "\")";
      },
      "N");
}

// An integer option's check: an optional sign and digits, within [lo, hi] (CLI::Range says "not in
// range" of text that is no number, and NonNegativeNumber names a 300-digit bound).
inline CLI::Validator whole_number(long long lo, long long hi) {
  return CLI::Validator(
      [lo, hi](std::string& text) -> std::string {
        const std::string want = "expected a whole number from " + std::to_string(lo) + " to " + std::to_string(hi);
        const std::size_t digits = text.find_first_not_of("+-") == 1 ? 1 : 0;
        if (text.size() <= digits || text.find_first_not_of("0123456789", digits) != std::string::npos)
          return want + " (got \"" + text + "\", not a whole number)";
        errno = 0;
        const long long x = std::strtoll(text.c_str(), nullptr, 10);
        if (errno == ERANGE || x < lo || x > hi) return want + " (got \"" + text + "\")";
        return {};
      },
      "N");
}

// "WxH" with both in [lo, hi] and nothing after them, into *w and *h.
inline bool parse_size(const std::string& text, int lo, int hi, int* w, int* h) {
  // Digits, one x, digits: sscanf alone would take " 320x240" and "+320x+240".
  const std::size_t x = text.find('x');
  if (x == 0 || x == std::string::npos || x + 1 == text.size() || text.find_first_not_of("0123456789x") != std::string::npos ||
      text.find('x', x + 1) != std::string::npos)
    return false;
  int end = 0;
  return std::sscanf(text.c_str(), "%dx%d%n", w, h, &end) == 2 && end == static_cast<int>(text.size()) && *w >= lo &&
         *h >= lo && *w <= hi && *h <= hi;
}

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
