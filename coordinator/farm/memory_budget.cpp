#include "memory_budget.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <string>

#include "accumulator.h"
#include "aux_sums.h"
#include "denoised_strategy.h"
#include "sample_job.h"

namespace aliquot {

namespace {

uint64_t cgroup_memory_limit() {
    // A container's limit (cgroup v2), which sysconf does not see; 0 when there is none.
    std::FILE* f = std::fopen("/sys/fs/cgroup/memory.max", "r");
    if (!f) return 0;
    unsigned long long v = 0;
    const bool number = std::fscanf(f, "%llu", &v) == 1;  // "max" when unlimited
    std::fclose(f);
    return number ? uint64_t(v) : 0;
}

std::string mib(uint64_t bytes) {
    char text[32];
    std::snprintf(text, sizeof text, "%.1f MiB", double(bytes) / (1024.0 * 1024.0));
    return text;
}

}  // namespace

uint64_t default_memory_limit() {
    const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
    uint64_t physical = pages > 0 && page > 0 ? uint64_t(pages) * uint64_t(page) : 0;
    if (const uint64_t cg = cgroup_memory_limit();
        cg > 0 && (physical == 0 || cg < physical))
        physical = cg;
    return physical > 0 ? physical / 2 : uint64_t(4) << 30;
}

uint64_t render_memory_estimate(uint32_t width, uint32_t height, bool has_reference,
                                bool first_hits, bool denoises) {
    const uint64_t pixels = uint64_t(width) * height;
    uint64_t per_pixel =
        Accumulator::kBytesPerPixel      // the accumulator
        + sizeof(PixelSums)              // the copy a checkpoint is written from (its
                                         // sums alone: CheckpointSnapshot),
        + 4                              // with the counts of a round planned ahead
        + 12                             // a round's jobs: counts, first indices
        + 16                             // the round's spp; a strategy's per pixel
        + 72                             // optimal's planning, the round ahead
        + 8                              // optimal's weights kept
        + (sizeof(PixelSums) + 12) / 2   // a round opened ahead: held results, jobs
        + 20;                            // the final image: RGB, spp, variance
    if (has_reference) per_pixel += 24;  // the reference, and the image compared to it
    if (first_hits)
        per_pixel += AuxSums::kBytesPerPixel    // the sums
                     + AuxSums::kBytesPerPixel  // their copy a checkpoint is written from
                     + sizeof(FirstHitSums) / 2  // a round opened ahead: held results'
                     + 24;                       // the image's albedo and normal layers
    // and a megabyte for the rest; `denoised`'s round ends: the copies they plan from,
    // their plans' buffers and Open Image Denoise's working memory, ~764 bytes a pixel.
    return pixels * per_pixel + (uint64_t(1) << 20) +
           (denoises ? DenoisedStrategy::round_end_memory(pixels) : 0);
}

uint64_t method_memory_estimate(uint32_t width, uint32_t height, bool has_reference,
                                bool aux, const std::string& method) {
    const bool denoises = method == "denoised";
    return render_memory_estimate(width, height, has_reference, aux || denoises,
                                  denoises);
}

std::string render_memory_note(uint32_t width, uint32_t height, bool denoises) {
    if (!denoises) return "";
    return mib(DenoisedStrategy::round_end_memory(uint64_t(width) * height)) +
           " of it to denoise its round ends, method denoised";
}

MemoryBudgetError::MemoryBudgetError(uint64_t needed_, uint64_t in_use_, size_t renders,
                                     uint64_t limit_, const std::string& note)
    : std::runtime_error("not enough memory for this render: it needs " + mib(needed_) +
                         (note.empty() ? "" : " (" + note + ")") + " and the " +
                         std::to_string(renders) + " render(s) in memory use " +
                         mib(in_use_) + " of the coordinator's " + mib(limit_) +
                         " (--memory-limit); wait for renders to finish, or submit a "
                         "smaller one"),
      needed(needed_),
      in_use(in_use_),
      limit(limit_) {}

void MemoryBudget::check_locked(uint64_t bytes, const std::string& note) const {
    if (limit_ > 0 && (bytes > limit_ || in_use_ > limit_ - bytes))
        throw MemoryBudgetError(bytes, in_use_, renders_, limit_, note);
}

void MemoryBudget::claim(uint64_t bytes, const std::string& note) {
    std::lock_guard lock(mutex_);
    check_locked(bytes, note);
    in_use_ += bytes;
    ++renders_;
}

void MemoryBudget::hold(uint64_t bytes) {
    std::lock_guard lock(mutex_);
    in_use_ += bytes;
    ++renders_;
}

void MemoryBudget::release(uint64_t bytes) {
    std::lock_guard lock(mutex_);
    in_use_ -= std::min(bytes, in_use_);
    if (renders_ > 0) --renders_;
}

uint64_t MemoryBudget::in_use() const {
    std::lock_guard lock(mutex_);
    return in_use_;
}

uint64_t MemoryBudget::reference_allowance(uint32_t width, uint32_t height) const {
    if (limit_ == 0) return 0;
    const uint64_t needed = render_memory_estimate(width, height, true);
    std::lock_guard lock(mutex_);
    check_locked(needed);
    const uint64_t rgb = uint64_t(width) * height * 3 * sizeof(float);
    return limit_ - in_use_ - needed + rgb;
}

}  // namespace aliquot
