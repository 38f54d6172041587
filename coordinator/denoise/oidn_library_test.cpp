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

// dlopen runs a library's initialisers: a real OIDN reached through a folder every user
// can write (someone else's file could be there instead) is refused, naming the folder,
// even when the operator's own variable names it.
TEST(OidnLibrary, ALibraryInAFolderOthersCanWriteIsRefused) {
    REQUIRE_DENOISER(denoiser);
    const fs::path planted =
        fs::path(testing::TempDir()) / ("oidn_planted_" + std::to_string(getpid()));
    fs::create_directories(planted);
    fs::permissions(planted, fs::perms::all);  // 0777, as a shared folder would be
    const fs::path lib = planted / "libOpenImageDenoise.so.2";
    fs::create_symlink(denoiser->library_path(), lib);
    std::string error;
    std::unique_ptr<OidnLibrary> loaded;
    {
        const testing_denoise::ScopedEnv chosen(kOidnLibraryVariable, lib.c_str());
        loaded = load_oidn_library(&error);
    }
    fs::remove_all(planted);
    EXPECT_EQ(loaded, nullptr);
    EXPECT_NE(error.find(planted.string() + " is writable by every user"),
              std::string::npos)
        << error;
}

// A clone under /tmp (sticky, everyone may write it) is still ours: nobody else may swap
// an entry of ours there, so the folder below decides.
TEST(OidnLibrary, ALibraryInOurFolderUnderAStickyFolderLoads) {
    REQUIRE_DENOISER(denoiser);
    const fs::path sticky =
        fs::path(testing::TempDir()) / ("oidn_sticky_" + std::to_string(getpid()));
    const fs::path ours = sticky / "clone";
    fs::create_directories(ours);
    fs::permissions(sticky, fs::perms::all | fs::perms::sticky_bit);  // 1777, as /tmp
    fs::permissions(ours, fs::perms::owner_all | fs::perms::group_read |
                              fs::perms::group_exec | fs::perms::others_read |
                              fs::perms::others_exec);
    const fs::path lib = ours / "libOpenImageDenoise.so.2";
    fs::create_symlink(denoiser->library_path(), lib);
    std::string error;
    std::unique_ptr<OidnLibrary> loaded;
    {
        const testing_denoise::ScopedEnv chosen(kOidnLibraryVariable, lib.c_str());
        loaded = load_oidn_library(&error);
    }
    fs::remove_all(sticky);
    EXPECT_NE(loaded, nullptr) << error;
}

}  // namespace
}  // namespace aliquot::oidn
