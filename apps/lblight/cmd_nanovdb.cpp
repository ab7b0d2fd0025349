// lblight nanovdb: a .vdb (a bake's model, a relit volume) converted into NanoVDB (.nvdb) for GPU
// renderers and real-time engines (docs/output-format.md, "NanoVDB").
#include <CLI/CLI.hpp>

#include <filesystem>
#include <iostream>

#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "lblight/core/error.h"
#include "lblight/io/nanovdb_io.h"

namespace fs = std::filesystem;

namespace lblight::cli {

Command add_nanovdb_command(CLI::App& app, const GlobalOptions&) {
  auto input = std::make_shared<std::string>(), output = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand(
      "nanovdb",
      "Convert a .vdb (a bake's <model>.vdb, a relit volume) into NanoVDB (.nvdb): every grid, with its name, "
      "class, voxel size and transform, by NanoVDB's own converter and checked by its validator. A bake writes "
      "<model>.nvdb itself with \"output\": {\"nanovdb\": true}. The materials and units stay in the .vdb's "
      "metadata, which NanoVDB does not carry.");
  cmd->add_option("input", *input, "Input .vdb")->required();
  cmd->add_option("-o,--output", *output, "Output .nvdb (default: the input with extension .nvdb)")->check(kNonEmpty);
  return {cmd, [input, output] {
            const fs::path in = *input;
            if (!fs::exists(in)) throw_invalid("no such file", {in.string(), {}, {}});
            if (in.extension() != ".vdb") throw_invalid("expected an OpenVDB file (.vdb)", {in.string(), {}, {}});
            const fs::path out = output->empty() ? fs::path(in).replace_extension(".nvdb") : fs::path(*output);
            check_output_file(in, out, ".nvdb");
            const NanoVdbWritten n = write_nanovdb(in, out);
            std::cout << n.grids << " grid(s), " << format_bytes(static_cast<double>(n.bytes)) << ": " << out.string()
                      << "\n";
            return 0;
          }};
}

}  // namespace lblight::cli
