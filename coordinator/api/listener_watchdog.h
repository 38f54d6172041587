// Notices a listener that has stopped accepting connections while the process goes on:
// gRPC 1.51's listener gives up for good after one failed accept (EMFILE in a connection
// flood), and a coordinator that is up but deaf looks healthy to every check but a new
// connection (docs/SECURITY.md, "gRPC listener").
#pragma once

#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

namespace aliquot {

class ListenerWatchdog {
public:
    // Every `period`, `reached()` is asked whether a new connection is answered; after
    // `failures` noes in a row `deaf()` is called (and the count starts again). Both run
    // on the watchdog's thread.
    ListenerWatchdog(std::chrono::milliseconds period, int failures,
                     std::function<bool()> reached, std::function<void()> deaf);
    // Stops the thread, waiting for a probe in progress.
    ~ListenerWatchdog();
    ListenerWatchdog(const ListenerWatchdog&) = delete;
    ListenerWatchdog& operator=(const ListenerWatchdog&) = delete;

private:
    void run();

    const std::chrono::milliseconds period_;
    const int failures_;
    std::function<bool()> reached_;
    std::function<void()> deaf_;
    std::mutex mutex_;
    std::condition_variable wake_;
    bool stopping_ = false;
    std::thread thread_;
};

// Whether a new TCP connection to host:port (a numeric address or a name) is accepted
// by the process listening there within `deadline`: not only queued by the kernel, which
// completes the handshake for a listener that never accepts. Told from /proc/net/tcp
// and tcp6, where a connection still waiting in the accept queue has no inode yet.
// Nothing is sent, so it asks a plaintext and a TLS port alike (a TLS client would need
// the certificate's name, and the server logs every name it does not match).
bool accepts_connections(const std::string& host, int port,
                         std::chrono::milliseconds deadline);

}  // namespace aliquot
