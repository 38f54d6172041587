#include "oidn_library.h"

#include <dlfcn.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <system_error>

#include "denoiser.h"

namespace aliquot::oidn {
namespace {

namespace fs = std::filesystem;

// The library's soname: OIDN 2.x, whose C API is the one Api declares.
constexpr const char* kSoname = "libOpenImageDenoise.so.2";

// pyoidn's copy under a repository's .venv, for whichever Python made the venv.
std::vector<std::string> venv_libraries(const fs::path& root) {
    std::vector<std::string> found;
    std::error_code ec;
    const fs::path lib = root / ".venv" / "lib";
    for (fs::directory_iterator it(lib, ec), end; !ec && it != end; it.increment(ec)) {
        const fs::path candidate =
            it->path() / "site-packages" / "pyoidn" / "oidn" / "lib" / kSoname;
        if (it->path().filename().string().rfind("python", 0) == 0 &&
            fs::exists(candidate, ec))
            found.push_back(candidate.string());
    }
    std::sort(found.begin(), found.end());
    return found;
}

// build/bin/aliquot -> the repository two folders up, where a fresh clone's .venv is.
fs::path root_above_executable() {
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (ec) return {};
    return exe.parent_path().parent_path().parent_path();
}

template <typename F>
bool bind(void* handle, const char* name, F* slot, std::string* missing) {
    void* symbol = dlsym(handle, name);
    if (symbol == nullptr) {
        *missing = name;
        return false;
    }
    *slot = reinterpret_cast<F>(symbol);
    return true;
}

bool bind_api(void* handle, Api* api, std::string* missing) {
    return bind(handle, "oidnNewDevice", &api->newDevice, missing) &&
           bind(handle, "oidnSetDeviceBool", &api->setDeviceBool, missing) &&
           bind(handle, "oidnCommitDevice", &api->commitDevice, missing) &&
           bind(handle, "oidnGetDeviceError", &api->getDeviceError, missing) &&
           bind(handle, "oidnReleaseDevice", &api->releaseDevice, missing) &&
           bind(handle, "oidnNewFilter", &api->newFilter, missing) &&
           bind(handle, "oidnSetSharedFilterImage", &api->setSharedFilterImage,
                missing) &&
           bind(handle, "oidnSetFilterBool", &api->setFilterBool, missing) &&
           bind(handle, "oidnSetFilterInt", &api->setFilterInt, missing) &&
           bind(handle, "oidnCommitFilter", &api->commitFilter, missing) &&
           bind(handle, "oidnExecuteFilter", &api->executeFilter, missing) &&
           bind(handle, "oidnReleaseFilter", &api->releaseFilter, missing);
}

}  // namespace

std::vector<std::string> oidn_library_candidates(const std::string& search_root) {
    const char* chosen = std::getenv(kOidnLibraryVariable);
    if (chosen != nullptr && *chosen != '\0') return {chosen};
    std::vector<std::string> candidates;
    auto add = [&](const std::vector<std::string>& paths) {
        for (const auto& p : paths)
            if (std::find(candidates.begin(), candidates.end(), p) == candidates.end())
                candidates.push_back(p);
    };
    if (!search_root.empty()) add(venv_libraries(search_root));
    const fs::path above = root_above_executable();
    if (!above.empty()) add(venv_libraries(above));
    candidates.push_back(kSoname);  // the loader's own search
    return candidates;
}

std::unique_ptr<OidnLibrary> load_oidn_library(std::string* error) {
#ifdef ALIQUOT_OIDN_SEARCH_ROOT
    const std::string search_root = ALIQUOT_OIDN_SEARCH_ROOT;
#else
    const std::string search_root;
#endif
    std::string tried;
    for (const auto& path : oidn_library_candidates(search_root)) {
        // RTLD_LOCAL: OIDN's symbols stay out of the process's namespace. Kept loaded.
        void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
        if (handle == nullptr) {
            const char* why = dlerror();  // names the path itself
            tried += (tried.empty() ? "" : "; ") +
                     (why != nullptr ? std::string(why) : path + ": cannot be loaded");
            continue;
        }
        auto library = std::make_unique<OidnLibrary>();
        std::string missing;
        if (!bind_api(handle, &library->api, &missing)) {
            tried += (tried.empty() ? "" : "; ") + path + ": has no " + missing +
                     " (not Open Image Denoise 2.x)";
            dlclose(handle);
            continue;
        }
        library->path = path;
        return library;
    }
    if (error != nullptr) {
        const char* chosen = std::getenv(kOidnLibraryVariable);
        *error = std::string("Intel Open Image Denoise (") + kSoname + ") not found (" +
                 tried + "); install it with scripts/install-deps.sh (pyoidn into the " +
                 "repository's .venv)" +
                 (chosen != nullptr && *chosen != '\0'
                      ? std::string(", or point ") + kOidnLibraryVariable +
                            " at an existing " + kSoname
                      : std::string(", or set ") + kOidnLibraryVariable + " to its path");
    }
    return nullptr;
}

}  // namespace aliquot::oidn
