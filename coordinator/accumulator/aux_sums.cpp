#include "aux_sums.h"

#include <cmath>
#include <string>

#include "aov_channels.h"

namespace aliquot {

namespace {

// A sample adds at most 1 in size to each component (albedo in [0, 1], a unit normal);
// the slack covers a float normal's rounding past 1. NaN fails the comparison.
constexpr double kMaxPerSample = 1.0 + 1e-3;

bool within(const FirstHitSums& f, uint64_t samples) {
    const double bound = kMaxPerSample * double(samples);
    bool ok = true;
    for (int c = 0; c < 3; ++c) {
        ok &= std::abs(f.albedo[c]) <= bound;
        ok &= std::abs(f.normal[c]) <= bound;
    }
    return ok;
}

}  // namespace

AuxSums::AuxSums(uint32_t width, uint32_t height)
    : width_(width), height_(height), sums_(size_t(width) * height) {}

void AuxSums::check(const SampleJobResult& result) const {
    if (!kept()) {
        if (!result.first_hits.empty())
            throw MergeError("result has first-hit sums the render did not ask for");
        return;
    }
    if (result.first_hits.size() != result.pixels.size())
        throw MergeError("result has " + std::to_string(result.first_hits.size()) +
                         " pixels of first-hit sums, " +
                         std::to_string(result.pixels.size()) + " of colour");
    // Each result pixel on its own: sums within their samples stay so when added.
    for (size_t i = 0; i < result.pixels.size(); ++i)
        if (!within(result.first_hits[i], result.pixels[i].samples))
            throw MergeError("result pixel " + std::to_string(i) +
                             "'s first-hit sums are non-finite or larger than its " +
                             std::to_string(result.pixels[i].samples) + " samples allow");
}

void AuxSums::add(const SampleJobResult& result) {
    if (!kept()) return;
    const PixelRect& r = result.rect;
    for (uint32_t row = 0; row < r.height; ++row)
        for (uint32_t col = 0; col < r.width; ++col) {
            const FirstHitSums& src = result.first_hits[size_t(row) * r.width + col];
            FirstHitSums& dst = sums_[size_t(r.y + row) * width_ + r.x + col];
            for (int c = 0; c < 3; ++c) {
                dst.albedo[c] += src.albedo[c];
                dst.normal[c] += src.normal[c];
            }
        }
}

Image AuxSums::means(const Accumulator& merged, bool normal) const {
    if (!kept() || merged.pixel_count() != sums_.size()) return {};
    Image img(width_, height_);
    for (size_t i = 0; i < sums_.size(); ++i) {
        const uint64_t n = merged.samples(i);
        const double inv = n ? 1.0 / double(n) : 0.0;
        const double* sum = normal ? sums_[i].normal : sums_[i].albedo;
        for (int c = 0; c < 3; ++c) img.rgb[3 * i + c] = float(sum[c] * inv);
    }
    return img;
}

Image AuxSums::albedo(const Accumulator& merged) const { return means(merged, false); }
Image AuxSums::normal(const Accumulator& merged) const { return means(merged, true); }

void AuxSums::add_layers(const Accumulator& merged, Image& image) const {
    if (!kept()) return;
    for (bool normal : {false, true}) {
        const Image m = means(merged, normal);
        if (m.pixel_count() != image.pixel_count()) return;
        for (int c = 0; c < 3; ++c) {
            Image::Channel ch{normal ? kNormalChannels[c] : kAlbedoChannels[c],
                              std::vector<float>(m.pixel_count())};
            for (size_t i = 0; i < m.pixel_count(); ++i) ch.values[i] = m.rgb[3 * i + c];
            image.extra.push_back(std::move(ch));
        }
    }
}

void merge_with_aux(Accumulator& merged, AuxSums& aux, const SampleJobResult& result) {
    add_with_aux(merged, aux, result, check_with_aux(merged, aux, result));
}

ResultTotals check_with_aux(Accumulator& merged, const AuxSums& aux,
                            const SampleJobResult& result, const uint32_t* counts) {
    aux.check(result);  // the colour's check also checks the rectangle
    return merged.check(result, counts);
}

void add_with_aux(Accumulator& merged, AuxSums& aux, const SampleJobResult& result,
                  const ResultTotals& totals) {
    merged.add(result, totals);
    aux.add(result);
}

}  // namespace aliquot
