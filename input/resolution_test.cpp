#include "resolution.h"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

namespace aliquot {
namespace {

std::string error_of(const std::string& text) {
    try {
        parse_resolution(text);
    } catch (const std::invalid_argument& e) {
        return e.what();
    }
    return "";
}

TEST(Resolution, ReadsWidthThenHeight) {
    const Resolution r = parse_resolution("48x40");
    EXPECT_EQ(r.width, 48u);
    EXPECT_EQ(r.height, 40u);
    EXPECT_EQ(parse_resolution("8192x1").width, kMaxResolutionSide);
}

TEST(Resolution, RefusesEverySideOutsideOneToTheLimit) {
    for (const char* bad :
         {"0x3", "3x0", "8193x2", "2x8193", "99999999999999999999999x2"})
        EXPECT_NE(error_of(bad), "") << bad;
}

TEST(Resolution, RefusesAnythingButDigitsXDigits) {
    for (const char* bad : {"", "12", "x", "12x", "x12", "-4x4", "+4x4", " 4x4", "4x4 ",
                            "4X4", "4x4x4", "4.0x4", "4 x 4"})
        EXPECT_NE(error_of(bad), "") << '"' << bad << '"';
}

TEST(Resolution, MessageSaysWhatWasExpectedAndWhatCame) {
    EXPECT_EQ(error_of("0x3"),
              "expected WxH with each side in 1..8192, e.g. 256x256, got \"0x3\"");
}

}  // namespace
}  // namespace aliquot
