// AuxSums: a render's per-pixel first-hit sums (albedo, normal) beside its Accumulator,
// for renders that will be denoised: what OIDN reads beside the colour (issue 34). Kept
// apart from the Accumulator so a render that does not ask for them holds nothing more.
#pragma once

#include <cstdint>
#include <vector>

#include "accumulator.h"
#include "image.h"
#include "sample_job.h"

namespace aliquot {

class AuxSums {
public:
    // Memory a pixel takes when the sums are kept.
    static constexpr size_t kBytesPerPixel = sizeof(FirstHitSums);

    // Kept: not. Takes only results without first-hit sums, holds nothing.
    AuxSums() = default;
    // Kept for a width x height render: every result must carry its pixels' sums.
    AuxSums(uint32_t width, uint32_t height);

    bool kept() const { return !sums_.empty(); }
    uint32_t width() const { return width_; }
    uint32_t height() const { return height_; }

    // Throws MergeError, touching nothing, unless the result carries first-hit sums
    // exactly when they are kept, one per pixel, each within what its samples can add (an
    // albedo or a normal component is at most 1 in size a sample, so a pixel of no
    // samples has all zero): then the means are finite, bounded floats whatever a worker
    // sends. The rectangle is the Accumulator's to check (merge_with_aux checks both
    // first).
    void check(const SampleJobResult& result) const;
    // Adds a checked result's sums.
    void add(const SampleJobResult& result);

    const FirstHitSums& at(size_t i) const { return sums_[i]; }

    // The mean albedo (RGB) and mean normal (XYZ in its rgb) of each pixel over its
    // samples, `merged` giving the counts; 0 where a pixel has none. Empty images when
    // not kept.
    Image albedo(const Accumulator& merged) const;
    Image normal(const Accumulator& merged) const;
    // Appends the layers of aov_channels.h ("albedo.R/G/B", "normal.X/Y/Z") to `image`
    // when kept.
    void add_layers(const Accumulator& merged, Image& image) const;

private:
    Image means(const Accumulator& merged, bool normal) const;

    uint32_t width_ = 0, height_ = 0;
    std::vector<FirstHitSums> sums_;
};

// Merges `result` into both or neither: throws MergeError, touching neither, when either
// would refuse it. check_with_aux, then add_with_aux.
void merge_with_aux(Accumulator& merged, AuxSums& aux, const SampleJobResult& result);
// Throws MergeError unless both would take `result` (Accumulator::check, with the job's
// `counts` when given); what it adds.
ResultTotals check_with_aux(Accumulator& merged, const AuxSums& aux,
                            const SampleJobResult& result,
                            const uint32_t* counts = nullptr);
// Adds a result check_with_aux took to both. Adds of disjoint rectangles may run at once.
void add_with_aux(Accumulator& merged, AuxSums& aux, const SampleJobResult& result,
                  const ResultTotals& totals);

}  // namespace aliquot
