// The worker service over real gRPC on loopback, fed results a broken or malicious worker
// could send. None may touch the image; every job must still be traced exactly once.
#include "grpc_server.h"

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "aliquot.grpc.pb.h"
#include "exr_io.h"
#include "scene_loader.h"
#include "trace_job.h"
#include "wire.h"

namespace aliquot {
namespace {

class WorkerServiceTest : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = std::filesystem::temp_directory_path() /
               ("aliquot-grpc-test-" + std::to_string(::getpid()));
        std::filesystem::remove_all(dir_);
        CoordinatorOptions options;
        options.data_dir = dir_;
        coordinator_ = std::make_unique<Coordinator>(options);
        server_ = std::make_unique<GrpcServer>(*coordinator_, "127.0.0.1:0");
        stub_ = v1::WorkerService::NewStub(
            grpc::CreateChannel("127.0.0.1:" + std::to_string(server_->port()),
                                grpc::InsecureChannelCredentials()));

        RenderSpec spec;
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
        coordinator_->register_worker("tester", 1);
    }
    void TearDown() override {
        server_.reset();
        coordinator_.reset();
        std::filesystem::remove_all(dir_);
    }

    v1::Lease lease() {
        grpc::ClientContext ctx;
        v1::LeaseRequest req;
        req.set_worker("tester");
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
    v1::CompleteStatus complete(uint64_t lease_id, const v1::SampleJobResult& result) {
        grpc::ClientContext ctx;
        v1::CompleteRequest req;
        req.set_worker("tester");
        req.set_lease_id(lease_id);
        *req.mutable_result() = result;
        v1::CompleteReply reply;
        EXPECT_TRUE(stub_->Complete(&ctx, req, &reply).ok());
        return reply.status();
    }
    uint64_t samples_merged() { return coordinator_->info(id_)->samples_done; }

    std::filesystem::path dir_;
    std::unique_ptr<Coordinator> coordinator_;
    std::unique_ptr<GrpcServer> server_;
    std::unique_ptr<v1::WorkerService::Stub> stub_;
    Scene scene_;
    std::unique_ptr<PathTracer> tracer_;
    std::string id_;
};

TEST_F(WorkerServiceTest, RejectsAResultWithTheWrongPixelCountAndReissuesTheJob) {
    const v1::Lease first = lease();
    v1::SampleJobResult bad = trace(first);
    bad.mutable_samples()->RemoveLast();
    EXPECT_EQ(complete(first.lease_id(), bad), v1::COMPLETE_STATUS_REJECTED);
    EXPECT_EQ(samples_merged(), 0u);
    const v1::Lease again = lease();  // the same job, under a new lease
    EXPECT_NE(again.lease_id(), first.lease_id());
    EXPECT_EQ(again.job().rect().width(), first.job().rect().width());
    EXPECT_EQ(complete(again.lease_id(), trace(again)), v1::COMPLETE_STATUS_MERGED);
    EXPECT_EQ(coordinator_->info(id_)->state, RenderState::Done);
}

TEST_F(WorkerServiceTest, RejectsNegativeSampleCounts) {
    const v1::Lease l = lease();
    v1::SampleJobResult bad = trace(l);
    bad.set_samples(0, uint64_t(-1));  // -1 as a worker with a sign bug would send it
    EXPECT_EQ(complete(l.lease_id(), bad), v1::COMPLETE_STATUS_REJECTED);
    EXPECT_EQ(samples_merged(), 0u);
}

TEST_F(WorkerServiceTest, RejectsNonFiniteSums) {
    const v1::Lease l = lease();
    v1::SampleJobResult bad = trace(l);
    bad.set_sum_even(0, std::numeric_limits<double>::quiet_NaN());
    EXPECT_EQ(complete(l.lease_id(), bad), v1::COMPLETE_STATUS_REJECTED);
    EXPECT_EQ(samples_merged(), 0u);
}

TEST_F(WorkerServiceTest, OnlyTheHolderCanGiveALeaseBack) {
    const v1::Lease l = lease();
    EXPECT_FALSE(coordinator_->abandon("intruder", l.lease_id()));
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
    {
        grpc::ClientContext ctx;
        v1::RenewRequest req;
        req.set_worker("tester");
        req.set_lease_id(l.lease_id());
        v1::RenewReply reply;
        ASSERT_TRUE(stub_->Abandon(&ctx, req, &reply).ok());
        EXPECT_TRUE(reply.valid());
    }
    const v1::Lease reissued = lease();
    EXPECT_EQ(complete(l.lease_id(), trace(l)), v1::COMPLETE_STATUS_IGNORED);
    EXPECT_EQ(complete(reissued.lease_id(), trace(reissued)), v1::COMPLETE_STATUS_MERGED);
}

// Issue 12, item 7: a render past the coordinator's memory budget is RESOURCE_EXHAUSTED.
TEST(ClientServiceMemory, ASubmissionPastTheMemoryBudgetIsResourceExhausted) {
    CoordinatorOptions options;
    options.memory_limit = 1024;
    Coordinator coordinator(options);
    GrpcServer server(coordinator, "127.0.0.1:0");
    auto stub = v1::ClientService::NewStub(
        grpc::CreateChannel("127.0.0.1:" + std::to_string(server.port()),
                            grpc::InsecureChannelCredentials()));
    grpc::ClientContext ctx;
    v1::SubmitRequest req;
    req.set_scene_name("cornell-box");
    req.set_scene_json(self_contained_scene_json("cornell-box"));
    req.set_width(64);
    req.set_height(64);
    req.set_strategy_json(R"({"method":"uniform","spp":1})");
    v1::RenderInfo reply;
    const grpc::Status status = stub->Submit(&ctx, req, &reply);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_NE(status.error_message().find("--memory-limit"), std::string::npos)
        << status.error_message();
    EXPECT_TRUE(coordinator.list(10).empty());
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
        GrpcServer server(coordinator, "127.0.0.1:0");
        auto stub = v1::ClientService::NewStub(
            grpc::CreateChannel("127.0.0.1:" + std::to_string(server.port()),
                                grpc::InsecureChannelCredentials()));
        grpc::ClientContext ctx;
        v1::SubmitRequest req;
        req.set_scene_name("cornell-box");
        req.set_scene_json(self_contained_scene_json("cornell-box"));
        req.set_width(8);
        req.set_height(8);
        req.set_strategy_json(R"({"method":"uniform","spp":1})");
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

TEST_F(WorkerServiceTest, TellsAWorkerItDoesNotKnowToRegisterFirst) {
    v1::LeaseRequest req;
    req.set_worker("stranger");
    v1::LeaseReply reply;
    {
        grpc::ClientContext ctx;
        ASSERT_TRUE(stub_->Lease(&ctx, req, &reply).ok());
    }
    EXPECT_TRUE(reply.register_first());
    EXPECT_FALSE(reply.has_lease());
    {
        grpc::ClientContext ctx;
        v1::RegisterRequest reg;
        reg.set_name("stranger");
        reg.set_threads(3);
        v1::RegisterReply ok;
        ASSERT_TRUE(stub_->Register(&ctx, reg, &ok).ok());
    }
    {
        grpc::ClientContext ctx;
        ASSERT_TRUE(stub_->Lease(&ctx, req, &reply).ok());
    }
    EXPECT_FALSE(reply.register_first());
    EXPECT_TRUE(reply.has_lease());
}

// Issue 12, item 5: a worker that cannot trace a lease says so, with why.
TEST_F(WorkerServiceTest, AFailedLeaseIsCountedOnceAndTheJobGoesBack) {
    const v1::Lease l = lease();
    auto fail = [&](const std::string& worker) {
        grpc::ClientContext ctx;
        v1::FailRequest req;
        req.set_worker(worker);
        req.set_lease_id(l.lease_id());
        req.set_reason("cannot open mesh.obj");
        v1::FailReply reply;
        EXPECT_TRUE(stub_->Fail(&ctx, req, &reply).ok());
        return reply.accepted();
    };
    EXPECT_FALSE(fail("intruder"));
    EXPECT_TRUE(fail("tester"));
    EXPECT_FALSE(fail("tester"));     // counted once
    const v1::Lease again = lease();  // the only worker alive tries again
    EXPECT_NE(again.lease_id(), l.lease_id());
    EXPECT_EQ(complete(again.lease_id(), trace(again)), v1::COMPLETE_STATUS_MERGED);
}

}  // namespace
}  // namespace aliquot
