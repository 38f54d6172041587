#include "seed_json.h"

#include <gtest/gtest.h>

namespace aliquot {

using nlohmann::json;

TEST(SeedJson, IsWrittenAsADecimalString) {
    EXPECT_EQ(seed_to_json(0), json("0"));
    EXPECT_EQ(seed_to_json(UINT64_MAX), json("18446744073709551615"));
}

TEST(SeedJson, EveryUint64SurvivesTheRoundTrip) {
    for (const uint64_t seed :
         {uint64_t(0), uint64_t(7), kExactDoubleLimit + 1, uint64_t(1) << 63, UINT64_MAX})
        EXPECT_EQ(seed_from_json(json::parse(seed_to_json(seed).dump())), seed);
}

TEST(SeedJson, ReadsIntegersExactlyWhateverTheirSize) {
    EXPECT_EQ(seed_from_json(json::parse("42")), 42u);
    EXPECT_EQ(seed_from_json(json::parse("18446744073709551615")), UINT64_MAX);
    EXPECT_EQ(seed_from_json(json::parse("9007199254740993")), kExactDoubleLimit + 1);
}

TEST(SeedJson, ReadsWholeDoublesUpTo2To53Only) {
    EXPECT_EQ(seed_from_json(json(16.0)), 16u);
    EXPECT_EQ(seed_from_json(json(double(kExactDoubleLimit))), kExactDoubleLimit);
    // 1e19 has lost digits on its way here: refused with the way out, not rounded.
    try {
        seed_from_json(json::parse("1e19"));
        FAIL() << "accepted 1e19";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("decimal string"), std::string::npos);
    }
}

TEST(SeedJson, RefusesWhatIsNotAWholeNumberFrom0To2To64) {
    for (const char* bad :
         {R"("")", R"("-1")", R"(" 1")", R"("1 ")", R"("0x10")", R"("1.5")",
          R"("18446744073709551616")", R"("99999999999999999999")", "-1", "2.5", "1e300",
          "true", "null", "[1]", R"({"seed":1})"})
        EXPECT_THROW(seed_from_json(json::parse(bad)), std::invalid_argument) << bad;
}

}  // namespace aliquot
