// aliquot render: the embedded default. One process, local threads, no servers.
#include <cstdio>
#include <iostream>
#include <memory>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "denoised_render.h"
#include "embedded_render.h"
#include "exr_io.h"
#include "name_option.h"
#include "png_output.h"
#include "progress_bar.h"
#include "render_json.h"
#include "render_options.h"

namespace aliquot::cli {

namespace {

struct RenderCommand {
    RenderOptions options;
    std::string out;
    bool json = false;
    bool aovs = false;
    bool denoise = false;
    std::string name;
    PngOptions png;

    void run() {
        check_render_options(options);
        check_fits_in_memory(options);
        check_writable(out, "--out");
        const std::string png_path = png.path_beside(out);
        // The library is found before any sample is traced, so a missing one costs
        // nothing.
        std::unique_ptr<Denoiser> denoiser;
        if (denoise) {
            std::string error;
            denoiser = Denoiser::open(&error);
            if (!denoiser) throw CommandError("--denoise: " + error);
            options.albedo_normal = true;  // OIDN's aux images: the render's first hits
        }
        RenderSpec spec = make_render_spec(options);
        spec.name = name;

        ProgressBar bar("render");
        const EmbeddedResult result = render_embedded(
            spec, options.threads, aovs || denoise, [&](const RenderInfo& p) {
                std::string note = "round " + std::to_string(p.rounds_done + 1) + ", " +
                                   std::to_string(int64_t(p.samples_per_second / 1e3)) +
                                   " k samples/s";
                if (p.error_estimate >= 0)
                    note += ", err~" + std::to_string(p.error_estimate).substr(0, 8);
                bar.update(p.samples_done, p.samples_planned, note);
            });
        bar.finish();
        Image image = result.image;
        bool used_aux = false;
        if (denoiser) {
            std::string error;
            const std::optional<Image> denoised =
                denoise_render(*denoiser, image, &error, &used_aux);
            if (!denoised) throw CommandError("--denoise: " + error);
            // Without --aovs the EXR has the denoised layer only, not the first hits it
            // was made with.
            if (!aovs) image.extra.clear();
            add_denoised_layer(*denoised, used_aux, image);
        }
        write_exr(out, image);
        if (png.png) write_png(image, png.exposure, png_path);
        const RenderInfo& info = result.info;
        if (json) {
            // The render as the farm's clients print it, plus what only a local run has.
            nlohmann::json summary = render_detail(info);
            summary["spp"] = options.spp;
            summary["threads"] = options.threads;
            summary["output"] = out;
            if (png.png) summary["png"] = png_path;
            if (denoiser)
                summary["denoised"] = used_aux ? "albedo+normal" : "colour only";
            std::cout << summary.dump() << std::endl;
        } else {
            std::printf(
                "rendered %s %ux%u with %s: %llu samples in %.2f s (%.0f samples/s); "
                "wrote %s\n",
                options.scene.c_str(), options.width, options.height, info.method.c_str(),
                (unsigned long long)info.samples_done, info.seconds,
                info.samples_per_second, out.c_str());
            if (png.png) std::printf("wrote %s\n", png_path.c_str());
            if (denoiser)
                std::printf(
                    "denoised with Open Image Denoise (%s): layer denoised.R/G/B\n",
                    used_aux ? "first-hit albedo and normal" : "colour only");
            if (info.outcome_json != "{}" && !info.outcome_json.empty())
                std::printf("outcome: %s\n", info.outcome_json.c_str());
        }
    }
};

}  // namespace

void register_render(CLI::App& app) {
    auto command = std::make_shared<RenderCommand>();
    CLI::App* cmd =
        app.add_subcommand("render", "render a scene in-process and write an EXR");
    add_render_options(*cmd, command->options);
    cmd->add_option("--out", command->out, "output .exr file")->required();
    cmd->add_flag("--json", command->json, "print one JSON summary object");
    cmd->add_flag("--aovs", command->aovs,
                  "add the layers sampleCount.Y and variance.Y to the EXR");
    cmd->add_flag("--denoise", command->denoise,
                  "add the layer denoised.R/G/B: the colour denoised by Intel Open Image "
                  "Denoise with the render's first-hit albedo and normal (implies "
                  "--albedo-normal; scripts/install-deps.sh installs the library)");
    command->png.add_to(*cmd);
    add_name_option(*cmd, command->name, "--json");
    cmd->callback([command] { command->run(); });
}

}  // namespace aliquot::cli
