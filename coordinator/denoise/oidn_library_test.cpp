#include "oidn_library.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "denoiser.h"
#include "test_denoiser.h"

namespace aliquot::oidn {
namespace {

namespace fs = std::filesystem;

TEST(OidnLibrary, TheVariableIsTheOnlyCandidateWhenSet) {
    const testing_denoise::ScopedEnv library(kOidnLibraryVariable,
                                             "/somewhere/libOpenImageDenoise.so.2");
    EXPECT_EQ(oidn_library_candidates("/any/root"),
              std::vector<std::string>{"/somewhere/libOpenImageDenoise.so.2"});
}

// A fresh clone after scripts/install-deps.sh: pyoidn's library under .venv, for
// whichever Python made it, is tried before the loader's own search.
TEST(OidnLibrary, TheRepositorysVenvComesBeforeTheLoadersSearch) {
    const testing_denoise::ScopedEnv unset(kOidnLibraryVariable, nullptr);
    const fs::path root =
        fs::path(testing::TempDir()) / ("oidn_root_" + std::to_string(getpid()));
    const fs::path lib =
        root /
        ".venv/lib/python3.13/site-packages/pyoidn/oidn/lib/libOpenImageDenoise.so.2";
    fs::create_directories(lib.parent_path());
    std::ofstream(lib).put('\0');
    const std::vector<std::string> candidates = oidn_library_candidates(root.string());
    fs::remove_all(root);
    ASSERT_GE(candidates.size(), 2u);
    EXPECT_EQ(candidates.front(), lib.string());
    EXPECT_EQ(candidates.back(), "libOpenImageDenoise.so.2");
}

}  // namespace
}  // namespace aliquot::oidn
