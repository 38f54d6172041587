#include "health_service.h"

namespace aliquot {

using grpc::health::v1::HealthCheckRequest;
using grpc::health::v1::HealthCheckResponse;

// One open Watch: sends the status, then each change, until the caller goes away.
class HealthService::Watcher final
    : public grpc::ServerWriteReactor<HealthCheckResponse> {
public:
    Watcher(HealthService& health, std::string service)
        : health_(health), service_(std::move(service)) {}

    // What the service says now; sent unless it is what was sent last. Called with the
    // service's lock held, so the watcher cannot be forgotten and deleted meanwhile.
    void tell(Status status) {
        std::lock_guard lock(mutex_);
        pending_ = status;
        send();
    }

    const std::string& service() const { return service_; }

    void OnWriteDone(bool ok) override {
        std::lock_guard lock(mutex_);
        writing_ = false;
        if (!ok) {
            finish(grpc::Status::CANCELLED);
            return;
        }
        send();
    }
    void OnCancel() override {
        std::lock_guard lock(mutex_);
        finish(grpc::Status::CANCELLED);
    }
    void OnDone() override {
        health_.forget(this);
        delete this;
    }

private:
    void send() {  // under mutex_
        if (finished_ || writing_) return;
        if (cancelled_) {
            finish(grpc::Status::CANCELLED);
            return;
        }
        if (pending_ == sent_) return;
        sent_ = pending_;
        response_.set_status(sent_);
        writing_ = true;
        StartWrite(&response_);
    }
    // Finishes once, and never while a write is out (OnWriteDone finishes then).
    void finish(const grpc::Status& status) {  // under mutex_
        cancelled_ = true;
        if (finished_ || writing_) return;
        finished_ = true;
        Finish(status);
    }

    HealthService& health_;
    const std::string service_;
    std::mutex mutex_;
    HealthCheckResponse response_;
    Status pending_ = HealthCheckResponse::UNKNOWN, sent_ = HealthCheckResponse::UNKNOWN;
    bool writing_ = false, cancelled_ = false, finished_ = false;
};

namespace {

// A Watch refused at once: the cap is reached.
class RefusedWatch final : public grpc::ServerWriteReactor<HealthCheckResponse> {
public:
    RefusedWatch() {
        Finish({grpc::StatusCode::RESOURCE_EXHAUSTED,
                "too many open health Watch streams; try again later"});
    }
    void OnDone() override { delete this; }
};

}  // namespace

HealthService::HealthService(std::vector<std::string> services, int max_watches)
    : services_(services.begin(), services.end()), max_watches_(max_watches) {}

HealthService::Status HealthService::status_of(const std::string& service) const {
    if (!services_.count(service)) return HealthCheckResponse::SERVICE_UNKNOWN;
    return serving_ ? HealthCheckResponse::SERVING : HealthCheckResponse::NOT_SERVING;
}

void HealthService::stop_serving() {
    std::lock_guard lock(mutex_);
    serving_ = false;
    for (Watcher* w : watchers_) w->tell(status_of(w->service()));
}

int HealthService::watches() {
    std::lock_guard lock(mutex_);
    return int(watchers_.size());
}

void HealthService::forget(Watcher* w) {
    std::lock_guard lock(mutex_);
    watchers_.erase(w);
}

grpc::ServerUnaryReactor* HealthService::Check(grpc::CallbackServerContext* ctx,
                                               const HealthCheckRequest* req,
                                               HealthCheckResponse* reply) {
    grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
    Status status;
    {
        std::lock_guard lock(mutex_);
        status = status_of(req->service());
    }
    if (status == HealthCheckResponse::SERVICE_UNKNOWN) {
        // As the protocol says: NOT_FOUND for a service the server does not have.
        reactor->Finish({grpc::StatusCode::NOT_FOUND, "unknown service"});
    } else {
        reply->set_status(status);
        reactor->Finish(grpc::Status::OK);
    }
    return reactor;
}

grpc::ServerWriteReactor<HealthCheckResponse>* HealthService::Watch(
    grpc::CallbackServerContext*, const HealthCheckRequest* req) {
    std::lock_guard lock(mutex_);
    if (int(watchers_.size()) >= max_watches_) return new RefusedWatch;
    auto* w = new Watcher(*this, req->service());
    watchers_.insert(w);
    // An unknown service is watched too: SERVICE_UNKNOWN, as the protocol says.
    w->tell(status_of(req->service()));
    return w;
}

}  // namespace aliquot
