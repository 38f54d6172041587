// httplib's server with the front before it (http_front.h): the listener hands each
// accepted socket to the front, and the server serves the requests the front has read.
// The plumbing between the two, apart from the routes (http_server_impl.h).
#pragma once

#include <httplib.h>

#include <functional>
#include <memory>

#include "http_front.h"
#include "http_server.h"

namespace aliquot {

// httplib's listener hands each accepted socket to its TaskQueue as a job that calls
// process_and_close_socket. This queue runs the job at once, and FrontedServer's
// process_and_close_socket gives the socket to the front: the listener never waits, and
// no thread is spent on a connection until its request has arrived (http_front.h).
class HandToFront : public httplib::TaskQueue {
public:
    void enqueue(std::function<void()> job) override { job(); }
    void shutdown() override {}
};

// What the HTTP server needs of httplib's server besides its routes: serving one request
// the front has read.
class FrontedRequests {
public:
    virtual ~FrontedRequests() = default;
    virtual bool serve(FrontConnection& connection, bool close, bool& closed) = 0;
    virtual void deepen_backlog() = 0;
    HttpFront* front = nullptr;  // set before the server listens
};

// What make_server makes: the server, and what of it the front and HttpServer use.
struct MadeServer {
    std::unique_ptr<httplib::Server> server;
    FrontedRequests* requests = nullptr;
    SSL_CTX* tls = nullptr;  // the SSLServer's, null for plain HTTP
};

// The server object: an SSLServer when the options name a certificate. SSLServer loads
// both files in its constructor and only says whether that worked, so the message names
// what to check.
MadeServer make_server(const HttpOptions& o);

}  // namespace aliquot
