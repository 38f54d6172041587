#include "log_line.h"

#include <gtest/gtest.h>

namespace aliquot {
namespace {

constexpr int64_t kNoon = 1796385600123;  // 2026-12-04T12:00:00.123Z

TEST(LogLine, TextIsTimeEventAndFields) {
    EXPECT_EQ(
        format_log_line(LogFormat::Text, kNoon, "round_ended",
                        {log_text("render", "r-000001"), log_number("round", int64_t(3)),
                         log_text("name", "my shot")}),
        "2026-12-04T12:00:00.123Z round_ended render=r-000001 round=3 name=\"my shot\"");
}

TEST(LogLine, JsonIsOneObject) {
    EXPECT_EQ(
        format_log_line(LogFormat::Json, kNoon, "submitted",
                        {log_text("render", "r-000001"), log_number("error", 0.25)}),
        "{\"time\":\"2026-12-04T12:00:00.123Z\",\"event\":\"submitted\","
        "\"render\":\"r-000001\",\"error\":0.25}");
}

TEST(LogLine, ANameCannotEndTheLineOrForgeAField) {
    const LogFields hostile = {log_text("worker", "w\nfake_event render=r-9\x01\"}\xff")};
    for (const LogFormat format : {LogFormat::Text, LogFormat::Json}) {
        const std::string line =
            format_log_line(format, kNoon, "worker_registered", hostile);
        EXPECT_EQ(line.find('\n'), std::string::npos);
        EXPECT_EQ(line.find('\x01'), std::string::npos);
        EXPECT_EQ(line.find('\xff'), std::string::npos);
        EXPECT_NE(line.find("\\ufffd"), std::string::npos);
    }
    EXPECT_EQ(format_log_line(LogFormat::Json, kNoon, "e", hostile),
              "{\"time\":\"2026-12-04T12:00:00.123Z\",\"event\":\"e\",\"worker\":"
              "\"w\\nfake_event render=r-9\\u0001\\\"}\\ufffd\"}");
}

TEST(LogLine, FormatsAreSpelledTextAndJson) {
    EXPECT_EQ(parse_log_format("text"), LogFormat::Text);
    EXPECT_EQ(parse_log_format("json"), LogFormat::Json);
    EXPECT_FALSE(parse_log_format("JSON"));
    EXPECT_EQ(log_number("x", 1.0 / 0.0).value, "null");
}

}  // namespace
}  // namespace aliquot
