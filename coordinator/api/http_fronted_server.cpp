// The server object behind the front, plain or TLS (http_fronted_server.h).
#include "http_fronted_server.h"

#include <stdexcept>

namespace aliquot {

namespace {

// httplib's Server or SSLServer with the front before it. httplib declares
// process_and_close_socket virtual (SSLServer overrides it too), and process_request
// protected: a subclass may serve a request over any Stream.
template <class Base>
class FrontedServer : public Base, public FrontedRequests {
public:
    using Base::Base;
    bool serve(FrontConnection& connection, bool close, bool& closed) override {
        return this->process_request(
            connection, close, closed,
            [&connection](httplib::Request& req) { req.ssl = connection.ssl(); });
    }

    // httplib listens with a backlog of 5, compiled in: a burst of connections (a
    // browser opens six at once) overflows it and each one over waits a second or more
    // for its SYN to be sent again. Listening again on the bound socket sets a deeper
    // one.
    void deepen_backlog() override { ::listen(this->svr_sock_, SOMAXCONN); }

private:
    bool process_and_close_socket(socket_t sock) override {
        front->admit(sock);
        return true;
    }
};

}  // namespace

MadeServer make_server(const HttpOptions& o) {
    MadeServer made;
    if (o.tls_cert.empty() && o.tls_key.empty()) {
        auto server = std::make_unique<FrontedServer<httplib::Server>>();
        made.requests = server.get();
        made.server = std::move(server);
        return made;
    }
    if (o.tls_cert.empty() || o.tls_key.empty())
        throw std::invalid_argument("http: a TLS certificate and its key go together");
    auto server = std::make_unique<FrontedServer<httplib::SSLServer>>(o.tls_cert.c_str(),
                                                                      o.tls_key.c_str());
    if (!server->is_valid())
        throw std::runtime_error(
            "http: cannot use TLS certificate " + o.tls_cert.string() + " with key " +
            o.tls_key.string() +
            " (unreadable, not PEM, or a key of another certificate)");
    made.tls = server->ssl_context();
    made.requests = server.get();
    made.server = std::move(server);
    return made;
}

}  // namespace aliquot
