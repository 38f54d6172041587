// What a hostile peer without the token can do to the HTTP listener (issue 30): a gzip
// bomb, a flood of header lines, heads trickled in on many connections, connections held
// open. Each runs against a real server on loopback and asks /healthz afterwards.
#include <arpa/inet.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <httplib.h>
#include <netinet/in.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/ssl.h>
#include <openssl/x509.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>
#include <zlib.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "http_server.h"
#include "http_session.h"
#include "test_tokens.h"

namespace aliquot {
namespace {

// A raw connection, as an attacker holds it: no thread of the test per connection.
class Peer {
public:
    // Connects to 127.0.0.1:port from `source` (any address of 127/8 is this host).
    explicit Peer(int port, const char* source = "127.0.0.1") {
        fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
        timeval timeout{10, 0};  // a test that goes wrong fails, it does not hang
        ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
        ::setsockopt(fd_, SOL_SOCKET, SO_SNDTIMEO, &timeout, sizeof timeout);
        sockaddr_in from{};
        from.sin_family = AF_INET;
        ::inet_pton(AF_INET, source, &from.sin_addr);
        ::bind(fd_, reinterpret_cast<sockaddr*>(&from), sizeof from);
        sockaddr_in to{};
        to.sin_family = AF_INET;
        to.sin_port = htons(uint16_t(port));
        to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        connected_ = ::connect(fd_, reinterpret_cast<sockaddr*>(&to), sizeof to) == 0;
    }
    ~Peer() { ::close(fd_); }
    Peer(const Peer&) = delete;
    Peer& operator=(const Peer&) = delete;

    bool connected() const { return connected_; }
    int fd() const { return fd_; }
    // Whether everything was sent (false once the server has closed).
    bool send(const std::string& bytes) {
        size_t sent = 0;
        while (sent < bytes.size()) {
            const ssize_t n =
                ::send(fd_, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
            if (n <= 0) return false;
            sent += size_t(n);
        }
        return true;
    }
    // Everything until the server closes (or 10 s pass): the response, if any.
    std::string read_all() {
        std::string got;
        char buffer[4096];
        ssize_t n;
        while ((n = ::recv(fd_, buffer, sizeof buffer, 0)) > 0)
            got.append(buffer, size_t(n));
        return got;
    }
    // Reads until a whole response head has come.
    std::string read_head() {
        std::string got;
        char c;
        while (got.find("\r\n\r\n") == std::string::npos && ::recv(fd_, &c, 1, 0) == 1)
            got += c;
        return got;
    }
    // Whether the server still holds the connection open: nothing to read, no end.
    bool still_open() const {
        char c;
        const ssize_t n = ::recv(fd_, &c, 1, MSG_PEEK | MSG_DONTWAIT);
        return n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK);
    }

private:
    int fd_ = -1;
    bool connected_ = false;
};

int status_of(const std::string& response) {
    return response.rfind("HTTP/1.1 ", 0) == 0 ? std::atoi(response.c_str() + 9) : 0;
}

// This process's resident memory in KiB.
long resident_kib() {
    std::ifstream status("/proc/self/status");
    std::string line;
    while (std::getline(status, line))
        if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
    return 0;
}

// `size` zero bytes, gzip-compressed: about a thousandth of that on the wire.
std::string gzip_of_zeros(size_t size) {
    z_stream z{};
    deflateInit2(&z, 9, Z_DEFLATED, 15 + 16, 9, Z_DEFAULT_STRATEGY);  // +16: gzip
    const std::string zeros(1 << 20, '\0');
    std::string out;
    char buffer[1 << 16];
    for (size_t done = 0; done < size; done += zeros.size()) {
        z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(zeros.data()));
        z.avail_in = uInt(zeros.size());
        const int flush = done + zeros.size() >= size ? Z_FINISH : Z_NO_FLUSH;
        do {
            z.next_out = reinterpret_cast<Bytef*>(buffer);
            z.avail_out = sizeof buffer;
            deflate(&z, flush);
            out.append(buffer, sizeof buffer - z.avail_out);
        } while (z.avail_out == 0);
    }
    deflateEnd(&z);
    return out;
}

class HttpFrontTest : public ::testing::Test {
protected:
    void start(FrontLimits limits = {}) {
        server_.reset();  // before the coordinator it serves
        coordinator_ = std::make_unique<Coordinator>(CoordinatorOptions{});
        HttpOptions options;
        options.tokens = testing::kTestTokens;
        options.front = limits;
        server_ = std::make_unique<HttpServer>(*coordinator_, "127.0.0.1:0", options);
    }
    void SetUp() override { start(); }
    int port() const { return server_->port(); }
    std::string host() const {
        return "Host: 127.0.0.1:" + std::to_string(port()) + "\r\n";
    }
    // /healthz from a well-behaved client.
    bool healthy() {
        httplib::Client c("127.0.0.1", port());
        c.set_read_timeout(10, 0);
        auto res = c.Get("/healthz");
        return res && res->status == 200;
    }

    std::unique_ptr<Coordinator> coordinator_;
    std::unique_ptr<HttpServer> server_;
};

// Issue 30, 2: 1 MB of gzip that inflates to 1000 MiB was inflated before the token was
// looked at. A compressed body is refused unread, with or without the token.
TEST_F(HttpFrontTest, ACompressedBodyIsRefusedWithoutBeingInflated) {
    const std::string bomb = gzip_of_zeros(size_t(128) << 20);
    ASSERT_LT(bomb.size(), 1u << 20);  // under the body limit, as the attack was
    const long before = resident_kib();
    httplib::Client c("127.0.0.1", port());
    c.set_read_timeout(10, 0);
    for (const char* path : {"/api/session", "/api/renders"}) {
        for (const bool with_token : {false, true}) {
            httplib::Headers headers = {{"Content-Encoding", "gzip"}};
            if (with_token)
                headers.emplace("Authorization", "Bearer " + testing::kTestTokens.client);
            auto res = c.Post(path, headers, bomb, "application/json");
            ASSERT_TRUE(res) << path;
            EXPECT_EQ(res->status, 415) << path << ": " << res->body;
            EXPECT_NE(res->body.find("compressed"), std::string::npos) << res->body;
        }
    }
    EXPECT_LT(resident_kib() - before, 32 * 1024);  // not the 128 MiB inflated
    // "identity" is no encoding at all.
    auto plain = c.Post("/api/session", {{"Content-Encoding", "identity"}},
                        R"({"token":"not-the-token-0123456789"})", "application/json");
    ASSERT_TRUE(plain);
    EXPECT_EQ(plain->status, 401);
    EXPECT_TRUE(healthy());
}

// Issue 30, 2: 2,000,000 header lines to /healthz were accepted (+500 MB). A head past
// 64 KiB is answered 431 (or the connection is cut while it is still being sent), never
// 200, and the server buffers no more of it.
TEST_F(HttpFrontTest, AFloodOfHeaderLinesIsRefusedWithBoundedMemory) {
    const long before = resident_kib();
    Peer peer(port());
    ASSERT_TRUE(peer.connected());
    std::string lines;
    for (int i = 0; i < 10000; ++i) lines += "X-Flood: " + std::to_string(i) + "\r\n";
    bool sent = peer.send("GET /healthz HTTP/1.1\r\n" + host());
    for (int i = 0; i < 100 && sent; ++i) sent = peer.send(lines);  // 1,000,000 lines
    if (sent) sent = peer.send("\r\n");
    const std::string response = peer.read_all();
    EXPECT_NE(status_of(response), 200) << response.substr(0, 200);
    if (!response.empty()) {
        EXPECT_EQ(status_of(response), 431) << response;
    }
    EXPECT_LT(resident_kib() - before, 32 * 1024);
    // Many header lines in few bytes are refused too.
    Peer short_lines(port());
    std::string head = "GET /healthz HTTP/1.1\r\n" + host();
    for (int i = 0; i < 200; ++i) head += "X: 1\r\n";
    ASSERT_TRUE(short_lines.send(head + "\r\n"));
    EXPECT_EQ(status_of(short_lines.read_all()), 431);
    EXPECT_TRUE(healthy());
}

// Issue 30, 4: 34 connections that trickle their heads took all 32 threads, and /healthz
// timed out. Heads are read by the front, so many more connections that have sent part of
// a head hold no thread: /healthz answers while every one of them is still open, and
// each is served once its head is whole.
TEST_F(HttpFrontTest, TrickledHeadsHoldNoThreadAndHealthStillAnswers) {
    std::vector<std::unique_ptr<Peer>> slow;
    for (int i = 0; i < 100; ++i) {
        slow.push_back(std::make_unique<Peer>(port()));
        ASSERT_TRUE(slow.back()->connected());
        ASSERT_TRUE(slow.back()->send("GET /healthz HTTP/1.1\r\n" + host() + "X-Slow: "));
    }
    EXPECT_TRUE(healthy());
    EXPECT_TRUE(healthy());
    size_t open = 0;
    for (const auto& p : slow) open += p->still_open();
    EXPECT_EQ(open, slow.size());
    for (const size_t i : {size_t(0), slow.size() - 1}) {
        ASSERT_TRUE(slow[i]->send("1\r\n\r\n"));
        EXPECT_EQ(status_of(slow[i]->read_head()), 200) << i;
    }
}

// A head still arriving when the request deadline passes is cut, however steadily it
// trickles: a byte now and then no longer keeps a connection (httplib's read timeout
// alone would wait for ever).
TEST_F(HttpFrontTest, AHeadStillTricklingAtTheDeadlineIsCut) {
    FrontLimits limits;
    limits.request_deadline = std::chrono::milliseconds(300);
    start(limits);
    Peer peer(port());
    ASSERT_TRUE(peer.send("GET /healthz HTTP/1.1\r\n" + host()));
    int sent = 0;
    while (sent < 200 && peer.still_open() && peer.send("X")) {
        ++sent;
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    EXPECT_LT(sent, 200) << "still trickling after 10 s";
    // 408, unless the cut reached us as a reset while a byte was under way.
    const int status = status_of(peer.read_all());
    EXPECT_TRUE(status == 408 || status == 0) << status;
    EXPECT_TRUE(healthy());
}

// When as many connections wait as the front holds, one more evicts the oldest waiting
// connection of the address that has the most: an attacker's own, never an earlier
// client's from another address.
TEST_F(HttpFrontTest, OneConnectionTooManyEvictsTheOldestOfTheBusiestAddress) {
    FrontLimits limits;
    limits.max_waiting = 8;
    start(limits);
    Peer browser(port(), "127.0.0.1");
    ASSERT_TRUE(browser.send("GET /healthz HTTP/1.1\r\n"));  // a slow client, first
    std::vector<std::unique_ptr<Peer>> flood;
    for (int i = 0; i < 8; ++i) {
        flood.push_back(std::make_unique<Peer>(port(), "127.0.0.2"));
        ASSERT_TRUE(flood.back()->connected()) << "127.0.0.2 is this host";
        ASSERT_TRUE(flood.back()->send("GET /healthz HTTP/1.1\r\n"));
        // A round trip while there is room: the front has taken those before in order.
        if (i == 5) {
            EXPECT_TRUE(healthy());
        }
    }
    EXPECT_EQ(flood[0]->read_all(), "");  // evicted: closed without a word
    for (size_t i = 1; i < flood.size(); ++i) EXPECT_TRUE(flood[i]->still_open()) << i;
    EXPECT_TRUE(browser.still_open());
    ASSERT_TRUE(browser.send(host() + "\r\n"));
    EXPECT_EQ(status_of(browser.read_head()), 200);
}

// Without the token, a body is read only when the front can read it whole first: a
// chunked or large one is refused before a thread would wait for it.
TEST_F(HttpFrontTest, WithoutTheTokenOnlyASmallBodyIsRead) {
    Peer chunked(port());
    ASSERT_TRUE(chunked.send("POST /api/session HTTP/1.1\r\n" + host() +
                             "Content-Type: application/json\r\n"
                             "Transfer-Encoding: chunked\r\n\r\n5\r\n{\"tok"));
    EXPECT_EQ(status_of(chunked.read_all()), 411);
    Peer large(port());
    ASSERT_TRUE(large.send("POST /api/session HTTP/1.1\r\n" + host() +
                           "Content-Type: application/json\r\n"
                           "Content-Length: 1000000\r\n\r\n{\"tok"));
    EXPECT_EQ(status_of(large.read_all()), 413);
    EXPECT_TRUE(healthy());
}

// A self-signed certificate for 127.0.0.1 and its key, as PEM files in `dir`.
void write_certificate(const std::filesystem::path& dir) {
    EVP_PKEY* key = EVP_EC_gen("P-256");
    X509* cert = X509_new();
    ASN1_INTEGER_set(X509_get_serialNumber(cert), 1);
    X509_gmtime_adj(X509_getm_notBefore(cert), 0);
    X509_gmtime_adj(X509_getm_notAfter(cert), 3600);
    X509_set_pubkey(cert, key);
    X509_NAME* name = X509_get_subject_name(cert);
    X509_NAME_add_entry_by_txt(name, "CN", MBSTRING_ASC,
                               reinterpret_cast<const unsigned char*>("127.0.0.1"), -1,
                               -1, 0);
    X509_set_issuer_name(cert, name);
    X509_sign(cert, key, EVP_sha256());
    FILE* c = std::fopen((dir / "cert.pem").c_str(), "w");
    PEM_write_X509(c, cert);
    std::fclose(c);
    FILE* k = std::fopen((dir / "key.pem").c_str(), "w");
    PEM_write_PrivateKey(k, key, nullptr, nullptr, 0, nullptr, nullptr);
    std::fclose(k);
    X509_free(cert);
    EVP_PKEY_free(key);
}

// A TLS connection that has completed its handshake (test side, blocking).
class TlsPeer {
public:
    explicit TlsPeer(int port) : tcp_(port) {
        ctx_ = SSL_CTX_new(TLS_client_method());
        ssl_ = SSL_new(ctx_);
        SSL_set_fd(ssl_, tcp_fd());
        ok_ = tcp_.connected() && SSL_connect(ssl_) == 1;
    }
    ~TlsPeer() {
        SSL_free(ssl_);
        SSL_CTX_free(ctx_);
    }
    bool ok() const { return ok_; }
    bool send(const std::string& bytes) {
        return SSL_write(ssl_, bytes.data(), int(bytes.size())) == int(bytes.size());
    }
    std::string read_some() {
        char buffer[4096];
        const int n = SSL_read(ssl_, buffer, sizeof buffer);
        return n > 0 ? std::string(buffer, size_t(n)) : "";
    }
    // Nothing to read and no end, inside TLS (session tickets the server sends after the
    // handshake are taken in on the way).
    bool still_open() {
        const int flags = ::fcntl(tcp_fd(), F_GETFL);
        ::fcntl(tcp_fd(), F_SETFL, flags | O_NONBLOCK);
        char c;
        const int n = SSL_read(ssl_, &c, 1);
        const bool open = n <= 0 && SSL_get_error(ssl_, n) == SSL_ERROR_WANT_READ;
        ::fcntl(tcp_fd(), F_SETFL, flags);
        return open;
    }

private:
    int tcp_fd() const { return tcp_.fd(); }
    Peer tcp_;
    SSL_CTX* ctx_ = nullptr;
    SSL* ssl_ = nullptr;
    bool ok_ = false;
};

// Under TLS the front also does the handshake: connections that never finish theirs, or
// that trickle a head inside the encrypted stream, hold no thread either; the cookie is
// named with __Host- and the port.
TEST(HttpFrontTls, StalledHandshakesAndTrickledHeadsHoldNoThread) {
    const auto dir = std::filesystem::temp_directory_path() /
                     ("aliquot-front-tls-" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    write_certificate(dir);
    Coordinator coordinator{CoordinatorOptions{}};
    HttpOptions options;
    options.tokens = testing::kTestTokens;
    options.tls_cert = dir / "cert.pem";
    options.tls_key = dir / "key.pem";
    HttpServer server(coordinator, "127.0.0.1:0", options);
    const int port = server.port();
    const std::string host = "Host: 127.0.0.1:" + std::to_string(port) + "\r\n";

    std::vector<std::unique_ptr<Peer>> silent;   // connect, then nothing
    std::vector<std::unique_ptr<Peer>> hello;    // a ClientHello's first bytes
    std::vector<std::unique_ptr<TlsPeer>> slow;  // a head inside TLS, unfinished
    for (int i = 0; i < 40; ++i) {
        silent.push_back(std::make_unique<Peer>(port));
        hello.push_back(std::make_unique<Peer>(port));
        ASSERT_TRUE(hello.back()->send(std::string("\x16\x03\x01\x02\x00\x01", 6)));
        slow.push_back(std::make_unique<TlsPeer>(port));
        ASSERT_TRUE(slow.back()->ok());
        ASSERT_TRUE(slow.back()->send("GET /healthz HTTP/1.1\r\n" + host + "X-Slow: "));
    }

    httplib::SSLClient client("127.0.0.1", port);
    client.enable_server_certificate_verification(false);
    client.set_read_timeout(10, 0);
    auto health = client.Get("/healthz");
    ASSERT_TRUE(health);
    EXPECT_EQ(health->status, 200);
    size_t silent_open = 0, hello_open = 0, slow_open = 0;
    for (size_t i = 0; i < silent.size(); ++i) {
        silent_open += silent[i]->still_open();
        hello_open += hello[i]->still_open();
        slow_open += slow[i]->still_open();
    }
    EXPECT_EQ(silent_open, silent.size());
    EXPECT_EQ(hello_open, hello.size());
    EXPECT_EQ(slow_open, slow.size());
    ASSERT_TRUE(slow[0]->send("1\r\n\r\n"));
    EXPECT_EQ(status_of(slow[0]->read_some()), 200);

    auto signed_in =
        client.Post("/api/session", "{\"token\":\"" + testing::kTestTokens.client + "\"}",
                    "application/json");
    ASSERT_TRUE(signed_in);
    ASSERT_EQ(signed_in->status, 200) << signed_in->body;
    const std::string set = signed_in->get_header_value("Set-Cookie");
    EXPECT_EQ(set.rfind(http_session::cookie_name(port, true) + "=", 0), 0u) << set;
    EXPECT_EQ(set.rfind("__Host-aliquot_session_", 0), 0u) << set;
    EXPECT_NE(set.find("; Secure"), std::string::npos) << set;
    auto renders = client.Get("/api/renders", {{"Cookie", set.substr(0, set.find(';'))}});
    ASSERT_TRUE(renders);
    EXPECT_EQ(renders->status, 200) << renders->body;
    std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace aliquot
