#include "wire.h"

#include <string>

namespace aliquot {

namespace {

void to_proto(const PixelRect& r, v1::PixelRect& out) {
    out.set_x(r.x);
    out.set_y(r.y);
    out.set_width(r.width);
    out.set_height(r.height);
}

PixelRect from_proto(const v1::PixelRect& r) {
    // Bounded so that width * height cannot overflow and a message cannot ask for a
    // rectangle larger than any image.
    if (r.width() > 65536 || r.height() > 65536)
        throw WireError("rectangle " + std::to_string(r.width()) + "x" +
                        std::to_string(r.height()) + " is too large");
    return {r.x(), r.y(), r.width(), r.height()};
}

void expect_size(const char* field, size_t got, size_t want) {
    if (got != want)
        throw WireError(std::string(field) + " has " + std::to_string(got) +
                        " values, expected " + std::to_string(want));
}

}  // namespace

void to_proto(const SampleJob& job, v1::SampleJob& out) {
    to_proto(job.rect, *out.mutable_rect());
    out.mutable_counts()->Assign(job.counts.begin(), job.counts.end());
    out.mutable_first_sample()->Assign(job.first_sample.begin(), job.first_sample.end());
    out.set_aux(job.aux);
}

SampleJob from_proto(const v1::SampleJob& in) {
    SampleJob job;
    job.rect = from_proto(in.rect());
    expect_size("counts", size_t(in.counts_size()), job.rect.size());
    expect_size("first_sample", size_t(in.first_sample_size()), job.rect.size());
    job.counts.assign(in.counts().begin(), in.counts().end());
    job.first_sample.assign(in.first_sample().begin(), in.first_sample().end());
    job.aux = in.aux();
    return job;
}

void to_proto(const SampleJobResult& result, v1::SampleJobResult& out) {
    to_proto(result.rect, *out.mutable_rect());
    const size_t n = result.pixels.size();
    auto* even = out.mutable_sum_even();
    auto* odd = out.mutable_sum_odd();
    even->Reserve(int(3 * n));
    odd->Reserve(int(3 * n));
    for (const PixelSums& p : result.pixels) {
        for (int c = 0; c < 3; ++c) {
            even->Add(p.even[c]);
            odd->Add(p.odd[c]);
        }
        out.add_sum_sq_luminance(p.sum_sq_luminance);
        out.add_samples(p.samples);
        out.add_rays(p.rays);
        out.add_nonfinite(p.nonfinite);
    }
    out.set_wall_seconds(result.wall_seconds);
    out.set_version(kWireVersion);
    if (!result.first_hits.empty()) {
        auto* albedo = out.mutable_sum_albedo();
        auto* normal = out.mutable_sum_normal();
        albedo->Reserve(int(3 * n));
        normal->Reserve(int(3 * n));
        for (const FirstHitSums& f : result.first_hits)
            for (int c = 0; c < 3; ++c) {
                albedo->Add(f.albedo[c]);
                normal->Add(f.normal[c]);
            }
    }
}

SampleJobResult from_proto(const v1::SampleJobResult& in) {
    if (in.version() != kWireVersion)
        throw WireError("result of wire protocol version " +
                        std::to_string(in.version()) +
                        ", this coordinator speaks version " +
                        std::to_string(kWireVersion) + ": update the worker");
    SampleJobResult result;
    result.rect = from_proto(in.rect());
    const size_t n = result.rect.size();
    expect_size("sum_even", size_t(in.sum_even_size()), 3 * n);
    expect_size("sum_odd", size_t(in.sum_odd_size()), 3 * n);
    expect_size("sum_sq_luminance", size_t(in.sum_sq_luminance_size()), n);
    expect_size("samples", size_t(in.samples_size()), n);
    expect_size("rays", size_t(in.rays_size()), n);
    expect_size("nonfinite", size_t(in.nonfinite_size()), n);
    result.pixels.resize(n);
    for (size_t i = 0; i < n; ++i) {
        PixelSums& p = result.pixels[i];
        for (int c = 0; c < 3; ++c) {
            p.even[c] = in.sum_even(int(3 * i + c));
            p.odd[c] = in.sum_odd(int(3 * i + c));
        }
        p.sum_sq_luminance = in.sum_sq_luminance(int(i));
        p.samples = in.samples(int(i));
        p.rays = in.rays(int(i));
        p.nonfinite = in.nonfinite(int(i));
    }
    result.wall_seconds = in.wall_seconds();
    // Whether the job asked for them is the coordinator's to check (AuxSums): here both
    // arrays are whole, or absent.
    if (in.sum_albedo_size() != 0 || in.sum_normal_size() != 0) {
        expect_size("sum_albedo", size_t(in.sum_albedo_size()), 3 * n);
        expect_size("sum_normal", size_t(in.sum_normal_size()), 3 * n);
        result.first_hits.resize(n);
        for (size_t i = 0; i < n; ++i)
            for (int c = 0; c < 3; ++c) {
                result.first_hits[i].albedo[c] = in.sum_albedo(int(3 * i + c));
                result.first_hits[i].normal[c] = in.sum_normal(int(3 * i + c));
            }
    }
    return result;
}

v1::CompleteStatus to_proto(CompleteStatus status) {
    switch (status) {
        case CompleteStatus::Merged:
            return v1::COMPLETE_STATUS_MERGED;
        case CompleteStatus::Ignored:
            return v1::COMPLETE_STATUS_IGNORED;
        case CompleteStatus::Rejected:
            return v1::COMPLETE_STATUS_REJECTED;
    }
    return v1::COMPLETE_STATUS_UNSPECIFIED;
}

CompleteStatus from_proto(v1::CompleteStatus status) {
    switch (status) {
        case v1::COMPLETE_STATUS_MERGED:
            return CompleteStatus::Merged;
        case v1::COMPLETE_STATUS_REJECTED:
            return CompleteStatus::Rejected;
        default:
            return CompleteStatus::Ignored;
    }
}

}  // namespace aliquot
