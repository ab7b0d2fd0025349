// The one guard every command puts in front of its outputs (lblight/io/run_paths.h) and the one
// rule for text that reaches a script or a terminal (lblight/core/script_text.h).
#include <catch2/catch.hpp>
#include <sys/stat.h>

#include <fstream>

#include "lblight/core/script_text.h"
#include "lblight/io/output_dir.h"
#include "lblight/io/run_paths.h"
#include "tests/support/expect_error.h"
#include "tests/support/test_support.h"

using namespace lblight;
using namespace lblight::test;
namespace fs = std::filesystem;

namespace {
void touch(const fs::path& p, const std::string& text = "x") {
  fs::create_directories(p.parent_path());
  std::ofstream(p) << text;
}
}  // namespace

TEST_CASE("RunPaths refuses outputs that are not regular files", "[io]") {
  TempDir tmp;
  const fs::path fifo = tmp.path() / "pipe.vdb";
  REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
  expect_invalid_input([&] { RunPaths().output_file(fifo, "-o").check(); }, "FIFO");
  expect_invalid_input([&] { RunPaths().output_file("/dev/null", "--png").check(); }, "character device");
  expect_invalid_input([&] { RunPaths().output_file(tmp.path(), "-o").check(); }, "a folder");
  touch(tmp.path() / "file");
  expect_invalid_input([&] { RunPaths().output_folder(tmp.path() / "file", "-o").check(); }, "is a file");
  expect_invalid_input([&] { RunPaths().output_file(tmp.path() / "file" / "x.vdb", "-o").check(); }, "not a folder");
  // The last line of defence: no writer goes through a FIFO either (it used to block).
  expect_invalid_input([&] { write_file_atomically(fifo, "text"); }, "FIFO");
  // What is allowed: a new name (also in folders still to be made), a regular file, a symlink to one.
  expect_invalid_input([&] { RunPaths().output_file(tmp.path() / "new" / "x.vdb", "-o").check(); }, "does not exist");
  RunPaths().output_folder(tmp.path() / "new" / "deeper", "-o").output_file(tmp.path() / "file2", "-o").check();
  fs::create_symlink(tmp.path() / "file", tmp.path() / "link");
  RunPaths().output_file(tmp.path() / "link", "-o").check();
}

TEST_CASE("RunPaths refuses an output that is, holds or lies inside an input, or another output", "[io]") {
  TempDir tmp;
  const fs::path bake = tmp.path() / "bake", vdb = bake / "m.vdb";
  touch(vdb);
  touch(bake / "manifest.json");
  expect_invalid_input([&] { RunPaths().input(vdb, "the bake").output_file(vdb, "-o").check(); }, "also the bake");
  expect_invalid_input(
      [&] { RunPaths().input(vdb, "the bake").output_file(bake / "sub" / ".." / "m.vdb", "-o").check(); }, "also");
  expect_invalid_input([&] { RunPaths().input(bake, "the bake").output_file(bake / "light.vdb", "-o").check(); },
                       "inside the bake");
  expect_invalid_input([&] { RunPaths().input(vdb, "part").output_folder(bake, "-o").check(); }, "holds part");
  expect_invalid_input([&] { RunPaths().input(bake, "part").output_folder(bake, "-o").check(); }, "also part");
  fs::create_hard_link(vdb, tmp.path() / "hard.vdb");
  expect_invalid_input([&] { RunPaths().input(vdb, "the input").output_file(tmp.path() / "hard.vdb", "-o").check(); },
                       "also the input");
  fs::create_symlink(bake, tmp.path() / "alias");
  expect_invalid_input(
      [&] { RunPaths().input(bake, "the bake").output_file(tmp.path() / "alias" / "x.vdb", "-o").check(); }, "inside");
  expect_invalid_input(
      [&] { RunPaths().output_file(tmp.path() / "a.exr", "-o").output_file(tmp.path() / "./a.exr", "--png").check(); },
      "same place");
  expect_invalid_input(
      [&] { RunPaths().output_folder(tmp.path() / "out", "-o").output_file(tmp.path() / "out" / "a", "x").check(); },
      "same place");
  // Neighbours are fine: a sibling whose name starts like the input folder's is not inside it.
  fs::create_directory(tmp.path() / "bake2");
  RunPaths().input(bake, "the bake").output_file(tmp.path() / "bake2" / "m.vdb", "-o").check();
  RunPaths().input(bake, "the bake").output_file(tmp.path() / "bake-light.vdb", "-o").check();
}

TEST_CASE("Script values: control characters refused, everything else quoted for bash and sbatch", "[io]") {
  expect_invalid_input([] { check_script_value("p\ntouch /tmp/x", "--partition"); }, "--partition");
  expect_invalid_input([] { check_script_value(std::string("a\0b", 3), "-o"); }, "0x00");
  expect_invalid_input([] { check_script_value("a\x1b[31m", "--account"); }, "\\x1b");
  check_script_value("p q$(x)'\"#\\", "--partition");
  CHECK(shell_word("plain-word_1.5/x:y") == "plain-word_1.5/x:y");
  CHECK(shell_word("a b") == "'a b'");
  CHECK(shell_word("it's") == "'it'\\''s'");
  CHECK(shell_word("") == "''");
  CHECK(sbatch_word("long") == "long");
  CHECK(sbatch_word("a b#c") == "\"a b#c\"");
  CHECK(sbatch_word("q\"\\") == "\"q\\\"\\\\\"");
  CHECK(printable("a\nb\tc\x1b[0m") == "a\\nb\\tc\\x1b[0m");
  // Every message echoes input through printable().
  const Error e(ErrorCategory::InvalidInput, "value 'x\ny'", {"f\x1b.json", {}, {}});
  CHECK(std::string(e.what()) == "f\\x1b.json: value 'x\\ny'");
}
