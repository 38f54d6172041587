// aliquot reference: a high-spp uniform render that other renders are judged against,
// cached by scene hash, resolution, spp and seed so a study renders each reference once.
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "embedded_render.h"
#include "exr_io.h"
#include "progress_bar.h"
#include "render_options.h"
#include "seed_json.h"

namespace aliquot::cli {

namespace {

// References use their own seed stream, far from any seed a user types, so a reference
// never shares random numbers with the render it judges.
constexpr uint64_t kReferenceSeed = uint64_t(1) << 40;

std::filesystem::path cache_dir() {
    if (const char* dir = std::getenv("ALIQUOT_CACHE")) return dir;
    if (const char* xdg = std::getenv("XDG_CACHE_HOME"))
        return std::filesystem::path(xdg) / "aliquot";
    if (const char* home = std::getenv("HOME"))
        return std::filesystem::path(home) / ".cache" / "aliquot";
    return ".aliquot-cache";
}

struct ReferenceCommand {
    RenderOptions options;
    std::string out;
    bool json = false, no_cache = false;

    void run() {
        if (options.spp == kSppNotGiven) options.spp = 8192;
        options.strategy.method = "uniform";
        if (options.seed == 0) options.seed = kReferenceSeed;
        check_render_options(options);
        check_fits_in_memory(options);
        check_writable(out, "--out");
        const RenderSpec spec = make_render_spec(options);
        const std::filesystem::path cached =
            cache_dir() / "references" /
            (scene_hash(spec.scene_json) + "-" + std::to_string(spec.width) + "x" +
             std::to_string(spec.height) + "-" + std::to_string(options.spp) +
             "spp-seed" + std::to_string(spec.seed) + ".exr");
        bool hit = !no_cache && std::filesystem::exists(cached);
        double seconds = 0;
        if (!hit) {
            ProgressBar bar("reference");
            const EmbeddedResult result =
                render_embedded(spec, options.threads, false, [&](const RenderInfo& p) {
                    bar.update(p.samples_done, p.samples_planned);
                });
            bar.finish();
            seconds = result.info.seconds;
            std::filesystem::create_directories(cached.parent_path());
            const std::filesystem::path tmp = cached.string() + ".part.exr";
            write_exr(tmp, result.image);
            std::filesystem::rename(tmp, cached);
        }
        std::filesystem::copy_file(cached, out,
                                   std::filesystem::copy_options::overwrite_existing);
        if (json) {
            std::cout << nlohmann::json{{"output", out},
                                        {"cached", cached.string()},
                                        {"cache_hit", hit},
                                        {"spp", options.spp},
                                        {"seed", seed_to_json(spec.seed)},
                                        {"seconds", seconds}}
                             .dump()
                      << std::endl;
        } else {
            std::cout << (hit ? "reference from cache: " : "rendered reference: ") << out
                      << std::endl;
        }
    }
};

}  // namespace

void register_reference(CLI::App& app) {
    auto c = std::make_shared<ReferenceCommand>();
    CLI::App* cmd = app.add_subcommand(
        "reference",
        "render (or take from the cache) a high-spp uniform reference image");
    add_render_options(*cmd, c->options);
    cmd->add_option("--out", c->out, "output .exr file")->required();
    cmd->add_flag("--json", c->json, "print one JSON summary object");
    cmd->add_flag("--no-cache", c->no_cache, "render even if the cache has it");
    cmd->callback([c] { c->run(); });
}

}  // namespace aliquot::cli
