#include "denoiser.h"

#include <cmath>
#include <mutex>

#include "oidn_library.h"

namespace aliquot {

struct Denoiser::Loaded {
    std::unique_ptr<oidn::OidnLibrary> library;
    oidn::Device device = nullptr;
    std::mutex calls;  // one filter at a time on the device

    ~Loaded() {
        if (device != nullptr) library->api.releaseDevice(device);
    }

    // OIDN's last error on the device, cleared by reading it: "" when none.
    std::string take_error() const {
        const char* message = nullptr;
        if (library->api.getDeviceError(device, &message) == oidn::kErrorNone) return "";
        return std::string("Open Image Denoise: ") +
               (message != nullptr && *message != '\0' ? message : "unknown error");
    }
};

namespace {

// OIDN reads HDR colour in [0, +inf): it makes a NaN 0 but an infinity its largest float,
// which spreads through the network's receptive field (denoiser_test.cpp), so such
// pixels, and negative ones, are given as black.
const std::vector<float>& finite_colour(const std::vector<float>& rgb,
                                        std::vector<float>* cleaned) {
    bool clean = true;
    for (float v : rgb)
        if (!(v >= 0.0f && v < INFINITY)) {
            clean = false;
            break;
        }
    if (clean) return rgb;
    *cleaned = rgb;
    for (float& v : *cleaned)
        if (!(v >= 0.0f && v < INFINITY)) v = 0.0f;
    return *cleaned;
}

bool same_size(const Image& a, const Image& b) {
    return a.width == b.width && a.height == b.height && a.rgb.size() == b.rgb.size();
}

}  // namespace

Denoiser::Denoiser(std::unique_ptr<Loaded> loaded) : loaded_(std::move(loaded)) {}
Denoiser::~Denoiser() = default;

const std::string& Denoiser::library_path() const { return loaded_->library->path; }

std::unique_ptr<Denoiser> Denoiser::open(std::string* error) {
    auto loaded = std::make_unique<Loaded>();
    loaded->library = oidn::load_oidn_library(error);
    if (!loaded->library) return nullptr;
    const oidn::Api& api = loaded->library->api;
    // The CPU device always, not OIDN's default pick: a GPU's kernels give slightly
    // different numbers (OIDN's docs), and the same inputs must give the same bytes.
    loaded->device = api.newDevice(oidn::kDeviceTypeCpu);
    if (loaded->device == nullptr) {
        if (error)
            *error = "Open Image Denoise: no CPU device (" + loaded->library->path + ")";
        return nullptr;
    }
    // No pinning: in the aliquot process OIDN shares TBB's worker threads with Embree,
    // and a thread pinned while denoising would stay pinned when it goes back to tracing.
    api.setDeviceBool(loaded->device, "setAffinity", false);
    api.commitDevice(loaded->device);
    if (std::string why = loaded->take_error(); !why.empty()) {
        if (error) *error = why + " (" + loaded->library->path + ")";
        return nullptr;
    }
    return std::unique_ptr<Denoiser>(new Denoiser(std::move(loaded)));
}

std::optional<Image> Denoiser::denoise(const Image& colour, const Image* albedo,
                                       const Image* normal, std::string* error,
                                       const std::atomic<bool>* stop) const {
    auto fail = [&](std::string why) -> std::optional<Image> {
        if (error) *error = std::move(why);
        return std::nullopt;
    };
    if (colour.width == 0 || colour.height == 0 ||
        colour.rgb.size() != colour.pixel_count() * 3)
        return fail(
            "denoise: the colour image is empty or its rgb is not width x height x 3");
    if (albedo != nullptr && !same_size(colour, *albedo))
        return fail("denoise: the albedo image's size differs from the colour's");
    if (normal != nullptr && !same_size(colour, *normal))
        return fail("denoise: the normal image's size differs from the colour's");
    if (normal != nullptr && albedo == nullptr)
        return fail(
            "denoise: a normal image needs an albedo image too (OIDN has no model "
            "for a normal alone)");

    std::vector<float> cleaned;
    const std::vector<float>& input = finite_colour(colour.rgb, &cleaned);
    Image out(colour.width, colour.height);
    out.attributes = colour.attributes;

    const oidn::Api& api = loaded_->library->api;
    std::lock_guard lock(loaded_->calls);
    loaded_->take_error();  // a stale error must not be reported as this call's
    oidn::Filter filter = api.newFilter(loaded_->device, "RT");
    if (filter == nullptr) return fail(loaded_->take_error());
    // OIDN only reads the inputs; its C API takes every image as void*.
    auto share = [&](const char* name, const std::vector<float>& rgb) {
        api.setSharedFilterImage(filter, name, const_cast<float*>(rgb.data()),
                                 oidn::kFormatFloat3, colour.width, colour.height, 0, 0,
                                 0);
    };
    share("color", input);
    if (albedo != nullptr) share("albedo", albedo->rgb);
    if (normal != nullptr) share("normal", normal->rgb);
    share("output", out.rgb);
    api.setFilterBool(filter, "hdr", true);
    // Said, not left to the default, since the bytes depend on it.
    api.setFilterInt(filter, "quality", oidn::kQualityHigh);
    if (stop != nullptr)
        api.setFilterProgressMonitorFunction(
            filter,
            [](void* user, double) {
                return !static_cast<const std::atomic<bool>*>(user)->load();
            },
            const_cast<std::atomic<bool>*>(stop));
    api.commitFilter(filter);
    if (std::string why = loaded_->take_error(); !why.empty()) {
        api.releaseFilter(filter);
        return fail(why);
    }
    api.executeFilter(filter);
    std::string why = loaded_->take_error();
    api.releaseFilter(filter);
    if (!why.empty()) return fail(why);
    return out;
}

}  // namespace aliquot
