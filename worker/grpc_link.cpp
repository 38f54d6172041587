#include "grpc_link.h"

#include <grpcpp/grpcpp.h>
#include <unistd.h>

#include "aliquot.grpc.pb.h"
#include "channel.h"
#include "wire.h"

namespace aliquot {

namespace {

constexpr auto kCallDeadline = std::chrono::seconds(10);

// This machine's name for the coordinator's workers list; "" when it has none.
std::string host_name() {
    char name[256] = {};
    if (gethostname(name, sizeof name - 1) != 0) return "";
    return std::string(name).substr(0, 128);  // the coordinator takes at most 128 bytes
}

}  // namespace

struct GrpcLink::Stub {
    std::shared_ptr<grpc::Channel> channel;
    std::unique_ptr<v1::WorkerService::Stub> stub;
};

GrpcLink::GrpcLink(CoordinatorEndpoint endpoint)
    : stub_(new Stub), endpoint_(std::move(endpoint)) {
    grpc::ChannelArguments args;
    // Keepalive matched with the coordinator's server settings
    // (coordinator/api/grpc_server.cpp).
    args.SetInt(GRPC_ARG_KEEPALIVE_TIME_MS, 20000);
    args.SetInt(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, 10000);
    args.SetInt(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
    // Reconnecting to a coordinator that went away: the first retry after 100 ms, then at
    // most a second apart (gRPC's default grows to 120 s); a connect attempt to a host
    // that does not answer gives up after a second (the default is 20 s). Calls fail fast
    // meanwhile and the worker loop retries at most a second apart too, so a worker is
    // back within about a second of the coordinator (docs/FARM.md).
    args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 100);
    args.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, 1000);
    args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 1000);
    stub_->channel = grpc::CreateCustomChannel(endpoint_.address,
                                               channel_credentials(endpoint_), args);
    stub_->stub = v1::WorkerService::NewStub(stub_->channel);
}

GrpcLink::~GrpcLink() = default;

std::unique_ptr<grpc::ClientContext> GrpcLink::context(
    std::chrono::milliseconds extra) const {
    auto ctx = std::make_unique<grpc::ClientContext>();
    ctx->set_deadline(std::chrono::system_clock::now() + kCallDeadline + extra);
    add_token(*ctx, endpoint_);
    return ctx;
}

static void check(const grpc::Status& status, const std::string& address,
                  bool registering = false) {
    if (status.ok()) return;
    // The worker token is missing, wrong or the client's: asking again will not help.
    if (status.error_code() == grpc::StatusCode::PERMISSION_DENIED ||
        (registering && status.error_code() == grpc::StatusCode::UNAUTHENTICATED))
        throw LinkRefused("coordinator " + address +
                          " refused this worker: " + status.error_message());
    // The coordinator does not know our session (it restarted since we registered).
    if (status.error_code() == grpc::StatusCode::UNAUTHENTICATED)
        throw WorkerUnknown("coordinator " + address + ": " + status.error_message());
    if (status.error_code() == grpc::StatusCode::UNAVAILABLE ||
        status.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED ||
        status.error_code() == grpc::StatusCode::CANCELLED)
        throw LinkUnavailable(address + ": " + status.error_message());
    throw std::runtime_error("coordinator " + address + ": " + status.error_message());
}

Registration GrpcLink::register_worker(const std::string& name, uint32_t threads) {
    v1::RegisterRequest req;
    req.set_name(name);
    req.set_threads(threads);
    req.set_host(host_name());
    req.set_version(ALIQUOT_VERSION);
    req.set_wire_version(kWireVersion);
    v1::RegisterReply reply;
    check(stub_->stub->Register(context().get(), req, &reply), endpoint_.address, true);
    if (reply.session().empty())
        throw std::runtime_error("coordinator " + endpoint_.address +
                                 " gave no worker session");
    return {reply.session(), reply.lease_ms()};
}

std::optional<LeaseGrant> GrpcLink::lease(const std::string& session,
                                          std::chrono::milliseconds wait) {
    v1::LeaseRequest req;
    req.set_session(session);
    req.set_wait_ms(uint32_t(wait.count()));
    v1::LeaseReply reply;
    check(stub_->stub->Lease(context(wait).get(), req, &reply), endpoint_.address);
    if (reply.register_first())
        throw WorkerUnknown("coordinator " + endpoint_.address +
                            " does not know this worker");
    return grant_of(reply);
}

std::optional<LeaseGrant> GrpcLink::grant_of(const v1::LeaseReply& reply) {
    if (!reply.has_lease()) return std::nullopt;
    const v1::Lease& l = reply.lease();
    return LeaseGrant{l.lease_id(),        l.render_id(),
                      l.scene_hash(),      {l.width(), l.height(), l.seed()},
                      from_proto(l.job()), l.lease_ms()};
}

// One Complete call; with `wait`, it also asks for the next lease, which goes to `next`.
CompleteOutcome GrpcLink::send_result(const std::string& session, uint64_t lease_id,
                                      const SampleJobResult& result,
                                      std::optional<std::chrono::milliseconds> wait,
                                      std::optional<LeaseGrant>* next) {
    v1::CompleteRequest req;
    req.set_session(session);
    req.set_lease_id(lease_id);
    to_proto(result, *req.mutable_result());
    if (wait) {
        req.set_lease_next(true);
        req.set_next_wait_ms(uint32_t(wait->count()));
    }
    v1::CompleteReply reply;
    check(stub_->stub->Complete(context(wait.value_or(std::chrono::milliseconds{})).get(),
                                req, &reply),
          endpoint_.address);
    // A coordinator that does not know the worker any more says so on the next Lease.
    if (next)
        *next = reply.next().register_first() ? std::nullopt : grant_of(reply.next());
    return {from_proto(reply.status()), reply.message()};
}

CompleteOutcome GrpcLink::complete_and_lease(const std::string& session,
                                             uint64_t lease_id,
                                             const SampleJobResult& result,
                                             std::chrono::milliseconds wait,
                                             std::optional<LeaseGrant>& next) {
    return send_result(session, lease_id, result, wait, &next);
}

CompleteOutcome GrpcLink::complete(const std::string& session, uint64_t lease_id,
                                   const SampleJobResult& result) {
    return send_result(session, lease_id, result, std::nullopt, nullptr);
}

std::optional<std::string> GrpcLink::fetch_scene(const std::string& session,
                                                 const std::string& hash) {
    v1::FetchSceneRequest req;
    req.set_session(session);
    req.set_hash(hash);
    v1::FetchSceneReply reply;
    const grpc::Status status = stub_->stub->FetchScene(context().get(), req, &reply);
    if (status.error_code() == grpc::StatusCode::NOT_FOUND) return std::nullopt;
    check(status, endpoint_.address);
    return reply.scene_json();
}

bool GrpcLink::renew(const std::string& session, uint64_t lease_id) {
    v1::RenewRequest req;
    req.set_session(session);
    req.set_lease_id(lease_id);
    v1::RenewReply reply;
    check(stub_->stub->Renew(context().get(), req, &reply), endpoint_.address);
    return reply.valid();
}

bool GrpcLink::abandon(const std::string& session, uint64_t lease_id) {
    v1::RenewRequest req;
    req.set_session(session);
    req.set_lease_id(lease_id);
    v1::RenewReply reply;
    check(stub_->stub->Abandon(context().get(), req, &reply), endpoint_.address);
    return reply.valid();
}

bool GrpcLink::fail(const std::string& session, uint64_t lease_id,
                    const std::string& reason) {
    v1::FailRequest req;
    req.set_session(session);
    req.set_lease_id(lease_id);
    req.set_reason(reason);
    v1::FailReply reply;
    check(stub_->stub->Fail(context().get(), req, &reply), endpoint_.address);
    return reply.accepted();
}

}  // namespace aliquot
