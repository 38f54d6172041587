// The one line a wrong command line earns, whoever found it wrong (CLI11's parser or a
// command's own checks): "aliquot: …", naming the command, with the nearest known word
// when the user mistyped one.
#pragma once

#include <string>

#include <CLI/CLI.hpp>

namespace aliquot::cli {

// For `aliquot WORD …` where WORD is no command: "unknown command 'rendr'; did you mean
// 'render'?", or the list of commands when none is near. "" when WORD is a command.
std::string unknown_command(const CLI::App& app, const std::string& word);

// CLI11's parse error `e` (not --help or --version) as one line without the "aliquot: "
// prefix: the command it arose in, and for an unknown option the nearest option of that
// command.
std::string parse_error_message(const CLI::App& app, const CLI::ParseError& e);

}  // namespace aliquot::cli
