// lblight decompress: an .lbh back into a .vdb (one Vec3f grid per solution), through the reader library.
#include <CLI/CLI.hpp>

#include <filesystem>
#include <iostream>

#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "lblight/compress/vdb_compress.h"
#include "lblight/core/error.h"

namespace fs = std::filesystem;

namespace lblight::cli {
namespace {

struct DecompressArgs {
  std::string input, output;
};

int run_decompress(const DecompressArgs& a) {
  const fs::path in = a.input, out = a.output;
  if (!fs::exists(in)) throw_invalid("no such file", {in.string(), {}, {}});
  if (fs::is_directory(in)) throw_invalid("is a folder; give an .lbh file", {in.string(), {}, {}});
  check_output_file(in, out, ".vdb");
  decompress_lbh(in, out);
  std::cout << "wrote " << out.string() << "\n";
  return 0;
}

}  // namespace

Command add_decompress_command(CLI::App& app, const GlobalOptions&) {
  auto args = std::make_shared<DecompressArgs>();
  CLI::App* cmd = app.add_subcommand(
      "decompress", "Decode every solution of an .lbh into a Vec3f grid of the same name and write them to a .vdb "
                    "(same lattice box and transform as the original).");
  cmd->add_option("input", args->input, "Input .lbh")->required();
  cmd->add_option("-o,--output", args->output, "Output .vdb")->required()->check(kNonEmpty);
  return {cmd, [args] { return run_decompress(*args); }};
}

}  // namespace lblight::cli
