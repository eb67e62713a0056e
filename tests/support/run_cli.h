// Tests: runs the bodybuilder executable as a user would (or another command), capturing stdout and
// stderr together.
#pragma once

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace bb::test {

struct CliRun {
  int status = -1;   // exit status, -1 when it did not exit normally
  std::string text;  // stdout and stderr
};

// Runs a shell command line, stdout and stderr together.
inline CliRun run_command(const std::string& command) {
  std::string cmd = command + " 2>&1";
  CliRun r;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf;
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.text.append(buf.data(), n);
  int st = pclose(p);
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

inline CliRun run_cli(const std::string& args) { return run_command(std::string(BB_BIN_DIR) + "/bodybuilder " + args); }

}  // namespace bb::test
