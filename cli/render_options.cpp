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
#include "strategy_parameters.h"
#include "whole_number_option.h"

namespace aliquot::cli {

namespace {

std::string joined(const std::vector<std::string>& words, const char* separator) {
    std::string s;
    for (const std::string& w : words) s += (s.empty() ? "" : separator) + w;
    return s;
}

// --help lists each parameter under the methods that read it.
std::string help_group(const StrategyParameter& p) {
    if (p.methods == strategy_methods()) return "Budget and caps (every method)";
    return "Parameters of " + joined(p.methods, ", ");
}

std::string parameter_help(const StrategyParameter& p) {
    // The help of a word names its values; a count's bounds go without saying unless the
    // table narrows them.
    if (p.kind() == StrategyParameter::Kind::Word) return p.help;
    if (p.kind() == StrategyParameter::Kind::Whole && p.max >= double(UINT32_MAX))
        return p.min == 0 ? p.help
                          : p.help + "; at least " + std::to_string(uint64_t(p.min));
    return p.help + "; " + p.bounds();
}

}  // namespace

void add_render_options(CLI::App& cmd, RenderOptions& o) {
    StrategyParams& s = o.strategy;
    cmd.add_option("--scene", o.scene, "built-in scene name or a .json scene file")
        ->capture_default_str();
    cmd.add_option("--resolution", o.resolution, "image size as WxH")
        ->capture_default_str();
    cmd.add_option("--seed", o.seed, "render seed")
        ->check(whole_number())
        ->capture_default_str();
    cmd.add_option("--threads", o.threads, "tracing threads (0: all cores)")
        ->check(whole_number());
    cmd.add_option("--reference", o.reference,
                   "reference EXR: error measured every round");
    cmd.add_flag("--albedo-normal", o.albedo_normal,
                 "workers also return each pixel's first-hit albedo and normal (for a "
                 "denoiser); with --aovs the EXR gets the layers albedo.R/G/B and "
                 "normal.X/Y/Z");
    std::string methods;
    for (const std::string& m : strategy_methods())
        methods += "\n  " + m + ": " + method_summary(m);
    cmd.add_option("--method", s.method, "sampling method:" + methods)
        ->capture_default_str();
    cmd.add_option("--sigma", o.sigma,
                   "oracle: EXR of a separate high-spp render with its AOVs (render "
                   "--aovs, another seed); its per-sample sigma steers the oracle")
        ->group("Parameters of oracle");
    // Every strategy parameter, from the one table (strategy_parameters.h): its flag,
    // help, bounds and default; check_render_options() refuses one out of bounds or
    // given to a method that does not read it.
    o.parameter_flags.clear();
    for (const StrategyParameter& p : strategy_parameters()) {
        CLI::Option* option = nullptr;
        if (p.key == "spp") {
            // Its own field: without --spp or --budget, a method that needs a budget
            // gets 64 samples per pixel.
            option = cmd.add_option(p.flag(), o.spp, parameter_help(p))
                         ->default_str(std::to_string(kDefaultSpp) + " unless --budget");
        } else {
            option = std::visit(
                [&](auto member) {
                    return cmd.add_option(p.flag(), s.*member, parameter_help(p))
                        ->capture_default_str();
                },
                p.member);
        }
        if (p.kind() == StrategyParameter::Kind::Whole) option->check(whole_number());
        option->group(help_group(p));
        o.parameter_flags.push_back({&p, option});
    }
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
        o.spp = (o.strategy.budget == 0 && needs_budget(o.strategy.method))
                    ? int64_t(kDefaultSpp)
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
    for (const auto& [parameter, option] : o.parameter_flags) {
        if (option->count() == 0) continue;
        // A parameter for another method would be ignored without a word: refused,
        // like --sigma without oracle.
        if (!parameter->applies_to(o.strategy.method))
            throw UsageError(parameter->flag() + ": only " +
                             joined(parameter->methods, ", ") +
                             (parameter->methods.size() == 1 ? " reads" : " read") +
                             " it, not --method " + o.strategy.method);
        const std::string why = parameter->out_of_bounds(o.strategy);
        if (!why.empty()) throw UsageError(parameter->flag() + ": " + why);
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
    spec.aux = o.albedo_normal;
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
    const uint64_t needed = method_memory_estimate(
        o.width, o.height, !o.reference.empty(), o.albedo_normal, o.strategy.method);
    const uint64_t limit = default_memory_limit();
    if (needed <= limit) return;
    const auto mib = [](uint64_t bytes) { return std::to_string(bytes >> 20) + " MiB"; };
    const std::string note =
        render_memory_note(o.width, o.height, o.strategy.method == "denoised");
    throw CommandError("--resolution " + std::to_string(o.width) + "x" +
                       std::to_string(o.height) + ": the render would hold about " +
                       mib(needed) + (note.empty() ? "" : " (" + note + ")") +
                       " in memory, more than the " + mib(limit) +
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
