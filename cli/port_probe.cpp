#include "port_probe.h"

#include <fcntl.h>
#include <netdb.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>

namespace aliquot::cli {

namespace {

// Host and port of a gRPC target; false for forms a TCP probe cannot read.
bool split_address(std::string address, std::string& host, std::string& port) {
    for (const char* scheme : {"dns:///", "dns:", "ipv4:", "ipv6:"}) {
        if (address.rfind(scheme, 0) == 0) {
            address.erase(0, std::string(scheme).size());
            break;
        }
    }
    const size_t colon = address.rfind(':');
    if (colon == std::string::npos || colon + 1 == address.size()) return false;
    host = address.substr(0, colon);
    port = address.substr(colon + 1);
    if (host.size() >= 2 && host.front() == '[' && host.back() == ']')
        host = host.substr(1, host.size() - 2);
    if (host.empty() || host.find_first_of("/[]") != std::string::npos) return false;
    return port.find_first_not_of("0123456789") == std::string::npos;
}

bool connects(const addrinfo& a, std::chrono::milliseconds within) {
    const int fd =
        socket(a.ai_family, a.ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, a.ai_protocol);
    if (fd < 0) return false;
    bool ok = connect(fd, a.ai_addr, a.ai_addrlen) == 0;
    if (!ok && errno == EINPROGRESS) {
        pollfd p{fd, POLLOUT, 0};
        int error = 0;
        socklen_t length = sizeof error;
        ok = poll(&p, 1, int(within.count())) == 1 &&
             getsockopt(fd, SOL_SOCKET, SO_ERROR, &error, &length) == 0 && error == 0;
    }
    close(fd);
    return ok;
}

}  // namespace

bool port_answers(const std::string& address, std::chrono::milliseconds within) {
    std::string host, port;
    if (!split_address(address, host, port)) return false;
    addrinfo hints{};
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    addrinfo* found = nullptr;
    if (getaddrinfo(host.c_str(), port.c_str(), &hints, &found) != 0) return false;
    bool answers = false;
    for (const addrinfo* a = found; a && !answers; a = a->ai_next)
        answers = connects(*a, within);
    freeaddrinfo(found);
    return answers;
}

}  // namespace aliquot::cli
