// `--log-format text|json` of the long-running commands (coordinator, worker): how the
// process writes its log lines on stderr (log_line.h).
#pragma once

#include <CLI/CLI.hpp>

namespace aliquot::cli {

void add_log_format_option(CLI::App& command);

}  // namespace aliquot::cli
