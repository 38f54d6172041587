// Token files: the secrets a coordinator makes at first start (DATA/client.token,
// DATA/worker.token, mode 0600) and the ones clients and workers are handed
// (--token-file, ALIQUOT_TOKEN). docs/SECURITY.md says who holds which.
#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>

namespace aliquot {

// A token that cannot be used, or a token file that cannot be read or made. Its message
// names the file, never the file's content.
class TokenError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// Throws TokenError unless `token` can be a bearer token: 16 to 1024 characters of RFC
// 6750's b64token alphabet (letters, digits, - . _ ~ + / =; shorter is guessable).
// `source` names where it came from for the message.
void check_token(std::string_view token, const std::string& source);

// The token in `path`, without the trailing newline (or whitespace) editors add.
std::string read_token_file(const std::filesystem::path& path);

// The token in `path`; when there is no such file, a new random one (256 bits, hex)
// written there with mode 0600, and `created` set.
std::string load_or_create_token_file(const std::filesystem::path& path, bool& created);

}  // namespace aliquot
