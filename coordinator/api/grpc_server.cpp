#include "grpc_server.h"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/impl/server_builder_option.h>
#include <grpcpp/resource_quota.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <new>

#include "access.h"
#include "admission.h"
#include "aliquot.grpc.pb.h"
#include "exr_io.h"
#include "farm_log.h"
#include "health_service.h"
#include "lease_polls.h"
#include "listener_watchdog.h"
#include "open_file_limit.h"
#include "render_proto.h"
#include "scene_loader.h"
#include "shown_id.h"
#include "stored_image.h"
#include "stream_watchdog.h"
#include "wire.h"
#include "worker_registry.h"

namespace aliquot {

namespace {

using grpc::ServerContext;
using grpc::Status;
using grpc::StatusCode;

// Before anything else a call does: the bearer token of its `authorization` metadata must
// be `role`'s (docs/SECURITY.md).
Status admit(const ServerContext* ctx, const Tokens& tokens, Role role) {
    const auto& metadata = ctx->client_metadata();
    const auto header = metadata.find("authorization");
    const std::string_view value =
        header == metadata.end()
            ? std::string_view()
            : std::string_view(header->second.data(), header->second.size());
    const Access access = check_access(tokens, bearer_token(value), role);
    if (access == Access::Granted) return Status::OK;
    return {access == Access::Forbidden ? StatusCode::PERMISSION_DENIED
                                        : StatusCode::UNAUTHENTICATED,
            access_message(access, role)};
}

Status too_many(const std::string& calls) {
    return {StatusCode::RESOURCE_EXHAUSTED,
            "too many open " + calls + " calls; try again later"};
}

// A place among `calls`' (GrpcLimits' max_watches, max_fetches and
// max_fetches_from_memory, and their shares per peer address), or the refusal to answer
// with: a call past one is refused rather than given a thread.
Status take_place(Admission& calls, const ServerContext& ctx, const std::string& name,
                  Admission::Place& place) {
    const std::string host = host_of_peer(ctx.peer());
    Admission::Ticket ticket = calls.take(host);
    place = std::move(ticket.place);
    if (place) return Status::OK;
    if (!ticket.peer_share_full) return too_many(name);
    return {StatusCode::RESOURCE_EXHAUSTED, "too many open " + name + " calls from " +
                                                host + " (at most " +
                                                std::to_string(calls.places_per_peer()) +
                                                " from one address); try again later"};
}

class ClientServiceImpl final : public v1::ClientService::Service {
public:
    ClientServiceImpl(Coordinator& c, const Tokens& tokens, const GrpcLimits& limits)
        : c_(c),
          tokens_(tokens),
          limits_(limits),
          watchdog_(limits.stream_grace, limits.stream_min_rate) {}

    Status Submit(ServerContext* ctx, const v1::SubmitRequest* req,
                  v1::RenderInfo* reply) override {
        if (Status s = admit(ctx, tokens_, Role::Client); !s.ok()) return s;
        try {
            RenderSpec spec;
            spec.scene_name = req->scene();
            spec.scene_json = req->scene_json();
            spec.width = req->width();
            spec.height = req->height();
            spec.seed = req->seed();
            spec.priority = req->priority();
            spec.name = req->name();
            spec.aux = req->albedo_normal();
            spec.strategy = nlohmann::json::parse(
                req->strategy_json().empty() ? "{}" : req->strategy_json());
            // The render must fit the budget before its reference is decoded, and the
            // reference what the budget leaves: its header alone can claim gigabytes.
            if (!req->reference_exr().empty())
                spec.reference =
                    decode_exr(req->reference_exr(), "the submitted reference",
                               ExrSize{req->width(), req->height()},
                               c_.reference_allowance(req->width(), req->height()));
            const std::string id = c_.submit(std::move(spec));
            to_proto(*c_.info(id), *reply);
            return Status::OK;
        } catch (const MemoryBudgetError& e) {
            return {StatusCode::RESOURCE_EXHAUSTED, e.what()};
        } catch (const ImageTooLarge& e) {
            return {StatusCode::RESOURCE_EXHAUSTED,
                    std::string("reference: ") + e.what()};
        } catch (const std::bad_alloc&) {
            // Parsing the scene or decoding the reference ran out: the request fails,
            // the coordinator goes on (what was allocated for it is freed by now).
            return {StatusCode::RESOURCE_EXHAUSTED, "out of memory reading the request"};
        } catch (const nlohmann::json::exception& e) {
            return {StatusCode::INVALID_ARGUMENT, std::string("strategy: ") + e.what()};
        } catch (const std::invalid_argument& e) {
            return {StatusCode::INVALID_ARGUMENT, e.what()};
        } catch (const SceneError& e) {
            return {StatusCode::INVALID_ARGUMENT, e.what()};
        } catch (const ImageFileError& e) {
            return {StatusCode::INVALID_ARGUMENT, std::string("reference: ") + e.what()};
        } catch (const std::exception& e) {
            return {StatusCode::INTERNAL, e.what()};
        }
    }

    Status GetRender(ServerContext* ctx, const v1::GetRenderRequest* req,
                     v1::RenderInfo* reply) override {
        if (Status s = admit(ctx, tokens_, Role::Client); !s.ok()) return s;
        const auto info = c_.info(req->id());
        if (!info) return {StatusCode::NOT_FOUND, "no render " + shown_id(req->id())};
        to_proto(*info, *reply);
        return Status::OK;
    }

    Status ListRenders(ServerContext* ctx, const v1::ListRendersRequest* req,
                       v1::ListRendersReply* reply) override {
        if (Status s = admit(ctx, tokens_, Role::Client); !s.ok()) return s;
        // Bounded as HTTP's list is: the reply is built in memory.
        const uint32_t limit =
            req->limit() ? std::min<uint32_t>(req->limit(), 1000) : 100;
        for (const RenderInfo& i : c_.list(limit)) to_proto(i, *reply->add_renders());
        reply->set_storage_warning(c_.storage_warning());
        return Status::OK;
    }

    Status Watch(ServerContext* ctx, const v1::GetRenderRequest* req,
                 grpc::ServerWriter<v1::RenderInfo>* writer) override {
        if (Status s = admit(ctx, tokens_, Role::Client); !s.ok()) return s;
        // Each open stream holds one of the server's threads while it waits.
        Admission::Place slot;
        if (Status s = take_place(watches_, *ctx, "Watch", slot); !s.ok()) return s;
        // Then it ends, OK, and its client opens another (GrpcLimits::watch_life).
        const auto end = std::chrono::steady_clock::now() + limits_.watch_life;
        uint64_t seen = 0;
        while (!ctx->IsCancelled()) {
            const auto info = c_.info(req->id());
            if (!info) return {StatusCode::NOT_FOUND, "no render " + shown_id(req->id())};
            v1::RenderInfo msg;
            to_proto(*info, msg);
            if (!paced_write(*ctx, *writer, msg,
                             StreamWatchdog::Clock::time_point::max()))
                return Status::OK;
            if (is_terminal(info->state)) return Status::OK;
            // At most a few updates a second, however fast jobs merge.
            std::this_thread::sleep_for(std::chrono::milliseconds(250));
            const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
                end - std::chrono::steady_clock::now());
            if (left.count() <= 0) return Status::OK;
            seen = c_.wait_for_change(
                seen, std::min<std::chrono::milliseconds>(left, std::chrono::seconds(1)));
        }
        return Status::OK;
    }

    Status Cancel(ServerContext* ctx, const v1::GetRenderRequest* req,
                  v1::RenderInfo* reply) override {
        if (Status s = admit(ctx, tokens_, Role::Client); !s.ok()) return s;
        const auto info = c_.cancel(req->id());
        if (!info) return {StatusCode::NOT_FOUND, "no render " + shown_id(req->id())};
        to_proto(*info, *reply);
        return Status::OK;
    }

    Status SetPriority(ServerContext* ctx, const v1::SetPriorityRequest* req,
                       v1::RenderInfo* reply) override {
        if (Status s = admit(ctx, tokens_, Role::Client); !s.ok()) return s;
        try {
            const auto info = c_.set_priority(req->id(), req->priority());
            if (!info) return {StatusCode::NOT_FOUND, "no render " + shown_id(req->id())};
            to_proto(*info, *reply);
            return Status::OK;
        } catch (const RenderFinished& e) {
            return {StatusCode::FAILED_PRECONDITION, e.what()};
        }
    }

    Status Delete(ServerContext* ctx, const v1::GetRenderRequest* req,
                  v1::DeleteReply*) override {
        if (Status s = admit(ctx, tokens_, Role::Client); !s.ok()) return s;
        switch (c_.remove(req->id())) {
            case Coordinator::Removal::Removed:
                return Status::OK;
            case Coordinator::Removal::Unknown:
                return {StatusCode::NOT_FOUND, "no render " + shown_id(req->id())};
            case Coordinator::Removal::Unfinished:
                break;
        }
        return {StatusCode::FAILED_PRECONDITION,
                "render " + shown_id(req->id()) + " has not finished; cancel it first"};
    }

    Status FetchImage(ServerContext* ctx, const v1::FetchImageRequest* req,
                      grpc::ServerWriter<v1::FileChunk>* writer) override {
        if (Status s = admit(ctx, tokens_, Role::Client); !s.ok()) return s;
        // Each holds a server thread and a chunk while it sends.
        Admission::Place fetch;
        if (Status s = take_place(fetches_, *ctx, "FetchImage", fetch); !s.ok()) return s;
        try {
            // A finished render's stored file is sent as it is read.
            if (const auto file = c_.image_file(req->id())) {
                std::ifstream in(stored_image(*file, req->aovs()),
                                 std::ios::binary | std::ios::ate);
                // Open, it stays readable even if the render is deleted meanwhile.
                if (!in)
                    return {StatusCode::NOT_FOUND,
                            "no image for render " + shown_id(req->id())};
                const auto whole = watchdog_.due(size_t(std::max<std::streamoff>(
                    std::streamoff(in.tellg()), std::streamoff(0))));
                in.seekg(0);
                std::string buffer(kChunk, '\0');
                while (in.read(buffer.data(), std::streamsize(buffer.size())) ||
                       in.gcount() > 0) {
                    v1::FileChunk chunk;
                    chunk.set_data(buffer.data(), size_t(in.gcount()));
                    if (!paced_write(*ctx, *writer, chunk, whole)) break;
                }
                return Status::OK;
            }
            // A render in memory is encoded in memory: a copy of its image, then the
            // encoded bytes while they are sent (up to ~1 GB at 8192x8192 with AOVs),
            // hence a cap of its own.
            Admission::Place from_memory;
            if (Status s = take_place(memory_fetches_, *ctx,
                                      "FetchImage of a running render", from_memory);
                !s.ok())
                return s;
            if (limits_.running_fetch_admitted) limits_.running_fetch_admitted();
            std::string bytes;
            {
                const auto image = c_.image(req->id(), req->aovs());
                if (!image)
                    return {StatusCode::NOT_FOUND,
                            "no image for render " + shown_id(req->id())};
                bytes = encode_exr(*image);
            }
            const auto whole = watchdog_.due(bytes.size());
            for (size_t off = 0; off < bytes.size(); off += kChunk) {
                v1::FileChunk chunk;
                chunk.set_data(bytes.data() + off, std::min(kChunk, bytes.size() - off));
                if (!paced_write(*ctx, *writer, chunk, whole)) break;
            }
            return Status::OK;
        } catch (const ImageFileError& e) {
            return {StatusCode::INTERNAL, e.what()};
        }
    }

    Status ListWorkers(ServerContext* ctx, const v1::ListWorkersRequest*,
                       v1::ListWorkersReply* reply) override {
        if (Status s = admit(ctx, tokens_, Role::Client); !s.ok()) return s;
        for (const WorkerStatus& w : c_.workers()) to_proto(w, *reply->add_workers());
        return Status::OK;
    }

    Status GetRounds(ServerContext* ctx, const v1::GetRenderRequest* req,
                     v1::GetRoundsReply* reply) override {
        if (Status s = admit(ctx, tokens_, Role::Client); !s.ok()) return s;
        const auto rounds = c_.rounds(req->id());
        if (!rounds) return {StatusCode::NOT_FOUND, "no render " + shown_id(req->id())};
        for (const RoundSummary& r : *rounds) {
            v1::RoundInfo* out = reply->add_rounds();
            out->set_index(r.index);
            out->set_samples_in_round(r.samples_in_round);
            out->set_samples_total(r.samples_total);
            out->set_seconds(r.seconds);
            out->set_error_estimate(r.error_estimate);
            out->set_error_vs_reference(r.error_vs_reference);
        }
        return Status::OK;
    }

    Status GetEvents(ServerContext* ctx, const v1::GetEventsRequest* req,
                     v1::GetEventsReply* reply) override {
        if (Status s = admit(ctx, tokens_, Role::Client); !s.ok()) return s;
        const uint32_t limit =
            req->limit() ? std::min<uint32_t>(req->limit(), 1000) : 100;
        // Numbers past int64's would wrap round to "from the first".
        const int64_t from = int64_t(std::min<uint64_t>(req->from(), INT64_MAX));
        const auto page = c_.events(req->id(), from - 1, limit);
        if (!page) return {StatusCode::NOT_FOUND, "no render " + shown_id(req->id())};
        for (const RenderEvent& e : page->events) to_proto(e, *reply->add_events());
        reply->set_omitted(page->omitted);
        return Status::OK;
    }

private:
    // Writes `message` to a stream, cancelling the call if the write has not ended within
    // the pace (GrpcLimits::stream_min_rate after stream_grace) or by `whole`, when all
    // the stream must have been taken; false once the stream is broken or cut.
    template <typename Message>
    bool paced_write(ServerContext& ctx, grpc::ServerWriter<Message>& writer,
                     const Message& message, StreamWatchdog::Clock::time_point whole) {
        const StreamWatchdog::WatchedWrite watched(
            watchdog_, ctx, std::min(whole, watchdog_.due(message.ByteSizeLong())));
        return writer.Write(message);
    }

    static constexpr size_t kChunk = 1 << 20;
    Coordinator& c_;
    const Tokens& tokens_;
    const GrpcLimits& limits_;
    // Its thread ends with the service, after the server has stopped every call.
    StreamWatchdog watchdog_;
    Admission watches_{size_t(std::max(limits_.max_watches, 0)),
                       size_t(std::max(limits_.max_watches_per_peer, 0))};
    Admission fetches_{size_t(std::max(limits_.max_fetches, 0)),
                       size_t(std::max(limits_.max_fetches_per_peer, 0))};
    Admission memory_fetches_{
        size_t(std::max(limits_.max_fetches_from_memory, 0)),
        size_t(std::max(limits_.max_fetches_from_memory_per_peer, 0))};
};

// Every call but Register carries the worker's session; one the coordinator did not issue
// (it restarted since) is answered register_first by Lease and UNAUTHENTICATED by the
// others, and the worker registers again (worker/grpc_link.cpp). Which lease is whose is
// the Coordinator's to check: the same code answers the embedded render's threads.
class WorkerServiceImpl final : public v1::WorkerService::Service {
public:
    WorkerServiceImpl(Coordinator& c, const Tokens& tokens, FarmMetrics* metrics,
                      const GrpcLimits& limits)
        : c_(c),
          tokens_(tokens),
          metrics_(metrics),
          polls_(limits.max_lease_polls, limits.max_lease_polls_per_session) {}

    int lease_polls_waiting() { return polls_.waiting(); }

    Status Register(ServerContext* ctx, const v1::RegisterRequest* req,
                    v1::RegisterReply* reply) override {
        if (Status s = admit(ctx, tokens_, Role::Worker); !s.ok()) return s;
        // The name keys the coordinator's worker table and the store's rows.
        if (req->name().empty() || req->name().size() > 128)
            return {StatusCode::INVALID_ARGUMENT, "a worker name is 1 to 128 bytes"};
        // Kept per worker and shown in every workers list: bounded like the name.
        if (req->host().size() > 128 || req->version().size() > 128)
            return {StatusCode::INVALID_ARGUMENT,
                    "a worker's host and version are at most 128 bytes each"};
        // Its threads are the farm's cores, for which every render's rounds are cut
        // (two jobs a core, round_cutter.h): 2^32-1 of them cut every round of every
        // render into the smallest tiles. The largest machines have a few hundred.
        if (req->threads() > kMaxWorkerThreads)
            return {StatusCode::INVALID_ARGUMENT,
                    "a worker states at most " + std::to_string(kMaxWorkerThreads) +
                        " threads, got " + std::to_string(req->threads())};
        // Every result of another version would be refused (wire.h) and count as a job
        // failure: such a worker is turned away before it leases anything.
        if (req->wire_version() != kWireVersion)
            return {
                StatusCode::FAILED_PRECONDITION,
                "worker of wire protocol version " + std::to_string(req->wire_version()) +
                    ", this coordinator speaks version " + std::to_string(kWireVersion) +
                    (req->wire_version() < kWireVersion ? ": update the worker"
                                                        : ": update the coordinator")};
        Registration r;
        try {
            // Failures count against the caller's host, never a name it chose.
            r = c_.register_worker(req->name(), req->threads(), ctx->peer());
            c_.describe_worker(req->name(), req->host(), req->version());
        } catch (const TooManyWorkers& e) {
            return {StatusCode::RESOURCE_EXHAUSTED, e.what()};
        }
        reply->set_lease_ms(r.lease_ms);
        reply->set_session(r.session);
        return Status::OK;
    }

    Status Lease(ServerContext* ctx, const v1::LeaseRequest* req,
                 v1::LeaseReply* reply) override {
        if (Status s = admit(ctx, tokens_, Role::Worker); !s.ok()) return s;
        answer_lease(req->session(), req->wait_ms(), *reply);
        return Status::OK;
    }

    Status Complete(ServerContext* ctx, const v1::CompleteRequest* req,
                    v1::CompleteReply* reply) override {
        if (Status s = admit(ctx, tokens_, Role::Worker); !s.ok()) return s;
        return known([&] {
            // The sums are copied once, from the parsed message's records into `result`
            // (one memcpy: wire.h), and moved from there to the merge and to a round
            // held ahead: never copied again.
            SampleJobResult result;
            try {
                result = from_proto(req->result());
            } catch (const WireError& e) {
                // Malformed: nothing is merged, and it counts as the sender's failure on
                // the job, as a rejected result does (fail checks the sender holds it;
                // anyone else changes nothing).
                if (!c_.fail(req->session(), req->lease_id(),
                             std::string("malformed result: ") + e.what())) {
                    reply->set_status(to_proto(CompleteStatus::Ignored));
                    reply->set_message("not your lease, or no longer out");
                    return;
                }
                reply->set_status(to_proto(CompleteStatus::Rejected));
                reply->set_message(e.what());
                return;
            }
            const auto began = std::chrono::steady_clock::now();
            const CompleteOutcome outcome =
                c_.complete(req->session(), req->lease_id(), std::move(result));
            if (metrics_) metrics_->observe_merge(seconds_since(began));
            reply->set_status(to_proto(outcome.status));
            reply->set_message(outcome.message);
            // One round trip a job: the next lease rides on the reply.
            if (req->lease_next() && outcome.status == CompleteStatus::Merged)
                answer_lease(req->session(), req->next_wait_ms(), *reply->mutable_next());
        });
    }

    Status FetchScene(ServerContext* ctx, const v1::FetchSceneRequest* req,
                      v1::FetchSceneReply* reply) override {
        if (Status s = admit(ctx, tokens_, Role::Worker); !s.ok()) return s;
        std::optional<std::string> json;
        const Status status =
            known([&] { json = c_.fetch_scene(req->session(), req->hash()); });
        if (!status.ok()) return status;
        if (!json) return {StatusCode::NOT_FOUND, "no scene " + shown_id(req->hash())};
        reply->set_scene_json(*json);
        return Status::OK;
    }

    Status Renew(ServerContext* ctx, const v1::RenewRequest* req,
                 v1::RenewReply* reply) override {
        if (Status s = admit(ctx, tokens_, Role::Worker); !s.ok()) return s;
        return known(
            [&] { reply->set_valid(c_.renew(req->session(), req->lease_id())); });
    }

    Status Abandon(ServerContext* ctx, const v1::RenewRequest* req,
                   v1::RenewReply* reply) override {
        if (Status s = admit(ctx, tokens_, Role::Worker); !s.ok()) return s;
        return known(
            [&] { reply->set_valid(c_.abandon(req->session(), req->lease_id())); });
    }

    Status Fail(ServerContext* ctx, const v1::FailRequest* req,
                v1::FailReply* reply) override {
        if (Status s = admit(ctx, tokens_, Role::Worker); !s.ok()) return s;
        return known([&] {
            reply->set_accepted(c_.fail(req->session(), req->lease_id(), req->reason()));
        });
    }

private:
    // What Lease answers `session`, waiting up to `wait_ms` for work (at most 30 s), if
    // a place to wait is free (LeasePolls); otherwise without waiting.
    void answer_lease(const std::string& session, uint32_t wait_ms,
                      v1::LeaseReply& reply) {
        auto wait = std::chrono::milliseconds(std::min<uint32_t>(wait_ms, 30000));
        std::optional<LeasePolls::Place> place;
        if (wait.count() > 0) {
            place.emplace(polls_, session);
            if (!place->taken()) wait = std::chrono::milliseconds(0);
        }
        const bool turned_away = place && !place->taken();
        const auto began = std::chrono::steady_clock::now();
        std::optional<LeaseGrant> grant;
        try {
            grant = c_.lease(session, wait);
            if (metrics_)
                metrics_->observe_lease(seconds_since(began), grant.has_value());
        } catch (const WorkerUnknown&) {
            // Registered with a coordinator before a restart: it must register again,
            // with its threads, before it gets work.
            reply.set_register_first(true);
            return;
        }
        if (!grant) {
            // A long-poll that waited asks again at once; one turned away, later.
            reply.set_retry_after_ms(turned_away ? kRetryAfterMs : 0);
            return;
        }
        v1::Lease* l = reply.mutable_lease();
        l->set_lease_id(grant->lease_id);
        l->set_render_id(grant->render_id);
        l->set_scene_hash(grant->scene_hash);
        l->set_width(grant->geometry.width);
        l->set_height(grant->geometry.height);
        l->set_seed(grant->geometry.seed);
        aliquot::to_proto(grant->job, *l->mutable_job());
        l->set_lease_ms(grant->lease_ms);
    }

    static double seconds_since(std::chrono::steady_clock::time_point t) {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - t)
            .count();
    }

    // Runs `call`; a session the coordinator does not know becomes UNAUTHENTICATED.
    template <typename Call>
    static Status known(Call&& call) {
        try {
            call();
        } catch (const WorkerUnknown& e) {
            return {StatusCode::UNAUTHENTICATED, e.what()};
        }
        return Status::OK;
    }

    // How long a Lease turned away by the caps is asked to wait before the next.
    static constexpr uint32_t kRetryAfterMs = 1000;
    Coordinator& c_;
    const Tokens& tokens_;
    FarmMetrics* metrics_;
    LeasePolls polls_;
};

}  // namespace

// One server's services: a server started again by the watchdog gets new ones.
struct GrpcServer::Services {
    Tokens tokens;
    ClientServiceImpl client;
    WorkerServiceImpl worker;
    HealthService health;
    Services(Coordinator& c, Tokens t, FarmMetrics* metrics, const GrpcLimits& limits)
        : tokens(std::move(t)),
          client(c, tokens, limits),
          worker(c, tokens, metrics, limits),
          // "" is the server as a whole, what a probe that names no service asks about.
          health({"", v1::ClientService::service_full_name(),
                  v1::WorkerService::service_full_name()},
                 limits.max_health_watches) {}
};

namespace {

std::shared_ptr<grpc::ServerCredentials> server_credentials(const GrpcSecurity& s) {
    if (s.tls_cert_pem.empty()) return grpc::InsecureServerCredentials();
    grpc::SslServerCredentialsOptions options;
    options.pem_key_cert_pairs.push_back({s.tls_key_pem, s.tls_cert_pem});
    return grpc::SslServerCredentials(options);
}

// Whether this builder's server has reflection. Loading libgrpc++_reflection adds its
// plugin to every ServerBuilder of the process (a static initializer), so the option
// removes it, and adds one back only when asked to.
class ReflectionOption final : public grpc::ServerBuilderOption {
public:
    explicit ReflectionOption(bool on) : on_(on) {}
    void UpdateArguments(grpc::ChannelArguments*) override {}
    void UpdatePlugins(
        std::vector<std::unique_ptr<grpc::ServerBuilderPlugin>>* plugins) override {
        auto reflection =
            std::make_unique<grpc::reflection::ProtoServerReflectionPlugin>();
        const std::string name = reflection->name();
        std::erase_if(*plugins, [&](const auto& p) { return p && p->name() == name; });
        if (on_) plugins->push_back(std::move(reflection));
    }

private:
    bool on_;
};

}  // namespace

GrpcServer::GrpcServer(Coordinator& coordinator, const std::string& address,
                       GrpcSecurity security, GrpcOptions options, GrpcLimits limits)
    : coordinator_(coordinator),
      security_(std::move(security)),
      options_(options),
      limits_(limits) {
    check_tokens(security_.tokens);
    if (security_.tls_cert_pem.empty() != security_.tls_key_pem.empty())
        throw std::invalid_argument("gRPC: TLS needs both a certificate and its key");
    // Every connection holds a descriptor: the more a flood needs to exhaust them, the
    // better (the watchdog below answers the rest).
    raise_open_file_limit();
    std::lock_guard lock(mutex_);
    listen(address);
    host_ = address.substr(0, address.rfind(':'));
    if (limits_.watchdog_failures <= 0) return;
    // Asked first of a port just opened: where the probe cannot tell (no /proc/net), a
    // listener must not be started again for ever.
    if (!reachable()) {
        log_farm_error("cannot check that gRPC's port " + std::to_string(port_) +
                           " accepts connections here; no listener watchdog",
                       "listener_watchdog_off");
        return;
    }
    watchdog_ = std::make_unique<ListenerWatchdog>(
        limits_.watchdog_period, limits_.watchdog_failures,
        [this] { return reachable(); }, [this] { listen_again(); });
}

void GrpcServer::listen(const std::string& address) {
    const GrpcLimits& limits = limits_;
    services_ = std::make_unique<Services>(coordinator_, security_.tokens,
                                           options_.metrics, limits);
    // gRPC's own health service is off: ours (health_service.h) caps Watch streams.
    grpc::EnableDefaultHealthCheckService(false);
    grpc::ServerBuilder builder;
    builder.SetOption(std::make_unique<ReflectionOption>(options_.reflection));
    int port = 0;
    builder.AddListeningPort(address, server_credentials(security_), &port);
    builder.RegisterService(&services_->client);
    builder.RegisterService(&services_->worker);
    builder.RegisterService(&services_->health);
    // What a peer can make the server hold (docs/SECURITY.md, "gRPC limits"): threads
    // (a call finding none is refused), buffers, streams per connection, and how long
    // a connection that says nothing or has nothing open is kept.
    grpc::ResourceQuota quota("aliquot-grpc");
    quota.SetMaxThreads(limits.max_threads);
    quota.Resize(limits.max_memory_bytes);
    builder.SetResourceQuota(quota);
    // No SO_REUSEPORT (gRPC's default): with it, sockets of this or another process
    // could share the port, the kernel handing each a share of new connections, a deaf
    // one too, where the watchdog's one probe might not land. Without it a second
    // coordinator on the same port fails to start instead of sharing it.
    builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
    builder.AddChannelArgument(GRPC_ARG_MAX_CONCURRENT_STREAMS,
                               limits.max_streams_per_connection);
    builder.AddChannelArgument(GRPC_ARG_SERVER_HANDSHAKE_TIMEOUT_MS,
                               int(limits.handshake_timeout.count()));
    builder.AddChannelArgument(GRPC_ARG_MAX_CONNECTION_IDLE_MS,
                               int(limits.max_idle.count()));
    // Keepalive matched with the workers' channel settings (worker/grpc_link.cpp).
    builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIME_MS, 20000);
    builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, 10000);
    builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
    builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS,
                               10000);
    builder.AddChannelArgument(GRPC_ARG_HTTP2_MAX_PING_STRIKES, 0);
    server_ = builder.BuildAndStart();
    if (!server_ || port == 0) {
        server_.reset();
        throw std::runtime_error("cannot listen on " + address);
    }
    port_ = port;
    if (!serving_) services_->health.stop_serving();
}

bool GrpcServer::reachable() {
    // Accepted, not only queued: what gRPC 1.51 stops doing after a failed accept.
    // A wildcard listens on loopback too (gRPC's "[::]" is dual-stack, or falls back
    // to 0.0.0.0 where IPv6 is off).
    std::string host = host_;
    if (host.empty() || host == "0.0.0.0" || host == "[::]" || host == "[::0]")
        host = "127.0.0.1";
    if (host.size() > 2 && host.front() == '[' && host.back() == ']')
        host = host.substr(1, host.size() - 2);
    return accepts_connections(
        host, port_, std::max(limits_.watchdog_period, std::chrono::milliseconds(1000)));
}

void GrpcServer::listen_again() {
    std::lock_guard lock(mutex_);
    if (stopped_) return;
    log_farm_error(
        "gRPC on port " + std::to_string(port_) +
            " accepts no new connections (out of file descriptors?); listening "
            "again",
        "listener_deaf");
    // Calls in progress are cut off: their clients and workers retry on a new
    // connection.
    server_->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
    server_.reset();
    services_.reset();
    try {
        listen(host_ + ":" + std::to_string(port_));
        ++restarts_;
    } catch (const std::exception& e) {
        // Up but deaf is worse than down: a supervisor restarts a process that exits.
        log_farm_error("cannot listen on port " + std::to_string(port_) + " again (" +
                           e.what() +
                           "); exiting so that a supervisor restarts the coordinator",
                       "listener_failed");
        std::fflush(stderr);
        std::_Exit(75);
    }
}

int GrpcServer::restarts() {
    std::lock_guard lock(mutex_);
    return restarts_;
}

GrpcServer::~GrpcServer() { shutdown(); }

void GrpcServer::stop_serving() {
    // NOT_SERVING for every service, and no later change.
    std::lock_guard lock(mutex_);
    serving_ = false;
    if (services_) services_->health.stop_serving();
}

void GrpcServer::shutdown() {
    stop_serving();
    // First the watchdog, which could otherwise start the server again.
    watchdog_.reset();
    std::lock_guard lock(mutex_);
    stopped_ = true;
    if (server_) {
        server_->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
        server_.reset();
    }
}

}  // namespace aliquot
