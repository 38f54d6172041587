// Fuzzes a checkpoint file as a restarted coordinator reads it from its data directory
// (a disk that filled mid-write, bit rot, another version's file): load_checkpoint, then
// the session restored from it and its next round planned, as resume() does. The
// contract is the one resume() relies on: a render that continues, or a std::exception
// (the render is marked as one that cannot resume), never a crash or an allocation the
// file's size does not justify.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "checkpoint.h"
#include "render_session.h"
#include "scene_loader.h"

namespace {

aliquot::RenderSpec spec_for(uint32_t width, uint32_t height) {
    aliquot::RenderSpec spec;
    spec.scene_name = "furnace";
    spec.scene_json = *aliquot::builtin_scene_json("furnace");
    spec.width = width;
    spec.height = height;
    spec.seed = 1;
    spec.strategy.method = "optimal";
    spec.strategy.budget = uint64_t(width) * height * 16;
    spec.strategy.plan_ahead = 1;  // the pilot split: a round planned ahead at once
    return spec;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    static const std::filesystem::path path =
        std::filesystem::temp_directory_path() /
        ("aliquot-checkpoint-fuzz-" + std::to_string(getpid()) + ".bin");
    std::ofstream(path, std::ios::binary | std::ios::trunc)
        .write(reinterpret_cast<const char*>(data), std::streamsize(size));
    try {
        std::optional<aliquot::Checkpoint> cp = aliquot::load_checkpoint(path);
        if (!cp) return 0;
        // The render the checkpoint says it is: small images only, so that one input
        // stays fast (the reader's own size checks are what bounds larger ones).
        if (cp->merged.pixel_count() > 64 * 64) return 0;
        aliquot::RenderSession session(
            "fuzz", spec_for(cp->merged.width(), cp->merged.height()), 0);
        session.restore(std::move(cp->merged), cp->strategy_state, cp->rounds_done,
                        cp->seconds, std::move(cp->planned_round));
        session.start();
        const auto far = aliquot::RenderSession::Clock::now() + std::chrono::hours(1);
        session.issue(1, "w", far);
    } catch (const std::exception&) {
    }
    return 0;
}
