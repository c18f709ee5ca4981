#pragma once
// The one place where odonav's command-line tools reach standard output: results a user asked for
// (a summary table, --help text, a JSON snapshot). Diagnostics never go here: they go through spdlog
// to stderr (logging.hpp), so a tool's stdout stays clean for pipes and scripts.
#include <iosfwd>

namespace odonav {

/// The tool's own result stream (standard output).
std::ostream& tool_output();

}  // namespace odonav
