// lblight schema: the scene file's JSON Schema (draft 2020-12), generated from the field tables
// the parser reads through (lblight/scene/scene_fields.h), for editors and pipeline checks.
#include <CLI/CLI.hpp>

#include <iostream>

#include "apps/lblight/commands.h"
#include "lblight/io/output_dir.h"
#include "lblight/io/run_paths.h"
#include "lblight/scene/scene_fields.h"

namespace lblight::cli {

Command add_schema_command(CLI::App& app, const GlobalOptions&) {
  auto output = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand(
      "schema",
      "Print the scene file's JSON Schema (draft 2020-12), generated from the parser's own field tables: "
      "fields, types, ranges, defaults and choices. Shipped configs name docs/scene.schema.json in \"$schema\" "
      "(editors then complete and check scenes). docs/scene-format.md.");
  cmd->add_option("-o,--output", *output, "Write it to this file instead of standard output");
  return {cmd, [output] {
            const std::string text = scene_json_schema().dump(2) + "\n";
            if (output->empty()) std::cout << text;
            else {
              RunPaths().output_file(*output, "-o").check();
              write_file_atomically(*output, text);
            }
            return 0;
          }};
}

}  // namespace lblight::cli
