// aliquot: one binary, one subcommand per verb. Thin on purpose: commands live in their
// files.
#include <cstdio>
#include <exception>
#include <string>

#include "commands.h"
#include "log_line.h"
#include "usage_message.h"

namespace {

// A failure on one line: "aliquot: ..." for people, or a JSON line when a long-running
// command (coordinator, worker) was told `--log-format json`, so that a log collector
// parses its last words too.
void report(const std::string& message) {
    if (aliquot::log_format() == aliquot::LogFormat::Json)
        aliquot::write_log_line("failed", {aliquot::log_text("message", message)});
    else
        std::fprintf(stderr, "aliquot: %s\n", message.c_str());
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"Aliquot: a Monte Carlo render farm about where the samples go"};
    app.set_version_flag("--version", "aliquot " ALIQUOT_VERSION);
    app.require_subcommand(1);
    aliquot::cli::register_render(app);
    aliquot::cli::register_compare(app);
    aliquot::cli::register_bench(app);
    aliquot::cli::register_coordinator(app);
    aliquot::cli::register_worker(app);
    aliquot::cli::register_submit(app);
    aliquot::cli::register_farm_clients(app);
    aliquot::cli::register_reference(app);
    aliquot::cli::register_study(app);
    aliquot::cli::register_health(app);
    aliquot::cli::register_logs(app);
    // A first word that is no option must name a command; CLI11 alone would answer
    // `aliquot rendr` with "A subcommand is required".
    if (argc > 1 && argv[1][0] != '-') {
        const std::string unknown = aliquot::cli::unknown_command(app, argv[1]);
        if (!unknown.empty()) {
            report(unknown);
            return aliquot::cli::kExitUsage;
        }
    }
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        // --help and --version end parsing as "errors" with status 0; every other parse
        // error is a usage error, whatever number CLI11 gives its kind, and reads like
        // the commands' own: one line, "aliquot: ".
        if (e.get_exit_code() == 0) return app.exit(e);
        report(aliquot::cli::parse_error_message(app, e));
        return aliquot::cli::kExitUsage;
    } catch (const aliquot::cli::UsageError& e) {
        report(e.what());
        return aliquot::cli::kExitUsage;
    } catch (const std::exception& e) {
        // Every error the user can cause arrives here as one line; no stack traces.
        report(e.what());
        return aliquot::cli::kExitFailure;
    }
    return 0;
}
