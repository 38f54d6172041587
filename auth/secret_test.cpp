#include "secret.h"

#include <gtest/gtest.h>

#include <set>

namespace aliquot {
namespace {

TEST(RandomHex, HasTwoDigitsPerByteAndDoesNotRepeat) {
    std::set<std::string> seen;
    for (int i = 0; i < 100; ++i) {
        const std::string h = random_hex(16);
        ASSERT_EQ(h.size(), 32u);
        EXPECT_EQ(h.find_first_not_of("0123456789abcdef"), std::string::npos);
        seen.insert(h);
    }
    EXPECT_EQ(seen.size(), 100u);
}

TEST(ConstantTimeEqual, ComparesWholeStrings) {
    EXPECT_TRUE(constant_time_equal("abc", "abc"));
    EXPECT_TRUE(constant_time_equal("", ""));
    EXPECT_FALSE(constant_time_equal("abc", "abd"));
    EXPECT_FALSE(constant_time_equal("abc", "ab"));
    EXPECT_FALSE(constant_time_equal("ab", "abc"));
    EXPECT_FALSE(constant_time_equal("", "a"));
    EXPECT_FALSE(constant_time_equal(std::string("a\0b", 3), std::string("a\0c", 3)));
}

}  // namespace
}  // namespace aliquot
