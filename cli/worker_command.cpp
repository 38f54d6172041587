// aliquot worker: pulls sample jobs from a coordinator until SIGTERM / SIGINT, then gives
// back what it holds.
#include <unistd.h>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <memory>
#include <thread>

#include "commands.h"
#include "endpoint_options.h"
#include "grpc_link.h"
#include "health_file.h"
#include "log_format_option.h"
#include "log_line.h"
#include "whole_number_option.h"
#include "worker_loop.h"

namespace aliquot::cli {

namespace {

struct WorkerCommand {
    EndpointOptions coordinator;
    int threads = 0;
    std::string name;
    std::string health_file;  // empty: none

    void run() {
        if (threads < 0) throw UsageError("--threads: must be 0 or more");
        if (threads == 0)
            threads = int(std::max(1u, std::thread::hardware_concurrency()));
        if (name.empty()) {
            char host[256] = {0};
            gethostname(host, sizeof host - 1);
            name = std::string(host) + "-" + std::to_string(getpid());
        }
        sigset_t stop;
        sigemptyset(&stop);
        sigaddset(&stop, SIGTERM);
        sigaddset(&stop, SIGINT);
        pthread_sigmask(SIG_BLOCK, &stop, nullptr);

        GrpcLink link(coordinator.resolve(Role::Worker));
        WorkerLoop loop(link, {name, threads, std::chrono::milliseconds(2000), false});
        std::unique_ptr<HealthFile> health;
        try {
            if (!health_file.empty())
                health = std::make_unique<HealthFile>(
                    health_file, [&loop] { return loop.stalest_beat(); });
        } catch (const std::runtime_error& e) {
            throw CommandError(e.what());
        }
        std::atomic<bool> refused{false};
        std::thread waiter([&] {
            int sig = 0;
            sigwait(&stop, &sig);
            if (!refused)
                write_log_line("worker_stopping", {log_text("worker", name),
                                                   log_number("signal", int64_t(sig))});
            loop.stop();
        });
        try {
            loop.run();
        } catch (const std::exception& e) {
            // The token was refused, or a thread could not start or go on: wake the
            // waiter, then end with the reason (non-zero: a supervisor restarts us).
            refused = true;
            pthread_kill(waiter.native_handle(), SIGINT);
            waiter.join();
            throw CommandError(e.what());
        }
        waiter.join();
        write_log_line("worker_stopped",
                       {log_text("worker", name),
                        log_number("samples_traced", int64_t(loop.samples_traced())),
                        log_number("jobs", int64_t(loop.jobs_done()))});
    }
};

}  // namespace

void register_worker(CLI::App& app) {
    auto c = std::make_shared<WorkerCommand>();
    CLI::App* cmd = app.add_subcommand("worker", "trace sample jobs for a coordinator");
    c->coordinator.add_to(*cmd, Role::Worker);
    // A worker is long-lived: it retries its coordinator for as long as it runs, so only
    // the token file is waited for.
    cmd->get_option("--connect-timeout")
        ->description(
            "seconds to wait for the implicit token file aliquot-data/worker.token to "
            "appear; the coordinator itself is retried for as long as the worker runs");
    cmd->add_option("--threads", c->threads, "tracing threads (0: all cores)")
        ->check(whole_number());
    cmd->add_option("--name", c->name, "worker name (default: host-pid)");
    add_log_format_option(*cmd);
    cmd->add_option("--health-file", c->health_file,
                    "a file whose modification time the worker keeps at the moment all "
                    "its threads were last known not stuck, for liveness probes "
                    "(deploy/healthcheck.sh; docs/DEPLOY.md)");
    cmd->callback([c] { c->run(); });
}

}  // namespace aliquot::cli
