#include "render_options.h"

#include <unistd.h>

#include <thread>

#include "commands.h"
#include "coordinator.h"
#include "exr_io.h"
#include "near_miss.h"
#include "resolution.h"
#include "scene_loader.h"
#include "sigma_map.h"
#include "whole_number_option.h"

namespace aliquot::cli {

void add_render_options(CLI::App& cmd, RenderOptions& o) {
    StrategyParams& s = o.strategy;
    cmd.add_option("--scene", o.scene, "built-in scene name or a .json scene file")
        ->capture_default_str();
    cmd.add_option("--resolution", o.resolution, "image size as WxH")
        ->capture_default_str();
    cmd.add_option("--spp", o.spp,
                   "samples per pixel (uniform; others: budget = spp x pixels); "
                   "without --spp or --budget, 64")
        ->check(whole_number());
    cmd.add_option("--seed", o.seed, "render seed")
        ->check(whole_number())
        ->capture_default_str();
    cmd.add_option("--threads", o.threads, "tracing threads (0: all cores)")
        ->check(whole_number());
    cmd.add_option("--reference", o.reference,
                   "reference EXR: error measured every round");
    cmd.add_option("--method", s.method,
                   "uniform | dammertz | adaptive | optimal | optimal-time | oracle | "
                   "cycles")
        ->capture_default_str();
    cmd.add_option("--sigma", o.sigma,
                   "oracle: EXR of a separate high-spp render with its AOVs (render "
                   "--aovs, another seed); its per-sample sigma steers the oracle");
    cmd.add_option("--sigma-radius", s.sigma_radius,
                   "optimal: pool each pixel's variance over (2r+1)^2 pixels (0: own)")
        ->capture_default_str();
    cmd.add_option(
           "--sigma-prior", s.sigma_prior,
           "optimal: shrink each pixel's variance towards its pool, a prior worth "
           "this many samples (0: off)")
        ->capture_default_str();
    cmd.add_option("--floor-fraction", s.floor_fraction,
                   "optimal: pilot and floor at this share of the budget's mean spp "
                   "(0: min_spp alone)")
        ->capture_default_str();
    cmd.add_option("--steer-rounds", s.steer_rounds,
                   "optimal: spend what the pilot leaves in this many rounds, each at "
                   "most half of what is left (0: doubling rounds)")
        ->capture_default_str();
    cmd.add_option("--plan-ahead", s.plan_ahead,
                   "optimal: plan the round after a steered round of at most this "
                   "share of the budget while that round is traced; at least the "
                   "pilot's share (1/2): the pilot in two halves, no round planned in "
                   "place, for large farms (0: never)")
        ->capture_default_str();
    cmd.add_option("--noise-threshold", s.noise_threshold, "cycles: noise threshold")
        ->capture_default_str();
    cmd.add_option("--adaptive-min-samples", s.adaptive_min_samples,
                   "cycles: samples before the first check (0: automatic)")
        ->capture_default_str();
    cmd.add_option("--adaptive-step", s.adaptive_step,
                   "cycles: samples between convergence checks")
        ->capture_default_str();
    cmd.add_option("--budget", s.budget, "total samples to spend")->check(whole_number());
    cmd.add_option("--max-variance", s.max_variance, "dammertz V; adaptive max variance")
        ->capture_default_str();
    cmd.add_option("--samples-per-iteration", s.samples_per_iteration, "dammertz S")
        ->check(whole_number())
        ->capture_default_str();
    cmd.add_option("--split-factor", s.split_factor, "dammertz split factor")
        ->capture_default_str();
    cmd.add_option("--min-bucket-size", s.min_bucket_size,
                   "dammertz smallest bucket side")
        ->check(whole_number())
        ->capture_default_str();
    cmd.add_option("--error-norm", s.error_norm, "dammertz error: seed | paper")
        ->capture_default_str();
    cmd.add_option("--initial-spp", s.initial_spp, "adaptive initial uniform pass")
        ->check(whole_number())
        ->capture_default_str();
    cmd.add_option("--alpha", s.alpha, "adaptive distribution exponent")
        ->capture_default_str();
    cmd.add_option("--bucket-size", s.bucket_size, "adaptive bucket side")
        ->check(whole_number())
        ->capture_default_str();
    cmd.add_option("--min-spp", s.min_spp, "optimal: samples every pixel gets first")
        ->check(whole_number())
        ->capture_default_str();
    cmd.add_option("--max-spp", s.max_spp,
                   "cap on any pixel's samples (0: method default)")
        ->check(whole_number());
    cmd.add_option("--max-samples", s.max_samples,
                   "cap on total samples (0: method default)")
        ->check(whole_number());
}

void check_render_options(RenderOptions& o) {
    check_scene_name(o.scene);
    try {
        const Resolution r = parse_resolution(o.resolution);
        o.width = r.width;
        o.height = r.height;
    } catch (const std::invalid_argument& e) {
        throw UsageError(std::string("--resolution: ") + e.what());
    }
    if (o.spp != kSppNotGiven && (o.spp < 1 || o.spp > (int64_t(1) << 31)))
        throw UsageError("--spp: must be in 1..2^31, got " + std::to_string(o.spp));
    // Without --spp or --budget every method that needs a sample budget gets the same
    // one, 64 samples per pixel (dammertz and cycles stop by their own measure).
    if (o.spp == kSppNotGiven)
        o.spp = (o.strategy.budget == 0 && o.strategy.method != "dammertz" &&
                 o.strategy.method != "cycles")
                    ? kDefaultSpp
                    : 0;
    o.strategy.spp = uint64_t(o.spp);
    if (o.threads < 0) throw UsageError("--threads: must be 0 or more");
    if (o.threads == 0)
        o.threads = int(std::max(1u, std::thread::hardware_concurrency()));
    if (!o.sigma.empty()) {
        if (o.strategy.method != "oracle")
            throw CommandError("--sigma: only --method oracle reads it");
        try {
            const Image image = read_exr(o.sigma);
            if (image.width != o.width || image.height != o.height)
                throw std::invalid_argument("is " + std::to_string(image.width) + "x" +
                                            std::to_string(image.height) +
                                            ", the render " + o.resolution);
            o.strategy.true_sigma =
                std::make_shared<const std::vector<float>>(per_sample_sigma(image));
        } catch (const std::exception& e) {
            throw CommandError("--sigma: " + o.sigma + ": " + e.what());
        }
    }
    try {
        validate(o.strategy, o.width, o.height);
    } catch (const std::invalid_argument& e) {
        throw UsageError(e.what());
    }
}

RenderSpec make_render_spec(const RenderOptions& o) {
    RenderSpec spec;
    spec.scene_name = o.scene;
    spec.scene_json = self_contained_scene_json(o.scene);
    spec.width = o.width;
    spec.height = o.height;
    spec.seed = o.seed;
    spec.strategy = o.strategy;
    if (!o.reference.empty()) spec.reference = read_exr(o.reference);
    return spec;
}

void check_scene_name(const std::string& scene) {
    // The scene loader's own rule for what is a file: a .json name or a path that exists.
    // Anything else can only be a built-in name, and a wrong one is a usage error, like
    // an unknown method; a scene file that cannot be read is a failure (exit status 1).
    if (builtin_scene_json(scene) ||
        std::filesystem::path(scene).extension() == ".json" ||
        std::filesystem::exists(scene))
        return;
    const std::vector<std::string> names = builtin_scene_names();
    const std::string near = closest(scene, names);
    std::string list;
    for (const std::string& n : names) list += (list.empty() ? "" : ", ") + n;
    throw UsageError("--scene: unknown scene '" + scene + "'" +
                     (near.empty() ? "" : "; did you mean '" + near + "'?") +
                     " (built-in scenes: " + list + "; or a path to a .json file)");
}

void check_fits_in_memory(const RenderOptions& o) {
    const uint64_t needed =
        render_memory_estimate(o.width, o.height, !o.reference.empty());
    const uint64_t limit = default_memory_limit();
    if (needed <= limit) return;
    const auto mib = [](uint64_t bytes) { return std::to_string(bytes >> 20) + " MiB"; };
    throw CommandError("--resolution " + std::to_string(o.width) + "x" +
                       std::to_string(o.height) + ": the render would hold about " +
                       mib(needed) + " in memory, more than the " + mib(limit) +
                       " (half of this machine's memory) a render may use; choose a "
                       "smaller --resolution");
}

void check_writable(const std::filesystem::path& path, const std::string& option) {
    namespace fs = std::filesystem;
    if (path.empty()) throw CommandError(option + ": no output path given");
    if (fs::is_directory(path))
        throw CommandError(option + ": " + path.string() + " is a directory");
    const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
    if (!fs::is_directory(dir))
        throw CommandError(option + ": cannot write " + path.string() + ": directory " +
                           dir.string() + " does not exist");
    if (access(dir.c_str(), W_OK) != 0 ||
        (fs::exists(path) && access(path.c_str(), W_OK) != 0))
        throw CommandError(option + ": cannot write " + path.string() +
                           ": permission denied");
}

}  // namespace aliquot::cli
