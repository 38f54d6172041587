#include "listener_watchdog.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <fstream>
#include <optional>
#include <sstream>

namespace aliquot {

namespace {

// The port of a /proc/net/tcp address ("0100007F:1F90").
int port_of(const std::string& address) {
    const size_t colon = address.rfind(':');
    return colon == std::string::npos
               ? -1
               : int(std::stoul(address.substr(colon + 1), nullptr, 16));
}

// Whether the connection from local port `client` to port `server` has been accepted:
// the server's end of it, established, has an inode. Nullopt while it is not listed.
std::optional<bool> accepted(int server, int client) {
    for (const char* table : {"/proc/net/tcp", "/proc/net/tcp6"}) {
        std::ifstream in(table);
        std::string line;
        std::getline(in, line);  // the header
        while (std::getline(in, line)) {
            std::istringstream fields(line);
            std::string slot, local, remote, state, queues, timer, retransmits, uid,
                timeout, inode;
            if (!(fields >> slot >> local >> remote >> state >> queues >> timer >>
                  retransmits >> uid >> timeout >> inode))
                continue;
            if (state != "01" || port_of(local) != server || port_of(remote) != client)
                continue;
            return inode != "0";
        }
    }
    return std::nullopt;
}

}  // namespace

bool accepts_connections(const std::string& host, int port,
                         std::chrono::milliseconds deadline) {
    addrinfo hints{};
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_NUMERICSERV;
    addrinfo* found = nullptr;
    if (getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &found) != 0)
        return false;
    const int fd = ::socket(found->ai_family, SOCK_STREAM | SOCK_CLOEXEC, 0);
    bool yes = false;
    // A full accept queue drops the SYN, and connect would retry for minutes.
    const auto seconds = std::chrono::duration_cast<std::chrono::seconds>(deadline);
    const timeval timeout{time_t(seconds.count()),
                          suseconds_t((deadline - seconds).count() * 1000)};
    if (fd >= 0) ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &timeout, sizeof timeout);
    if (fd >= 0 && ::connect(fd, found->ai_addr, found->ai_addrlen) == 0) {
        sockaddr_storage mine{};
        socklen_t length = sizeof mine;
        ::getsockname(fd, reinterpret_cast<sockaddr*>(&mine), &length);
        const int client = ntohs(mine.ss_family == AF_INET6
                                     ? reinterpret_cast<sockaddr_in6*>(&mine)->sin6_port
                                     : reinterpret_cast<sockaddr_in*>(&mine)->sin_port);
        const auto end = std::chrono::steady_clock::now() + deadline;
        do {
            yes = accepted(port, client).value_or(false);
            if (!yes) std::this_thread::sleep_for(std::chrono::milliseconds(20));
        } while (!yes && std::chrono::steady_clock::now() < end);
    }
    if (fd >= 0) ::close(fd);
    freeaddrinfo(found);
    return yes;
}

ListenerWatchdog::ListenerWatchdog(std::chrono::milliseconds period, int failures,
                                   std::function<bool()> reached,
                                   std::function<void()> deaf)
    : period_(period),
      failures_(failures),
      reached_(std::move(reached)),
      deaf_(std::move(deaf)),
      thread_([this] { run(); }) {}

ListenerWatchdog::~ListenerWatchdog() {
    {
        std::lock_guard lock(mutex_);
        stopping_ = true;
    }
    wake_.notify_all();
    thread_.join();
}

void ListenerWatchdog::run() {
    int failed = 0;
    std::unique_lock lock(mutex_);
    while (!wake_.wait_for(lock, period_, [this] { return stopping_; })) {
        lock.unlock();
        try {
            failed = reached_() ? 0 : failed + 1;
            if (failed >= failures_) {
                failed = 0;
                deaf_();
            }
        } catch (const std::exception&) {
            // A probe that cannot be made this time proves nothing either way.
        }
        lock.lock();
    }
}

}  // namespace aliquot
