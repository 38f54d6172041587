// The aliquot subcommands: each file registers one with the CLI11 app.
#pragma once

#include <stdexcept>

#include <CLI/CLI.hpp>

namespace aliquot::cli {

// Exit statuses, as in the rest of the Unix world (and CLI11's own parse errors): a
// script can tell a command it wrote wrong from one that met a failure.
constexpr int kExitFailure = 1;  // the command was right; running it failed
constexpr int kExitUsage = 2;    // the command line is wrong: nothing was attempted

// A failure while running: printed as one line "aliquot: <message>", exit status 1.
class CommandError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// A command line that cannot be right whatever the files, network or coordinator say (an
// option out of range, two options that exclude each other): one line, exit status 2.
class UsageError : public CommandError {
public:
    using CommandError::CommandError;
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
void register_health(CLI::App& app);  // a probe of gRPC health
void register_logs(CLI::App& app);    // a render's events

}  // namespace aliquot::cli
