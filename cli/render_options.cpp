#include "render_options.h"

#include <unistd.h>

#include <cstdio>
#include <thread>

#include "commands.h"

namespace aliquot::cli {

void add_render_options(CLI::App& cmd, RenderOptions& o) {
    cmd.add_option("--scene", o.scene, "built-in scene name or a .json scene file")
        ->capture_default_str();
    cmd.add_option("--resolution", o.resolution, "image size as WxH")->capture_default_str();
    cmd.add_option("--spp", o.spp, "samples per pixel")->capture_default_str();
    cmd.add_option("--seed", o.seed, "render seed")->capture_default_str();
    cmd.add_option("--threads", o.threads, "tracing threads (0: all cores)");
}

void check_render_options(RenderOptions& o) {
    unsigned w = 0, h = 0;
    char x = 0, tail = 0;
    if (std::sscanf(o.resolution.c_str(), "%u%c%u%c", &w, &x, &h, &tail) != 3 || x != 'x')
        throw CommandError("--resolution: expected WxH, e.g. 256x256, got \"" + o.resolution +
                           "\"");
    if (w == 0 || h == 0 || w > kMaxResolution || h > kMaxResolution)
        throw CommandError("--resolution: each side must be in 1.." +
                           std::to_string(kMaxResolution) + ", got " + o.resolution);
    o.width = w;
    o.height = h;
    if (o.spp < 1 || o.spp > (int64_t(1) << 31))
        throw CommandError("--spp: must be in 1..2^31, got " + std::to_string(o.spp));
    if (o.threads < 0) throw CommandError("--threads: must be 0 or more");
    if (o.threads == 0) o.threads = int(std::max(1u, std::thread::hardware_concurrency()));
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
    if (access(dir.c_str(), W_OK) != 0 || (fs::exists(path) && access(path.c_str(), W_OK) != 0))
        throw CommandError(option + ": cannot write " + path.string() + ": permission denied");
}

}  // namespace aliquot::cli
