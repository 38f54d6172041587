#include "json_field.h"

#include <gtest/gtest.h>

#include <functional>
#include <string>

namespace aliquot {
namespace {

using nlohmann::json;

std::string error_of(const std::function<void()>& f) {
    try {
        f();
    } catch (const JsonError& e) {
        return e.what();
    }
    return "";
}

TEST(JsonField, ErrorsCarryThePointerOfTheOffendingValue) {
    const json doc = parse_json(R"({"renders": [{"resolution": 7}]})");
    const JsonField res = JsonField(doc).require("renders").at(0).require("resolution");
    EXPECT_EQ(res.pointer(), "/renders/0/resolution");
    EXPECT_EQ(error_of([&] { res.string("expected WxH"); }),
              "/renders/0/resolution: expected WxH");
}

TEST(JsonField, MissingKeyIsReportedAtTheObject) {
    const json doc = parse_json(R"({"camera": {}})");
    EXPECT_EQ(error_of([&] { JsonField(doc).require("camera").require("fov"); }),
              "/camera: missing key \"fov\"");
    EXPECT_EQ(error_of([&] { JsonField(doc).require("shapes"); }),
              "/: missing key \"shapes\"");
}

TEST(JsonField, UnknownKeysNameTheKeysExpected) {
    const json doc = parse_json(R"({"a": 1, "colour": 2})");
    EXPECT_EQ(error_of([&] {
                  JsonField(doc).allow_keys({"a", "b"});
              }),
              "/colour: unknown key (expected a, b)");
}

TEST(JsonField, PointersEscapeSlashAndTilde) {
    const json doc = parse_json(R"({"a/b~c": {"x": 1}})");
    EXPECT_EQ(JsonField(doc).require("a/b~c").require("x").pointer(), "/a~1b~0c/x");
}

TEST(JsonField, WholeNumbersRefuseNegativesFractionsAndOutOfRange) {
    const json doc = json::parse(R"([16, 16.0, -1, 2.5, "3", 9])");
    const JsonField list(doc);
    EXPECT_EQ(list.at(0).whole(), 16u);
    EXPECT_EQ(list.at(1).whole(), 16u);
    EXPECT_EQ(error_of([&] { list.at(2).whole(); }),
              "/2: expected a whole number of at least 0");
    EXPECT_NE(error_of([&] { list.at(3).whole(); }), "");
    EXPECT_NE(error_of([&] { list.at(4).whole(); }), "");
    EXPECT_EQ(error_of([&] { list.at(5).whole(1, 8); }),
              "/5: expected a whole number from 1 to 8");
}

TEST(JsonField, NumbersAndStringsFailWithTheCallersExpectation) {
    const json doc = json::parse(R"({"n": "x", "s": 1})");
    EXPECT_EQ(error_of([&] { JsonField(doc).require("n").number("expected fov"); }),
              "/n: expected fov");
    EXPECT_EQ(error_of([&] { JsonField(doc).require("s").string(); }),
              "/s: expected a string");
}

TEST(ParseJson, RefusesDuplicateKeysAtTheirObject) {
    EXPECT_EQ(error_of([] { parse_json(R"({"shapes": [{}, {"type": 1, "type": 2}]})"); }),
              "/shapes/1: duplicate key \"type\"");
    EXPECT_EQ(error_of([] { parse_json(R"({"a": 1, "a": 1})"); }),
              "/: duplicate key \"a\"");
}

TEST(ParseJson, SyntaxErrorsSayWhereInTheText) {
    EXPECT_EQ(error_of([] { parse_json("{\n  \"camera\": ,\n}"); }).substr(0, 35),
              "invalid JSON at line 2, column 13: ");
    try {
        parse_json("{");
    } catch (const JsonError& e) {
        EXPECT_FALSE(e.pointer().has_value());
    }
}

// JsonDocument takes its tree apart by recursion, so how deep a document nests is
// bounded; nothing of ours nests more than a few levels.
TEST(ParseJson, RefusesNestingDeeperThanTheLimit) {
    const auto nested = [](int depth) {
        return std::string(size_t(depth), '[') + std::string(size_t(depth), ']');
    };
    EXPECT_NO_THROW(parse_json(nested(kMaxJsonDepth)));
    EXPECT_NO_THROW(JsonDocument(nested(kMaxJsonDepth)));
    try {
        JsonDocument doc(nested(kMaxJsonDepth + 1));
        FAIL() << "expected JsonError";
    } catch (const JsonError& e) {
        EXPECT_EQ(e.reason(), "nested deeper than 256");
        EXPECT_EQ(e.pointer()->size(), 2u * kMaxJsonDepth);  // "/0" at every level
    }
}

TEST(ParseJson, ADocumentReadsAsParseJsonDoes) {
    const std::string text = R"({"a": [1, {"b": null}], "c": "d"})";
    EXPECT_EQ(JsonDocument(text).root(), parse_json(text));
    EXPECT_THROW(JsonDocument(R"({"a": 1, "a": 2})"), JsonError);
    EXPECT_THROW(JsonDocument("{"), JsonError);
}

}  // namespace
}  // namespace aliquot
