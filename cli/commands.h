// The aliquot subcommands: each file registers one with the CLI11 app.
#pragma once

#include <stdexcept>

#include <CLI/CLI.hpp>

namespace aliquot::cli {

// An error the user can fix: printed as one line "aliquot: <message>", exit status 1.
class CommandError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

void register_render(CLI::App& app);
void register_compare(CLI::App& app);
void register_bench(CLI::App& app);
void register_coordinator(CLI::App& app);
void register_worker(CLI::App& app);
void register_submit(CLI::App& app);
void register_farm_clients(CLI::App& app);  // status, watch, fetch, cancel, priority,
                                            // delete, workers
void register_reference(CLI::App& app);
void register_study(CLI::App& app);

}  // namespace aliquot::cli
