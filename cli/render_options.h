// Options shared by every command that starts a render (render, submit, bench,
// reference): parsed and checked once, with one clear message naming the option that is
// wrong.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>

#include "render_spec.h"
#include "strategy_parameters.h"

namespace aliquot::cli {

struct RenderOptions {
    std::string scene = "cornell-box";
    std::string resolution = "256x256";
    uint32_t width = 256, height = 256;
    int64_t spp = -1;  // kSppNotGiven: then kDefaultSpp, unless --budget
    uint64_t seed = 0;
    int threads = 0;             // 0: all hardware threads
    std::string reference;       // optional reference EXR
    std::string sigma;           // oracle: EXR of a separate render with spp and variance
    bool albedo_normal = false;  // RenderSpec::aux: first-hit albedo and normal too
    StrategyParams strategy;
    // Each strategy parameter's flag, so that check_render_options() knows which were
    // given (CLI11 keeps them for as long as the command lives).
    std::vector<std::pair<const StrategyParameter*, const CLI::Option*>> parameter_flags;
};

// Adds --scene, --resolution, --seed, --threads, --reference, --method, --sigma and every
// strategy parameter of strategy_parameters() (--spp, --budget, --max-variance, ...),
// grouped in --help by the methods that read them.
void add_render_options(CLI::App& cmd, RenderOptions& options);
// Parses the resolution and checks ranges and the scene's name; throws CommandError, or
// UsageError for a parameter out of its bounds or given to a method that does not read
// it.
void check_render_options(RenderOptions& options);
// A name that is neither a built-in scene nor a scene file: UsageError, with the nearest
// built-in name.
void check_scene_name(const std::string& scene);
// For a render in this process (render, bench, reference): CommandError, in the words of
// its own options, when its buffers would not fit the memory a render may use here; the
// in-process coordinator would refuse it anyway, naming the farm's --memory-limit.
void check_fits_in_memory(const RenderOptions& options);
// The spec the options describe: loads the scene (inlining meshes) and the reference.
RenderSpec make_render_spec(const RenderOptions& options);
// Fails early, before any work, if `path` cannot be written.
void check_writable(const std::filesystem::path& path, const std::string& option);

constexpr int64_t kSppNotGiven = -1;

}  // namespace aliquot::cli
