// The dashboard's signed-in browsers. Signing in with the client token opens a session: a
// random id of its own, which the browser's cookie carries instead of the token. The id
// opens the HTTP API of this server only (gRPC never knows it), signing out or expiry
// ends it, and the table is bounded. Kept in memory: a restart, which is also the only
// way the coordinator takes a new client token (docs/SECURITY.md, "Rotating tokens"),
// signs every browser out.
#pragma once

#include <chrono>
#include <cstddef>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <string_view>

namespace aliquot {

struct SessionLimits {
    // Sessions at once at most; signing in past it ends the least recently used one.
    // Only holders of the client token can open sessions, so this bounds memory, not
    // an attacker.
    size_t max_sessions = 1024;
    // A session unused this long ends (a dashboard that stays open uses it all the time),
    // and so does every session this long after signing in, used or not.
    std::chrono::milliseconds idle = std::chrono::hours(12);
    std::chrono::milliseconds lifetime = std::chrono::hours(7 * 24);
};

class BrowserSessions {
public:
    using Clock = std::function<std::chrono::steady_clock::time_point()>;

    explicit BrowserSessions(
        SessionLimits limits = {},
        Clock clock = [] { return std::chrono::steady_clock::now(); });

    // A new session's id: 256 random bits as 64 hex digits.
    std::string open();
    // Whether `id` names a live session; using it keeps it from idling out.
    bool use(std::string_view id);
    // Ends the session `id` names, if any (signing out).
    void close(std::string_view id);
    size_t size() const;

private:
    struct Session {
        std::string verifier;
        std::chrono::steady_clock::time_point opened, used;
    };
    bool expired(const Session& s, std::chrono::steady_clock::time_point now) const;

    const SessionLimits limits_;
    const Clock clock_;
    mutable std::mutex mutex_;
    // By the id's first half (the selector); its second half (the verifier) is compared
    // in constant time, so how long a lookup takes tells a guesser nothing of the secret.
    std::map<std::string, Session, std::less<>> sessions_;
};

}  // namespace aliquot
