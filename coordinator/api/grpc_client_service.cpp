// aliquot.v1.ClientService over Coordinator (grpc_client_service.h): every call admitted
// by the client token first, the streams (Watch, FetchImage) each holding a place.
#include "grpc_client_service.h"

#include <algorithm>
#include <chrono>
#include <fstream>
#include <new>
#include <string>
#include <thread>

#include "admission.h"
#include "aliquot.grpc.pb.h"
#include "exr_io.h"
#include "grpc_access.h"
#include "render_proto.h"
#include "scene_loader.h"
#include "shown_id.h"
#include "stored_image.h"
#include "stream_watchdog.h"

namespace aliquot {

namespace {

using grpc::ServerContext;
using grpc::Status;
using grpc::StatusCode;

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
            if (r.mean_bias) out->set_mean_bias(*r.mean_bias);
            if (r.mean_bias_se) out->set_mean_bias_se(*r.mean_bias_se);
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

}  // namespace

std::unique_ptr<grpc::Service> make_client_service(Coordinator& c, const Tokens& tokens,
                                                   const GrpcLimits& limits) {
    return std::make_unique<ClientServiceImpl>(c, tokens, limits);
}

}  // namespace aliquot
