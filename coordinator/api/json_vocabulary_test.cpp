// One JSON vocabulary: the proto's JSON mapping (protobuf's own printer, as grpcurl and
// gateways print the client service's messages), the HTTP API and `--json` name every
// field alike and spell every state alike. docs/API.md, "One vocabulary", states the
// rules these tests hold the three to.
#include <google/protobuf/util/json_util.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <set>
#include <string>

#include "http_api.h"
#include "render_json.h"
#include "render_proto.h"

namespace aliquot {
namespace {

using nlohmann::json;

// The message as protobuf's JSON mapping prints it by default (json_name, as grpcurl
// does), every field present.
json proto_json(const google::protobuf::Message& message) {
    google::protobuf::util::JsonPrintOptions options;
    options.always_print_primitive_fields = true;
    std::string text;
    EXPECT_TRUE(
        google::protobuf::util::MessageToJsonString(message, &text, options).ok());
    return json::parse(text);
}

std::set<std::string> keys(const json& object) {
    std::set<std::string> out;
    for (const auto& [key, value] : object.items()) out.insert(key);
    return out;
}

// Rule 1: a proto field "X_json" holds JSON text that the API writes as the object "X";
// every other field has the API's name.
std::string api_name(const std::string& proto_field) {
    const std::string suffix = "_json";
    if (proto_field.size() > suffix.size() &&
        proto_field.compare(proto_field.size() - suffix.size(), suffix.size(), suffix) ==
            0)
        return proto_field.substr(0, proto_field.size() - suffix.size());
    return proto_field;
}

// The client service's messages name their JSON fields as the proto does (json_name), so
// a printer that uses JSON names and one that keeps the proto's names agree.
TEST(JsonVocabulary, EveryClientMessageFieldKeepsItsProtoNameInJson) {
    const auto* service =
        v1::RenderInfo::descriptor()->file()->FindServiceByName("ClientService");
    ASSERT_NE(service, nullptr);
    std::set<const google::protobuf::Descriptor*> messages;
    for (int m = 0; m < service->method_count(); ++m) {
        messages.insert(service->method(m)->input_type());
        messages.insert(service->method(m)->output_type());
    }
    for (size_t seen = 0; seen != messages.size();) {  // and the messages they hold
        seen = messages.size();
        for (const auto* message : std::set(messages))
            for (int f = 0; f < message->field_count(); ++f)
                if (const auto* inner = message->field(f)->message_type())
                    messages.insert(inner);
    }
    for (const auto* message : messages)
        for (int f = 0; f < message->field_count(); ++f)
            EXPECT_EQ(message->field(f)->json_name(), message->field(f)->name())
                << message->full_name();
}

RenderInfo a_render() {
    RenderInfo i;
    i.id = "r-000001";
    i.scene_name = "cornell-box";
    i.method = "uniform";
    i.strategy_json = R"({"method":"uniform","spp":4})";
    i.outcome_json = "{}";
    i.state = RenderState::Failed;
    i.error = "why";
    i.finished_ms = 2;
    i.mean_bias = -0.05;  // optional in the proto: printed only when present
    i.mean_bias_se = 0.001;
    return i;
}

TEST(JsonVocabulary, EveryRenderFieldOfTheProtoHasTheApisName) {
    v1::RenderInfo message;
    to_proto(a_render(), message);
    const std::set<std::string> api = keys(render_detail(a_render()));
    for (const std::string& field : keys(proto_json(message)))
        EXPECT_TRUE(api.count(api_name(field))) << field << " is not in the API's render";
    // And the other way: what the API has beyond the proto is derived there.
    std::set<std::string> proto;
    for (const std::string& field : keys(proto_json(message)))
        proto.insert(api_name(field));
    for (const std::string& key : api)
        EXPECT_TRUE(proto.count(key) || key == "progress")
            << key << " is not in the proto";
}

TEST(JsonVocabulary, WorkersAndRoundsHaveTheSameFieldsEverywhere) {
    v1::WorkerInfo worker;
    to_proto(
        WorkerStatus{"w1", "busy", 2, {"r-000001/3"}, 10, 1.5, 7, "host1", "0.1.0", 2},
        worker);
    EXPECT_EQ(keys(proto_json(worker)), keys(http_api::worker_json(from_proto(worker))));

    v1::RoundInfo round;
    round.set_mean_bias(-0.05);  // optional: printed only when present
    round.set_mean_bias_se(0.001);
    std::set<std::string> columns(std::begin(http_api::kRoundColumns),
                                  std::end(http_api::kRoundColumns));
    EXPECT_EQ(keys(proto_json(round)), columns);
}

// Rule 2: an enum value's JSON spelling is its proto name without the enum's prefix, in
// lower case: RENDER_STATE_CANCELLED is "cancelled".
TEST(JsonVocabulary, StatesAreTheProtoNamesWithoutPrefixInLowerCase) {
    const auto* states = v1::RenderState_descriptor();
    for (int k = 0; k < states->value_count(); ++k) {
        const auto* value = states->value(k);
        if (value->number() == v1::RENDER_STATE_UNSPECIFIED) continue;
        std::string spelled = value->name().substr(std::string("RENDER_STATE_").size());
        std::transform(spelled.begin(), spelled.end(), spelled.begin(),
                       [](unsigned char c) { return char(std::tolower(c)); });
        EXPECT_EQ(to_string(from_proto(v1::RenderState(value->number()))), spelled);
    }
}

// Rule 3: 64-bit seeds are strings, as in protobuf's JSON mapping.
TEST(JsonVocabulary, SeedsAreStringsInTheProtoMappingAndTheApi) {
    RenderInfo info = a_render();
    info.seed = UINT64_MAX;
    v1::RenderInfo message;
    to_proto(info, message);
    EXPECT_EQ(proto_json(message)["seed"], "18446744073709551615");
    EXPECT_EQ(render_detail(info)["seed"], "18446744073709551615");
}

// A render's event: GetEvents' message and the HTTP API's document have the same fields
// (`fields_json` carrying the object `fields`).
TEST(JsonVocabulary, EventsHaveTheSameFieldsEverywhere) {
    const RenderEvent e{"r-000001",
                        3,
                        7,
                        EventKind::RoundEnded,
                        {log_number("round", int64_t(2)), log_text("name", "a")}};
    v1::RenderEvent message;
    to_proto(e, message);
    std::set<std::string> proto;
    for (const std::string& field : keys(proto_json(message)))
        proto.insert(api_name(field));
    const json api = event_json(e);
    EXPECT_EQ(proto, keys(api));
    EXPECT_EQ(api["fields"], json::parse(message.fields_json()));
    EXPECT_EQ(api["fields"]["round"], 2);
}

}  // namespace
}  // namespace aliquot
