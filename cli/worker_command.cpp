// aliquot worker: pulls sample jobs from a coordinator until SIGTERM / SIGINT, then gives
// back what it holds.
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <memory>
#include <thread>

#include "commands.h"
#include "grpc_link.h"
#include "worker_loop.h"

namespace aliquot::cli {

namespace {

struct WorkerCommand {
    std::string coordinator = "127.0.0.1:7070";
    int threads = 0;
    std::string name;

    void run() {
        if (threads < 0) throw CommandError("--threads: must be 0 or more");
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

        GrpcLink link(coordinator);
        WorkerLoop loop(link, {name, threads, std::chrono::milliseconds(2000), false});
        std::thread waiter([&] {
            int sig = 0;
            sigwait(&stop, &sig);
            std::fprintf(stderr, "worker %s: stopping (signal %d)\n", name.c_str(), sig);
            loop.stop();
        });
        loop.run();
        waiter.join();
        std::fprintf(stderr, "worker %s: traced %llu samples in %llu jobs\n",
                     name.c_str(), (unsigned long long)loop.samples_traced(),
                     (unsigned long long)loop.jobs_done());
    }
};

}  // namespace

void register_worker(CLI::App& app) {
    auto c = std::make_shared<WorkerCommand>();
    CLI::App* cmd = app.add_subcommand("worker", "trace sample jobs for a coordinator");
    cmd->add_option("--coordinator", c->coordinator, "coordinator address host:port")
        ->capture_default_str();
    cmd->add_option("--threads", c->threads, "tracing threads (0: all cores)");
    cmd->add_option("--name", c->name, "worker name (default: host-pid)");
    cmd->callback([c] { c->run(); });
}

}  // namespace aliquot::cli
