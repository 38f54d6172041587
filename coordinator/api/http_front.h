// The HTTP server's front door: one thread reads the request of every waiting connection
// at once, and hands a connection to the server's threads only when its whole request
// head (and a small body) has arrived. A client that trickles its head (slowloris)
// therefore costs a buffer, never a thread, and cannot keep /healthz from being answered.
// The front also caps the head's size and lines, the time a request may take to arrive,
// and how many connections may wait (docs/SECURITY.md, "HTTP connections").
//
// Why our own front: Debian's cpp-httplib is a compiled library whose socket reads cannot
// be changed by defines, and it gives each connection a thread from accept to close. It
// does let a subclass take over `process_and_close_socket` and call `process_request`
// with any Stream; HttpServer does that and passes every accepted socket to
// HttpFront::admit.
#pragma once

#include <httplib.h>
#include <poll.h>

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

namespace aliquot {

struct FrontLimits {
    // A request line and its headers, bytes and lines at most: a larger head is answered
    // 431 and its connection closed, never buffered further.
    size_t max_head_bytes = 64 * 1024;
    size_t max_header_lines = 100;
    // Bodies up to this many bytes (by Content-Length) are read by the front with the
    // head; a request without a token may not send a larger one (HttpServer refuses it
    // before reading), so an unauthenticated peer never holds a thread while it sends.
    size_t max_small_body = 16 * 1024;
    // From when the front starts waiting on a connection (accepted, or its previous
    // response sent) to its whole request, TLS handshake included: a kept-alive
    // connection idles this long at most, and a trickled head is cut at this age.
    std::chrono::milliseconds request_deadline{10000};
    // Connections waiting for their request (or holding a complete one that waits for a
    // thread) at most. One more evicts the oldest waiting connection of the peer address
    // that has the most waiting, so a single address cannot crowd out everyone else.
    size_t max_waiting = 256;
    // The server's threads, and how many of them one peer address may hold at once: the
    // rest stay for other addresses (a probe's /healthz).
    size_t threads = 32;
    size_t max_threads_per_peer = 24;
    // A thread's longest wait for one read or write of a request it serves (the read
    // timeout of a body sent with the client token, the write timeout of every response).
    std::chrono::milliseconds io_timeout{5000};
    // A response to a request without the client token must be sent within this long: a
    // peer that reads it slowly frees its thread then.
    std::chrono::milliseconds untrusted_response_deadline{20000};
    // Requests on one connection at most; the last response says Connection: close.
    size_t requests_per_connection = 100;
    // A paced response (images and downloads, event streams) must be taken at
    // min_read_rate at least, after a grace: each write within read_grace + its bytes /
    // min_read_rate, and one of known size whole within read_grace + size /
    // min_read_rate. Else its connection is closed and what it held (a thread, an image
    // place) is free: io_timeout alone bounds one wait, so a reader taking a few bytes
    // every second (curl --limit-rate 2k) kept a 32 MiB download for hours.
    std::chrono::milliseconds read_grace{30000};
    size_t min_read_rate = 64 * 1024;  // bytes a second
};

// One accepted connection, as httplib reads and writes it: the bytes the front buffered
// first, then the socket (or its TLS session), every wait bounded.
class FrontConnection : public httplib::Stream {
public:
    FrontConnection(int fd, SSL* ssl, const FrontLimits& limits);
    ~FrontConnection() override;
    FrontConnection(const FrontConnection&) = delete;
    FrontConnection& operator=(const FrontConnection&) = delete;

    bool is_readable() const override;
    bool is_writable() const override;
    ssize_t read(char* ptr, size_t size) override;
    ssize_t write(const char* ptr, size_t size) override;
    void get_remote_ip_and_port(std::string& ip, int& port) const override;
    void get_local_ip_and_port(std::string& ip, int& port) const override;
    // httplib answers 500 to a Stream whose socket() is at or above FD_SETSIZE, because
    // its own streams select() on them; this one polls, so it reports none.
    socket_t socket() const override { return INVALID_SOCKET; }

    SSL* ssl() const { return ssl_; }
    const std::string& peer() const { return peer_ip_; }

private:
    friend class HttpFront;
    enum class Progress { Waiting, Complete, Closed, TooLarge };
    // Reads what the socket has without blocking (handshake first under TLS) and says
    // whether a whole request is buffered.
    Progress receive();
    Progress examine();
    // Waits up to `timeout` for `events` on the socket; false on timeout or error.
    bool wait_for(short events, std::chrono::steady_clock::time_point until) const;
    std::chrono::steady_clock::time_point write_until() const;
    // A paced response's reader's time for `bytes`.
    std::chrono::steady_clock::duration reading_time(size_t bytes) const;
    // write() without its pace's bookkeeping.
    ssize_t send_all(const char* ptr, size_t size);
    // A short answer sent before closing, best effort and without blocking.
    void refuse(int status, const std::string& message);

    const int fd_;
    SSL* const ssl_;  // null for plain HTTP
    const FrontLimits& limits_;
    std::string peer_ip_;
    int peer_port_ = 0;
    bool handshake_done_ = false;
    bool failed_ = false;  // a socket or TLS error: not kept alive, no close_notify
    short wanted_events_ = 0x001;  // POLLIN; POLLOUT while a TLS step needs to write
    std::string buffer_;           // received, not yet read by httplib
    size_t consumed_ = 0;          // of buffer_
    std::chrono::steady_clock::time_point waiting_since_, deadline_;
    size_t requests_ = 0;
    bool trusted_ = false;      // the current request carries the client token
    bool close_after_ = false;  // the current response says Connection: close
    std::chrono::steady_clock::time_point response_deadline_;
    bool paced_ = false;        // the current response's writes each have a deadline
    mutable bool cut_ = false;  // its reader fell behind the pace: reset, not closed
    // Of the write under way; none between writes.
    std::chrono::steady_clock::time_point write_deadline_ =
        std::chrono::steady_clock::time_point::max();
};

class HttpFront {
public:
    // Serves one request of `connection` with httplib (close: say Connection: close;
    // closed: set when the connection must not be used again); false when it failed.
    using Serve =
        std::function<bool(FrontConnection& connection, bool close, bool& closed)>;

    // `tls`: the server's TLS context (owned by the caller), null for plain HTTP.
    HttpFront(FrontLimits limits, SSL_CTX* tls, Serve serve);
    ~HttpFront();
    HttpFront(const HttpFront&) = delete;
    HttpFront& operator=(const HttpFront&) = delete;

    // Takes an accepted socket (httplib's listener thread); never blocks.
    void admit(int fd);
    // Closes every connection and ends the threads; idempotent.
    void stop();

    // For httplib's pre- and post-routing handlers, which run on the thread that serves
    // the connection: the current request carries the client token (its response is not
    // hurried), or its response closes the connection (its body was not read).
    static void trust_current_request();
    static void close_after_current_response();
    // For a route, before its response is written: pace it (FrontLimits::min_read_rate);
    // `size`, when known, also bounds the whole response.
    static void pace_current_response(std::optional<size_t> size);

private:
    void run_front();
    void serve_front_once(std::vector<std::unique_ptr<FrontConnection>>& waiting,
                          std::vector<pollfd>& fds);
    void run_worker();
    void take_incoming(std::vector<std::unique_ptr<FrontConnection>>& waiting);
    void make_room(std::vector<std::unique_ptr<FrontConnection>>& waiting);
    void to_ready(std::unique_ptr<FrontConnection> c);
    std::unique_ptr<FrontConnection> next_ready();
    void finished(std::unique_ptr<FrontConnection> c, bool keep);
    void wake();

    const FrontLimits limits_;
    SSL_CTX* const tls_;
    const Serve serve_;
    const int wake_fd_;  // an eventfd: admit, resume and stop wake the front's poll

    mutable std::mutex mutex_;
    std::condition_variable ready_cv_;
    std::vector<int> incoming_fds_;
    std::vector<std::unique_ptr<FrontConnection>> resumed_;
    std::deque<std::unique_ptr<FrontConnection>> ready_;
    std::map<std::string, size_t> serving_per_peer_;
    std::set<int> serving_fds_;  // shut down at stop, to end a thread's wait at once
    bool stopping_ = false;

    std::thread front_;
    std::vector<std::thread> workers_;
    std::once_flag stopped_;
};

}  // namespace aliquot
