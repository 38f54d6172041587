// aliquot coordinator: the long-running farm process. Stops cleanly on SIGTERM / SIGINT.
#include <sys/stat.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <vector>

#include "commands.h"
#include "grpc_server.h"
#include "http_server.h"
#include "log_format_option.h"
#include "log_line.h"
#include "metrics.h"
#include "token_file.h"
#include "whole_number_option.h"

namespace aliquot::cli {

namespace {

namespace fs = std::filesystem;

// The directory of the running executable, to find files shipped beside it.
fs::path executable_dir() {
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    return ec ? fs::current_path() : exe.parent_path();
}

// The built dashboard: the source tree's web/dist seen from build/bin, or an installed
// share/aliquot/web seen from bin/.
fs::path default_web_dir() {
    const fs::path bin = executable_dir();
    for (const fs::path& p :
         {bin / ".." / ".." / "web" / "dist", bin / ".." / "share" / "aliquot" / "web"})
        if (fs::exists(p / "index.html")) return fs::weakly_canonical(p);
    return bin / ".." / ".." / "web" / "dist";
}

// "512M", "2G", "1048576": bytes, with an optional K, M or G (powers of 1024).
uint64_t parse_bytes(const std::string& text) {
    const std::string why =
        "--memory-limit: expected bytes with an optional K, M or G, like 8G, got '" +
        text + "'";
    if (text.empty() || !std::isdigit(static_cast<unsigned char>(text[0])))
        throw UsageError(why);
    char* end = nullptr;
    errno = 0;
    const unsigned long long n = std::strtoull(text.c_str(), &end, 10);
    if (errno != 0) throw UsageError(why);
    std::string unit(end);
    if (!unit.empty() && (unit.back() == 'B' || unit.back() == 'b')) unit.pop_back();
    int shift = 0;
    if (unit.size() > 1) throw UsageError(why);
    if (!unit.empty()) {
        switch (std::toupper(static_cast<unsigned char>(unit[0]))) {
            case 'K':
                shift = 10;
                break;
            case 'M':
                shift = 20;
                break;
            case 'G':
                shift = 30;
                break;
            default:
                throw UsageError(why);
        }
    }
    if (n == 0 || n > (UINT64_MAX >> shift)) throw UsageError(why);
    return uint64_t(n) << shift;
}

// "90s", "30m", "1h", "2d" or plain seconds: how long workers are remembered unheard.
std::chrono::milliseconds parse_duration(const std::string& text, const char* option) {
    const std::string why = std::string(option) +
                            ": expected a duration like 90s, 30m, 1h or 2d (plain: "
                            "seconds), got '" +
                            text + "'";
    if (text.empty() || !std::isdigit(static_cast<unsigned char>(text[0])))
        throw UsageError(why);
    char* end = nullptr;
    errno = 0;
    const double n = std::strtod(text.c_str(), &end);
    const std::string unit(end);
    double seconds = 0;
    if (unit.empty() || unit == "s")
        seconds = n;
    else if (unit == "m")
        seconds = n * 60;
    else if (unit == "h")
        seconds = n * 3600;
    else if (unit == "d")
        seconds = n * 86400;
    else
        throw UsageError(why);
    // At most a year: a longer one is "for ever" in effect, and the milliseconds must
    // not overflow.
    if (errno != 0 || !(seconds > 0) || seconds > 366.0 * 86400) throw UsageError(why);
    return std::chrono::milliseconds(int64_t(seconds * 1000));
}

// The whole of a PEM file named by `option`.
std::string read_pem(const std::string& path, const char* option) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream text;
    text << in.rdbuf();
    if (!in || text.str().empty())
        throw CommandError(std::string(option) + ": cannot read " + path);
    return text.str();
}

// A role's token: from the file the operator named, else DATA/ROLE.token, made at the
// first start. Says where it is, never what it is.
std::string role_token(const std::string& file, const fs::path& data_dir, Role role) {
    const std::string name(to_string(role));
    try {
        if (!file.empty()) return read_token_file(file);
        bool created = false;
        const fs::path path = data_dir / (name + ".token");
        std::string token = load_or_create_token_file(path, created);
        write_log_line(created ? "token_written" : "token_read",
                       {log_text("role", name), log_text("path", path.string())});
        return token;
    } catch (const TokenError& e) {
        throw CommandError(e.what());
    }
}

struct CoordinatorCommand {
    std::string grpc_address = "127.0.0.1:7070";
    std::string data_dir = "aliquot-data";
    std::string http_address;  // empty: no HTTP API or dashboard
    std::string web_dir;       // empty: default_web_dir()
    std::vector<std::string>
        study_dirs;  // more places `aliquot study --out` wrote reports
    std::vector<std::string> allowed_hosts;            // --allow-host
    std::string client_token_file, worker_token_file;  // empty: DATA/ROLE.token
    std::string tls_cert, tls_key;                     // empty: plaintext
    double lease_seconds = 30;
    double lost_seconds = 10;
    uint32_t max_side = 8192;
    std::string memory_limit;  // empty: default_memory_limit()
    uint32_t max_job_failures = FailurePolicy{}.max_job_failures;
    bool fail_on_fewer_hosts = false;
    std::string forget_workers = "1h";
    size_t max_workers = CoordinatorOptions{}.max_workers;
    size_t max_workers_per_host = CoordinatorOptions{}.max_workers_per_host;
    double keep_days = 0;  // 0: finished renders are kept for ever
    bool grpc_reflection = false;

    void run() {
        // Written `!(x > 0)` so that "nan" is refused too.
        if (!(lease_seconds > 0)) throw UsageError("--lease-seconds: must be positive");
        if (!(lost_seconds > 0)) throw UsageError("--lost-seconds: must be positive");
        if (max_side == 0) throw UsageError("--max-resolution: must be 1 or more");
        if (max_job_failures == 0)
            throw UsageError("--max-job-failures: must be 1 or more");
        if (max_workers == 0) throw UsageError("--max-workers: must be 1 or more");
        if (max_workers_per_host == 0)
            throw UsageError("--max-workers-per-host: must be 1 or more");
        const std::chrono::milliseconds forget_after =
            parse_duration(forget_workers, "--forget-workers");
        if (!(keep_days >= 0 && keep_days <= 36500))
            throw UsageError("--keep-days: must be 0 (keep for ever) to 36500");
        const uint64_t memory =
            memory_limit.empty() ? default_memory_limit() : parse_bytes(memory_limit);
        // Block the stop signals before any thread starts, then wait for one below.
        sigset_t stop;
        sigemptyset(&stop);
        sigaddset(&stop, SIGTERM);
        sigaddset(&stop, SIGINT);
        pthread_sigmask(SIG_BLOCK, &stop, nullptr);

        if (tls_cert.empty() != tls_key.empty())
            throw UsageError("--tls-cert and --tls-key go together");
        // Everything the coordinator writes (record, images, checkpoints, tokens, study
        // reports) is its users' business: the owner's alone, whatever umask it was
        // started with. The Coordinator also sets the modes of what it makes, for
        // callers that keep their umask.
        ::umask(077);
        std::error_code ec;
        fs::create_directories(data_dir, ec);
        fs::permissions(data_dir, fs::perms::owner_all, ec);
        GrpcSecurity security;
        security.tokens = {role_token(client_token_file, data_dir, Role::Client),
                           role_token(worker_token_file, data_dir, Role::Worker)};
        if (!tls_cert.empty()) {
            security.tls_cert_pem = read_pem(tls_cert, "--tls-cert");
            security.tls_key_pem = read_pem(tls_key, "--tls-key");
        }

        CoordinatorOptions options;
        options.data_dir = data_dir;
        options.lease_time = std::chrono::milliseconds(int64_t(lease_seconds * 1000));
        options.worker_lost_after =
            std::chrono::milliseconds(int64_t(lost_seconds * 1000));
        options.max_side = max_side;
        options.memory_limit = memory;
        options.failure_policy.max_job_failures = max_job_failures;
        options.failure_policy.fail_on_fewer_hosts = fail_on_fewer_hosts;
        options.forget_workers_after = forget_after;
        options.max_workers = max_workers;
        options.max_worker_sessions = std::max(options.max_worker_sessions, max_workers);
        options.max_workers_per_host = max_workers_per_host;
        options.keep_finished =
            std::chrono::milliseconds(int64_t(keep_days * 24 * 3600 * 1000.0));
        Coordinator coordinator(options);
        // One registry for the process: the gRPC services observe into it, /metrics
        // serves it.
        FarmMetrics metrics(coordinator);
        GrpcServer server(coordinator, grpc_address, security,
                          {.metrics = &metrics, .reflection = grpc_reflection});
        write_log_line("listening",
                       {log_text("service", "grpc"), log_text("address", grpc_address),
                        log_number("port", int64_t(server.port())),
                        log_text("tls", security.tls_cert_pem.empty() ? "off" : "on"),
                        log_text("data", data_dir),
                        log_number("memory_limit_mib", int64_t(memory >> 20))});
        std::unique_ptr<HttpServer> http;
        if (!http_address.empty()) {
            HttpOptions http_options;
            // The same tokens as gRPC: the dashboard signs in with the client's.
            http_options.tokens = security.tokens;
            http_options.web_dir =
                web_dir.empty() ? default_web_dir() : fs::path(web_dir);
            // Study reports: the data directory's, then the --studies directories or, by
            // default from a build tree, the source tree's docs/studies and out/ (where
            // `aliquot study` writes unless told otherwise).
            http_options.allowed_hosts = allowed_hosts;
            // The dashboard and its API carry the same tokens and images as gRPC: under
            // TLS they are served over HTTPS with the same certificate.
            http_options.tls_cert = tls_cert;
            http_options.tls_key = tls_key;
            http_options.metrics = &metrics;
            http_options.study_dirs = {{"data", fs::path(data_dir) / "studies"}};
            const fs::path repo = executable_dir() / ".." / "..";
            if (!study_dirs.empty()) {
                for (size_t i = 0; i < study_dirs.size(); ++i)
                    http_options.study_dirs.emplace_back("dir" + std::to_string(i + 1),
                                                         study_dirs[i]);
            } else if (fs::exists(repo / "CMakeLists.txt")) {
                for (const fs::path& dir : {repo / "docs" / "studies", repo / "out"})
                    if (fs::is_directory(dir))
                        http_options.study_dirs.emplace_back(
                            dir.filename() == "out" ? "out" : "docs",
                            fs::weakly_canonical(dir));
            }
            http = std::make_unique<HttpServer>(coordinator, http_address, http_options);
            write_log_line("listening",
                           {log_text("service", tls_cert.empty() ? "http" : "https"),
                            log_text("address", http_address),
                            log_number("port", int64_t(http->port())),
                            log_text("tls", tls_cert.empty() ? "off" : "on"),
                            log_text("dashboard", http_options.web_dir.string())});
        }
        int sig = 0;
        sigwait(&stop, &sig);
        write_log_line("coordinator_stopping", {log_number("signal", int64_t(sig))});
        // Probes see NOT_SERVING while the farm winds down, before the port closes.
        server.stop_serving();
        coordinator.stop();
        if (http) http->shutdown();
        server.shutdown();
    }
};

}  // namespace

void register_coordinator(CLI::App& app) {
    auto c = std::make_shared<CoordinatorCommand>();
    CLI::App* cmd = app.add_subcommand("coordinator", "run a coordinator (gRPC, SQLite)");
    cmd->add_option("--grpc", c->grpc_address, "listen address host:port")
        ->capture_default_str();
    cmd->add_option(
        "--http", c->http_address,
        "HTTP address host:port for the JSON API and dashboard (default: off)");
    cmd->add_option(
        "--studies", c->study_dirs,
        "a directory of study reports to list besides DATA/studies, instead of the "
        "source tree's docs/studies and out/ (repeatable)");
    cmd->add_option("--allow-host", c->allowed_hosts,
                    "a Host name the HTTP API answers besides its listen address, e.g. a "
                    "compose or Kubernetes service name: NAME (any port) or NAME:PORT "
                    "(repeatable; docs/SECURITY.md)");
    cmd->add_option("--client-token-file", c->client_token_file,
                    "file holding the client token (default: DATA/client.token, made at "
                    "the first start, mode 0600)");
    cmd->add_option("--worker-token-file", c->worker_token_file,
                    "file holding the worker token (default: DATA/worker.token, made at "
                    "the first start, mode 0600)");
    cmd->add_option("--tls-cert", c->tls_cert,
                    "PEM certificate (chain): serve gRPC and HTTP over TLS");
    cmd->add_option("--tls-key", c->tls_key, "PEM private key of --tls-cert");
    cmd->add_option("--web", c->web_dir,
                    "built dashboard directory (default: web/dist of the source tree)");
    cmd->add_option("--data", c->data_dir, "directory for SQLite, checkpoints, images")
        ->capture_default_str();
    cmd->add_option("--lease-seconds", c->lease_seconds, "lease length without renewal")
        ->capture_default_str();
    cmd->add_option("--lost-seconds", c->lost_seconds,
                    "silence after which a worker is lost")
        ->capture_default_str();
    cmd->add_option("--max-resolution", c->max_side, "largest accepted image side")
        ->check(whole_number())
        ->capture_default_str();
    add_log_format_option(*cmd);
    cmd->add_option("--memory-limit", c->memory_limit,
                    "bytes (K, M, G suffixes) the renders in memory may use together; a "
                    "submission past it is refused (default: half the physical memory, " +
                        std::to_string(default_memory_limit() >> 20) + "M here)");
    cmd->add_flag("--grpc-reflection", c->grpc_reflection,
                  "serve gRPC server reflection (grpcurl, grpc_cli), without a token: it "
                  "tells the services' schema only (docs/SECURITY.md)");
    cmd->add_option("--max-job-failures", c->max_job_failures,
                    "worker hosts (the addresses workers call from, not their names) a "
                    "job may fail on before its render fails (docs/FARM.md)")
        ->check(whole_number())
        ->capture_default_str();
    cmd->add_flag("--fail-on-fewer-hosts", c->fail_on_fewer_hosts,
                  "let a job that failed --max-job-failures times fail its render when "
                  "no other live host could take it, so that a farm on fewer machines "
                  "fails a render no worker can trace; off, one host (one holder of the "
                  "worker token) never fails a render alone (docs/SECURITY.md)");
    cmd->add_option("--forget-workers", c->forget_workers,
                    "forget workers (in memory and in the record) unheard this long: "
                    "90s, 30m, 1h, 2d")
        ->capture_default_str();
    cmd->add_option("--max-workers", c->max_workers,
                    "workers remembered at once; registering past it forgets the "
                    "longest-silent one holding no lease")
        ->check(whole_number())
        ->capture_default_str();
    cmd->add_option("--max-workers-per-host", c->max_workers_per_host,
                    "workers (and their sessions) one address may have registered at "
                    "once; past it a Register from there is refused unless one of its "
                    "own is lost (docs/SECURITY.md)")
        ->check(whole_number())
        ->capture_default_str();
    cmd->add_option(
           "--keep-days", c->keep_days,
           "delete finished renders (image, record, rounds) this many days after "
           "they finished; 0 keeps them for ever")
        ->capture_default_str();
    cmd->callback([c] { c->run(); });
}

}  // namespace aliquot::cli
