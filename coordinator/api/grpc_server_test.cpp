// The worker service over real gRPC on loopback, fed results a broken or malicious worker
// could send. None may touch the image; every job must still be traced exactly once.
#include "grpc_server.h"
#include "test_tokens.h"

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <sys/resource.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "aliquot.grpc.pb.h"
#include "exr_io.h"
#include "scene_loader.h"
#include "sum_records.h"
#include "trace_job.h"
#include "wire.h"

namespace aliquot {
namespace {

// A result message whose sums are changed as a buggy or hostile worker's would be: the
// records decoded, edited and encoded again, so only the values differ.
template <class Edit>
v1::SampleJobResult with_sums(const v1::SampleJobResult& message, Edit edit) {
    SampleJobResult result = from_proto(message);
    edit(result);
    v1::SampleJobResult out;
    to_proto(result, out);
    return out;
}

// The message with its last pixel's record cut off: the wrong pixel count.
v1::SampleJobResult one_pixel_short(v1::SampleJobResult message) {
    message.mutable_pixels()->resize(message.pixels().size() - kPixelRecordBytes);
    return message;
}

class WorkerServiceTest : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = std::filesystem::temp_directory_path() /
               ("aliquot-grpc-test-" + std::to_string(::getpid()));
        std::filesystem::remove_all(dir_);
        CoordinatorOptions options;
        options.data_dir = dir_;
        coordinator_ = std::make_unique<Coordinator>(options);
        server_ = std::make_unique<GrpcServer>(*coordinator_, "127.0.0.1:0",
                                               testing::test_security());
        stub_ = v1::WorkerService::NewStub(testing::loopback_channel(server_->port()));

        RenderSpec& spec = spec_;
        spec.scene_name = "cornell-box";
        spec.scene_json = self_contained_scene_json("cornell-box");
        spec.width = 8;  // one job: the whole image fits one 32x32 tile
        spec.height = 8;
        spec.seed = 3;
        spec.strategy.method = "uniform";
        spec.strategy.spp = 1;
        scene_ = parse_scene(spec.scene_json, "test", ".");
        tracer_ = std::make_unique<PathTracer>(scene_);
        id_ = coordinator_->submit(spec);
        session_ = register_over_wire("tester");
    }
    void TearDown() override {
        server_.reset();
        coordinator_.reset();
        std::filesystem::remove_all(dir_);
    }

    std::string register_over_wire(const std::string& name) {
        testing::TokenContext ctx(Role::Worker);
        v1::RegisterRequest req;
        req.set_name(name);
        req.set_threads(1);
        req.set_wire_version(kWireVersion);
        v1::RegisterReply reply;
        EXPECT_TRUE(stub_->Register(&ctx, req, &reply).ok());
        return reply.session();
    }
    v1::Lease lease() {
        testing::TokenContext ctx(Role::Worker);
        v1::LeaseRequest req;
        req.set_session(session_);
        req.set_wait_ms(2000);
        v1::LeaseReply reply;
        EXPECT_TRUE(stub_->Lease(&ctx, req, &reply).ok());
        EXPECT_TRUE(reply.has_lease());
        return reply.lease();
    }
    v1::SampleJobResult trace(const v1::Lease& l) {
        const SampleJobResult r = trace_sample_job(
            *tracer_, {l.width(), l.height(), l.seed()}, from_proto(l.job()));
        v1::SampleJobResult out;
        to_proto(r, out);
        return out;
    }
    v1::CompleteReply complete_as(const std::string& session, uint64_t lease_id,
                                  const v1::SampleJobResult& result) {
        testing::TokenContext ctx(Role::Worker);
        v1::CompleteRequest req;
        req.set_session(session);
        req.set_lease_id(lease_id);
        *req.mutable_result() = result;
        v1::CompleteReply reply;
        EXPECT_TRUE(stub_->Complete(&ctx, req, &reply).ok());
        return reply;
    }
    v1::CompleteStatus complete(uint64_t lease_id, const v1::SampleJobResult& result) {
        return complete_as(session_, lease_id, result).status();
    }
    // Renew or Abandon (`give_back`) as `session`: whether the lease was that session's.
    bool renew_as(const std::string& session, uint64_t lease_id, bool give_back = false) {
        testing::TokenContext ctx(Role::Worker);
        v1::RenewRequest req;
        req.set_session(session);
        req.set_lease_id(lease_id);
        v1::RenewReply reply;
        const grpc::Status status = give_back ? stub_->Abandon(&ctx, req, &reply)
                                              : stub_->Renew(&ctx, req, &reply);
        EXPECT_TRUE(status.ok()) << status.error_message();
        return reply.valid();
    }
    bool fail_as(const std::string& session, uint64_t lease_id) {
        testing::TokenContext ctx(Role::Worker);
        v1::FailRequest req;
        req.set_session(session);
        req.set_lease_id(lease_id);
        req.set_reason("cannot open mesh.obj");
        v1::FailReply reply;
        EXPECT_TRUE(stub_->Fail(&ctx, req, &reply).ok());
        return reply.accepted();
    }
    uint64_t samples_merged() { return coordinator_->info(id_)->samples_done; }

    std::filesystem::path dir_;
    std::unique_ptr<Coordinator> coordinator_;
    std::unique_ptr<GrpcServer> server_;
    std::unique_ptr<v1::WorkerService::Stub> stub_;
    Scene scene_;
    std::unique_ptr<PathTracer> tracer_;
    std::string id_;
    RenderSpec spec_;
    std::string session_;  // the worker "tester"'s
};

TEST_F(WorkerServiceTest, RejectsAResultWithTheWrongPixelCountAndReissuesTheJob) {
    const v1::Lease first = lease();
    const v1::SampleJobResult bad = one_pixel_short(trace(first));
    EXPECT_EQ(complete(first.lease_id(), bad), v1::COMPLETE_STATUS_REJECTED);
    EXPECT_EQ(samples_merged(), 0u);
    const v1::Lease again = lease();  // the same job, under a new lease
    EXPECT_NE(again.lease_id(), first.lease_id());
    EXPECT_EQ(again.job().rect().width(), first.job().rect().width());
    EXPECT_EQ(complete(again.lease_id(), trace(again)), v1::COMPLETE_STATUS_MERGED);
    EXPECT_EQ(coordinator_->info(id_)->state, RenderState::Done);
}

// Issue 14: one round trip a job. A Complete asking for the next lease gets it on its
// reply after a merged result, and none after a refused one (that worker backs off).
TEST_F(WorkerServiceTest, ACompleteCarriesTheNextLeaseAfterAMergedResult) {
    RenderSpec second = spec_;
    second.seed = 4;
    const std::string id2 = coordinator_->submit(second);
    const v1::Lease first = lease();
    const auto complete_and_lease = [&](const v1::Lease& l,
                                        const v1::SampleJobResult& result) {
        testing::TokenContext ctx(Role::Worker);
        v1::CompleteRequest req;
        req.set_session(session_);
        req.set_lease_id(l.lease_id());
        *req.mutable_result() = result;
        req.set_lease_next(true);
        req.set_next_wait_ms(0);
        v1::CompleteReply reply;
        EXPECT_TRUE(stub_->Complete(&ctx, req, &reply).ok());
        return reply;
    };
    const v1::CompleteReply merged = complete_and_lease(first, trace(first));
    EXPECT_EQ(merged.status(), v1::COMPLETE_STATUS_MERGED);
    ASSERT_TRUE(merged.next().has_lease());
    const v1::Lease& next = merged.next().lease();
    EXPECT_EQ(next.render_id(), id2);
    EXPECT_EQ(coordinator_->leases_out(), 1u);

    const v1::SampleJobResult wrong = one_pixel_short(trace(next));
    const v1::CompleteReply rejected = complete_and_lease(next, wrong);
    EXPECT_EQ(rejected.status(), v1::COMPLETE_STATUS_REJECTED);
    EXPECT_FALSE(rejected.has_next());
    EXPECT_EQ(coordinator_->leases_out(), 0u);  // the job waits for a lease asked for
}

TEST_F(WorkerServiceTest, RejectsNegativeSampleCounts) {
    const v1::Lease l = lease();
    // -1 as a worker with a sign bug would send it
    const v1::SampleJobResult bad = with_sums(
        trace(l), [](SampleJobResult& r) { r.pixels[0].samples = uint64_t(-1); });
    EXPECT_EQ(complete(l.lease_id(), bad), v1::COMPLETE_STATUS_REJECTED);
    EXPECT_EQ(samples_merged(), 0u);
}

TEST_F(WorkerServiceTest, RejectsNonFiniteSums) {
    const v1::Lease l = lease();
    const v1::SampleJobResult bad = with_sums(trace(l), [](SampleJobResult& r) {
        r.pixels[0].even[0] = std::numeric_limits<double>::quiet_NaN();
    });
    EXPECT_EQ(complete(l.lease_id(), bad), v1::COMPLETE_STATUS_REJECTED);
    EXPECT_EQ(samples_merged(), 0u);
}

TEST_F(WorkerServiceTest, OnlyTheHolderCanGiveALeaseBack) {
    const v1::Lease l = lease();
    EXPECT_FALSE(coordinator_->abandon(register_over_wire("intruder"), l.lease_id()));
    EXPECT_EQ(complete(l.lease_id(), trace(l)), v1::COMPLETE_STATUS_MERGED);
    EXPECT_EQ(samples_merged(), 64u);
}

TEST_F(WorkerServiceTest, IgnoresAResultForAnUnknownLease) {
    const v1::Lease l = lease();
    EXPECT_EQ(complete(l.lease_id() + 12345, trace(l)), v1::COMPLETE_STATUS_IGNORED);
    EXPECT_EQ(samples_merged(), 0u);
}

TEST_F(WorkerServiceTest, IgnoresAResultSentTwice) {
    const v1::Lease l = lease();
    const v1::SampleJobResult r = trace(l);
    EXPECT_EQ(complete(l.lease_id(), r), v1::COMPLETE_STATUS_MERGED);
    const Image once = *coordinator_->image(id_, true);
    EXPECT_EQ(complete(l.lease_id(), r), v1::COMPLETE_STATUS_IGNORED);
    const Image twice = *coordinator_->image(id_, true);
    EXPECT_EQ(once.rgb, twice.rgb);
    EXPECT_EQ(samples_merged(), 64u);
}

TEST_F(WorkerServiceTest, IgnoresALateResultForALeaseGivenToAnotherWorker) {
    const v1::Lease l = lease();
    EXPECT_TRUE(renew_as(session_, l.lease_id(), /*give_back=*/true));
    const v1::Lease reissued = lease();
    EXPECT_EQ(complete(l.lease_id(), trace(l)), v1::COMPLETE_STATUS_IGNORED);
    EXPECT_EQ(complete(reissued.lease_id(), trace(reissued)), v1::COMPLETE_STATUS_MERGED);
}

// Issue 12, item 7: a render past the coordinator's memory budget is RESOURCE_EXHAUSTED.
TEST(ClientServiceMemory, ASubmissionPastTheMemoryBudgetIsResourceExhausted) {
    CoordinatorOptions options;
    options.memory_limit = 1024;
    Coordinator coordinator(options);
    GrpcServer server(coordinator, "127.0.0.1:0", testing::test_security());
    auto stub = v1::ClientService::NewStub(testing::loopback_channel(server.port()));
    testing::TokenContext ctx(Role::Client);
    const v1::SubmitRequest req =
        testing::small_submission(self_contained_scene_json("cornell-box"), 64);
    v1::RenderInfo reply;
    const grpc::Status status = stub->Submit(&ctx, req, &reply);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_NE(status.error_message().find("--memory-limit"), std::string::npos)
        << status.error_message();
    EXPECT_TRUE(coordinator.list(10).empty());
}

// `image`'s bytes with the header's data window claiming side x side and no pixels
// behind it: what a hostile client sends to make the coordinator allocate.
std::string claiming(const Image& image, int32_t side) {
    std::string bytes = encode_exr(image);
    const std::string key("dataWindow\0box2i\0", 17);
    const size_t at = bytes.find(key) + key.size() + 4;  // past the attribute's size
    const int32_t window[4] = {0, 0, side - 1, side - 1};
    std::memcpy(&bytes[at], window, sizeof window);  // little-endian, as EXR is
    return bytes;
}

// Issue 30, item 6: an 8192x8192 reference of 14 channels under --memory-limit 2G was
// decoded (3.6 GB) before the budget refused its render. The render's budget and the
// reference's header are checked first: refused at once, nothing allocated.
TEST(ClientServiceMemory, AReferencePastTheBudgetIsRefusedBeforeItIsDecoded) {
    CoordinatorOptions options;
    options.memory_limit = uint64_t(2) << 30;
    Coordinator coordinator(options);
    GrpcServer server(coordinator, "127.0.0.1:0", testing::test_security());
    auto stub = v1::ClientService::NewStub(testing::loopback_channel(server.port()));
    Image many(1, 1);
    for (int c = 0; c < 11; ++c) many.extra.push_back({"c" + std::to_string(c), {0.0f}});
    rusage before{};
    getrusage(RUSAGE_SELF, &before);
    {
        testing::TokenContext ctx(Role::Client);
        v1::SubmitRequest req =
            testing::small_submission(self_contained_scene_json("cornell-box"), 8192);
        req.set_reference_exr(claiming(many, 8192));
        v1::RenderInfo reply;
        const grpc::Status status = stub->Submit(&ctx, req, &reply);
        EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
        EXPECT_NE(status.error_message().find("--memory-limit"), std::string::npos)
            << status.error_message();
    }
    rusage after{};
    getrusage(RUSAGE_SELF, &after);
    EXPECT_LT(after.ru_maxrss - before.ru_maxrss, 64 * 1024) << "KiB more at the peak";
    // A render that fits, with a reference whose extra layers do not fit beside it.
    CoordinatorOptions tight;
    tight.memory_limit = render_memory_estimate(64, 64, true);
    Coordinator small(tight);
    GrpcServer small_server(small, "127.0.0.1:0", testing::test_security());
    auto small_stub =
        v1::ClientService::NewStub(testing::loopback_channel(small_server.port()));
    for (const bool layers : {true, false}) {
        testing::TokenContext ctx(Role::Client);
        v1::SubmitRequest req =
            testing::small_submission(self_contained_scene_json("cornell-box"), 64);
        Image reference(64, 64);
        if (layers) reference.extra.push_back({"Z", std::vector<float>(64 * 64, 0.0f)});
        req.set_reference_exr(encode_exr(reference));
        v1::RenderInfo reply;
        const grpc::Status status = small_stub->Submit(&ctx, req, &reply);
        EXPECT_EQ(status.error_code(),
                  layers ? grpc::StatusCode::RESOURCE_EXHAUSTED : grpc::StatusCode::OK)
            << status.error_message();
    }
}

// Issue 12, item 9: a worker a restarted coordinator does not know is told to register.
// Issue 13: the submitted reference crossed through /tmp/aliquot-PID-in-N.exr, and a
// local user's symlink there was overwritten with the uploaded bytes. Now it never
// touches a file.
TEST(ClientServiceReference, ASubmittedReferenceIsWrittenToNoPredictableFile) {
    namespace fs = std::filesystem;
    const fs::path victim = fs::temp_directory_path() /
                            ("aliquot_victim_" + std::to_string(getpid()) + ".txt");
    std::ofstream(victim) << "a local user's file";
    std::vector<fs::path> traps;
    for (const char* tag : {"in", "out"})
        for (int n = 0; n < 4; ++n) {
            traps.push_back(fs::temp_directory_path() /
                            ("aliquot-" + std::to_string(getpid()) + "-" + tag + "-" +
                             std::to_string(n) + ".exr"));
            fs::remove(traps.back());
            fs::create_symlink(victim, traps.back());
        }
    {
        Coordinator coordinator(CoordinatorOptions{});
        GrpcServer server(coordinator, "127.0.0.1:0", testing::test_security());
        auto stub = v1::ClientService::NewStub(testing::loopback_channel(server.port()));
        testing::TokenContext ctx(Role::Client);
        v1::SubmitRequest req =
            testing::small_submission(self_contained_scene_json("cornell-box"), 8);
        req.set_reference_exr(encode_exr(Image(8, 8)));
        v1::RenderInfo reply;
        EXPECT_TRUE(stub->Submit(&ctx, req, &reply).ok());
    }
    std::ostringstream text;
    text << std::ifstream(victim).rdbuf();
    EXPECT_EQ(text.str(), "a local user's file");
    for (const fs::path& t : traps) fs::remove(t);
    fs::remove(victim);
}

// Found in review: any name was a key of the coordinator's worker table and a store row.
TEST_F(WorkerServiceTest, AWorkerNameLongerThan128BytesIsRefused) {
    testing::TokenContext ctx(Role::Worker);
    v1::RegisterRequest reg;
    reg.set_name(std::string(129, 'w'));
    reg.set_threads(1);
    v1::RegisterReply reply;
    EXPECT_EQ(stub_->Register(&ctx, reg, &reply).error_code(),
              grpc::StatusCode::INVALID_ARGUMENT);
}

// Review of issue 34: a worker from before the first-hit sums (wire version 0, which
// sends no version) registered and leased, and each of its results was refused and
// counted as a job failure. It is turned away at registration, saying why.
TEST_F(WorkerServiceTest, AWorkerOfAnotherWireVersionIsRefusedAtRegistration) {
    for (const uint32_t version : {0u, kWireVersion - 1, kWireVersion + 1}) {
        testing::TokenContext ctx(Role::Worker);
        v1::RegisterRequest reg;
        reg.set_name("old");
        reg.set_threads(1);
        reg.set_wire_version(version);
        v1::RegisterReply reply;
        const grpc::Status status = stub_->Register(&ctx, reg, &reply);
        EXPECT_EQ(status.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
        EXPECT_NE(status.error_message().find("wire protocol version " +
                                              std::to_string(version)),
                  std::string::npos)
            << status.error_message();
        EXPECT_TRUE(reply.session().empty());
    }
    for (const WorkerStatus& w : coordinator_->workers()) EXPECT_NE(w.name, "old");
}

// Issue 32: what a worker says of itself is kept and listed, so it is bounded like its
// name.
TEST_F(WorkerServiceTest, AWorkerHostOrVersionLongerThan128BytesIsRefused) {
    for (const bool host : {true, false}) {
        testing::TokenContext ctx(Role::Worker);
        v1::RegisterRequest reg;
        reg.set_name("long");
        reg.set_threads(1);
        if (host)
            reg.set_host(std::string(129, 'h'));
        else
            reg.set_version(std::string(129, 'v'));
        v1::RegisterReply reply;
        EXPECT_EQ(stub_->Register(&ctx, reg, &reply).error_code(),
                  grpc::StatusCode::INVALID_ARGUMENT);
    }
    EXPECT_FALSE(coordinator_->knows_worker("long"));
}

// Review of issue 33 (hostile workers): a worker's threads count as the farm's cores,
// two jobs each a round, so one Register stating 2^32-1 threads had every round of every
// render cut into the smallest tiles, 16 pixels a side (a 1920x1080 round into 8,160
// jobs). More than kMaxWorkerThreads is refused and registers nothing.
TEST_F(WorkerServiceTest, AWorkerStatingMoreThanTheMostThreadsIsRefused) {
    for (const uint32_t threads : {kMaxWorkerThreads + 1, uint32_t(UINT32_MAX)}) {
        testing::TokenContext ctx(Role::Worker);
        v1::RegisterRequest reg;
        reg.set_name("many");
        reg.set_threads(threads);
        reg.set_wire_version(kWireVersion);
        v1::RegisterReply reply;
        const grpc::Status status = stub_->Register(&ctx, reg, &reply);
        EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << threads;
        EXPECT_NE(status.error_message().find("at most 1024 threads"), std::string::npos)
            << status.error_message();
    }
    EXPECT_FALSE(coordinator_->knows_worker("many"));
    testing::TokenContext ctx(Role::Worker);
    v1::RegisterRequest reg;
    reg.set_name("many");
    reg.set_threads(kMaxWorkerThreads);
    reg.set_wire_version(kWireVersion);
    v1::RegisterReply reply;
    EXPECT_TRUE(stub_->Register(&ctx, reg, &reply).ok());
}

TEST_F(WorkerServiceTest, TellsAWorkerItDoesNotKnowToRegisterFirst) {
    v1::LeaseRequest req;
    req.set_session("0123456789abcdef0123456789abcdef");  // never issued here
    v1::LeaseReply reply;
    {
        testing::TokenContext ctx(Role::Worker);
        ASSERT_TRUE(stub_->Lease(&ctx, req, &reply).ok());
    }
    EXPECT_TRUE(reply.register_first());
    EXPECT_FALSE(reply.has_lease());
    {
        testing::TokenContext ctx(Role::Worker);
        v1::RegisterRequest reg;
        reg.set_name("stranger");
        reg.set_threads(3);
        reg.set_wire_version(kWireVersion);
        v1::RegisterReply ok;
        ASSERT_TRUE(stub_->Register(&ctx, reg, &ok).ok());
        EXPECT_EQ(ok.session().size(), 32u);
        req.set_session(ok.session());
    }
    {
        testing::TokenContext ctx(Role::Worker);
        ASSERT_TRUE(stub_->Lease(&ctx, req, &reply).ok());
    }
    EXPECT_FALSE(reply.register_first());
    EXPECT_TRUE(reply.has_lease());
}

// Issue 12, item 5: a worker that cannot trace a lease says so, with why.
TEST_F(WorkerServiceTest, AFailedLeaseIsCountedOnceAndTheJobGoesBack) {
    const v1::Lease l = lease();
    // Another session, even under the holder's name (so that it is still the only
    // worker alive), is not heard.
    EXPECT_FALSE(fail_as(register_over_wire("tester"), l.lease_id()));
    EXPECT_TRUE(fail_as(session_, l.lease_id()));
    EXPECT_FALSE(fail_as(session_, l.lease_id()));  // counted once
    const v1::Lease again = lease();                // the only worker alive tries again
    EXPECT_NE(again.lease_id(), l.lease_id());
    EXPECT_EQ(complete(again.lease_id(), trace(again)), v1::COMPLETE_STATUS_MERGED);
}

// Issue 13: worker T completed V's lease with radiance 100 and correct counts: merged,
// V's honest result ignored, the final image wrong. Over the wire now, a second
// registered worker (one named like the holder too) is refused on every call about the
// lease, nothing changes, and the holder's result gives the image a render without the
// intruder gives.
TEST_F(WorkerServiceTest, AnotherWorkerCannotCompleteOrRevokeALease) {
    const v1::Lease l = lease();
    const v1::SampleJobResult honest = trace(l);
    for (const std::string& intruder :
         {register_over_wire("intruder"), register_over_wire("tester")}) {
        ASSERT_FALSE(intruder.empty());
        ASSERT_NE(intruder, session_);
        // The right rectangle and sample counts.
        const v1::SampleJobResult bogus = with_sums(honest, [](SampleJobResult& r) {
            for (PixelSums& p : r.pixels)
                for (int c = 0; c < 3; ++c) {
                    p.even[c] = 100.0 * double(p.samples);
                    p.odd[c] = 0;
                }
        });
        const v1::CompleteReply reply = complete_as(intruder, l.lease_id(), bogus);
        EXPECT_EQ(reply.status(), v1::COMPLETE_STATUS_IGNORED);
        EXPECT_EQ(reply.message(), "not your lease");
        v1::SampleJobResult wrong = honest;  // would be rejected, the job re-issued
        wrong.mutable_rect()->set_x(1);
        EXPECT_EQ(complete_as(intruder, l.lease_id(), wrong).status(),
                  v1::COMPLETE_STATUS_IGNORED);
        const v1::SampleJobResult malformed = one_pixel_short(honest);
        EXPECT_EQ(complete_as(intruder, l.lease_id(), malformed).status(),
                  v1::COMPLETE_STATUS_IGNORED);
        EXPECT_FALSE(renew_as(intruder, l.lease_id()));
        EXPECT_FALSE(renew_as(intruder, l.lease_id(), /*give_back=*/true));
        EXPECT_FALSE(fail_as(intruder, l.lease_id()));
    }
    EXPECT_EQ(samples_merged(), 0u);
    EXPECT_EQ(coordinator_->leases_out(), 1u);
    EXPECT_TRUE(renew_as(session_, l.lease_id()));
    EXPECT_EQ(complete(l.lease_id(), honest), v1::COMPLETE_STATUS_MERGED);
    EXPECT_EQ(coordinator_->info(id_)->state, RenderState::Done);

    // The same render with no intruder, in memory.
    CoordinatorOptions plain;
    Coordinator alone(plain);
    const std::string id = alone.submit(spec_);
    const std::string session = alone.register_worker("tester", 1).session;
    const auto grant = alone.lease(session, std::chrono::milliseconds(0));
    ASSERT_TRUE(grant);
    EXPECT_EQ(alone.complete(session, grant->lease_id, from_proto(honest)).status,
              CompleteStatus::Merged);
    EXPECT_EQ(coordinator_->image(id_, true)->rgb, alone.image(id, true)->rgb);
}

// A session the coordinator never issued (or issued before a restart) is UNAUTHENTICATED
// on every call but Lease, and changes nothing: the worker registers again.
TEST_F(WorkerServiceTest, AnUnknownSessionIsToldToRegister) {
    const v1::Lease l = lease();
    const std::string stranger = "ffffffffffffffffffffffffffffffff";
    {
        testing::TokenContext ctx(Role::Worker);
        v1::CompleteRequest req;
        req.set_session(stranger);
        req.set_lease_id(l.lease_id());
        *req.mutable_result() = trace(l);
        v1::CompleteReply reply;
        EXPECT_EQ(stub_->Complete(&ctx, req, &reply).error_code(),
                  grpc::StatusCode::UNAUTHENTICATED);
    }
    {
        testing::TokenContext ctx(Role::Worker);
        v1::RenewRequest req;
        req.set_session(stranger);
        req.set_lease_id(l.lease_id());
        v1::RenewReply reply;
        EXPECT_EQ(stub_->Abandon(&ctx, req, &reply).error_code(),
                  grpc::StatusCode::UNAUTHENTICATED);
    }
    {
        testing::TokenContext ctx(Role::Worker);
        v1::FetchSceneRequest req;
        req.set_session(stranger);
        req.set_hash(l.scene_hash());
        v1::FetchSceneReply reply;
        EXPECT_EQ(stub_->FetchScene(&ctx, req, &reply).error_code(),
                  grpc::StatusCode::UNAUTHENTICATED);
    }
    EXPECT_EQ(coordinator_->leases_out(), 1u);
    EXPECT_EQ(complete(l.lease_id(), trace(l)), v1::COMPLETE_STATUS_MERGED);
}

}  // namespace
}  // namespace aliquot

namespace aliquot {
namespace {

// Issue 13: anyone who reached the port could do anything. Now each service wants its
// role's token, and a refused call changes nothing.
TEST(GrpcTokens, NoTokenIsUnauthenticatedAndTheOtherRolesTokenIsPermissionDenied) {
    Coordinator coordinator{CoordinatorOptions{}};
    GrpcServer server(coordinator, "127.0.0.1:0", testing::test_security());
    auto channel = testing::loopback_channel(server.port());
    auto client = v1::ClientService::NewStub(channel);
    auto worker = v1::WorkerService::NewStub(channel);

    const v1::SubmitRequest submit =
        testing::small_submission(self_contained_scene_json("cornell-box"), 8);
    v1::RegisterRequest reg;
    reg.set_name("intruder");
    reg.set_threads(1);
    reg.set_wire_version(kWireVersion);
    const auto submit_with = [&](grpc::ClientContext& ctx) {
        v1::RenderInfo reply;
        return client->Submit(&ctx, submit, &reply);
    };
    const auto register_with = [&](grpc::ClientContext& ctx) {
        v1::RegisterReply reply;
        return worker->Register(&ctx, reg, &reply);
    };
    {
        grpc::ClientContext none;
        EXPECT_EQ(submit_with(none).error_code(), grpc::StatusCode::UNAUTHENTICATED);
        grpc::ClientContext wrong;
        wrong.AddMetadata("authorization", "Bearer not-the-client-token-at-all");
        EXPECT_EQ(submit_with(wrong).error_code(), grpc::StatusCode::UNAUTHENTICATED);
        grpc::ClientContext basic;
        basic.AddMetadata("authorization", "Basic " + testing::kTestTokens.client);
        EXPECT_EQ(submit_with(basic).error_code(), grpc::StatusCode::UNAUTHENTICATED);
        testing::TokenContext worker_token(Role::Worker);
        const grpc::Status denied = submit_with(worker_token);
        EXPECT_EQ(denied.error_code(), grpc::StatusCode::PERMISSION_DENIED);
        EXPECT_EQ(denied.error_message().find(testing::kTestTokens.client),
                  std::string::npos);
    }
    {
        grpc::ClientContext none;
        EXPECT_EQ(register_with(none).error_code(), grpc::StatusCode::UNAUTHENTICATED);
        testing::TokenContext client_token(Role::Client);
        EXPECT_EQ(register_with(client_token).error_code(),
                  grpc::StatusCode::PERMISSION_DENIED);
    }
    EXPECT_TRUE(coordinator.list(10).empty());
    EXPECT_TRUE(coordinator.workers().empty());
    {
        testing::TokenContext ctx(Role::Client);
        v1::ListWorkersRequest req;
        v1::ListWorkersReply reply;
        EXPECT_TRUE(client->ListWorkers(&ctx, req, &reply).ok());
    }
    testing::TokenContext client_token(Role::Client);
    EXPECT_TRUE(submit_with(client_token).ok());
    testing::TokenContext worker_token(Role::Worker);
    EXPECT_TRUE(register_with(worker_token).ok());
}

TEST(GrpcTokens, AServerRefusesMissingOrEqualTokens) {
    Coordinator coordinator{CoordinatorOptions{}};
    EXPECT_THROW(GrpcServer(coordinator, "127.0.0.1:0", GrpcSecurity{}),
                 std::invalid_argument);
    GrpcSecurity same{{"same-token-0123456789", "same-token-0123456789"}, "", ""};
    EXPECT_THROW(GrpcServer(coordinator, "127.0.0.1:0", same), std::invalid_argument);
}

// A Watch request of a small render that stays running (it has no worker).
v1::GetRenderRequest running_render(Coordinator& coordinator) {
    RenderSpec spec;
    spec.scene_name = "cornell-box";
    spec.scene_json = self_contained_scene_json("cornell-box");
    spec.width = spec.height = 8;
    spec.strategy.spp = 1;
    v1::GetRenderRequest req;
    req.set_id(coordinator.submit(spec));
    return req;
}

// Whether a new Watch of `req` gets its first update, tried again while the streams'
// places are all held: a generous number of tries, not a timing check.
bool a_watch_is_served(v1::ClientService::Stub& stub, const v1::GetRenderRequest& req) {
    for (int attempt = 0; attempt < 200; ++attempt) {
        testing::TokenContext ctx(Role::Client);
        ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(5));
        auto reader = stub.Watch(&ctx, req);
        v1::RenderInfo info;
        const bool served = reader->Read(&info);
        ctx.TryCancel();
        reader->Finish();
        if (served) return true;
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return false;
}

// Found in review of issue 13: every Watch held a server thread for as long as its client
// kept it open, without limit.
TEST(GrpcStreams, OpenStreamsAreCappedAndOneMoreIsResourceExhausted) {
    Coordinator coordinator{CoordinatorOptions{}};
    // Every stream comes from one address here: the cap in all, not its share, is tested
    // (GrpcWatch.OneAddressHoldsAtMostItsShareAndAnotherIsStillServed has the share).
    GrpcLimits limits;
    limits.max_watches_per_peer = limits.max_watches;
    GrpcServer server(coordinator, "127.0.0.1:0", testing::test_security(), GrpcOptions{},
                      limits);
    auto stub = v1::ClientService::NewStub(testing::loopback_channel(server.port()));
    const v1::GetRenderRequest req = running_render(coordinator);

    std::vector<std::unique_ptr<testing::TokenContext>> contexts;
    std::vector<std::unique_ptr<grpc::ClientReader<v1::RenderInfo>>> readers;
    v1::RenderInfo info;
    for (int i = 0; i < 32; ++i) {
        contexts.push_back(std::make_unique<testing::TokenContext>(Role::Client));
        readers.push_back(stub->Watch(contexts.back().get(), req));
        ASSERT_TRUE(readers.back()->Read(&info)) << "stream " << i;
    }
    testing::TokenContext one_more(Role::Client);
    auto refused = stub->Watch(&one_more, req);
    EXPECT_FALSE(refused->Read(&info));
    EXPECT_EQ(refused->Finish().error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);

    // A closed stream gives its place back.
    contexts.front()->TryCancel();
    readers.front()->Finish();
    EXPECT_TRUE(a_watch_is_served(*stub, req));
    for (size_t i = 1; i < readers.size(); ++i) {
        contexts[i]->TryCancel();
        readers[i]->Finish();
    }
}

// Review (hostile clients): a Watch whose client reads nothing held its place for as long
// as the client's gRPC answered pings (its few updates fill the buffers only after
// hours). A stream now ends, OK, after its life (GrpcLimits::watch_life, shortened here),
// and its place serves the next Watch; the client's `aliquot watch` opens another.
TEST(GrpcStreams, AWatchEndsAfterItsLifeAndItsPlaceComesBack) {
    Coordinator coordinator{CoordinatorOptions{}};
    GrpcLimits limits;
    limits.max_watches = 1;
    limits.watch_life = std::chrono::milliseconds(300);
    GrpcServer server(coordinator, "127.0.0.1:0", testing::test_security(), GrpcOptions{},
                      limits);
    auto stub = v1::ClientService::NewStub(testing::loopback_channel(server.port()));
    const v1::GetRenderRequest req = running_render(coordinator);

    testing::TokenContext idle_ctx(Role::Client);
    // Ends the test rather than hang it, were the stream never to end.
    idle_ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
    auto idle = stub->Watch(&idle_ctx, req);
    v1::RenderInfo info;
    ASSERT_TRUE(idle->Read(&info));  // it holds the one place, and reads no more

    EXPECT_TRUE(a_watch_is_served(*stub, req));
    // The idle stream ended by itself, OK, while its render still runs.
    while (idle->Read(&info)) {
    }
    EXPECT_TRUE(idle->Finish().ok());
    EXPECT_TRUE(info.state() == v1::RENDER_STATE_QUEUED ||
                info.state() == v1::RENDER_STATE_RUNNING);
}

// Review of issue 32: GetEvents sent a hostile id of 1 MB back whole in its error, as
// every call did that names a render. Each error now shows 64 bytes of it at most, and
// its length.
TEST(GrpcIds, AnUnknownIdOfAMegabyteComesBackShortInEveryError) {
    Coordinator coordinator{CoordinatorOptions{}};
    GrpcServer server(coordinator, "127.0.0.1:0", testing::test_security());
    auto stub = v1::ClientService::NewStub(testing::loopback_channel(server.port()));
    const std::string id = "r-" + std::string(1 << 20, 'x') + "\n";
    const auto expect_short = [&](const char* call, const grpc::Status& status) {
        EXPECT_EQ(status.error_code(), grpc::StatusCode::NOT_FOUND) << call;
        EXPECT_LT(status.error_message().size(), 120u) << call;
        EXPECT_NE(status.error_message().find("(1048579 bytes)"), std::string::npos)
            << call << ": " << status.error_message().substr(0, 200);
    };
    // A unary call of the client service with the hostile id, by its stub method.
    const auto call = [&](const char* name, auto method, const auto& req, auto reply) {
        testing::TokenContext ctx(Role::Client);
        expect_short(name, ((*stub).*method)(&ctx, req, &reply));
    };
    using Stub = v1::ClientService::Stub;
    v1::GetRenderRequest render;
    render.set_id(id);
    v1::GetEventsRequest events;
    events.set_id(id);
    v1::SetPriorityRequest priority;
    priority.set_id(id);
    call("GetEvents", &Stub::GetEvents, events, v1::GetEventsReply{});
    call("GetRender", &Stub::GetRender, render, v1::RenderInfo{});
    call("Cancel", &Stub::Cancel, render, v1::RenderInfo{});
    call("SetPriority", &Stub::SetPriority, priority, v1::RenderInfo{});
    call("Delete", &Stub::Delete, render, v1::DeleteReply{});
    call("GetRounds", &Stub::GetRounds, render, v1::GetRoundsReply{});
    {
        testing::TokenContext ctx(Role::Client);
        auto reader = stub->Watch(&ctx, render);
        v1::RenderInfo info;
        while (reader->Read(&info)) {
        }
        expect_short("Watch", reader->Finish());
    }
    {
        testing::TokenContext ctx(Role::Client);
        v1::FetchImageRequest req;
        req.set_id(id);
        auto reader = stub->FetchImage(&ctx, req);
        v1::FileChunk chunk;
        while (reader->Read(&chunk)) {
        }
        expect_short("FetchImage", reader->Finish());
    }
}

// Issue 34: over the wire, a render with first hits leases jobs that ask for them, and
// its worker's sums come back as the EXR's albedo and normal layers.
TEST_F(WorkerServiceTest, ARenderWithFirstHitsGetsThemOverTheWire) {
    RenderSpec spec = spec_;
    spec.aux = true;
    spec.priority = 10;  // leased before the fixture's render
    const std::string id = coordinator_->submit(spec);
    const v1::Lease l = lease();
    ASSERT_EQ(l.render_id(), id);
    EXPECT_TRUE(l.job().aux());
    const v1::SampleJobResult result = trace(l);
    EXPECT_EQ(result.first_hits().size(), 8 * 8 * kFirstHitRecordBytes);
    EXPECT_EQ(complete(l.lease_id(), result), v1::COMPLETE_STATUS_MERGED);
    const std::optional<Image> image = coordinator_->image(id, true);
    ASSERT_TRUE(image);
    size_t layers = 0;
    for (const Image::Channel& c : image->extra)
        layers += c.name.rfind("albedo.", 0) == 0 || c.name.rfind("normal.", 0) == 0;
    EXPECT_EQ(layers, 6u);
}

// Issue 34: a worker from before wire version 1 (the first-hit sums) sends no version.
// Its result is refused with the reason, nothing of it merges, and the job goes out
// again.
TEST_F(WorkerServiceTest, AResultOfAnOlderWireVersionIsRefusedAndNothingMerges) {
    const v1::Lease l = lease();
    v1::SampleJobResult old = trace(l);
    old.clear_version();
    const v1::CompleteReply reply = complete_as(session_, l.lease_id(), old);
    EXPECT_EQ(reply.status(), v1::COMPLETE_STATUS_REJECTED);
    EXPECT_NE(reply.message().find("wire protocol version 0"), std::string::npos)
        << reply.message();
    EXPECT_EQ(samples_merged(), 0u);
    const v1::Lease again = lease();
    EXPECT_EQ(complete(again.lease_id(), trace(again)), v1::COMPLETE_STATUS_MERGED);
}

}  // namespace
}  // namespace aliquot
