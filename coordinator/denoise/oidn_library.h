// OidnLibrary: Open Image Denoise's C API, the few calls the Denoiser makes, found in a
// libOpenImageDenoise.so.2 loaded at run time. The declarations are ours, from OIDN 2.x's
// oidn.h (the pyoidn wheel carries the library but no headers); they are C functions with
// plain types, the same in every 2.x release.
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

namespace aliquot::oidn {

using Device = struct DeviceImpl*;
using Filter = struct FilterImpl*;

// oidn.h's enum values that we pass.
inline constexpr int kDeviceTypeCpu = 1;  // OIDN_DEVICE_TYPE_CPU
inline constexpr int kErrorNone = 0;      // OIDN_ERROR_NONE
inline constexpr int kFormatFloat3 = 3;   // OIDN_FORMAT_FLOAT3
inline constexpr int kQualityHigh = 6;    // OIDN_QUALITY_HIGH

struct Api {
    Device (*newDevice)(int type);
    void (*setDeviceBool)(Device, const char* name, bool value);
    void (*commitDevice)(Device);
    int (*getDeviceError)(Device, const char** message);
    void (*releaseDevice)(Device);
    Filter (*newFilter)(Device, const char* type);
    void (*setSharedFilterImage)(Filter, const char* name, void* pointer, int format,
                                 size_t width, size_t height, size_t byte_offset,
                                 size_t pixel_byte_stride, size_t row_byte_stride);
    void (*setFilterBool)(Filter, const char* name, bool value);
    void (*setFilterInt)(Filter, const char* name, int value);
    void (*commitFilter)(Filter);
    // OIDN calls `monitor` as the filter runs; it stops the filter by returning false
    // (executeFilter then leaves a device error).
    void (*setFilterProgressMonitorFunction)(Filter,
                                             bool (*monitor)(void* user, double n),
                                             void* user);
    void (*executeFilter)(Filter);
    void (*releaseFilter)(Filter);
};

// The library, loaded once per path for the process's life: it is never unloaded, since
// its thread pool (TBB's) may outlive any one device.
struct OidnLibrary {
    std::string path;
    Api api{};
};

// The candidates, in order (denoiser.h says which and why); search_root is the source
// tree baked in at configure time (empty: none).
std::vector<std::string> oidn_library_candidates(const std::string& search_root);

// Loads the first candidate that loads and has every call, or nullptr with *error listing
// what was tried and how to install the library.
std::unique_ptr<OidnLibrary> load_oidn_library(std::string* error);

}  // namespace aliquot::oidn
