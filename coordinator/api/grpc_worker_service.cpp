// aliquot.v1.WorkerService over Coordinator (grpc_worker_service.h): every call admitted
// by the worker token first, Lease's long polls each holding a place (LeasePolls).
#include "grpc_worker_service.h"

#include <algorithm>
#include <chrono>
#include <exception>
#include <new>
#include <optional>
#include <string>
#include <utility>

#include "aliquot.grpc.pb.h"
#include "grpc_access.h"
#include "lease_polls.h"
#include "render_proto.h"
#include "shown_id.h"
#include "wire.h"
#include "worker_registry.h"

namespace aliquot {

namespace {

using grpc::ServerContext;
using grpc::Status;
using grpc::StatusCode;

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
            // The sums are read where protobuf parsed them, in `req`, which outlives the
            // merge (wire.h's from_proto_in_place): `result` is passed by reference,
            // and only a result held for the round ahead copies them, once.
            SampleJobResult result;
            try {
                from_proto_in_place(req->result(), result);
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
                c_.complete(req->session(), req->lease_id(), std::as_const(result));
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
        } catch (const std::bad_alloc&) {
            // A merge that could not keep what it needs gave its job back
            // (RenderSession:: begin_merge): the worker may send again later, or another
            // traces it.
            return {StatusCode::RESOURCE_EXHAUSTED, "the coordinator is out of memory"};
        } catch (const std::exception& e) {
            // Said here rather than left to gRPC's own catch (UNKNOWN, no reason).
            return {StatusCode::INTERNAL, e.what()};
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

std::unique_ptr<grpc::Service> make_worker_service(Coordinator& c, const Tokens& tokens,
                                                   FarmMetrics* metrics,
                                                   const GrpcLimits& limits) {
    return std::make_unique<WorkerServiceImpl>(c, tokens, metrics, limits);
}

}  // namespace aliquot
