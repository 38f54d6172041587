#include "oidn_library.h"

#include <dlfcn.h>
#include <sys/stat.h>
#include <unistd.h>

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

// Why the file or directory `path` (no symlink followed at its last component) could be
// another user's: "" when it is owned by root or by us and writable by nobody else. A
// symlink's own mode means nothing, only who owns it. A sticky directory of root's or
// ours (/tmp) is trusted although everyone may write it: there nobody may rename or
// remove an entry of another's, so what decides is the entry below, which must exist
// (an absent name is one anyone could make there between this check and the load).
std::string untrusted_because(const fs::path& path) {
    struct stat st {};
    if (lstat(path.c_str(), &st) != 0) return path.string() + " does not exist";
    if (st.st_uid != 0 && st.st_uid != geteuid())
        return path.string() + " is owned by another user (uid " +
               std::to_string(st.st_uid) + ")";
    if (S_ISDIR(st.st_mode) && (st.st_mode & S_ISVTX) != 0) return "";
    if (!S_ISLNK(st.st_mode) && (st.st_mode & (S_IWGRP | S_IWOTH)) != 0)
        return path.string() + " is writable by " +
               ((st.st_mode & S_IWOTH) != 0 ? "every user" : "its group");
    return "";
}

// Every reason from / down to `path` itself, lexically (each symlink on the way) and once
// more with the symlinks resolved; "" when none.
std::string untrusted_path(const std::string& library) {
    std::error_code ec;
    const fs::path lexical = fs::absolute(library, ec).lexically_normal();
    if (ec) return library + " has no absolute path";
    std::vector<std::string> reasons;
    auto check = [&](const fs::path& full) {
        fs::path prefix;
        for (const auto& part : full) {
            prefix /= part;
            const std::string why = untrusted_because(prefix);
            if (!why.empty() &&
                std::find(reasons.begin(), reasons.end(), why) == reasons.end())
                reasons.push_back(why);
        }
    };
    check(lexical);
    const fs::path resolved = fs::weakly_canonical(lexical, ec);
    if (!ec) check(resolved);
    std::string joined;
    for (const auto& why : reasons) joined += (joined.empty() ? "" : ", ") + why;
    return joined;
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
           bind(handle, "oidnSetFilterProgressMonitorFunction",
                &api->setFilterProgressMonitorFunction, missing) &&
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
        // dlopen runs the file's initialisers: a file or a directory above it that
        // another user could have written is refused before it is opened. The bare soname
        // is the loader's own search, trusted as the system's directories are.
        const std::string untrusted =
            path.find('/') == std::string::npos ? "" : untrusted_path(path);
        if (!untrusted.empty()) {
            tried += (tried.empty() ? "" : "; ") + path + ": refused, " + untrusted;
            continue;
        }
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
