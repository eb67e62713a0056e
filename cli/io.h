// Small file helpers for the CLI: every output is written to a temporary file beside the
// target and renamed into place, so nothing half-written is ever left behind.
#pragma once

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <unistd.h>

#include "bb/result.h"

namespace bb::cli {

inline Status write_atomic(const std::string& path, std::string_view bytes) {
  namespace fs = std::filesystem;
  fs::path target(path);
  std::error_code ec;
  if (target.has_parent_path()) fs::create_directories(target.parent_path(), ec);
  if (ec) return Error{path, "", "cannot create directory: " + ec.message()};
  fs::path tmp = target;
  tmp += ".tmp" + std::to_string(::getpid());
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) return Error{path, "", "cannot open for writing"};
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.flush();
    if (!out) {
      out.close();
      fs::remove(tmp, ec);
      return Error{path, "", "write failed (disk full?)"};
    }
  }
  fs::rename(tmp, target, ec);
  if (ec) {
    fs::remove(tmp, ec);
    return Error{path, "", "cannot move the finished file into place: " + ec.message()};
  }
  return Ok{};
}

// Checks, without creating anything, that the output folder `dir` can be written before a
// command spends time on work it could not save: `dir` must be a writable folder, or the nearest
// of its parents that exists must be. The error names the folder and why.
inline Status check_output_dir(const std::string& dir) {
  namespace fs = std::filesystem;
  if (dir.empty()) return Ok{};
  std::error_code ec;
  fs::path p = fs::absolute(dir, ec);
  if (ec) return Error{dir, "", "cannot use as the output folder: " + ec.message()};
  while (!fs::exists(p, ec) && p.has_parent_path() && p.parent_path() != p) p = p.parent_path();
  if (!fs::is_directory(p, ec))
    return Error{dir, "", "cannot be the output folder: " + p.string() + " is a file, not a folder"};
  if (::access(p.c_str(), W_OK | X_OK) != 0) return Error{dir, "", "cannot be the output folder: " + p.string() + " is not writable"};
  return Ok{};
}

// Encodes RGBA8 pixels (rows top to bottom) as PNG and writes them atomically.
Status write_png(const std::string& path, int width, int height, const unsigned char* rgba);

}  // namespace bb::cli
