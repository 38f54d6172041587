// Round digest: what a change that should leave every decision alone (a faster round end)
// is checked against. Each method renders a synthetic image (noise, fireflies and ray
// costs that vary over it) through the farm's round cutting; each round's per-pixel
// counts, the jobs it was cut into, the error estimate after it and the final buffers are
// hashed. Two builds that print the same lines planned the same renders, bit for bit.
// With THREADS, the round end's passes run on that many threads (bands.h).
//
// With PLAN_AHEAD, optimal's plan_ahead is that (0: every round planned after the one
// before has merged, as before plan_ahead existed).
//
// Usage: round_digest [WxH] [method,...] [threads] [spp] [plan_ahead]
//        (defaults: 480x270 uniform,dammertz,adaptive,optimal,optimal-time,cycles,
//        the machine's threads, 128 spp of budget, the default plan_ahead)
#include <cstdio>
#include <cstring>
#include <sstream>
#include <string>
#include <vector>

#include "bands.h"
#include "error_estimate.h"
#include "resolution.h"
#include "round_cutter.h"
#include "strategy_params.h"
#include "synthetic_source.h"

using namespace aliquot;

namespace {

struct Digest {
    uint64_t h = 1469598103934665603ull;  // FNV-1a
    void add(const void* data, size_t bytes) {
        const unsigned char* p = static_cast<const unsigned char*>(data);
        for (size_t i = 0; i < bytes; ++i) h = (h ^ p[i]) * 1099511628211ull;
    }
    template <typename T>
    void add(const T& v) {
        add(&v, sizeof v);
    }
};

SyntheticImage scene(uint32_t w, uint32_t h) {
    SyntheticImage image(w, h, 7);
    for (uint32_t y = 0; y < h; ++y)
        for (uint32_t x = 0; x < w; ++x) {
            SyntheticPixel& p = image.at(x, y);
            p.mean = 0.2 + 0.6 * double(x) / w;
            p.sigma = (x / 16 + y / 16) % 3 == 0 ? 0.5 : 0.05 * (1 + y % 7);
            p.rays = 1 + (x * 7 + y * 3) % 5;
            if ((x * 13 + y * 29) % 97 == 0) {
                p.firefly_probability = 0.02;
                p.firefly_value = 40;
            }
        }
    return image;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc > 1 && (std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h")) {
        std::puts(
            "usage: round_digest [WxH] [method,...] [threads] [spp] [plan_ahead]\n"
            "prints a line a round of each method; two builds printing the same lines\n"
            "planned the same renders, bit for bit");
        return 0;
    }
    const Resolution size = parse_resolution(argc > 1 ? argv[1] : "480x270");
    std::vector<std::string> methods;
    std::stringstream list(
        argc > 2 ? argv[2] : "uniform,dammertz,adaptive,optimal,optimal-time,cycles");
    for (std::string m; std::getline(list, m, ',');) methods.push_back(m);
    if (argc > 3) set_band_threads(unsigned(std::atoi(argv[3])));
    const uint64_t spp = argc > 4 ? std::strtoull(argv[4], nullptr, 10) : 128;
    const SyntheticImage image = scene(size.width, size.height);
    for (const std::string& method : methods) {
        StrategyParams params;
        params.method = method;
        params.budget = spp * size.width * size.height;
        params.max_variance = 1e-5;
        params.max_spp = 1024;
        if (argc > 5) params.plan_ahead = std::strtod(argv[5], nullptr);
        const auto strategy = make_strategy(params, size.width, size.height);
        Accumulator merged(size.width, size.height);
        Digest all;
        const SyntheticRun run = run_synthetic(
            *strategy, image, merged, 40, [&](const Round& round, const Accumulator& m) {
                Digest d;
                d.add(round.spp.data(), round.spp.size() * sizeof(uint32_t));
                const double e = estimate_mean_abs_error(m);
                d.add(e);
                all.add(d.h);
                std::printf("%s round %u: %016llx  samples %llu  estimate %.17g\n",
                            method.c_str(), round.index, (unsigned long long)d.h,
                            (unsigned long long)round.total(), e);
            });
        // Cutting, on the last buffers, at every tile size.
        Round even{0, std::vector<uint32_t>(merged.pixel_count(), 3)};
        for (uint32_t tile : {0u, 16u, 32u, 64u, 128u})
            for (const SampleJob& job : cut_round(even, merged, tile)) {
                all.add(job.rect);
                all.add(job.counts.data(), job.counts.size() * sizeof(uint32_t));
                all.add(job.first_sample.data(),
                        job.first_sample.size() * sizeof(job.first_sample[0]));
            }
        Accumulator copy;
        copy.copy_from(merged);
        for (size_t i = 0; i < copy.pixel_count(); ++i) all.add(copy.at(i));
        std::printf("%s: %u rounds%s, digest %016llx\n", method.c_str(), run.rounds,
                    run.finished ? "" : " (cut at 40)", (unsigned long long)all.h);
    }
}
