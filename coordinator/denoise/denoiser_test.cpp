#include "denoiser.h"

#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>

#include <gtest/gtest.h>

#include <atomic>

#include "test_denoiser.h"

namespace aliquot {
namespace {

// Set for the child process of SameInputsGiveSameBytesInAnotherProcess: where it writes
// its denoised bytes.
constexpr const char* kBytesOutVariable = "ALIQUOT_DENOISE_BYTES_OUT";

// A uniform in [0, 1) from a hash of (seed, i): the same on every machine and library.
float hashed_uniform(uint64_t seed, uint64_t i) {
    uint64_t z = seed * 0x9e3779b97f4a7c15ull + i + 0x632be59bd9b4e5bbull;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    z ^= z >> 31;
    return float(z >> 40) / float(1ull << 24);
}

// A grey `level` seen through Monte Carlo noise: each pixel the mean of 4 exponential
// draws (mean `level`), as a light's contribution found by few samples would be.
Image noisy_constant(uint32_t size, float level, uint64_t seed) {
    Image image(size, size);
    for (size_t p = 0; p < image.pixel_count(); ++p) {
        float sum = 0.0f;
        for (int k = 0; k < 4; ++k)
            sum += -std::log(1.0f - hashed_uniform(seed, p * 4 + k));
        const float value = level * sum / 4.0f;
        for (int c = 0; c < 3; ++c) image.rgb[p * 3 + c] = value;
    }
    return image;
}

Image constant_image(uint32_t size, float r, float g, float b) {
    Image image(size, size);
    for (size_t p = 0; p < image.pixel_count(); ++p) {
        image.rgb[p * 3 + 0] = r;
        image.rgb[p * 3 + 1] = g;
        image.rgb[p * 3 + 2] = b;
    }
    return image;
}

double rmse_from(const Image& image, float level) {
    double sum = 0.0;
    for (float v : image.rgb) sum += (double(v) - level) * (double(v) - level);
    return std::sqrt(sum / double(image.rgb.size()));
}

std::vector<char> bytes_of(const Image& image) {
    std::vector<char> bytes(image.rgb.size() * sizeof(float));
    std::memcpy(bytes.data(), image.rgb.data(), bytes.size());
    return bytes;
}

// The input both determinism tests denoise, with aux images as a render gives them.
std::optional<Image> denoise_fixed_input(const Denoiser& denoiser, std::string* error) {
    const Image colour = noisy_constant(48, 0.5f, 7);
    const Image albedo = constant_image(48, 0.8f, 0.8f, 0.8f);
    const Image normal = constant_image(48, 0.0f, 0.0f, 1.0f);
    return denoiser.denoise(colour, &albedo, &normal, error);
}

TEST(Denoiser, NoisyConstantDenoisesToNearTheConstant) {
    REQUIRE_DENOISER(denoiser);
    const Image noisy = noisy_constant(64, 0.5f, 1);
    std::string error;
    const std::optional<Image> clean = denoiser->denoise(noisy, nullptr, nullptr, &error);
    ASSERT_TRUE(clean) << error;
    ASSERT_EQ(clean->width, 64u);
    ASSERT_EQ(clean->height, 64u);
    const double before = rmse_from(noisy, 0.5f);
    const double after = rmse_from(*clean, 0.5f);
    EXPECT_GT(before, 0.2);  // the noise is there: 0.5 / sqrt(4)
    EXPECT_LT(after, 0.2 * before) << "before " << before << ", after " << after;
    double mean = 0.0;
    for (float v : clean->rgb) mean += v;
    EXPECT_NEAR(mean / double(clean->rgb.size()), 0.5, 0.05);
}

TEST(Denoiser, UsesAlbedoAndNormalOfTheSameSize) {
    REQUIRE_DENOISER(denoiser);
    std::string error;
    const std::optional<Image> clean = denoise_fixed_input(*denoiser, &error);
    ASSERT_TRUE(clean) << error;
    EXPECT_LT(rmse_from(*clean, 0.5f), 0.1);
    for (float v : clean->rgb) ASSERT_TRUE(std::isfinite(v));
}

TEST(Denoiser, RefusesMismatchedOrLoneAuxImages) {
    REQUIRE_DENOISER(denoiser);
    const Image colour = noisy_constant(16, 0.5f, 2);
    const Image small = constant_image(8, 0.5f, 0.5f, 0.5f);
    const Image albedo = constant_image(16, 0.5f, 0.5f, 0.5f);
    std::string error;
    EXPECT_FALSE(denoiser->denoise(colour, &small, nullptr, &error));
    EXPECT_NE(error.find("albedo"), std::string::npos) << error;
    EXPECT_FALSE(denoiser->denoise(colour, &albedo, &small, &error));
    EXPECT_NE(error.find("normal"), std::string::npos) << error;
    EXPECT_FALSE(denoiser->denoise(colour, nullptr, &albedo, &error));
    EXPECT_NE(error.find("needs an albedo"), std::string::npos) << error;
    EXPECT_FALSE(denoiser->denoise(Image(), nullptr, nullptr, &error));
}

TEST(Denoiser, NonFiniteAndNegativePixelsDoNotSpread) {
    REQUIRE_DENOISER(denoiser);
    Image colour = noisy_constant(32, 0.5f, 3);
    colour.rgb[(16 * 32 + 16) * 3] = NAN;
    colour.rgb[(4 * 32 + 4) * 3 + 1] = INFINITY;
    colour.rgb[(8 * 32 + 20) * 3 + 2] = -3.0f;
    std::string error;
    const std::optional<Image> clean =
        denoiser->denoise(colour, nullptr, nullptr, &error);
    ASSERT_TRUE(clean) << error;
    for (float v : clean->rgb) ASSERT_TRUE(std::isfinite(v));
    // OIDN itself clamps an infinity to its largest float, which spread over the image
    // (an RMSE of 3e21) before we gave such pixels as black.
    EXPECT_LT(rmse_from(*clean, 0.5f), 0.15);
}

TEST(Denoiser, SameInputsGiveSameBytesTwiceInOneProcess) {
    REQUIRE_DENOISER(denoiser);
    std::string error;
    const std::optional<Image> first = denoise_fixed_input(*denoiser, &error);
    ASSERT_TRUE(first) << error;
    const std::optional<Image> second = denoise_fixed_input(*denoiser, &error);
    ASSERT_TRUE(second) << error;
    EXPECT_EQ(bytes_of(*first), bytes_of(*second));
    // A second device of its own, as another render's Denoiser would be.
    std::unique_ptr<Denoiser> other = Denoiser::open(&error);
    ASSERT_TRUE(other) << error;
    const std::optional<Image> third = denoise_fixed_input(*other, &error);
    ASSERT_TRUE(third) << error;
    EXPECT_EQ(bytes_of(*first), bytes_of(*third));
}

// A render that ends while its round end denoises (issue 33's review): the denoise gives
// up rather than run its minutes out, and the watch changes no byte when it does not.
TEST(Denoiser, AStopTurnedOnEndsTheDenoiseAndAStopLeftOffChangesNoByte) {
    REQUIRE_DENOISER(denoiser);
    const Image colour = noisy_constant(64, 0.5f, 4);
    std::string error;
    std::atomic<bool> stop = true;
    EXPECT_FALSE(denoiser->denoise(colour, nullptr, nullptr, &error, &stop));
    EXPECT_FALSE(error.empty());
    const std::optional<Image> unwatched =
        denoiser->denoise(colour, nullptr, nullptr, &error);
    ASSERT_TRUE(unwatched) << error;
    stop = false;
    const std::optional<Image> watched =
        denoiser->denoise(colour, nullptr, nullptr, &error, &stop);
    ASSERT_TRUE(watched) << error;
    EXPECT_EQ(bytes_of(*watched), bytes_of(*unwatched));
}

TEST(Denoiser, SameInputsGiveSameBytesInAnotherProcess) {
    REQUIRE_DENOISER(denoiser);
    std::string error;
    const std::optional<Image> here = denoise_fixed_input(*denoiser, &error);
    ASSERT_TRUE(here) << error;
    // The child: this same test, run again by the parent below, writes its bytes and
    // stops.
    if (const char* child_out = std::getenv(kBytesOutVariable)) {
        const std::vector<char> bytes = bytes_of(*here);
        std::ofstream(child_out, std::ios::binary)
            .write(bytes.data(), std::streamsize(bytes.size()));
        return;
    }

    const std::string out =
        testing::TempDir() + "denoised_bytes_" + std::to_string(getpid());
    const std::string self = std::filesystem::read_symlink("/proc/self/exe").string();
    const pid_t child = fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
        setenv(kBytesOutVariable, out.c_str(), 1);
        execl(self.c_str(), self.c_str(),
              "--gtest_filter=Denoiser.SameInputsGiveSameBytesInAnotherProcess",
              (char*)nullptr);
        _exit(127);
    }
    int status = 0;
    ASSERT_EQ(waitpid(child, &status, 0), child);
    ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "status " << status;
    std::ifstream in(out, std::ios::binary);
    const std::vector<char> there{std::istreambuf_iterator<char>(in), {}};
    std::remove(out.c_str());
    EXPECT_EQ(bytes_of(*here), there);
}

TEST(Denoiser, MissingLibraryNamesThePathAndTheInstallCommand) {
    const testing_denoise::ScopedEnv library(kOidnLibraryVariable,
                                             "/nonexistent/libOpenImageDenoise.so.2");
    std::string error;
    EXPECT_EQ(Denoiser::open(&error), nullptr);
    EXPECT_NE(error.find("/nonexistent/libOpenImageDenoise.so.2"), std::string::npos)
        << error;
    EXPECT_NE(error.find("scripts/install-deps.sh"), std::string::npos) << error;
    EXPECT_NE(error.find(kOidnLibraryVariable), std::string::npos) << error;
}

TEST(Denoiser, ALibraryWithoutOidnsCallsIsRefused) {
    // libz is a real shared library every build of ours has (the image room links it).
    const testing_denoise::ScopedEnv library(kOidnLibraryVariable, "libz.so.1");
    std::string error;
    EXPECT_EQ(Denoiser::open(&error), nullptr);
    EXPECT_NE(error.find("has no oidnNewDevice"), std::string::npos) << error;
}

}  // namespace
}  // namespace aliquot
