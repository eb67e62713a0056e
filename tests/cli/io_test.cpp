// The CLI's file helpers (cli/io.h): UTF-8 checks, JSON text of any file name, and the atomic
// write's refusals.
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "io.h"

namespace fs = std::filesystem;
using bb::cli::check_output_file;
using bb::cli::json_text;
using bb::cli::valid_utf8;
using bb::cli::write_atomic;

namespace {

fs::path fresh_dir(const char* name) {
  fs::path d = fs::temp_directory_path() / "bb_cli_io_test" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::string read(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

}  // namespace

TEST(Io, Utf8IsCheckedByteByByte) {
  EXPECT_TRUE(valid_utf8(""));
  EXPECT_TRUE(valid_utf8("walk_01"));
  EXPECT_TRUE(valid_utf8("pas de caf\xC3\xA9"));          // é
  EXPECT_TRUE(valid_utf8("\xE2\x82\xAC 5"));              // €
  EXPECT_TRUE(valid_utf8("\xF0\x9F\x9A\xB6"));            // U+1F6B6, four bytes
  EXPECT_FALSE(valid_utf8("clip\xFF"));                   // no such lead byte
  EXPECT_FALSE(valid_utf8("caf\xC3"));                    // cut short at the end
  EXPECT_FALSE(valid_utf8("caf\xC3" "e"));                // a lead byte without its continuation
  EXPECT_FALSE(valid_utf8("\xC0\x80"));                   // overlong NUL
  EXPECT_FALSE(valid_utf8("\xED\xA0\x80"));               // a surrogate
  EXPECT_FALSE(valid_utf8("\xF4\x90\x80\x80"));           // past U+10FFFF
  EXPECT_FALSE(valid_utf8("\x80"));                       // a continuation byte alone
}

// A Linux file name may hold any bytes; nlohmann's dump() stops the program on one that is not
// UTF-8 (it did for `inspect --json` of such a file). json_text writes U+FFFD instead.
TEST(Io, JsonTextOfAnyFileName) {
  nlohmann::ordered_json j;
  j["file"] = std::string("bad\xFF.json");
  EXPECT_THROW((void)j.dump(), nlohmann::json::type_error);
  EXPECT_EQ(json_text(j), "{\"file\":\"bad\xEF\xBF\xBD.json\"}");
  EXPECT_EQ(nlohmann::json::parse(json_text(j, 2))["file"], "bad\xEF\xBF\xBD.json");
}

TEST(Io, WriteAtomicRefusesWhatIsNoFileAndFollowsLinks) {
  const fs::path d = fresh_dir("atomic");
  // A folder in the way: refused by name, nothing left beside it.
  fs::create_directories(d / "taken");
  auto folder = write_atomic((d / "taken").string(), "x");
  ASSERT_FALSE(folder.ok());
  EXPECT_EQ(folder.error().message(), (d / "taken").string() + ": cannot write: it is a folder");
  auto empty = write_atomic("", "x");
  ASSERT_FALSE(empty.ok());
  EXPECT_NE(empty.error().message().find("no file name"), std::string::npos);
  // A symbolic link: the file it names is replaced, the link stays a link.
  std::ofstream(d / "target.png") << "old";
  fs::create_symlink("target.png", d / "link.png");
  ASSERT_TRUE(write_atomic((d / "link.png").string(), "new").ok());
  EXPECT_TRUE(fs::is_symlink(d / "link.png"));
  EXPECT_EQ(read(d / "target.png"), "new");
  // A new file in a new folder.
  ASSERT_TRUE(write_atomic((d / "sub" / "a.txt").string(), "abc").ok());
  EXPECT_EQ(read(d / "sub" / "a.txt"), "abc");
  for (const auto& f : fs::recursive_directory_iterator(d))
    EXPECT_EQ(f.path().filename().string().find(".tmp"), std::string::npos) << f.path();  // nothing half-written
}

TEST(Io, OutputFilesAreCheckedBeforeAnyWork) {
  const fs::path d = fresh_dir("check");
  EXPECT_TRUE(check_output_file((d / "new.png").string()).ok());
  EXPECT_TRUE(check_output_file((d / "not_yet" / "new.png").string()).ok());  // write_atomic makes the folder
  EXPECT_FALSE(check_output_file("").ok());
  EXPECT_FALSE(check_output_file(d.string()).ok());
  std::ofstream(d / "file") << "x";
  EXPECT_FALSE(check_output_file((d / "file" / "new.png").string()).ok());  // its folder is a file
}

// A folder the process may not make anything in is refused before any work, also where access()
// says yes (as it does to root on /proc), and the check leaves nothing behind.
TEST(Io, OutputFoldersAreCheckedByMakingAFolderThere) {
  const fs::path d = fresh_dir("probe");
  EXPECT_TRUE(bb::cli::check_output_dir((d / "a" / "b").string()).ok());
  EXPECT_TRUE(fs::is_empty(d));  // the probe is removed, the folders to come are not made yet
  if (!fs::is_directory("/proc/self")) GTEST_SKIP() << "no procfs here";
  auto proc = bb::cli::check_output_dir("/proc/bb_out");
  ASSERT_FALSE(proc.ok());
  EXPECT_EQ(proc.error().file, "/proc/bb_out");
  EXPECT_NE(proc.error().reason.find("/proc"), std::string::npos) << proc.error().reason;
}
