// aliquot render: the embedded default. One process, local threads, no servers.
#include <cstdio>
#include <iostream>
#include <memory>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "exr_io.h"
#include "local_render.h"
#include "progress_bar.h"
#include "render_options.h"
#include "scene_loader.h"
#include "uniform_strategy.h"

namespace aliquot::cli {

namespace {

struct RenderCommand {
    RenderOptions options;
    std::string out;
    bool json = false;
    bool aovs = false;

    void run() {
        check_render_options(options);
        check_writable(out, "--out");
        const Scene scene = load_scene(options.scene);
        const PathTracer tracer(scene);
        const RenderGeometry geometry{options.width, options.height, options.seed};
        UniformStrategy strategy(options.width, options.height, uint32_t(options.spp));
        Accumulator merged(options.width, options.height);

        ProgressBar bar("render");
        const RenderStats stats = render_locally(
            tracer, geometry, strategy, merged, options.threads, [&](const RenderProgress& p) {
                const double rate = p.seconds > 0 ? double(p.samples_done) / p.seconds : 0;
                bar.update(p.samples_done, p.samples_planned,
                           "round " + std::to_string(p.round + 1) + ", " +
                               std::to_string(int64_t(rate / 1e3)) + " k samples/s");
            });
        bar.finish();
        write_exr(out, merged.image(aovs));

        const double sps = stats.seconds > 0 ? double(stats.samples) / stats.seconds : 0.0;
        if (json) {
            nlohmann::json summary = {
                {"scene", options.scene},     {"width", options.width},
                {"height", options.height},   {"spp", options.spp},
                {"seed", options.seed},       {"threads", options.threads},
                {"samples", stats.samples},   {"rays", stats.rays},
                {"rounds", stats.rounds},     {"nonfinite_samples", stats.nonfinite},
                {"seconds", stats.seconds},   {"samples_per_second", sps},
                {"output", out}};
            std::cout << summary.dump() << std::endl;
        } else {
            std::printf("rendered %s %ux%u at %lld spp in %.2f s (%.0f samples/s); wrote %s\n",
                        options.scene.c_str(), options.width, options.height,
                        (long long)options.spp, stats.seconds, sps, out.c_str());
            if (stats.nonfinite)
                std::printf("warning: %llu samples had non-finite radiance and were dropped\n",
                            (unsigned long long)stats.nonfinite);
        }
    }
};

}  // namespace

void register_render(CLI::App& app) {
    auto command = std::make_shared<RenderCommand>();
    CLI::App* cmd = app.add_subcommand("render", "render a scene in-process and write an EXR");
    add_render_options(*cmd, command->options);
    cmd->add_option("--out", command->out, "output .exr file")->required();
    cmd->add_flag("--json", command->json, "print one JSON summary object");
    cmd->add_flag("--aovs", command->aovs, "add channels spp and variance to the EXR");
    cmd->callback([command] { command->run(); });
}

}  // namespace aliquot::cli
