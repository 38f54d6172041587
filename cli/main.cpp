// aliquot: one binary, one subcommand per verb. Thin on purpose: commands live in their
// files.
#include <cstdio>
#include <exception>

#include "commands.h"

int main(int argc, char** argv) {
    CLI::App app{"Aliquot: a Monte Carlo render farm about where the samples go"};
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
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e);
    } catch (const std::exception& e) {
        // Every error the user can cause arrives here as one line; no stack traces.
        std::fprintf(stderr, "aliquot: %s\n", e.what());
        return 1;
    }
    return 0;
}
