// The standard services beside the coordinator's own, over real gRPC on loopback: health
// as Kubernetes' probes ask it (no token), and server reflection as grpcurl lists
// services.
#include <google/protobuf/descriptor.h>
#include <google/protobuf/message.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <memory>
#include <string>

#include <grpc/health/v1/health.grpc.pb.h>
#include "grpc_server.h"
#include "test_tokens.h"

namespace aliquot {
namespace {

using grpc::health::v1::HealthCheckRequest;
using grpc::health::v1::HealthCheckResponse;

class GrpcStandardServices : public ::testing::Test {
protected:
    void start(GrpcOptions options = {}) {
        CoordinatorOptions c;  // in memory
        coordinator_ = std::make_unique<Coordinator>(c);
        server_ = std::make_unique<GrpcServer>(*coordinator_, "127.0.0.1:0",
                                               testing::test_security(), options);
        channel_ = testing::loopback_channel(server_->port());
    }

    // What Health/Check answers for `service`, asked as a probe asks: no token at all.
    grpc::StatusCode check(const std::string& service,
                           HealthCheckResponse::ServingStatus* status) {
        grpc::ClientContext ctx;
        HealthCheckRequest req;
        req.set_service(service);
        HealthCheckResponse reply;
        const grpc::Status s =
            grpc::health::v1::Health::NewStub(channel_)->Check(&ctx, req, &reply);
        *status = reply.status();
        return s.error_code();
    }

    // The services reflection lists, as the text of its answer, or the call's error. The
    // reflection messages are those libgrpc++_reflection registered with protobuf's
    // generated pool: compiling reflection.proto here again would register it twice.
    std::string reflection_list(grpc::StatusCode* code) {
        namespace pb = google::protobuf;
        const pb::Descriptor* request_type =
            pb::DescriptorPool::generated_pool()->FindMessageTypeByName(
                "grpc.reflection.v1alpha."
                "ServerReflectionRequest");
        const pb::Descriptor* response_type =
            pb::DescriptorPool::generated_pool()->FindMessageTypeByName(
                "grpc.reflection.v1alpha."
                "ServerReflectionResponse");
        EXPECT_TRUE(request_type && response_type);
        if (!request_type || !response_type) return {};
        std::unique_ptr<pb::Message> request(
            pb::MessageFactory::generated_factory()->GetPrototype(request_type)->New());
        std::unique_ptr<pb::Message> response(
            pb::MessageFactory::generated_factory()->GetPrototype(response_type)->New());
        request->GetReflection()->SetString(
            request.get(), request_type->FindFieldByName("list_services"), "");

        grpc::ClientContext ctx;
        const grpc::internal::RpcMethod method(
            "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo",
            grpc::internal::RpcMethod::BIDI_STREAMING, channel_);
        std::unique_ptr<grpc::ClientReaderWriter<pb::Message, pb::Message>> stream(
            grpc::internal::ClientReaderWriterFactory<pb::Message, pb::Message>::Create(
                channel_.get(), method, &ctx));
        stream->Write(*request);
        stream->WritesDone();
        std::string text;
        while (stream->Read(response.get())) text += response->ShortDebugString();
        *code = stream->Finish().error_code();
        return text;
    }

    std::unique_ptr<Coordinator> coordinator_;
    std::unique_ptr<GrpcServer> server_;
    std::shared_ptr<grpc::Channel> channel_;
};

TEST_F(GrpcStandardServices, HealthAnswersServingPerServiceWithoutAToken) {
    start();
    HealthCheckResponse::ServingStatus status{};
    for (const std::string service :
         {"", "aliquot.v1.ClientService", "aliquot.v1.WorkerService"}) {
        EXPECT_EQ(check(service, &status), grpc::StatusCode::OK) << service;
        EXPECT_EQ(status, HealthCheckResponse::SERVING) << service;
    }
    // A service the server does not have is NOT_FOUND, as the protocol says.
    EXPECT_EQ(check("aliquot.v1.NoSuchService", &status), grpc::StatusCode::NOT_FOUND);
}

TEST_F(GrpcStandardServices, HealthTurnsNotServingWhenShuttingDownWhileCallsStillWork) {
    start();
    server_->stop_serving();
    HealthCheckResponse::ServingStatus status{};
    for (const std::string service :
         {"", "aliquot.v1.ClientService", "aliquot.v1.WorkerService"}) {
        EXPECT_EQ(check(service, &status), grpc::StatusCode::OK) << service;
        EXPECT_EQ(status, HealthCheckResponse::NOT_SERVING) << service;
    }
    // The port is still open and the services still answer until shutdown().
    testing::TokenContext ctx(Role::Client);
    v1::ListRendersReply reply;
    EXPECT_TRUE(v1::ClientService::NewStub(channel_)
                    ->ListRenders(&ctx, v1::ListRendersRequest(), &reply)
                    .ok());
    server_->stop_serving();  // idempotent
    server_->shutdown();
}

TEST_F(GrpcStandardServices, ReflectionListsEveryServiceWhenTurnedOn) {
    start({.metrics = nullptr, .reflection = true});
    grpc::StatusCode code{};
    const std::string listed = reflection_list(&code);
    EXPECT_EQ(code, grpc::StatusCode::OK);
    for (const char* service :
         {"aliquot.v1.ClientService", "aliquot.v1.WorkerService", "grpc.health.v1.Health",
          "grpc.reflection.v1alpha.ServerReflection"})
        EXPECT_NE(listed.find(std::string("name: \"") + service + "\""),
                  std::string::npos)
            << service << " not in " << listed;
}

TEST_F(GrpcStandardServices, ReflectionIsOffByDefault) {
    start();
    grpc::StatusCode code{};
    reflection_list(&code);
    EXPECT_EQ(code, grpc::StatusCode::UNIMPLEMENTED);
}

}  // namespace
}  // namespace aliquot
