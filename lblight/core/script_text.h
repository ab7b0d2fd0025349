// Text from users that reaches a generated script or a terminal (docs/reliability.md, "Scripts
// and messages"): one rule for each. A value that enters a script (Slurm's #SBATCH lines, bash
// commands) is refused when it holds a control character (a newline would start a command of its
// own) and is quoted otherwise; text echoed in a message shows its control characters escaped.
#pragma once

#include <string>
#include <string_view>

namespace lblight {

// The first control character (0x00-0x1f, 0x7f) of `text`, or -1.
int first_control_character(std::string_view text);

// `text` with control characters written as \n, \t, \r or \xNN (and backslashes left as they
// are): what a message may echo of input.
std::string printable(std::string_view text);

// Error(InvalidInput) naming `what` when `value` holds a control character; allowed: printable
// text. Every value a generated script receives passes here first.
void check_script_value(const std::string& value, const std::string& what);

// One word for bash: as it is when made of safe characters only, else single-quoted ('\'' for a
// quote).
std::string shell_word(const std::string& value);

// One argument of an #SBATCH line: sbatch's own parser takes double quotes and backslash escapes
// (also inside quotes, unlike bash), and cuts the line at an unquoted '#'.
std::string sbatch_word(const std::string& value);

}  // namespace lblight
