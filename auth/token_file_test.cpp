#include "token_file.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <fstream>

namespace aliquot {
namespace {

namespace fs = std::filesystem;

class TokenFileTest : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() /
               ("aliquot-token-" + std::to_string(::getpid()) + "-" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(dir_);
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }
    void write(const fs::path& p, const std::string& text) {
        std::ofstream(p, std::ios::binary) << text;
    }
    fs::path dir_;
};

TEST_F(TokenFileTest, AFirstStartMakesAPrivateRandomTokenAndLaterStartsReadIt) {
    bool created = false;
    const std::string token = load_or_create_token_file(dir_ / "client.token", created);
    EXPECT_TRUE(created);
    EXPECT_EQ(token.size(), 64u);
    struct stat st {};
    ASSERT_EQ(::stat((dir_ / "client.token").c_str(), &st), 0);
    EXPECT_EQ(st.st_mode & 0777, 0600u);
    EXPECT_EQ(load_or_create_token_file(dir_ / "client.token", created), token);
    EXPECT_FALSE(created);
    EXPECT_NE(load_or_create_token_file(dir_ / "worker.token", created), token);
}

TEST_F(TokenFileTest, ReadingDropsTheTrailingNewline) {
    write(dir_ / "t", "0123456789abcdef-token\r\n");
    EXPECT_EQ(read_token_file(dir_ / "t"), "0123456789abcdef-token");
}

TEST_F(TokenFileTest, AnUnusableTokenIsRefusedWithoutQuotingIt) {
    write(dir_ / "short", "hunter2\n");
    write(dir_ / "spaces", "the admin password is here\n");
    write(dir_ / "empty", "\n");
    for (const char* name : {"short", "spaces", "empty"}) {
        try {
            read_token_file(dir_ / name);
            ADD_FAILURE() << name << " was accepted";
        } catch (const TokenError& e) {
            const std::string m = e.what();
            EXPECT_NE(m.find(name), std::string::npos) << m;
            EXPECT_EQ(m.find("hunter2"), std::string::npos) << m;
            EXPECT_EQ(m.find("admin"), std::string::npos) << m;
        }
    }
    EXPECT_THROW(read_token_file(dir_ / "missing"), TokenError);
    EXPECT_THROW(check_token(std::string(2000, 'a'), "ALIQUOT_TOKEN"), TokenError);
    // Characters an HTTP header or cookie would split or percent-decode.
    for (const char* bad :
         {"0123456789abcdef%41", "0123456789abcdef;x", "0123456789abcdef,"})
        EXPECT_THROW(check_token(bad, "ALIQUOT_TOKEN"), TokenError) << bad;
    EXPECT_NO_THROW(check_token("dGhpcyBpcyBiYXNlNjQ=/+_-.~", "ALIQUOT_TOKEN"));
}

TEST_F(TokenFileTest, ACorruptOrMissingDirectoryIsATokenError) {
    bool created = false;
    EXPECT_THROW(load_or_create_token_file(dir_ / "no" / "such" / "t", created),
                 TokenError);
}

}  // namespace
}  // namespace aliquot
