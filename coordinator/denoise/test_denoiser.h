// The room's tests' one Denoiser, and how a test without Open Image Denoise says so: it
// skips loudly, or fails where the library must be there (scripts/test.sh, CI).
#pragma once

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <optional>
#include <string>

#include "denoiser.h"

namespace aliquot::testing_denoise {

// scripts/test.sh sets this: there install-deps.sh has installed the library, and a skip
// would hide a break.
inline constexpr const char* kRequireVariable = "ALIQUOT_REQUIRE_OIDN";

// One Denoiser for the binary (a device starts a thread pool); nullptr and *why when OIDN
// is absent.
inline const Denoiser* shared_denoiser(std::string* why) {
    static std::string error;
    static const std::unique_ptr<Denoiser> denoiser = Denoiser::open(&error);
    *why = error;
    return denoiser.get();
}

// Sets an environment variable (or unsets it, for nullptr) for one test and puts back
// what was there.
class ScopedEnv {
public:
    ScopedEnv(const char* name, const char* value) : name_(name) {
        if (const char* old = std::getenv(name)) old_ = old;
        if (value)
            setenv(name, value, 1);
        else
            unsetenv(name);
    }
    ~ScopedEnv() {
        if (old_)
            setenv(name_, old_->c_str(), 1);
        else
            unsetenv(name_);
    }
    ScopedEnv(const ScopedEnv&) = delete;
    ScopedEnv& operator=(const ScopedEnv&) = delete;

private:
    const char* name_;
    std::optional<std::string> old_;
};

}  // namespace aliquot::testing_denoise

// Declares `name`, the shared Denoiser, or skips the test (fails, with
// ALIQUOT_REQUIRE_OIDN).
#define REQUIRE_DENOISER(name)                                                       \
    std::string why_absent;                                                          \
    const Denoiser* name = ::aliquot::testing_denoise::shared_denoiser(&why_absent); \
    if (name == nullptr) {                                                           \
        if (std::getenv(::aliquot::testing_denoise::kRequireVariable) != nullptr)    \
            FAIL() << ::aliquot::testing_denoise::kRequireVariable << " is set but " \
                   << why_absent;                                                    \
        std::fprintf(                                                                \
            stderr,                                                                  \
            "\n*** SKIPPING: Open Image Denoise is not installed, so this test "     \
            "proves nothing ***\n%s\n\n",                                            \
            why_absent.c_str());                                                     \
        GTEST_SKIP() << "Open Image Denoise not installed: " << why_absent;          \
    }
