// `aliquot compare A.exr B.exr`: the error of image A against the reference B.
#include <cstdio>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "error_metric.h"
#include "exr_io.h"
#include "whole_number_option.h"

namespace aliquot::cli {
namespace {

struct CompareOptions {
    std::string test, reference;
    bool json = false;
    int bucket_size = 16;
};

void run_compare(const CompareOptions& o) {
    // Checked here rather than with a CLI11 validator so that every user error leaves
    // through main's one-line "aliquot: ..." path with exit status 1.
    if (o.bucket_size <= 0)
        throw UsageError("--bucket-size must be positive, got " +
                         std::to_string(o.bucket_size));
    const Image test = read_exr(o.test);
    const Image reference = read_exr(o.reference);
    ErrorMetrics m;
    try {
        m = compare_images(test, reference, o.bucket_size);
    } catch (const ImageMismatch& e) {
        throw CommandError(std::string(e.what()) + " (" + o.test + " vs " + o.reference +
                           ")");
    }

    if (o.json) {
        // ordered_json keeps the keys in the order people read them, not alphabetical.
        const nlohmann::ordered_json out = {
            {"mean_abs", m.mean_abs},         {"rmse", m.rmse},
            {"relative_mse", m.relative_mse}, {"max_bucket", m.max_bucket},
            {"p99_bucket", m.p99_bucket},     {"width", test.width},
            {"height", test.height},
        };
        std::printf("%s\n", out.dump().c_str());
        return;
    }
    const std::string bucket = std::to_string(o.bucket_size) + "px";
    std::printf("%-22s %ux%u\n", "resolution", test.width, test.height);
    std::printf("%-22s %.6g\n", "E (mean abs)", m.mean_abs);
    std::printf("%-22s %.6g\n", "RMSE", m.rmse);
    std::printf("%-22s %.6g\n", "relMSE", m.relative_mse);
    std::printf("%-22s %.6g\n", ("max bucket E (" + bucket + ")").c_str(), m.max_bucket);
    std::printf("%-22s %.6g\n", ("p99 bucket E (" + bucket + ")").c_str(), m.p99_bucket);
}

}  // namespace

void register_compare(CLI::App& app) {
    // The options outlive this function: CLI11 fills them during parse and runs the
    // callback.
    auto options = std::make_shared<CompareOptions>();
    CLI::App* cmd = app.add_subcommand(
        "compare", "Error of image A against the reference B (E, RMSE, relMSE, buckets)");
    cmd->add_option("A", options->test, "image to measure (OpenEXR)")->required();
    cmd->add_option("B", options->reference, "reference image (OpenEXR)")->required();
    cmd->add_flag("--json", options->json, "print one JSON object instead of text");
    cmd->add_option("--bucket-size", options->bucket_size,
                    "side in pixels of the buckets for the max and p99 bucket error")
        ->check(whole_number())
        ->capture_default_str();
    cmd->callback([options] { run_compare(*options); });
}

}  // namespace aliquot::cli
