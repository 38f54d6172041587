// `--name` of submit and render: a render's name for people, refused on the command line
// (exit 2) when the coordinator would refuse it (render_spec.h).
#pragma once

#include <string>

#include <CLI/CLI.hpp>

namespace aliquot::cli {

void add_name_option(CLI::App& command, std::string& name, const std::string& shown_by);

}  // namespace aliquot::cli
