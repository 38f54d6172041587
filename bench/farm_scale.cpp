// The coordinator at farm scale: one Coordinator (with a data directory, so rounds are
// recorded and checkpointed as in production) fed by N simulated workers, threads of this
// process that lease a job, make a valid synthetic result at once (synthetic_result.h)
// and complete it. Nothing is traced, so the coordinator is the only thing that can be
// slow. A result goes through the wire as a worker's does: the simulated worker encodes
// it (wire.h's to_proto, serialized: the worker's cost, not counted below) and the
// coordinator's side parses them and decodes them (from_proto_in_place) as the gRPC
// server's Complete does, which is counted: only gRPC's transport is left out. For each
// method and worker count, until the render ends or the time is up: pixel-samples merged
// per second, leases per second, and the Lease and Complete latencies (median and 99th
// percentile) of the calls that got a job; round_end_share is the seconds the coordinator
// spent ending rounds (Coordinator::round_end_seconds) ÷ the render's; round_end_ms and
// round_end_cpu_ms are one round end's wall and CPU time (the CPU time is what it costs
// however loaded the machine is); round_end_wait_share and round_end_wait_ms count only
// the round ends the workers waited through, those after which the next round had not
// been opened ahead (docs/FARM.md, "Two rounds out"). One JSON object per line.
//
// With a RATE (samples a second), each simulated worker takes as long as a worker core
// that traces at that rate would (it sleeps out the rest of samples ÷ RATE after making
// the result): N of them are a farm of N such cores that costs this machine no tracing,
// and the wait shares are those of a real farm of that size. plan_wait_share is the time
// the render had no job to lease because a plan made ahead was late (every job of the
// round out leased: RenderSession::plan_wait_seconds) ÷ the render's; with the waited
// round ends, what the farm waited on the coordinator. largest_round_wait_share is then
// the round that waited on it the most: the waited round end that opened it and its late
// plan ÷ its seconds, that round end included (read by polling the coordinator's
// counters every 2 ms, as bench/round_end_share.sh does every 20), and farm_efficiency
// the samples merged a second ÷ (N × RATE): what the farm traced of what it could have,
// every idle moment counted (round ends, a round planned ahead that is late, a round's
// last jobs, and this process's own CPU for the synthetic results). worker_wait_share
// splits it: the workers' seconds in Lease (no job to trace: round ends, late plans, a
// round's last jobs, the cap on the round ahead) ÷ (N × the render's seconds), the farm's
// own idling; what farm_efficiency loses beyond it is each job's time past its pace
// (making and encoding its result when that outlasts the pace, Complete, a late wake on
// this machine's cores), which a worker's courier (worker/courier.h) mostly hides.
//
// coordinator_cpu_s_per_g_samples is the coordinator's CPU seconds for each 10^9
// pixel-samples merged, whatever the machine's cores or load: the process's CPU time
// (getrusage) over the render, less what the simulated workers spent making and encoding
// their synthetic results and what this bench's own polling thread spent (each thread's
// clock). So it holds leases, merges and round ends on every thread (the calls' threads,
// the band pool, plans made ahead, the record writer). worker_cores_per_coordinator_core
// is then how many worker cores tracing RATE samples a second (2 M without one, about
// today's worker core) one coordinator core keeps fed: 10^9 ÷ (that × RATE).
// wire_cpu_s_per_g_samples is the part of it the results' parse and decode took (each
// calling thread's clock), so a run compares with a build from before the wire was
// counted by the difference.
//
// The budget is SPP samples a pixel on average (uniform: SPP a pixel); issue 33 asks for
// 64 to 1024. With RENDERS, that many such renders are submitted at once and the workers
// serve them all (issue 33: 16 concurrent renders at 256 workers); samples, rounds and
// plan waits are then their sums, the seconds those until the last ended, and
// largest_round_wait_share is not measured (0).
//
// Usage: farm_scale [WxH] [seconds] [workers,...] [method,...] [rate] [spp] [renders]
//        (defaults: 1920x1080 10 1,16,64,256
//        uniform,dammertz,adaptive,optimal,optimal-time 0 64 1)
// A method written `optimal:K` (or `optimal-time:K`) runs with steer_rounds K, and
// `optimal/P` with plan_ahead P (both: `optimal:K/P`).
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "coordinator.h"
#include "resolution.h"
#include "scene_loader.h"
#include "synthetic_result.h"
#include "wire.h"

using namespace aliquot;
using Clock = std::chrono::steady_clock;

namespace {

std::vector<std::string> split(const std::string& text) {
    std::vector<std::string> out;
    std::stringstream in(text);
    for (std::string item; std::getline(in, item, ',');)
        if (!item.empty()) out.push_back(item);
    return out;
}

// CPU seconds of the calling thread, and of the whole process.
double thread_cpu() {
    timespec t{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}
double process_cpu() {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    const auto seconds = [](const timeval& t) {
        return double(t.tv_sec) + 1e-6 * double(t.tv_usec);
    };
    return seconds(u.ru_utime) + seconds(u.ru_stime);
}

double percentile(std::vector<double> v, double q) {
    if (v.empty()) return 0;
    std::sort(v.begin(), v.end());
    return v[std::min(v.size() - 1, size_t(q * double(v.size())))];
}

struct Run {
    std::string method;
    int workers = 0;
    double seconds = 0;
    uint64_t samples = 0, leases = 0;
    uint32_t rounds = 0;
    double round_end_seconds = 0, round_end_cpu_seconds = 0, round_end_wait_seconds = 0;
    double plan_wait_seconds = 0;
    std::string state;
    std::vector<double> lease_ms, complete_ms;
    double largest_round_wait_share = 0;
    double coordinator_cpu_seconds = 0;  // see the top of this file
    double worker_wait_seconds = 0;      // the workers' seconds in Lease, all summed
    double wire_cpu_seconds =
        0;  // of coordinator_cpu_seconds: parsing and decoding results
};

// "optimal:K/P": the method, steer_rounds K and plan_ahead P, each optional.
void parse_method(const std::string& text, StrategyParams& p) {
    const size_t slash = text.find('/');
    const std::string head = text.substr(0, slash);
    const size_t colon = head.find(':');
    p.method = head.substr(0, colon);
    if (colon != std::string::npos) {
        const std::string k = head.substr(colon + 1);
        if (k.empty() || k.size() > 2 ||
            k.find_first_not_of("0123456789") != std::string::npos)
            throw std::invalid_argument("in " + text +
                                        ", K (steer_rounds) must be 0 to 99");
        p.steer_rounds = uint32_t(std::stoul(k));
    }
    if (slash != std::string::npos) {
        size_t used = 0;
        const std::string f = text.substr(slash + 1);
        p.plan_ahead = std::stod(f, &used);
        if (used != f.size() || !(p.plan_ahead >= 0 && p.plan_ahead <= 1))
            throw std::invalid_argument("in " + text + ", P (plan_ahead) must be 0 to 1");
    }
}

Run run(uint32_t width, uint32_t height, const std::string& method, int workers,
        double seconds, double rate, uint32_t spp, int renders) {
    namespace fs = std::filesystem;
    const fs::path dir =
        fs::temp_directory_path() / ("aliquot-farm-scale-" + std::to_string(getpid()));
    fs::remove_all(dir);
    Run out;
    out.method = method;
    out.workers = workers;
    {
        CoordinatorOptions options;
        options.data_dir = dir;
        Coordinator coordinator(options);
        RenderSpec spec;
        spec.scene_name = "cornell-box";
        spec.scene_json = self_contained_scene_json("cornell-box");
        spec.width = width;
        spec.height = height;
        parse_method(method, spec.strategy);
        spec.strategy.budget = uint64_t(spp) * width * height;  // spp on average
        spec.strategy.max_variance = 1e-4;  // dammertz: keep splitting past a few rounds
        // The submission (the render's buffers) is the coordinator's CPU, not the
        // poller's.
        const double process_began = process_cpu();
        std::vector<std::string> ids;
        for (int k = 0; k < renders; ++k) ids.push_back(coordinator.submit(spec));
        const std::string& id = ids.front();
        const double poller_began = thread_cpu();
        const auto all_ended = [&] {
            for (const std::string& each : ids)
                if (!is_terminal(coordinator.info(each)->state)) return false;
            return true;
        };

        std::atomic<bool> stop{false};
        double synthetic_cpu = 0;  // the simulated workers' own work, under `mutex`
        std::string broken;        // why a result did not come through, under `mutex`
        std::mutex mutex;
        const auto start = Clock::now();
        std::vector<std::thread> threads;
        for (int w = 0; w < workers; ++w)
            threads.emplace_back([&, w] {
                const std::string session =
                    coordinator.register_worker("sim-" + std::to_string(w), 1).session;
                std::vector<double> leases, completes;
                double made = 0;     // CPU seconds making synthetic results
                double waiting = 0;  // seconds in Lease: no job to trace
                double wire = 0;     // CPU seconds parsing and decoding results
                while (!stop) {
                    const auto asked = Clock::now();
                    auto grant =
                        coordinator.lease(session, std::chrono::milliseconds(100));
                    const auto granted = Clock::now();
                    waiting += std::chrono::duration<double>(granted - asked).count();
                    if (!grant) continue;
                    // What a worker's Complete puts on the wire: making and encoding
                    // it (and freeing all of it but the bytes) is the worker's work.
                    const double making = thread_cpu();
                    std::string bytes;
                    uint64_t samples = 0;  // the bench's own
                    {
                        const SampleJobResult result = bench::synthetic_result(*grant);
                        samples = result.total_samples();
                        v1::SampleJobResult message;
                        to_proto(result, message);
                        bytes = message.SerializeAsString();
                    }
                    made += thread_cpu() - making;
                    if (rate > 0)
                        std::this_thread::sleep_until(
                            granted +
                            std::chrono::duration_cast<Clock::duration>(
                                std::chrono::duration<double>(double(samples) / rate)));
                    const auto sent = Clock::now();
                    // As the gRPC server's Complete: parsed, decoded in place, merged
                    // from the parsed message, which is freed after (counted as the
                    // wire's). A result that does not come through is this bench's bug:
                    // the run stops.
                    try {
                        double decoding = thread_cpu();
                        auto received = std::make_unique<v1::SampleJobResult>();
                        if (!received->ParseFromString(bytes))
                            throw WireError("the result's bytes do not parse");
                        SampleJobResult decoded;
                        from_proto_in_place(*received, decoded);
                        wire += thread_cpu() - decoding;
                        coordinator.complete(session, grant->lease_id,
                                             std::as_const(decoded));
                        decoding = thread_cpu();
                        received.reset();
                        wire += thread_cpu() - decoding;
                    } catch (const std::exception& e) {
                        std::lock_guard lock(mutex);
                        broken = e.what();
                        stop = true;
                    }
                    const double freeing = thread_cpu();  // the worker's bytes
                    std::string().swap(bytes);
                    made += thread_cpu() - freeing;
                    const auto done = Clock::now();
                    leases.push_back(
                        std::chrono::duration<double, std::milli>(granted - asked)
                            .count());
                    completes.push_back(
                        std::chrono::duration<double, std::milli>(done - sent).count());
                }
                std::lock_guard lock(mutex);
                synthetic_cpu += made;
                out.wire_cpu_seconds += wire;
                out.worker_wait_seconds += waiting;
                out.lease_ms.insert(out.lease_ms.end(), leases.begin(), leases.end());
                out.complete_ms.insert(out.complete_ms.end(), completes.begin(),
                                       completes.end());
            });
        uint64_t seen = 0;
        uint32_t rounds_seen = 0;
        double waited = 0;        // the waited round-end seconds counted so far
        double opening_wait = 0;  // of the round end that opened the round out
        auto round_began = start;
        while (Clock::now() - start < std::chrono::duration<double>(seconds) &&
               !all_ended()) {
            seen = coordinator.wait_for_change(seen, std::chrono::milliseconds(2));
            if (renders > 1) continue;  // the rounds' waits are one render's
            const uint32_t rounds = coordinator.info(id)->rounds_done;
            if (rounds == rounds_seen) continue;
            // A round has ended (and the round end has run: info waits for the render's
            // lock). Its seconds include the waited round end that opened it.
            const auto now = Clock::now();
            if (rounds_seen > 0)
                out.largest_round_wait_share = std::max(
                    out.largest_round_wait_share,
                    opening_wait /
                        (std::chrono::duration<double>(now - round_began).count() +
                         opening_wait));
            // The counter is added to just after the render's lock is let go. A round's
            // wait on the coordinator is also the plan made ahead that was late.
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
            const double counted = coordinator.round_end_wait_seconds() +
                                   coordinator.plan_wait_seconds(id).value_or(0);
            opening_wait = counted - waited;
            waited = counted;
            round_began = now;
            rounds_seen = rounds;
        }
        out.seconds = std::chrono::duration<double>(Clock::now() - start).count();
        out.state = "done";
        for (const std::string& each : ids) {
            const RenderInfo info = *coordinator.info(each);
            out.samples += info.samples_done;
            out.rounds += info.rounds_done;
            if (info.state != RenderState::Done)
                out.state = std::string(to_string(info.state));
            out.plan_wait_seconds += coordinator.plan_wait_seconds(each).value_or(0);
        }
        const double poller_cpu = thread_cpu() - poller_began;
        stop = true;
        coordinator.stop();
        for (std::thread& t : threads) t.join();
        if (!broken.empty())
            throw std::runtime_error("a simulated worker's result: " + broken);
        // After the joins: every synthetic result counted. What the workers did between
        // the render's end and `stop` is a few empty leases.
        out.coordinator_cpu_seconds =
            process_cpu() - process_began - synthetic_cpu - poller_cpu;
        out.round_end_seconds = coordinator.round_end_seconds();
        out.round_end_cpu_seconds = coordinator.round_end_cpu_seconds();
        out.round_end_wait_seconds = coordinator.round_end_wait_seconds();
        out.leases = out.lease_ms.size();
    }
    fs::remove_all(dir);
    return out;
}

}  // namespace

constexpr const char* kUsage =
    "usage: farm_scale [WxH] [seconds] [workers,...] [method[:K][/P],...] [rate] [spp] "
    "[renders]\n";

int main(int argc, char** argv) try {
    if (argc > 1 && (std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h")) {
        std::fputs(kUsage, stdout);
        return 0;
    }
    const Resolution size = parse_resolution(argc > 1 ? argv[1] : "1920x1080");
    const double seconds = argc > 2 ? std::atof(argv[2]) : 10;
    std::vector<int> counts;
    for (const std::string& n : split(argc > 3 ? argv[3] : "1,16,64,256"))
        counts.push_back(std::max(1, std::atoi(n.c_str())));
    const std::vector<std::string> methods =
        split(argc > 4 ? argv[4] : "uniform,dammertz,adaptive,optimal,optimal-time");
    const double rate = argc > 5 ? std::atof(argv[5]) : 0;
    const int spp = argc > 6 ? std::atoi(argv[6]) : 64;
    if (spp < 1 || spp > 65536) throw std::invalid_argument("spp must be 1 to 65536");
    const int renders = argc > 7 ? std::atoi(argv[7]) : 1;
    if (renders < 1 || renders > 256)
        throw std::invalid_argument("renders must be 1 to 256");
    for (const std::string& method : methods)
        for (const int workers : counts) {
            const Run r = run(size.width, size.height, method, workers, seconds, rate,
                              uint32_t(spp), renders);
            const double per_g =
                r.samples ? r.coordinator_cpu_seconds / (double(r.samples) * 1e-9) : 0.0;
            std::printf(
                "{\"image\": \"%ux%u\", \"spp\": %d, \"renders\": %d, \"method\": "
                "\"%s\", \"workers\": "
                "%d, "
                "\"seconds\": %.2f, \"state\": \"%s\", \"rounds\": %u, "
                "\"pixel_samples_per_second\": %.0f, \"leases_per_second\": %.0f, "
                "\"lease_ms_p50\": %.3f, \"lease_ms_p99\": %.3f, "
                "\"complete_ms_p50\": %.3f, \"complete_ms_p99\": %.3f, "
                "\"round_end_share\": %.4f, \"round_end_ms\": %.1f, "
                "\"round_end_cpu_ms\": %.1f, \"round_end_wait_share\": %.4f, "
                "\"round_end_wait_ms\": %.1f, \"plan_wait_share\": %.4f, "
                "\"largest_round_wait_share\": %.4f, \"farm_efficiency\": %.3f, "
                "\"coordinator_cpu_s_per_g_samples\": %.2f, "
                "\"worker_cores_per_coordinator_core\": %.0f, \"worker_wait_share\": "
                "%.4f, \"wire_cpu_s_per_g_samples\": %.2f}\n",
                size.width, size.height, spp, renders, method.c_str(), workers, r.seconds,
                r.state.c_str(), r.rounds, double(r.samples) / r.seconds,
                double(r.leases) / r.seconds, percentile(r.lease_ms, 0.5),
                percentile(r.lease_ms, 0.99), percentile(r.complete_ms, 0.5),
                percentile(r.complete_ms, 0.99), r.round_end_seconds / r.seconds,
                r.rounds ? 1e3 * r.round_end_seconds / r.rounds : 0.0,
                r.rounds ? 1e3 * r.round_end_cpu_seconds / r.rounds : 0.0,
                r.round_end_wait_seconds / r.seconds,
                r.rounds ? 1e3 * r.round_end_wait_seconds / r.rounds : 0.0,
                r.plan_wait_seconds / r.seconds, r.largest_round_wait_share,
                rate > 0 ? double(r.samples) / r.seconds / (workers * rate) : 0.0, per_g,
                per_g > 0 ? 1e9 / (per_g * (rate > 0 ? rate : 2e6)) : 0.0,
                r.worker_wait_seconds / (r.seconds * workers),
                r.samples ? r.wire_cpu_seconds / (double(r.samples) * 1e-9) : 0.0);
            std::fflush(stdout);
        }
} catch (const std::exception& e) {
    std::fprintf(stderr, "farm_scale: %s\n%s", e.what(), kUsage);
    return 2;
}
