// What one address's worker names count for over the wire (docs/SECURITY.md, "Cores and
// names one address counts"): names cost a holder of the worker token nothing, so how
// many one address may register, and the cores they count toward cutting, are bounded per
// address (the peer's host, whatever port each connection comes from).
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "aliquot.grpc.pb.h"
#include "grpc_server.h"
#include "scene_loader.h"
#include "test_tokens.h"
#include "wire.h"

namespace aliquot {
namespace {

grpc::Status register_over(v1::WorkerService::Stub& stub, const std::string& name,
                           uint32_t threads) {
    testing::TokenContext ctx(Role::Worker);
    v1::RegisterRequest req;
    req.set_name(name);
    req.set_threads(threads);
    req.set_wire_version(kWireVersion);
    v1::RegisterReply reply;
    return stub.Register(&ctx, req, &reply);
}

// Past max_workers_per_host names from one address a Register is RESOURCE_EXHAUSTED,
// saying which bound and how to raise it; the names it has register again, and another
// address registers as before.
TEST(WorkerShare, AnAddressPastItsShareOfWorkersIsRefusedSayingSo) {
    CoordinatorOptions options;
    options.max_workers_per_host = 4;
    Coordinator coordinator(options);
    GrpcServer server(coordinator, "127.0.0.1:0", testing::test_security());
    // A channel per name: each its own connection and port, as separate processes'.
    std::vector<std::unique_ptr<v1::WorkerService::Stub>> stubs;
    for (int i = 0; i < 6; ++i)
        stubs.push_back(
            v1::WorkerService::NewStub(testing::loopback_channel(server.port())));
    for (int i = 0; i < 4; ++i)
        EXPECT_TRUE(register_over(*stubs[size_t(i)], "w" + std::to_string(i), 2).ok());
    const grpc::Status refused = register_over(*stubs[4], "w4", 2);
    EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_NE(refused.error_message().find(
                  "ipv4:127.0.0.1 has 4 workers registered, the most one address may "
                  "(--max-workers-per-host)"),
              std::string::npos)
        << refused.error_message();
    EXPECT_FALSE(coordinator.knows_worker("w4"));
    EXPECT_TRUE(register_over(*stubs[5], "w0", 2).ok());  // a worker registering again
    const auto other = testing::channel_from("127.0.0.2", server.port());
    ASSERT_TRUE(other) << "127.0.0.2 is this host";
    EXPECT_TRUE(register_over(*v1::WorkerService::NewStub(other), "w4", 2).ok());
}

// Names registered over the wire that take no job add no core: a 256x256 render (uniform,
// 8 spp: one round) is cut into the 28 jobs of a small farm, not the 256 smallest tiles
// that 8 names of 1024 threads each asked for.
TEST(WorkerShare, NamesThatTakeNoJobLeaveTheCutAsItWas) {
    Coordinator coordinator{CoordinatorOptions{}};
    GrpcServer server(coordinator, "127.0.0.1:0", testing::test_security());
    for (int i = 0; i < 8; ++i) {
        const auto stub =
            v1::WorkerService::NewStub(testing::loopback_channel(server.port()));
        ASSERT_TRUE(
            register_over(*stub, "idle-" + std::to_string(i), kMaxWorkerThreads).ok());
    }
    // Built here, not from the farm's small_test_spec: that header shows the scene room,
    // which the farm links privately (room_links).
    RenderSpec spec;
    spec.scene_name = "cornell-box";
    spec.scene_json = self_contained_scene_json("cornell-box");
    spec.strategy.method = "uniform";
    spec.width = spec.height = 256;
    spec.strategy.spp = 8;
    coordinator.submit(spec);
    const std::string honest =
        coordinator.register_worker("honest", 2, "ipv4:10.0.0.1:5").session;
    size_t jobs = 0;
    while (coordinator.lease(honest, std::chrono::milliseconds(0))) ++jobs;
    EXPECT_EQ(jobs, 28u);
}

}  // namespace
}  // namespace aliquot
