// What a peer can make the gRPC server hold, and whether it keeps listening (issue 30):
// a connection flood that runs the process out of file descriptors, health Watch
// streams without a token, Lease long-polls, FetchImage of a large stored image.
#include <arpa/inet.h>
#include <fcntl.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include <grpc/health/v1/health.grpc.pb.h>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <thread>

#include "aliquot.grpc.pb.h"
#include "exr_io.h"
#include "grpc_server.h"
#include "held_places.h"
#include "peak_memory.h"
#include "scene_loader.h"
#include "test_tokens.h"
#include "trace_job.h"
#include "wire.h"

namespace aliquot {
namespace {

using grpc::health::v1::Health;
using grpc::health::v1::HealthCheckRequest;
using grpc::health::v1::HealthCheckResponse;

// A line of /proc/self/status, in kB ("VmHWM", "VmRSS").
size_t entries(const char* dir) {
    size_t n = 0;
    for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir)) ++n;
    return n;
}

// Whether a new connection (a channel of its own) has health Check answered.
bool answers_a_new_connection(int port) {
    grpc::ChannelArguments args;
    args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
    auto channel = grpc::CreateCustomChannel("127.0.0.1:" + std::to_string(port),
                                             grpc::InsecureChannelCredentials(), args);
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(1));
    HealthCheckResponse reply;
    return Health::NewStub(channel)->Check(&ctx, HealthCheckRequest(), &reply).ok();
}

// Default limits but those `change` sets.
template <typename Change>
GrpcLimits limits(Change&& change) {
    GrpcLimits l;
    change(l);
    return l;
}

// The soft RLIMIT_NOFILE as it was, put back at the end of a test.
class SoftFileLimit {
public:
    SoftFileLimit() { getrlimit(RLIMIT_NOFILE, &saved_); }
    ~SoftFileLimit() { setrlimit(RLIMIT_NOFILE, &saved_); }
    void set(rlim_t soft) {
        rlimit l = saved_;
        l.rlim_cur = soft;
        setrlimit(RLIMIT_NOFILE, &l);
    }
    rlim_t hard() const { return saved_.rlim_max; }

private:
    rlimit saved_{};
};

TEST(GrpcListener, StartingRaisesTheSoftOpenFileLimitToTheHardOne) {
    SoftFileLimit limit;
    if (limit.hard() == RLIM_INFINITY || limit.hard() < 512) GTEST_SKIP();
    limit.set(256);
    Coordinator coordinator{CoordinatorOptions{}};
    GrpcServer server(coordinator, "127.0.0.1:0", testing::test_security());
    rlimit now{};
    getrlimit(RLIMIT_NOFILE, &now);
    EXPECT_EQ(now.rlim_cur, limit.hard());
}

// Floods `port` with plain connections, no byte sent, until this process has no file
// descriptor left, then queues one more: the server's accept fails with EMFILE. Waits
// until gRPC has logged that, then closes them all. stderr goes to a file meanwhile.
void flood_until_accept_fails(int port) {
    const std::string log_path = std::filesystem::temp_directory_path() /
                                 ("aliquot-flood-" + std::to_string(::getpid()) + ".log");
    const int log =
        ::open(log_path.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
    ASSERT_GE(log, 0);
    ::unlink(log_path.c_str());
    const int saved_stderr = ::dup(2);
    ::dup2(log, 2);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(uint16_t(port));
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    const auto connect_to = [&](int fd) {
        return ::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
    };
    // Made while descriptors are free, connected once none are.
    const int last = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    std::vector<int> held;
    {
        SoftFileLimit limit;
        limit.set(entries("/proc/self/fd") + 64);
        for (int fd; held.size() < 100000 &&
                     (fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0)) >= 0;) {
            held.push_back(fd);
            connect_to(fd);
        }
        connect_to(last);
        // gRPC logs "Failed accept4: Too many open files" once its accept has failed.
        std::string text;
        for (int i = 0; i < 400 && text.find("Failed accept4") == std::string::npos;
             ++i) {
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
            char buf[4096];
            const ssize_t n = ::pread(log, buf, sizeof buf, 0);
            text.assign(buf, n > 0 ? size_t(n) : 0);
        }
        for (int fd : held) ::close(fd);
        ::close(last);
        ::dup2(saved_stderr, 2);
        ::close(saved_stderr);
        ::close(log);
        ASSERT_NE(text.find("Failed accept4"), std::string::npos)
            << "the flood never made the server's accept fail; its log: " << text;
    }
}

// The failure itself, as gRPC 1.51 (Debian bookworm's) has it: after one failed accept
// its listener never accepts again, though descriptors are free.
TEST(GrpcListener, WithoutTheWatchdogAFloodLeavesTheListenerDeafForGood) {
    Coordinator coordinator{CoordinatorOptions{}};
    GrpcServer server(coordinator, "127.0.0.1:0", testing::test_security(), {},
                      limits([](GrpcLimits& l) { l.watchdog_failures = 0; }));
    ASSERT_TRUE(answers_a_new_connection(server.port()));
    flood_until_accept_fails(server.port());
    for (int attempt = 0; attempt < 3; ++attempt)
        EXPECT_FALSE(answers_a_new_connection(server.port()));
}

TEST(GrpcListener, TheWatchdogListensAgainAfterAFloodRanOutOfDescriptors) {
    Coordinator coordinator{CoordinatorOptions{}};
    GrpcServer server(coordinator, "127.0.0.1:0", testing::test_security(), {},
                      limits([](GrpcLimits& l) {
                          l.watchdog_period = std::chrono::milliseconds(200);
                          l.watchdog_failures = 2;
                      }));
    ASSERT_TRUE(answers_a_new_connection(server.port()));
    flood_until_accept_fails(server.port());
    bool answered = false;
    for (int attempt = 0; attempt < 60 && !answered; ++attempt)
        answered = answers_a_new_connection(server.port());
    EXPECT_TRUE(answered);
    EXPECT_GE(server.restarts(), 1);
    // The services are back with the listener, token checks and all.
    testing::TokenContext ctx(Role::Client);
    v1::ListRendersReply reply;
    EXPECT_TRUE(v1::ClientService::NewStub(testing::loopback_channel(server.port()))
                    ->ListRenders(&ctx, v1::ListRendersRequest(), &reply)
                    .ok());
}

TEST(GrpcHealth, WatchStreamsNeedNoTokenAndAreCapped) {
    Coordinator coordinator{CoordinatorOptions{}};
    GrpcServer server(coordinator, "127.0.0.1:0", testing::test_security(), {},
                      limits([](GrpcLimits& l) { l.max_health_watches = 4; }));
    auto stub = Health::NewStub(testing::loopback_channel(server.port()));
    std::vector<std::unique_ptr<grpc::ClientContext>> contexts;
    std::vector<std::unique_ptr<grpc::ClientReader<HealthCheckResponse>>> readers;
    HealthCheckResponse reply;
    HealthCheckRequest req;
    for (int i = 0; i < 4; ++i) {
        contexts.push_back(std::make_unique<grpc::ClientContext>());  // no token
        readers.push_back(stub->Watch(contexts.back().get(), req));
        ASSERT_TRUE(readers.back()->Read(&reply)) << "stream " << i;
        EXPECT_EQ(reply.status(), HealthCheckResponse::SERVING);
    }
    {
        grpc::ClientContext one_more;
        auto refused = stub->Watch(&one_more, req);
        EXPECT_FALSE(refused->Read(&reply));
        EXPECT_EQ(refused->Finish().error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    }
    // Check is not a stream: never refused for the Watch streams.
    grpc::ClientContext check;
    EXPECT_TRUE(stub->Check(&check, req, &reply).ok());

    // A closed stream gives its place back.
    contexts.front()->TryCancel();
    readers.front()->Finish();
    bool reopened = false;
    for (int attempt = 0; attempt < 100 && !reopened; ++attempt) {
        contexts.front() = std::make_unique<grpc::ClientContext>();
        readers.front() = stub->Watch(contexts.front().get(), req);
        reopened = readers.front()->Read(&reply);
        if (!reopened) {
            readers.front()->Finish();
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
        }
    }
    ASSERT_TRUE(reopened);
    // Every open Watch hears that the server is stopping.
    server.stop_serving();
    for (size_t i = 0; i < readers.size(); ++i) {
        ASSERT_TRUE(readers[i]->Read(&reply)) << "stream " << i;
        EXPECT_EQ(reply.status(), HealthCheckResponse::NOT_SERVING);
        contexts[i]->TryCancel();
        readers[i]->Finish();
    }
}

// A Lease call sent without waiting for its answer.
struct PendingLease {
    testing::TokenContext ctx{Role::Worker};
    v1::LeaseReply reply;
    grpc::Status status;
    std::unique_ptr<grpc::ClientAsyncResponseReader<v1::LeaseReply>> call;
};

class GrpcLeasePolls : public ::testing::Test {
protected:
    void start(GrpcLimits limits) {
        coordinator_ = std::make_unique<Coordinator>(CoordinatorOptions{});  // no work
        server_ =
            std::make_unique<GrpcServer>(*coordinator_, "127.0.0.1:0",
                                         testing::test_security(), GrpcOptions{}, limits);
        stub_ = v1::WorkerService::NewStub(testing::loopback_channel(server_->port()));
    }
    void TearDown() override {
        coordinator_->stop();  // wakes the polls still waiting
        for (size_t i = answered_; i < polls_.size(); ++i) next();
        server_.reset();
    }
    std::string register_worker(const std::string& name) {
        testing::TokenContext ctx(Role::Worker);
        v1::RegisterRequest req;
        req.set_name(name);
        req.set_threads(1);
        req.set_wire_version(kWireVersion);
        v1::RegisterReply reply;
        EXPECT_TRUE(stub_->Register(&ctx, req, &reply).ok());
        return reply.session();
    }
    // Asks for a lease, willing to wait 20 s for one.
    void poll(const std::string& session) {
        auto p = std::make_unique<PendingLease>();
        p->ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
        v1::LeaseRequest req;
        req.set_session(session);
        req.set_wait_ms(20000);
        p->call = stub_->AsyncLease(&p->ctx, req, &queue_);
        p->call->Finish(&p->reply, &p->status, p.get());
        polls_.push_back(std::move(p));
    }
    // The next poll answered, in the order they are.
    PendingLease& next() {
        void* tag = nullptr;
        bool ok = false;
        EXPECT_TRUE(queue_.Next(&tag, &ok));
        ++answered_;
        return *static_cast<PendingLease*>(tag);
    }

    std::unique_ptr<Coordinator> coordinator_;
    std::unique_ptr<GrpcServer> server_;
    std::unique_ptr<v1::WorkerService::Stub> stub_;
    grpc::CompletionQueue queue_;
    std::vector<std::unique_ptr<PendingLease>> polls_;
    size_t answered_ = 0;
};

TEST_F(GrpcLeasePolls, APollBeyondTheCapsIsAnsweredAtOnceEmptyWithRetryAfter) {
    start(limits([](GrpcLimits& l) {
        l.max_lease_polls = 4;
        l.max_lease_polls_per_session = 2;
    }));
    const std::string a = register_worker("a"), b = register_worker("b"),
                      c = register_worker("c");
    for (int i = 0; i < 3; ++i) poll(a);  // the third is past a's two
    for (int i = 0; i < 2; ++i) poll(b);  // four wait now
    poll(c);                              // past the four in all
    // While six polls are out and no work comes, the two past the caps are answered
    // first: the others wait for work or for 20 s.
    for (int i = 0; i < 2; ++i) {
        PendingLease& p = next();
        ASSERT_TRUE(p.status.ok()) << p.status.error_message();
        EXPECT_FALSE(p.reply.has_lease());
        EXPECT_FALSE(p.reply.register_first());
        EXPECT_GT(p.reply.retry_after_ms(), 0u);
    }
    EXPECT_EQ(answered_, 2u);
}

TEST_F(GrpcLeasePolls, ManyPollsDoNotMakeAThreadEach) {
    start(limits([](GrpcLimits& l) {
        l.max_threads = 32;
        l.max_lease_polls = 8;
        l.max_lease_polls_per_session = 8;
    }));
    const size_t threads_before = entries("/proc/self/task");
    std::vector<std::string> sessions;
    for (int i = 0; i < 20; ++i)
        sessions.push_back(register_worker("w" + std::to_string(i)));
    constexpr int kPolls = 300;
    for (int i = 0; i < kPolls; ++i) poll(sessions[i % sessions.size()]);
    // All but the eight that wait are answered at once (empty, or refused when no server
    // thread is free).
    for (int i = 0; i < kPolls - 8; ++i) {
        PendingLease& p = next();
        EXPECT_FALSE(p.reply.has_lease());
    }
    EXPECT_LT(entries("/proc/self/task"), threads_before + 48);
}

// A render run to its end over the in-process worker link, its image then left on disk.
std::string finished_render(Coordinator& c, uint32_t side) {
    RenderSpec spec;
    spec.scene_name = "cornell-box";
    spec.scene_json = self_contained_scene_json("cornell-box");
    spec.width = spec.height = side;
    spec.seed = 3;
    spec.strategy.method = "uniform";
    spec.strategy.spp = 1;
    const Scene scene = parse_scene(spec.scene_json, "test", ".");
    PathTracer tracer(scene);
    const std::string id = c.submit(spec);
    const std::string session = c.register_worker("tracer", 1).session;
    while (auto grant = c.lease(session, std::chrono::milliseconds(0)))
        c.complete(session, grant->lease_id,
                   trace_sample_job(tracer, grant->geometry, grant->job));
    for (int i = 0; i < 400 && !c.image_file(id); ++i)
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    return id;
}

class GrpcFetchImage : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = std::filesystem::temp_directory_path() /
               ("aliquot-fetch-test-" + std::to_string(::getpid()));
        std::filesystem::remove_all(dir_);
        CoordinatorOptions options;
        options.data_dir = dir_;
        coordinator_ = std::make_unique<Coordinator>(options);
        server_ = std::make_unique<GrpcServer>(*coordinator_, "127.0.0.1:0",
                                               testing::test_security());
        stub_ = v1::ClientService::NewStub(testing::loopback_channel(server_->port()));
    }
    void TearDown() override {
        server_.reset();
        coordinator_.reset();
        std::filesystem::remove_all(dir_);
    }
    // Random bytes of `size` stored as the finished render `id`'s image, sent as they are
    // stored: far more than the sockets' buffers and a stream's window take of a client
    // that reads nothing.
    std::string store_random_image(const std::string& id, size_t size, uint64_t seed) {
        const auto file = coordinator_->image_file(id);
        EXPECT_TRUE(file);
        std::string stored(size, '\0');
        std::mt19937_64 random(seed);
        for (size_t i = 0; i + 8 <= stored.size(); i += 8) {
            const uint64_t v = random();
            std::memcpy(&stored[i], &v, 8);
        }
        if (file) std::ofstream(*file, std::ios::binary | std::ios::trunc) << stored;
        return stored;
    }
    // The server again, with `limits`.
    void restart(const GrpcLimits& limits) {
        server_.reset();
        server_ =
            std::make_unique<GrpcServer>(*coordinator_, "127.0.0.1:0",
                                         testing::test_security(), GrpcOptions{}, limits);
        stub_ = v1::ClientService::NewStub(testing::loopback_channel(server_->port()));
    }
    std::string fetch(const std::string& id, bool aovs) {
        testing::TokenContext ctx(Role::Client);
        v1::FetchImageRequest req;
        req.set_id(id);
        req.set_aovs(aovs);
        auto reader = stub_->FetchImage(&ctx, req);
        std::string bytes;
        v1::FileChunk chunk;
        while (reader->Read(&chunk)) bytes += chunk.data();
        const grpc::Status status = reader->Finish();
        EXPECT_TRUE(status.ok()) << status.error_message();
        return bytes;
    }

    std::filesystem::path dir_;
    std::unique_ptr<Coordinator> coordinator_;
    std::unique_ptr<GrpcServer> server_;
    std::unique_ptr<v1::ClientService::Stub> stub_;
};

TEST_F(GrpcFetchImage, AStoredImageIsSentAsItWasEncodedWithAndWithoutAovs) {
    const std::string id = finished_render(*coordinator_, 40);
    const auto file = coordinator_->image_file(id);
    ASSERT_TRUE(file);
    const Image stored = read_exr(*file);
    ASSERT_FALSE(stored.extra.empty());
    EXPECT_EQ(fetch(id, true), encode_exr(stored));
    Image plain = stored;
    plain.extra.clear();
    // The same bytes as before, when the image was read and encoded again; twice, the
    // second from the copy without AOVs made by the first.
    EXPECT_EQ(fetch(id, false), encode_exr(plain));
    EXPECT_EQ(fetch(id, false), encode_exr(plain));
}

TEST_F(GrpcFetchImage, ConcurrentFetchesOfALargeStoredImageHoldNoCopyOfIt) {
    const std::string id = finished_render(*coordinator_, 8);
    const auto file = coordinator_->image_file(id);
    ASSERT_TRUE(file);
    {
        // In its place a 2048x2048 image with both AOV layers: 80 MB as floats, a
        // megabyte or two on disk (all zero: RLE, issue 33, makes runs of zeros, where a
        // constant 1.0f took 18 MB, which the fetches below would hold whole as clients).
        Image big(2048, 2048);
        for (const char* name : {"sampleCount.Y", "variance.Y"})
            big.extra.push_back({name, std::vector<float>(big.pixel_count(), 0.0f)});
        write_exr(*file, big);
    }
    const testing::PeakMemory peak;
    std::vector<std::thread> fetches;
    for (int i = 0; i < 8; ++i)
        fetches.emplace_back([&, i] { EXPECT_FALSE(fetch(id, i % 2 == 0).empty()); });
    for (std::thread& t : fetches) t.join();
    // Each used to hold the decoded image (80 MB) and its encoding.
    EXPECT_LT(peak.grown_kb(), 64u * 1024) << "kB";
}

// Review (hostile clients): a client that stops reading a FetchImage held its call (a
// server thread, one of the 16 places) for as long as its gRPC answered keepalive pings:
// the server's Write waits for room in the stream's window. Its writes must now keep a
// pace (GrpcLimits::stream_min_rate after stream_grace, shortened here), or the call is
// cut and the next fetch gets its place. Before, every later fetch was
// RESOURCE_EXHAUSTED.
TEST_F(GrpcFetchImage, AClientThatStopsReadingIsCutAndTheNextFetchGetsItsPlace) {
    const std::string id = finished_render(*coordinator_, 8);
    const std::string stored = store_random_image(id, size_t(32) << 20, 7);
    restart(limits([](GrpcLimits& l) {
        l.max_fetches = 1;
        l.stream_grace = std::chrono::milliseconds(500);
        l.stream_min_rate = 16 << 20;
    }));
    v1::FetchImageRequest req;
    req.set_id(id);
    req.set_aovs(true);

    // The stalled client: a connection of its own, whose window does not grow.
    grpc::ChannelArguments args;
    args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
    args.SetInt(GRPC_ARG_HTTP2_BDP_PROBE, 0);
    auto stalled_stub = v1::ClientService::NewStub(
        grpc::CreateCustomChannel("127.0.0.1:" + std::to_string(server_->port()),
                                  grpc::InsecureChannelCredentials(), args));
    testing::TokenContext stalled_ctx(Role::Client);
    auto stalled = stalled_stub->FetchImage(&stalled_ctx, req);
    v1::FileChunk chunk;
    ASSERT_TRUE(stalled->Read(&chunk));  // it holds the one place, and reads no more
    size_t stalled_bytes = chunk.data().size();

    // Refused while the stalled client holds the place; served once it is cut (a reader
    // that takes the whole file at once). A generous number of tries, not a timing check.
    bool served = false;
    for (int attempt = 0; attempt < 200 && !served; ++attempt) {
        testing::TokenContext ctx(Role::Client);
        auto reader = stub_->FetchImage(&ctx, req);
        std::string bytes;
        while (reader->Read(&chunk)) bytes += chunk.data();
        served = reader->Finish().ok() && bytes == stored;
        if (!served) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    EXPECT_TRUE(served);
    // The stalled stream was cut short, with an error.
    while (stalled->Read(&chunk)) stalled_bytes += chunk.data().size();
    EXPECT_FALSE(stalled->Finish().ok());
    EXPECT_LT(stalled_bytes, stored.size());
}

// Review of issue 33 (hostile clients): the pace bounds how long one stream holds a
// FetchImage place, not how many a client that reconnects as fast as it is cut opens. One
// address now holds at most its share (2 of 3 here): two fetches from 127.0.0.1 that stop
// reading hold its share, a third from it is refused, and one from 127.0.0.2 is served.
TEST_F(GrpcFetchImage, OneAddressHoldsAtMostItsShareAndAnotherIsStillServed) {
    const std::string id = finished_render(*coordinator_, 8);
    const std::string stored = store_random_image(id, size_t(16) << 20, 11);
    restart(limits([](GrpcLimits& l) {
        l.max_fetches = 3;
        l.max_fetches_per_peer = 2;
    }));
    v1::FetchImageRequest req;
    req.set_id(id);
    req.set_aovs(true);
    grpc::ChannelArguments stalled_args;
    stalled_args.SetInt(GRPC_ARG_HTTP2_BDP_PROBE, 0);
    struct Stalled {
        std::unique_ptr<v1::ClientService::Stub> stub;
        testing::TokenContext ctx{Role::Client};
        std::unique_ptr<grpc::ClientReader<v1::FileChunk>> reader;
    };
    std::vector<std::unique_ptr<Stalled>> stalled;
    v1::FileChunk chunk;
    for (int i = 0; i < 2; ++i) {
        auto s = std::make_unique<Stalled>();
        s->ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
        const auto channel =
            testing::channel_from("127.0.0.1", server_->port(), stalled_args);
        ASSERT_TRUE(channel);
        s->stub = v1::ClientService::NewStub(channel);
        s->reader = s->stub->FetchImage(&s->ctx, req);
        ASSERT_TRUE(s->reader->Read(&chunk));  // it holds a place, and reads no more
        stalled.push_back(std::move(s));
    }
    {
        testing::TokenContext ctx(Role::Client);
        auto refused = stub_->FetchImage(&ctx, req);  // from 127.0.0.1 too
        const bool served = refused->Read(&chunk);
        EXPECT_FALSE(served);
        if (served) ctx.TryCancel();  // without the share: ended, not read whole
        const grpc::Status status = refused->Finish();
        EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
        EXPECT_NE(status.error_message().find("at most 2 from one address"),
                  std::string::npos)
            << status.error_message();
    }
    {
        const auto channel = testing::channel_from("127.0.0.2", server_->port());
        ASSERT_TRUE(channel) << "127.0.0.2 is this host";
        auto other = v1::ClientService::NewStub(channel);
        testing::TokenContext ctx(Role::Client);
        auto reader = other->FetchImage(&ctx, req);
        std::string bytes;
        while (reader->Read(&chunk)) bytes += chunk.data();
        const grpc::Status status = reader->Finish();
        EXPECT_TRUE(status.ok()) << status.error_message();
        EXPECT_TRUE(bytes == stored);
    }
    for (auto& s : stalled) {
        s->ctx.TryCancel();
        s->reader->Finish();
    }
}

// The same for FetchImage of a running render, encoded in memory (GrpcLimits'
// max_fetches_from_memory, 2): one address holds at most one of them.
TEST_F(GrpcFetchImage, OneAddressHoldsOneFetchOfARunningRenderAndAnotherIsStillServed) {
    testing::HeldPlaces held(1);
    restart(limits([&](GrpcLimits& l) { l.running_fetch_admitted = held.hook(); }));
    v1::FetchImageRequest req;
    {
        testing::TokenContext ctx(Role::Client);
        v1::RenderInfo info;
        ASSERT_TRUE(stub_
                        ->Submit(&ctx,
                                 testing::small_submission(
                                     self_contained_scene_json("cornell-box"), 8),
                                 &info)
                        .ok());
        req.set_id(info.id());  // no worker: it stays in memory
    }
    const auto status_of = [&](v1::ClientService::Stub& from) {
        testing::TokenContext ctx(Role::Client);
        ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
        auto reader = from.FetchImage(&ctx, req);
        v1::FileChunk chunk;
        while (reader->Read(&chunk)) {
        }
        return reader->Finish();
    };
    std::thread holder([&] { status_of(*stub_); });
    ASSERT_TRUE(held.all_held());
    const grpc::Status refused = status_of(*stub_);  // 127.0.0.1 again
    EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_NE(refused.error_message().find("at most 1 from one address"),
              std::string::npos)
        << refused.error_message();
    const auto channel = testing::channel_from("127.0.0.2", server_->port());
    ASSERT_TRUE(channel) << "127.0.0.2 is this host";
    const grpc::Status other = status_of(*v1::ClientService::NewStub(channel));
    // Served: past the places, whatever the render's image is by then.
    EXPECT_NE(other.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED)
        << other.error_message();
    EXPECT_EQ(held.admitted(), 2u);
    held.release();
    holder.join();
}

// The same for Watch streams (2 of 3 here).
TEST(GrpcWatch, OneAddressHoldsAtMostItsShareAndAnotherIsStillServed) {
    Coordinator coordinator{CoordinatorOptions{}};  // no worker: the render stays queued
    GrpcServer server(coordinator, "127.0.0.1:0", testing::test_security(), GrpcOptions{},
                      limits([](GrpcLimits& l) {
                          l.max_watches = 3;
                          l.max_watches_per_peer = 2;
                      }));
    auto stub = v1::ClientService::NewStub(testing::loopback_channel(server.port()));
    v1::GetRenderRequest req;
    {
        testing::TokenContext ctx(Role::Client);
        v1::RenderInfo info;
        const grpc::Status status = stub->Submit(
            &ctx, testing::small_submission(self_contained_scene_json("cornell-box"), 8),
            &info);
        ASSERT_TRUE(status.ok()) << status.error_message();
        req.set_id(info.id());
    }
    std::vector<std::unique_ptr<testing::TokenContext>> contexts;
    std::vector<std::unique_ptr<grpc::ClientReader<v1::RenderInfo>>> readers;
    const auto watch = [&](v1::ClientService::Stub& from) {
        contexts.push_back(std::make_unique<testing::TokenContext>(Role::Client));
        // Ends the test rather than hang it, were a stream to stay open.
        contexts.back()->set_deadline(std::chrono::system_clock::now() +
                                      std::chrono::seconds(30));
        readers.push_back(from.Watch(contexts.back().get(), req));
        v1::RenderInfo info;
        return readers.back()->Read(&info);
    };
    ASSERT_TRUE(watch(*stub));
    ASSERT_TRUE(watch(*stub));
    const bool served = watch(*stub);
    EXPECT_FALSE(served);
    if (served) contexts.back()->TryCancel();  // without the share: ended
    const grpc::Status refused = readers.back()->Finish();
    readers.pop_back();
    contexts.pop_back();
    EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_NE(refused.error_message().find("at most 2 from one address"),
              std::string::npos)
        << refused.error_message();
    const auto channel = testing::channel_from("127.0.0.2", server.port());
    ASSERT_TRUE(channel) << "127.0.0.2 is this host";
    auto other = v1::ClientService::NewStub(channel);
    EXPECT_TRUE(watch(*other));
    for (size_t i = 0; i < readers.size(); ++i) {
        contexts[i]->TryCancel();
        readers[i]->Finish();
    }
}

}  // namespace
}  // namespace aliquot
