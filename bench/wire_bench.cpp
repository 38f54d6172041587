// What one SampleJobResult costs on the wire, per pixel: the worker's encode (wire.h's
// to_proto, then the message serialized) and the coordinator's decode (the bytes parsed
// as the gRPC server's Complete receives them, then from_proto_in_place, as Complete
// reads them; decode_copy also copies the sums out, as from_proto does and as a result
// held for the round ahead is), each in CPU time of this thread, the least of several
// passes. The sums vary per pixel like a render's (no run of
// equal values a codec could exploit). Prints one JSON object per job size.
//
// Usage: wire_bench [side,...] [spp] [aux 0|1]  (defaults: 16,64,256 64 0)
#include <time.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

#include "aliquot.pb.h"
#include "wire.h"

using namespace aliquot;

namespace {

double thread_cpu() {
    timespec t{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

SampleJobResult made_result(uint32_t side, uint32_t spp, bool aux) {
    SampleJobResult r;
    r.rect = {64, 32, side, side};
    r.pixels.resize(r.rect.size());
    for (size_t i = 0; i < r.pixels.size(); ++i) {
        PixelSums& p = r.pixels[i];
        const double radiance = 0.2 + 0.6 * double(i % 97) / 97.0;
        for (int c = 0; c < 3; ++c) {
            p.even[c] = 0.5 * spp * radiance * (1 + 0.01 * c + 1e-3 * double(i % 13));
            p.odd[c] = 0.5 * spp * radiance * (1 - 0.01 * c - 1e-3 * double(i % 7));
        }
        p.sum_sq_luminance = spp * radiance * radiance * 1.0625;
        p.samples = spp;
        p.rays = 3 * spp + i % 11;
        p.nonfinite = i % 101 == 0;
    }
    if (aux) {
        r.first_hits.resize(r.pixels.size());
        for (size_t i = 0; i < r.first_hits.size(); ++i)
            for (int c = 0; c < 3; ++c) {
                r.first_hits[i].albedo[c] = spp * (0.3 + 0.001 * double((i + c) % 89));
                r.first_hits[i].normal[c] =
                    spp * (-0.5 + 0.01 * double((i * 3 + c) % 83));
            }
    }
    r.wall_seconds = 0.25;
    return r;
}

}  // namespace

int main(int argc, char** argv) {
    std::vector<uint32_t> sides;
    std::stringstream list(argc > 1 ? argv[1] : "16,64,256");
    for (std::string s; std::getline(list, s, ',');)
        sides.push_back(uint32_t(std::stoul(s)));
    const uint32_t spp = argc > 2 ? uint32_t(std::atoi(argv[2])) : 64;
    const bool aux = argc > 3 && std::atoi(argv[3]) != 0;
    for (const uint32_t side : sides) {
        const SampleJobResult result = made_result(side, spp, aux);
        const double pixels = double(result.pixels.size());
        // About 4 M pixels a pass, so small jobs are timed over many.
        const int reps = std::max(1, int(4e6 / pixels));
        double encode = 1e30, decode = 1e30, decode_copy = 1e30;
        std::string bytes;
        size_t merged = 0;  // keeps the decode from being optimised away
        for (int pass = 0; pass < 5; ++pass) {
            double began = thread_cpu();
            for (int k = 0; k < reps; ++k) {
                v1::SampleJobResult message;
                to_proto(result, message);
                bytes.clear();
                message.SerializeToString(&bytes);
            }
            encode = std::min(encode, (thread_cpu() - began) / (reps * pixels));
            began = thread_cpu();
            for (int k = 0; k < reps; ++k) {
                v1::SampleJobResult message;
                if (!message.ParseFromString(bytes)) return 1;
                SampleJobResult in_place;
                from_proto_in_place(message, in_place);
                merged += in_place.pixels.size();
            }
            decode = std::min(decode, (thread_cpu() - began) / (reps * pixels));
            began = thread_cpu();
            for (int k = 0; k < reps; ++k) {
                v1::SampleJobResult message;
                if (!message.ParseFromString(bytes)) return 1;
                merged += from_proto(message).pixels.size();
            }
            decode_copy = std::min(decode_copy, (thread_cpu() - began) / (reps * pixels));
        }
        if (merged == 0) return 1;
        std::printf(
            "{\"job\": \"%ux%u\", \"spp\": %u, \"aux\": %d, \"wire_version\": %u, "
            "\"bytes_per_pixel\": %.1f, \"encode_ns_per_pixel\": %.1f, "
            "\"decode_ns_per_pixel\": %.1f, \"decode_copy_ns_per_pixel\": %.1f}\n",
            side, side, spp, int(aux), kWireVersion, double(bytes.size()) / pixels,
            1e9 * encode, 1e9 * decode, 1e9 * decode_copy);
    }
}
