// `aliquot compare A.exr B.exr`: the error of image A against the reference B, and of A
// denoised when A has a denoised layer or --denoise asks (issue 34).
#include <cstdio>
#include <memory>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "denoised_render.h"
#include "error_metric.h"
#include "exr_io.h"
#include "whole_number_option.h"

namespace aliquot::cli {
namespace {

struct CompareOptions {
    std::string test, reference;
    bool json = false;
    bool denoise = false;
    int bucket_size = 16;
};

// A's denoised colour: its denoised.R/G/B layer, or with --denoise A denoised here (with
// its albedo and normal layers when it has them). nullopt when neither. `how` says which.
std::optional<Image> denoised_test(const CompareOptions& o, const Image& test,
                                   std::string* how) {
    if (!o.denoise) {
        std::optional<Image> layer = denoised_layer(test);
        if (layer) *how = "layer denoised.R/G/B";
        return layer;
    }
    std::string error;
    const std::unique_ptr<Denoiser> denoiser = Denoiser::open(&error);
    if (!denoiser) throw CommandError("--denoise: " + error);
    bool used_aux = false;
    std::optional<Image> denoised = denoise_render(*denoiser, test, &error, &used_aux);
    if (!denoised) throw CommandError("--denoise: " + error + " (" + o.test + ")");
    *how = used_aux ? "Open Image Denoise, first-hit albedo and normal"
                    : "Open Image Denoise, colour only";
    return denoised;
}

nlohmann::ordered_json metrics_json(const ErrorMetrics& m) {
    return {{"mean_abs", m.mean_abs},
            {"rmse", m.rmse},
            {"relative_mse", m.relative_mse},
            {"max_bucket", m.max_bucket},
            {"p99_bucket", m.p99_bucket},
            // A fraction, as relative_mse; NaN (a black reference, an image holding NaN
            // or inf) dumps as null.
            {"mean_bias", m.mean_bias},
            {"mean_bias_se", m.mean_bias_se},
            {"bias_beyond_noise", bias_beyond_noise(m)}};
}

// The lines every image's metrics print, raw and denoised alike.
void print_metrics(const ErrorMetrics& m, const std::string& bucket) {
    std::printf("%-22s %.6g\n", "E (mean abs)", m.mean_abs);
    std::printf("%-22s %.6g\n", "RMSE", m.rmse);
    std::printf("%-22s %.6g\n", "relMSE", m.relative_mse);
    std::printf("%-22s %.6g\n", ("max bucket E (" + bucket + ")").c_str(), m.max_bucket);
    std::printf("%-22s %.6g\n", ("p99 bucket E (" + bucket + ")").c_str(), m.p99_bucket);
    // E rewards a method that darkens its image (docs/RESULTS.md): the bias beside it.
    std::printf("%-22s %s\n", "mean bias", mean_bias_text(m).c_str());
}

void run_compare(const CompareOptions& o) {
    // Checked here rather than with a CLI11 validator so that every user error leaves
    // through main's one-line "aliquot: ..." path with exit status 1.
    if (o.bucket_size <= 0)
        throw UsageError("--bucket-size must be positive, got " +
                         std::to_string(o.bucket_size));
    const Image test = read_exr(o.test);
    const Image reference = read_exr(o.reference);
    ErrorMetrics m;
    std::optional<ErrorMetrics> d;  // A denoised, against the same reference
    std::string how;
    try {
        m = compare_images(test, reference, o.bucket_size);
        if (const std::optional<Image> denoised = denoised_test(o, test, &how))
            d = compare_images(*denoised, reference, o.bucket_size);
    } catch (const ImageMismatch& e) {
        throw CommandError(std::string(e.what()) + " (" + o.test + " vs " + o.reference +
                           ")");
    }

    if (o.json) {
        // ordered_json keeps the keys in the order people read them, not alphabetical.
        nlohmann::ordered_json out = metrics_json(m);
        out["width"] = test.width;
        out["height"] = test.height;
        if (d) {
            out["denoised"] = metrics_json(*d);
            out["denoised"]["source"] = how;
        }
        std::printf("%s\n", out.dump().c_str());
        return;
    }
    const std::string bucket = std::to_string(o.bucket_size) + "px";
    std::printf("%-22s %ux%u\n", "resolution", test.width, test.height);
    print_metrics(m, bucket);
    if (!d) return;
    // Beside the raw figures, in the same words: what allocation is judged by when the
    // image will be denoised.
    std::printf("denoised (%s):\n", how.c_str());
    print_metrics(*d, bucket);
}

}  // namespace

void register_compare(CLI::App& app) {
    // The options outlive this function: CLI11 fills them during parse and runs the
    // callback.
    auto options = std::make_shared<CompareOptions>();
    CLI::App* cmd = app.add_subcommand(
        "compare",
        "Error of image A against the reference B (E, RMSE, relMSE, buckets, the mean "
        "bias and its standard error), and of A "
        "denoised when it has a denoised layer or --denoise asks");
    cmd->add_option("A", options->test, "image to measure (OpenEXR)")->required();
    cmd->add_option("B", options->reference, "reference image (OpenEXR)")->required();
    cmd->add_flag("--json", options->json, "print one JSON object instead of text");
    cmd->add_flag("--denoise", options->denoise,
                  "denoise A with Intel Open Image Denoise (using its albedo and normal "
                  "layers when it has them) and report that error too; without it, an A "
                  "with a denoised.R/G/B layer has that layer measured");
    cmd->add_option("--bucket-size", options->bucket_size,
                    "side in pixels of the buckets for the max and p99 bucket error")
        ->check(whole_number())
        ->capture_default_str();
    cmd->callback([options] { run_compare(*options); });
}

}  // namespace aliquot::cli
