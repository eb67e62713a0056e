// Small file helpers for the CLI: every output is written to a temporary file beside the
// target and renamed into place, so nothing half-written is ever left behind.
#pragma once

#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <system_error>
#include <unistd.h>

#include "bb/result.h"

namespace bb::cli {

// A JSON document as text. File names and other strings that are not valid UTF-8 (a Linux file
// name may hold any bytes) have their bad bytes written as U+FFFD instead of stopping the program.
template <class Json>
std::string json_text(const Json& j, int indent = -1) {
  return j.dump(indent, ' ', false, Json::error_handler_t::replace);
}

// Whether `s` is valid UTF-8 (no overlong forms, surrogates or code points past U+10FFFF).
inline bool valid_utf8(std::string_view s) {
  std::size_t i = 0;
  while (i < s.size()) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    int n = c < 0x80 ? 0 : (c >> 5) == 0x6 ? 1 : (c >> 4) == 0xE ? 2 : (c >> 3) == 0x1E ? 3 : -1;
    if (n < 0) return false;
    if (n == 0) { ++i; continue; }
    if (i + n >= s.size()) return false;
    std::uint32_t cp = c & (0x3F >> n);
    for (int k = 1; k <= n; ++k) {
      const unsigned char d = static_cast<unsigned char>(s[i + k]);
      if ((d >> 6) != 0x2) return false;
      cp = (cp << 6) | (d & 0x3F);
    }
    static constexpr std::uint32_t kLeast[4] = {0, 0x80, 0x800, 0x10000};
    if (cp < kLeast[n] || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return false;
    i += n + 1;
  }
  return true;
}

// An error (named `path`) where `target` exists and is not a regular file: a folder, a device or a
// pipe, which a rename onto it would replace.
inline Status refuse_non_file(const std::string& path, const std::filesystem::path& target) {
  std::error_code ec;
  const std::filesystem::file_status st = std::filesystem::status(target, ec);
  if (!std::filesystem::exists(st) || std::filesystem::is_regular_file(st)) return Ok{};
  return Error{path, "", std::filesystem::is_directory(st) ? "cannot write: it is a folder" : "cannot write: it exists and is not a regular file"};
}

// Writes `bytes` to `path` through a temporary file beside it, renamed into place. The target
// must be a regular file or not exist: a folder, a device or a pipe is refused (a rename would
// replace it); a symbolic link is followed, so the file it names is what is replaced.
inline Status write_atomic(const std::string& path, std::string_view bytes) {
  namespace fs = std::filesystem;
  if (path.empty()) return Error{"(empty file name)", "", "cannot write: no file name given"};
  fs::path target(path);
  std::error_code ec;
  if (fs::is_symlink(fs::symlink_status(target, ec))) {
    fs::path to = fs::read_symlink(target, ec);
    if (!ec) target = to.is_absolute() ? to : target.parent_path() / to;
  }
  if (auto st = refuse_non_file(path, target); !st) return st;
  ec.clear();
  if (target.has_parent_path()) fs::create_directories(target.parent_path(), ec);
  if (ec) return Error{path, "", "cannot create directory: " + ec.message()};
  // pid and a count: jobs of one process writing at once never share a temporary file.
  static std::atomic<unsigned> serial{0};
  fs::path tmp = target;
  tmp += ".tmp" + std::to_string(::getpid()) + "." + std::to_string(serial++);
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
    const std::string why = ec.message();
    fs::remove(tmp, ec);
    return Error{path, "", "cannot move the finished file into place: " + why};
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
  // A folder made and removed again says whether the writes to come can happen (access() says yes to
  // root almost anywhere, /proc and /sys too).
  std::string probe = (p / ".bodybuilder-probe-XXXXXX").string();
  if (::mkdtemp(probe.data()) == nullptr) {
    const int e = errno;
    return Error{dir, "", "cannot be the output folder: no folder can be made in " + p.string() + " (" +
                                 std::generic_category().message(e) + ")"};
  }
  ::rmdir(probe.c_str());
  return Ok{};
}

// Checks, before any work, that the file `path` can be written: a name is given, it is not a
// folder or other non-regular file, and its folder can be written (check_output_dir).
inline Status check_output_file(const std::string& path) {
  namespace fs = std::filesystem;
  if (path.empty()) return Error{"(empty file name)", "", "cannot write: no file name given"};
  if (auto st = refuse_non_file(path, path); !st) return st;
  const fs::path parent = fs::path(path).parent_path();
  if (auto s = check_output_dir(parent.empty() ? "." : parent.string()); !s) return Error{path, "", s.error().reason};
  return Ok{};
}

// Encodes RGBA8 pixels (rows top to bottom) as PNG and writes them atomically.
Status write_png(const std::string& path, int width, int height, const unsigned char* rgba);

}  // namespace bb::cli
