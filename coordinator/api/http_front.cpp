#include "http_front.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <openssl/err.h>
#include <openssl/ssl.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "farm_log.h"

namespace aliquot {

namespace {

using Clock = std::chrono::steady_clock;

// The connection the calling thread serves a request of (see trust_current_request).
thread_local FrontConnection* serving_now = nullptr;

// OpenSSL writes to its socket with write(), not send(MSG_NOSIGNAL): a browser that left
// would end the process with SIGPIPE. Blocked in the front's own threads only, so that no
// other thread of the process changes; the write fails with EPIPE instead.
void block_sigpipe() {
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGPIPE);
    pthread_sigmask(SIG_BLOCK, &set, nullptr);
}

bool iequals(std::string_view a, std::string_view b) {
    return a.size() == b.size() &&
           std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
               return std::tolower((unsigned char)x) == std::tolower((unsigned char)y);
           });
}

std::string_view trim(std::string_view s) {
    while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
    while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
    return s;
}

// The body length a head declares, for the front to wait for: 0 when it declares none or
// one the front does not read (chunked, too large, malformed: httplib and HttpServer's
// checks decide those on a thread).
size_t small_body_length(std::string_view head, size_t max_small_body) {
    size_t length = 0;
    while (!head.empty()) {
        const size_t end = head.find("\r\n");
        const std::string_view line = head.substr(0, end);
        head.remove_prefix(end == std::string_view::npos ? head.size() : end + 2);
        const size_t colon = line.find(':');
        if (colon == std::string_view::npos) continue;
        const std::string_view name = trim(line.substr(0, colon));
        const std::string_view value = trim(line.substr(colon + 1));
        if (iequals(name, "Transfer-Encoding")) return 0;
        if (!iequals(name, "Content-Length")) continue;
        if (value.empty() || value.size() > 9 ||
            !std::all_of(value.begin(), value.end(),
                         [](char c) { return c >= '0' && c <= '9'; }))
            return 0;
        length = std::stoul(std::string(value));
    }
    return length <= max_small_body ? length : 0;
}

}  // namespace

// ---- FrontConnection ----

namespace {

// An IPv4 or IPv6 socket address as httplib's Request spells it: the address in text and
// the port; anything else leaves both as they were.
void address_text(const sockaddr_storage& addr, std::string& ip, int& port) {
    char text[INET6_ADDRSTRLEN] = {};
    if (addr.ss_family == AF_INET) {
        const auto* a = reinterpret_cast<const sockaddr_in*>(&addr);
        ::inet_ntop(AF_INET, &a->sin_addr, text, sizeof text);
        port = ntohs(a->sin_port);
    } else if (addr.ss_family == AF_INET6) {
        const auto* a = reinterpret_cast<const sockaddr_in6*>(&addr);
        ::inet_ntop(AF_INET6, &a->sin6_addr, text, sizeof text);
        port = ntohs(a->sin6_port);
    } else {
        return;
    }
    ip = text;
}

}  // namespace

FrontConnection::FrontConnection(int fd, SSL* ssl, const FrontLimits& limits)
    : fd_(fd), ssl_(ssl), limits_(limits) {
    sockaddr_storage addr{};
    socklen_t len = sizeof addr;
    if (::getpeername(fd_, reinterpret_cast<sockaddr*>(&addr), &len) == 0)
        address_text(addr, peer_ip_, peer_port_);
}

FrontConnection::~FrontConnection() {
    if (ssl_) {
        // close_notify, best effort: the socket does not block, and a session that
        // failed must not be shut down (OpenSSL's rule).
        if (handshake_done_ && !failed_ && !cut_) {
            ERR_clear_error();
            SSL_shutdown(ssl_);
        }
        SSL_free(ssl_);
        ERR_clear_error();
    }
    if (cut_) {
        // Reset, not a FIN behind the unsent bytes: the slow reader would otherwise
        // take the kernel's send buffer (megabytes) at its own pace.
        const linger abort{1, 0};
        ::setsockopt(fd_, SOL_SOCKET, SO_LINGER, &abort, sizeof abort);
    }
    ::shutdown(fd_, SHUT_RDWR);
    ::close(fd_);
}

FrontConnection::Progress FrontConnection::examine() {
    const std::string_view pending = std::string_view(buffer_).substr(consumed_);
    const size_t end = pending.find("\r\n\r\n");
    if (end == std::string_view::npos)
        return pending.size() >= limits_.max_head_bytes ? Progress::TooLarge
                                                        : Progress::Waiting;
    if (end + 4 > limits_.max_head_bytes) return Progress::TooLarge;
    const std::string_view head = pending.substr(0, end);
    // Every line break before the blank line ends the request line or a header line.
    size_t lines = 0;
    for (size_t at = head.find("\r\n"); at != std::string_view::npos;
         at = head.find("\r\n", at + 2))
        ++lines;
    if (lines > limits_.max_header_lines) return Progress::TooLarge;
    const size_t body = small_body_length(head, limits_.max_small_body);
    return pending.size() >= end + 4 + body ? Progress::Complete : Progress::Waiting;
}

FrontConnection::Progress FrontConnection::receive() {
    if (ssl_ && !handshake_done_) {
        ERR_clear_error();
        const int r = SSL_do_handshake(ssl_);
        if (r != 1) {
            const int error = SSL_get_error(ssl_, r);
            if (error == SSL_ERROR_WANT_READ || error == SSL_ERROR_WANT_WRITE) {
                wanted_events_ = error == SSL_ERROR_WANT_READ ? POLLIN : POLLOUT;
                return Progress::Waiting;
            }
            failed_ = true;
            return Progress::Closed;
        }
        handshake_done_ = true;
    }
    // The head's cap and a small body's: what a complete request can need at most.
    const size_t cap = limits_.max_head_bytes + limits_.max_small_body;
    char chunk[16384];
    for (;;) {
        const Progress progress = examine();
        if (progress != Progress::Waiting) return progress;
        const size_t room = std::min(sizeof chunk, cap - (buffer_.size() - consumed_));
        if (ssl_) {
            ERR_clear_error();
            const int r = SSL_read(ssl_, chunk, int(room));
            if (r > 0) {
                buffer_.append(chunk, size_t(r));
                continue;
            }
            const int error = SSL_get_error(ssl_, r);
            if (error == SSL_ERROR_WANT_READ || error == SSL_ERROR_WANT_WRITE) {
                wanted_events_ = error == SSL_ERROR_WANT_READ ? POLLIN : POLLOUT;
                return Progress::Waiting;
            }
            if (error != SSL_ERROR_ZERO_RETURN) failed_ = true;
            return Progress::Closed;
        }
        const ssize_t r = ::recv(fd_, chunk, room, 0);
        if (r > 0) {
            buffer_.append(chunk, size_t(r));
            continue;
        }
        if (r < 0 && errno == EINTR) continue;
        if (r < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
            wanted_events_ = POLLIN;
            return Progress::Waiting;
        }
        return Progress::Closed;
    }
}

void FrontConnection::refuse(int status, const std::string& message) {
    const std::string body = "{\"error\":\"" + message + "\"}";
    const std::string response =
        "HTTP/1.1 " + std::to_string(status) + " " +
        (status == 431 ? "Request Header Fields Too Large" : "Request Timeout") +
        "\r\nContent-Type: application/json\r\nContent-Length: " +
        std::to_string(body.size()) + "\r\nConnection: close\r\n\r\n" + body;
    if (!ssl_) {
        (void)::send(fd_, response.data(), response.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
    } else if (handshake_done_ && !failed_) {
        ERR_clear_error();
        if (SSL_write(ssl_, response.data(), int(response.size())) <= 0) failed_ = true;
    }
}

bool FrontConnection::wait_for(short events, Clock::time_point until) const {
    for (;;) {
        const auto left =
            std::chrono::duration_cast<std::chrono::milliseconds>(until - Clock::now());
        if (left.count() <= 0) return false;
        pollfd p{fd_, events, 0};
        const int r = ::poll(&p, 1, int(std::min<int64_t>(left.count(), INT_MAX)));
        if (r > 0) return true;  // ready, or an error the next call reports
        if (r < 0 && errno != EINTR) return false;
    }
}

Clock::time_point FrontConnection::write_until() const {
    return std::min(
        {Clock::now() + limits_.io_timeout, response_deadline_, write_deadline_});
}

// How long a paced reader may take for `bytes`: the grace, then min_read_rate.
Clock::duration FrontConnection::reading_time(size_t bytes) const {
    const double seconds =
        double(bytes) / double(std::max<size_t>(limits_.min_read_rate, 1));
    return limits_.read_grace +
           std::chrono::duration_cast<Clock::duration>(
               std::chrono::duration<double>(std::min(seconds, 1e9)));
}

bool FrontConnection::is_readable() const {
    if (consumed_ < buffer_.size()) return true;
    if (ssl_ && SSL_pending(ssl_) > 0) return true;
    return wait_for(POLLIN, Clock::now() + limits_.io_timeout);
}

bool FrontConnection::is_writable() const {
    // Room for the next write, for a paced response, within the grace.
    const auto until =
        paced_ ? std::min(write_until(), Clock::now() + reading_time(0)) : write_until();
    if (!wait_for(POLLOUT, until)) {
        cut_ = paced_;
        return false;
    }
    // Whether the peer is still there (httplib's test): nothing to read, or something.
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, 0) <= 0) return true;
    char c;
    return ::recv(fd_, &c, 1, MSG_PEEK | MSG_DONTWAIT) > 0;
}

ssize_t FrontConnection::read(char* ptr, size_t size) {
    for (;;) {
        if (consumed_ < buffer_.size()) {
            const size_t n = std::min(size, buffer_.size() - consumed_);
            std::memcpy(ptr, buffer_.data() + consumed_, n);
            consumed_ += n;
            if (consumed_ == buffer_.size()) {
                buffer_.clear();
                consumed_ = 0;
            }
            return ssize_t(n);
        }
        // Read ahead into the buffer: httplib reads a head a byte at a time.
        const auto until = Clock::now() + limits_.io_timeout;
        char chunk[4096];
        if (ssl_) {
            ERR_clear_error();
            const int r = SSL_read(ssl_, chunk, int(sizeof chunk));
            if (r > 0) {
                buffer_.assign(chunk, size_t(r));
                continue;
            }
            const int error = SSL_get_error(ssl_, r);
            if (error == SSL_ERROR_ZERO_RETURN) return 0;
            if ((error == SSL_ERROR_WANT_READ && wait_for(POLLIN, until)) ||
                (error == SSL_ERROR_WANT_WRITE && wait_for(POLLOUT, until)))
                continue;
            if (error != SSL_ERROR_WANT_READ && error != SSL_ERROR_WANT_WRITE)
                failed_ = true;
            return -1;
        }
        const ssize_t r = ::recv(fd_, chunk, sizeof chunk, 0);
        if (r > 0) {
            buffer_.assign(chunk, size_t(r));
            continue;
        }
        if (r == 0) return 0;
        if (errno == EINTR) continue;
        if ((errno == EAGAIN || errno == EWOULDBLOCK) && wait_for(POLLIN, until))
            continue;
        return -1;
    }
}

ssize_t FrontConnection::write(const char* ptr, size_t size) {
    if (paced_) write_deadline_ = Clock::now() + reading_time(size);
    const ssize_t written = send_all(ptr, size);
    write_deadline_ = Clock::time_point::max();
    // A paced response that could not be sent (its reader fell behind, or left) is
    // never kept alive, and is reset.
    if (written < 0 && paced_) failed_ = cut_ = true;
    return written;
}

ssize_t FrontConnection::send_all(const char* ptr, size_t size) {
    size_t sent = 0;
    while (sent < size) {
        // A reader that keeps taking a little never makes a wait time out.
        if (Clock::now() >= std::min(write_deadline_, response_deadline_)) return -1;
        if (ssl_) {
            // After a WANT_*, OpenSSL wants the same arguments again: `sent` moves only
            // when a whole call succeeded.
            ERR_clear_error();
            const int r =
                SSL_write(ssl_, ptr + sent, int(std::min<size_t>(size - sent, INT_MAX)));
            if (r > 0) {
                sent += size_t(r);
                continue;
            }
            const int error = SSL_get_error(ssl_, r);
            if ((error == SSL_ERROR_WANT_WRITE && wait_for(POLLOUT, write_until())) ||
                (error == SSL_ERROR_WANT_READ && wait_for(POLLIN, write_until())))
                continue;
            if (error != SSL_ERROR_WANT_READ && error != SSL_ERROR_WANT_WRITE)
                failed_ = true;
            return -1;
        }
        const ssize_t r = ::send(fd_, ptr + sent, size - sent, MSG_NOSIGNAL);
        if (r > 0) {
            sent += size_t(r);
            continue;
        }
        if (r < 0 && errno == EINTR) continue;
        if (r < 0 && (errno == EAGAIN || errno == EWOULDBLOCK) &&
            wait_for(POLLOUT, write_until()))
            continue;
        return -1;
    }
    return ssize_t(size);
}

void FrontConnection::get_remote_ip_and_port(std::string& ip, int& port) const {
    ip = peer_ip_;
    port = peer_port_;
}

void FrontConnection::get_local_ip_and_port(std::string& ip, int& port) const {
    sockaddr_storage addr{};
    socklen_t len = sizeof addr;
    if (::getsockname(fd_, reinterpret_cast<sockaddr*>(&addr), &len) == 0)
        address_text(addr, ip, port);
}

// ---- HttpFront ----

HttpFront::HttpFront(FrontLimits limits, SSL_CTX* tls, Serve serve)
    : limits_(limits),
      tls_(tls),
      serve_(std::move(serve)),
      wake_fd_(::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC)) {
    if (wake_fd_ < 0) throw std::runtime_error("http: cannot make an eventfd");
    if (limits_.threads == 0 || limits_.max_threads_per_peer == 0 ||
        limits_.max_waiting == 0)
        throw std::invalid_argument("http: the front needs threads and room to wait");
    front_ = std::thread([this] { run_front(); });
    for (size_t i = 0; i < limits_.threads; ++i)
        workers_.emplace_back([this] { run_worker(); });
}

HttpFront::~HttpFront() {
    stop();
    ::close(wake_fd_);
}

void HttpFront::wake() {
    const uint64_t one = 1;
    (void)!::write(wake_fd_, &one, sizeof one);
}

void HttpFront::admit(int fd) {
    {
        std::lock_guard lock(mutex_);
        if (!stopping_) {
            incoming_fds_.push_back(fd);
            fd = -1;
        }
    }
    if (fd >= 0) {
        ::close(fd);
        return;
    }
    wake();
}

void HttpFront::stop() {
    std::call_once(stopped_, [this] {
        {
            std::lock_guard lock(mutex_);
            stopping_ = true;
            // A thread waiting on its client's socket sees the end at once. The socket
            // stays open until that thread lets go of it, so its number is not reused.
            for (int fd : serving_fds_) ::shutdown(fd, SHUT_RDWR);
        }
        ready_cv_.notify_all();
        wake();
        if (front_.joinable()) front_.join();
        for (std::thread& t : workers_)
            if (t.joinable()) t.join();
        std::lock_guard lock(mutex_);
        for (int fd : incoming_fds_) ::close(fd);
        incoming_fds_.clear();
        resumed_.clear();
        ready_.clear();
    });
}

void HttpFront::trust_current_request() {
    if (!serving_now) return;
    serving_now->trusted_ = true;
    serving_now->response_deadline_ = Clock::time_point::max();
}

void HttpFront::close_after_current_response() {
    if (serving_now) serving_now->close_after_ = true;
}

void HttpFront::pace_current_response(std::optional<size_t> size) {
    if (!serving_now) return;
    serving_now->paced_ = true;
    if (size)
        serving_now->response_deadline_ =
            std::min(serving_now->response_deadline_,
                     Clock::now() + serving_now->reading_time(*size));
}

void HttpFront::make_room(std::vector<std::unique_ptr<FrontConnection>>& waiting) {
    // The oldest waiting connection of the address with the most waiting: a flood from
    // one address evicts its own, and one that reconnects as fast as it is cut never
    // reaches the others.
    std::map<std::string_view, size_t> per_peer;
    for (const auto& c : waiting) ++per_peer[c->peer()];
    const auto crowded = std::max_element(
        per_peer.begin(), per_peer.end(),
        [](const auto& a, const auto& b) { return a.second < b.second; });
    if (crowded == per_peer.end()) return;
    auto oldest = waiting.end();
    for (auto it = waiting.begin(); it != waiting.end(); ++it)
        if ((*it)->peer() == crowded->first &&
            (oldest == waiting.end() ||
             (*it)->waiting_since_ < (*oldest)->waiting_since_))
            oldest = it;
    waiting.erase(oldest);  // closes it
}

void HttpFront::take_incoming(std::vector<std::unique_ptr<FrontConnection>>& waiting) {
    std::vector<int> fds;
    std::vector<std::unique_ptr<FrontConnection>> resumed;
    size_t ready = 0;
    {
        std::lock_guard lock(mutex_);
        fds.swap(incoming_fds_);
        resumed.swap(resumed_);
        ready = ready_.size();
    }
    const auto now = Clock::now();
    const auto enter = [&](std::unique_ptr<FrontConnection> c) {
        c->waiting_since_ = now;
        c->deadline_ = now + limits_.request_deadline;
        c->wanted_events_ = POLLIN;
        c->buffer_.erase(0, c->consumed_);
        c->consumed_ = 0;
        if (c->examine() == FrontConnection::Progress::Complete) {
            to_ready(std::move(c));  // a pipelined request, already here
            ++ready;
            return;
        }
        if (waiting.size() + ready >= limits_.max_waiting) make_room(waiting);
        if (waiting.size() + ready >= limits_.max_waiting) return;  // all have requests
        waiting.push_back(std::move(c));
    };
    for (auto& c : resumed) enter(std::move(c));
    for (int fd : fds) {
        SSL* ssl = nullptr;
        try {
            if (::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) | O_NONBLOCK) != 0)
                throw std::runtime_error("fcntl");
            if (tls_) {
                ssl = SSL_new(tls_);
                if (!ssl || SSL_set_fd(ssl, fd) != 1) throw std::runtime_error("SSL_new");
                SSL_set_accept_state(ssl);
            }
            auto c = std::make_unique<FrontConnection>(fd, ssl, limits_);
            fd = -1;
            ssl = nullptr;
            enter(std::move(c));
        } catch (const std::exception&) {
            // Out of memory or TLS state: this connection is dropped, the front lives on.
            if (ssl) SSL_free(ssl);
            if (fd >= 0) ::close(fd);
        }
    }
}

void HttpFront::to_ready(std::unique_ptr<FrontConnection> c) {
    c->trusted_ = false;
    c->close_after_ = false;
    c->response_deadline_ = Clock::now() + limits_.untrusted_response_deadline;
    c->paced_ = false;
    {
        std::lock_guard lock(mutex_);
        ready_.push_back(std::move(c));
    }
    // Each thread looks whether its peer may have another; cheap at 32 threads.
    ready_cv_.notify_all();
}

void HttpFront::run_front() {
    block_sigpipe();
    std::vector<std::unique_ptr<FrontConnection>> waiting;
    std::vector<pollfd> fds;
    for (;;) {
        {
            std::lock_guard lock(mutex_);
            if (stopping_) break;
        }
        // Nothing a peer sends may end the process: whatever fails (an allocation)
        // costs the connections it touched, and the front goes on.
        try {
            serve_front_once(waiting, fds);
        } catch (const std::exception& e) {
            log_farm_error(std::string("front: ") + e.what(), "http_error");
        }
    }
}

void HttpFront::serve_front_once(std::vector<std::unique_ptr<FrontConnection>>& waiting,
                                 std::vector<pollfd>& fds) {
    take_incoming(waiting);
    auto now = Clock::now();
    auto next = now + std::chrono::seconds(60);
    fds.assign(1, pollfd{wake_fd_, POLLIN, 0});
    for (const auto& c : waiting) {
        fds.push_back(pollfd{c->fd_, c->wanted_events_, 0});
        next = std::min(next, c->deadline_);
    }
    const auto timeout =
        std::chrono::duration_cast<std::chrono::milliseconds>(next - now).count() + 1;
    if (::poll(fds.data(), fds.size(), int(std::max<int64_t>(timeout, 0))) < 0 &&
        errno != EINTR)
        log_farm_error(std::string("front: poll: ") + std::strerror(errno), "http_error");
    if (fds[0].revents) {
        uint64_t count;
        (void)!::read(wake_fd_, &count, sizeof count);
    }
    now = Clock::now();
    std::vector<std::unique_ptr<FrontConnection>> still;
    still.reserve(waiting.size());
    for (size_t i = 0; i < waiting.size(); ++i) {
        std::unique_ptr<FrontConnection>& c = waiting[i];
        using P = FrontConnection::Progress;
        P progress = P::Waiting;
        try {
            if (fds[i + 1].revents) progress = c->receive();
        } catch (const std::bad_alloc&) {
            progress = P::Closed;
        }
        switch (progress) {
            case P::Complete:
                to_ready(std::move(c));
                break;
            case P::TooLarge:
                c->refuse(
                    431, "request head too large (at most " +
                             std::to_string(limits_.max_head_bytes) + " bytes and " +
                             std::to_string(limits_.max_header_lines) + " header lines)");
                break;
            case P::Closed:
                break;
            case P::Waiting:
                if (now >= c->deadline_) {
                    // Only a request begun gets an answer; an idle kept-alive
                    // connection just closes, as the client expects.
                    if (!c->buffer_.empty())
                        c->refuse(408, "the request did not arrive in time");
                    break;
                }
                still.push_back(std::move(c));
                break;
        }
    }
    waiting.swap(still);  // what is left in `still` closes here
}

std::unique_ptr<FrontConnection> HttpFront::next_ready() {
    std::unique_lock lock(mutex_);
    for (;;) {
        if (stopping_) return nullptr;
        for (auto it = ready_.begin(); it != ready_.end(); ++it) {
            size_t& held = serving_per_peer_[(*it)->peer()];
            if (held >= limits_.max_threads_per_peer) continue;
            ++held;
            std::unique_ptr<FrontConnection> c = std::move(*it);
            ready_.erase(it);
            serving_fds_.insert(c->fd_);
            return c;
        }
        ready_cv_.wait(lock);
    }
}

void HttpFront::finished(std::unique_ptr<FrontConnection> c, bool keep) {
    {
        std::lock_guard lock(mutex_);
        const auto held = serving_per_peer_.find(c->peer());
        if (held != serving_per_peer_.end() && --held->second == 0)
            serving_per_peer_.erase(held);
        serving_fds_.erase(c->fd_);
        if (keep && !stopping_) {
            try {
                resumed_.push_back(std::move(c));
            } catch (const std::bad_alloc&) {
                // `c` closes below
            }
        }
    }
    ready_cv_.notify_all();  // a peer may have a thread to spare again
    if (!c) wake();
    // else: `c` closes here, outside the lock
}

void HttpFront::run_worker() {
    block_sigpipe();
    for (;;) {
        // Nothing a request does may end the process: a failure costs its connection.
        try {
            std::unique_ptr<FrontConnection> c = next_ready();
            if (!c) return;
            bool keep = false;
            serving_now = c.get();
            try {
                ++c->requests_;
                const bool last = c->requests_ >= limits_.requests_per_connection;
                bool closed = false;
                const bool ok = serve_(*c, last, closed);
                keep = ok && !closed && !last && !c->close_after_ && !c->failed_;
            } catch (const std::exception& e) {
                log_farm_error(std::string("a request failed: ") + e.what(),
                               "http_error");
            } catch (...) {
                log_farm_error("a request failed", "http_error");
            }
            serving_now = nullptr;
            finished(std::move(c), keep);
        } catch (const std::exception& e) {
            log_farm_error(e.what(), "http_error");
        }
    }
}

}  // namespace aliquot
