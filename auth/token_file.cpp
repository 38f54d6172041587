#include "token_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>

#include "secret.h"

namespace aliquot {

namespace {

constexpr size_t kMaxToken = 1024;

std::string why(const std::filesystem::path& path, const char* what) {
    return "token file " + path.string() + ": " + what;
}

}  // namespace

void check_token(std::string_view token, const std::string& source) {
    if (token.empty()) throw TokenError(source + ": the token is empty");
    if (token.size() < 16)
        throw TokenError(source + ": the token is shorter than 16 characters");
    if (token.size() > kMaxToken)
        throw TokenError(source + ": the token is longer than 1024 characters");
    // RFC 6750's b64token alphabet: what a bearer header carries unchanged, and what a
    // cookie value may hold (no ; , " \ or %, which HTTP libraries split or decode).
    for (const char c : token) {
        const bool ok = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') ||
                        (c >= '0' && c <= '9') || c == '-' || c == '.' || c == '_' ||
                        c == '~' || c == '+' || c == '/' || c == '=';
        if (!ok)
            throw TokenError(source +
                             ": a token is letters, digits and - . _ ~ + / = only (as "
                             "`openssl rand -hex 32` makes)");
    }
}

std::string read_token_file(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw TokenError(why(path, std::strerror(errno)));
    std::string text(kMaxToken + 64, '\0');
    in.read(text.data(), std::streamsize(text.size()));
    text.resize(size_t(in.gcount()));
    if (in.bad()) throw TokenError(why(path, "cannot be read"));
    while (!text.empty() && (text.back() == '\n' || text.back() == '\r' ||
                             text.back() == ' ' || text.back() == '\t'))
        text.pop_back();
    check_token(text, "token file " + path.string());
    return text;
}

std::string load_or_create_token_file(const std::filesystem::path& path, bool& created) {
    created = false;
    const std::string token = random_hex(32);
    // O_EXCL: never write through a file (or symlink) someone put there first; if one is
    // there, it is the token.
    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    if (fd < 0) {
        if (errno == EEXIST) return read_token_file(path);
        throw TokenError(why(path, std::strerror(errno)));
    }
    const std::string line = token + "\n";
    const bool written =
        ::write(fd, line.data(), line.size()) == ssize_t(line.size()) && ::fsync(fd) == 0;
    ::close(fd);
    if (!written) {
        const std::string error = std::strerror(errno);
        ::unlink(
            path.c_str());  // never leave a half-written secret to be read next start
        throw TokenError(why(path, error.c_str()));
    }
    created = true;
    return token;
}

}  // namespace aliquot
