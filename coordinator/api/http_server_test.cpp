// The HTTP API over real sockets on loopback, with an in-memory coordinator fed by fake
// workers (sums made up in-process, no tracing): what the dashboard relies on, that every
// bad request gets a 4xx with a message, and that responses stay small with many renders.
#include "http_server.h"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <httplib.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <mutex>
#include <random>
#include <thread>

#include <grpcpp/grpcpp.h>
#include <sys/stat.h>

#include "aliquot.grpc.pb.h"
#include "exr_io.h"
#include "grpc_server.h"
#include "held_places.h"
#include "http_api.h"
#include "http_session.h"
#include "peak_memory.h"
#include "png_encoder.h"
#include "scene_loader.h"
#include "test_tokens.h"

namespace aliquot {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

constexpr size_t kMaxResponse = 100 * 1024;

// Options with the tokens every server needs; the tests' clients send the client's.
HttpOptions options_with_tokens() {
    HttpOptions options;
    options.tokens = testing::kTestTokens;
    return options;
}

const std::string kClientBearer = "Bearer " + testing::kTestTokens.client;

// A worker that answers every job with made-up sums: a smooth image plus per-pixel noise
// that differs between even and odd samples, so error estimates are non-zero.
// Registers `worker` (1 thread) for a session, which its calls carry.
size_t fake_jobs(Coordinator& c, const std::string& worker, size_t max_jobs = 1000000) {
    const std::string session = c.register_worker(worker, 1).session;
    size_t jobs = 0;
    while (jobs < max_jobs) {
        const std::optional<LeaseGrant> grant =
            c.lease(session, std::chrono::milliseconds(0));
        if (!grant) break;
        SampleJobResult result;
        result.rect = grant->job.rect;
        result.wall_seconds = 0.01;
        for (size_t i = 0; i < grant->job.rect.size(); ++i) {
            const uint32_t x = result.rect.x + uint32_t(i % result.rect.width);
            const uint32_t y = result.rect.y + uint32_t(i / result.rect.width);
            const uint64_t n = grant->job.counts[i], first = grant->job.first_sample[i];
            const uint64_t evens = (n + (first % 2 == 0 ? 1 : 0)) / 2;
            const double v = 0.2 + 0.1 * std::sin(0.3 * x) + 0.002 * double(y);
            const double noise = (x * 7 + y * 13) % 5 == 0 ? 0.3 : 0.02;
            PixelSums p;
            for (int ch = 0; ch < 3; ++ch) {
                p.even[ch] = double(evens) * (v + noise);
                p.odd[ch] = double(n - evens) * (v - noise);
            }
            p.sum_sq_luminance = double(n) * (v * v + noise * noise);
            p.samples = n;
            p.rays = 2 * n;
            result.pixels.push_back(p);
        }
        c.complete(session, grant->lease_id, result);
        ++jobs;
    }
    return jobs;
}

// An event stream opened over a raw socket, so that a test holds many at once without a
// thread each and can drop one the way a closed browser tab does.
struct RawStream {
    int fd = -1;
    int status = 0;
    std::string head, body;  // body: what arrived after the headers so far

    RawStream() = default;
    RawStream(RawStream&& o) noexcept
        : fd(std::exchange(o.fd, -1)),
          status(o.status),
          head(std::move(o.head)),
          body(std::move(o.body)) {}
    RawStream& operator=(RawStream&&) = delete;
    ~RawStream() { close(); }
    void close() {
        if (fd >= 0) ::close(fd);
        fd = -1;
    }
    // Reads until `text` has arrived after the headers (or the peer closes, or 10 s).
    bool read_until(const std::string& text) {
        char buffer[4096];
        while (body.find(text) == std::string::npos) {
            const ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
            if (n <= 0) return false;
            body.append(buffer, size_t(n));
        }
        return true;
    }
};

// `credentials`: a header line that carries a token ("Authorization: ..." or
// "Cookie: ..."), none when empty. `source`: the client's address (any of 127/8 is this
// host), for tests of what one address may hold.
RawStream open_stream(int port, const std::string& path = "/api/events",
                      const std::string& credentials = "Authorization: " + kClientBearer,
                      const char* source = "127.0.0.1") {
    RawStream s;
    s.fd = ::socket(AF_INET, SOCK_STREAM, 0);
    timeval timeout{10, 0};  // generous: a refused or starved request fails, not hangs
    ::setsockopt(s.fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
    sockaddr_in from{};
    from.sin_family = AF_INET;
    ::inet_pton(AF_INET, source, &from.sin_addr);
    if (::bind(s.fd, reinterpret_cast<sockaddr*>(&from), sizeof from) != 0) return s;
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(uint16_t(port));
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::connect(s.fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) return s;
    const std::string request =
        "GET " + path + " HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(port) + "\r\n" +
        (credentials.empty() ? "" : credentials + "\r\n") + "\r\n";
    if (::send(s.fd, request.data(), request.size(), MSG_NOSIGNAL) < 0) return s;
    char buffer[4096];
    std::string got;
    size_t end;
    while ((end = got.find("\r\n\r\n")) == std::string::npos) {
        const ssize_t n = ::recv(s.fd, buffer, sizeof buffer, 0);
        if (n <= 0) return s;
        got.append(buffer, size_t(n));
    }
    s.head = got.substr(0, end);
    s.body = got.substr(end + 4);
    if (s.head.rfind("HTTP/1.1 ", 0) == 0) s.status = std::atoi(s.head.c_str() + 9);
    return s;
}

// The JSON body of a plain (Content-Length) response read by open_stream.
json body_json(RawStream& s) {
    const std::string key = "content-length: ";
    std::string lower = s.head;
    std::transform(lower.begin(), lower.end(), lower.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    const size_t at = lower.find(key);
    if (at == std::string::npos) return {};
    const size_t length = std::stoul(lower.substr(at + key.size()));
    char buffer[4096];
    while (s.body.size() < length) {
        const ssize_t n = ::recv(s.fd, buffer, sizeof buffer, 0);
        if (n <= 0) break;
        s.body.append(buffer, size_t(n));
    }
    return json::parse(s.body, nullptr, false);
}

class HttpServerTest : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() /
               ("aliquot-http-test-" + std::to_string(::getpid()));
        fs::remove_all(dir_);
        fs::create_directories(dir_ / "web");
        std::ofstream(dir_ / "web" / "index.html")
            << "<!doctype html><title>dash</title>";
        fs::create_directories(dir_ / "studies" / "equal-budget" / "charts");
        std::ofstream(dir_ / "studies" / "equal-budget" / "report.md")
            << "# Equal budget\n\n![](charts/error.png)\n";
        std::ofstream(dir_ / "studies" / "equal-budget" / "charts" / "error.png")
            << "png";
        std::ofstream(dir_ / "secret.txt") << "not served";
        fs::create_directories(dir_ / "studies" / "no-report");  // output, not a study
        std::ofstream(dir_ / "studies" / "no-report" / "image.png") << "png";

        coordinator_ = std::make_unique<Coordinator>(CoordinatorOptions{});
        metrics_ = std::make_unique<FarmMetrics>(*coordinator_);
        HttpOptions options = options_with_tokens();
        options.metrics = metrics_.get();
        options.web_dir = dir_ / "web";
        options.study_dirs = {{"data", dir_ / "studies"}};
        options.event_interval = std::chrono::milliseconds(50);
        server_ = std::make_unique<HttpServer>(*coordinator_, "127.0.0.1:0", options);
        client_ = std::make_unique<httplib::Client>("127.0.0.1", server_->port());
        client_->set_read_timeout(10, 0);
        client_->set_bearer_token_auth(testing::kTestTokens.client);
    }
    void TearDown() override {
        server_.reset();
        metrics_.reset();
        coordinator_.reset();
        fs::remove_all(dir_);
    }

    json get_json(const std::string& path, int expect = 200) {
        auto res = client_->Get(path.c_str());
        EXPECT_TRUE(res) << path;
        if (!res) return {};
        EXPECT_EQ(res->status, expect) << path << ": " << res->body;
        EXPECT_LT(res->body.size(), kMaxResponse) << path;
        return json::parse(res->body);
    }
    json post_json(const std::string& path, const std::string& body, int expect) {
        auto res = client_->Post(path.c_str(), body, "application/json");
        EXPECT_TRUE(res) << path;
        if (!res) return {};
        EXPECT_EQ(res->status, expect) << path << " " << body << ": " << res->body;
        return json::parse(res->body);
    }
    std::string submit(const json& body) {
        return post_json("/api/renders", body.dump(), 201).value("id", "");
    }

    fs::path dir_;
    std::unique_ptr<Coordinator> coordinator_;
    std::unique_ptr<FarmMetrics> metrics_;
    std::unique_ptr<HttpServer> server_;
    std::unique_ptr<httplib::Client> client_;
};

TEST_F(HttpServerTest, HealthAndScenes) {
    EXPECT_EQ(get_json("/healthz")["ok"], true);
    const json scenes = get_json("/api/scenes");
    EXPECT_NE(std::find(scenes["scenes"].begin(), scenes["scenes"].end(), "cornell-box"),
              scenes["scenes"].end());
    EXPECT_EQ(scenes["methods"].size(), submittable_methods().size());
    for (const auto& m : scenes["methods"]) EXPECT_NE(m, "oracle");  // refused on a farm
    EXPECT_EQ(scenes["defaults"]["method"], "uniform");
}

TEST_F(HttpServerTest, MethodsListEachMethodsParametersWithDefaultsAndBounds) {
    const json methods = get_json("/api/methods")["methods"];
    ASSERT_EQ(methods.size(), strategy_methods().size());
    const auto method = [&](const std::string& name) {
        for (const json& m : methods)
            if (m["name"] == name) return m;
        return json();
    };
    EXPECT_EQ(method("oracle")["submittable"], false);  // refused on a farm
    EXPECT_EQ(method("optimal")["submittable"], true);
    std::map<std::string, json> optimal;
    // A named copy: a temporary's member would dangle inside the loop.
    const json optimal_method = method("optimal");
    for (const json& p : optimal_method["parameters"])
        optimal[p["key"].get<std::string>()] = p;
    EXPECT_EQ(optimal.count("alpha"), 0u);  // adaptive's
    EXPECT_EQ(optimal["spp"]["default"], 64);
    EXPECT_EQ(optimal["sigma_radius"]["kind"], "whole");
    EXPECT_EQ(optimal["sigma_radius"]["max"], 64);
    EXPECT_EQ(optimal["sigma_radius"]["bounds"], "a whole number from 0 to 64");
    EXPECT_EQ(optimal["floor_fraction"]["default"], 0.5);
    EXPECT_EQ(optimal["floor_fraction"]["max_exclusive"], true);
    EXPECT_FALSE(optimal["plan_ahead"]["help"].get<std::string>().empty());
    std::map<std::string, json> dammertz;
    // A named copy: a temporary's member would dangle inside the loop.
    const json dammertz_method = method("dammertz");
    for (const json& p : dammertz_method["parameters"])
        dammertz[p["key"].get<std::string>()] = p;
    EXPECT_EQ(dammertz["error_norm"]["values"], json({"seed", "paper"}));
    EXPECT_EQ(dammertz["spp"]["default"], 0);  // stops by its own measure

    // A value past its bound is refused naming the key and the bound, as listed.
    auto res = client_->Post("/api/renders",
                             R"({"strategy":{"method":"optimal","sigma_radius":65}})",
                             "application/json");
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 400);
    EXPECT_NE(res->body.find("'sigma_radius': expected a whole number from 0 to 64"),
              std::string::npos)
        << res->body;
    // Any method that needs a budget and is given none gets spp's listed default.
    const json created = post_json(
        "/api/renders", R"({"resolution":"8x8","strategy":{"method":"optimal"}})", 201);
    EXPECT_EQ(created["strategy"]["spp"], 64);
}

TEST_F(HttpServerTest, SubmittedRenderIsListedAndReadBack) {
    auto res = client_->Post("/api/renders",
                             R"({"scene":"cornell-box","resolution":"24x16","seed":3,
                                 "strategy":{"method":"uniform","spp":8}})",
                             "application/json");
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 201) << res->body;
    const json created = json::parse(res->body);
    const std::string id = created["id"];
    EXPECT_EQ(res->get_header_value("Location"), "/api/renders/" + id);
    EXPECT_EQ(created["width"], 24);
    EXPECT_EQ(created["height"], 16);
    EXPECT_EQ(created["strategy"]["spp"], 8);
    EXPECT_EQ(created["state"], "queued");  // no worker has a job of it yet
    EXPECT_EQ(created["queue_position"], 1);

    const json list = get_json("/api/renders");
    ASSERT_EQ(list["renders"].size(), 1u);
    EXPECT_EQ(list["renders"][0]["id"], id);
    EXPECT_FALSE(list["renders"][0].contains("strategy"));  // compact

    fake_jobs(*coordinator_, "w1");
    const json done = get_json("/api/renders/" + id);
    EXPECT_EQ(done["state"], "done");
    EXPECT_EQ(done["samples_done"], 24 * 16 * 8);
    EXPECT_EQ(done["progress"], 1.0);
    EXPECT_TRUE(done["error_estimate"].is_number());
    EXPECT_TRUE(done["error_vs_reference"].is_null());
}

// Seeds are 64-bit: written as decimal strings, read from strings or numbers.
TEST_F(HttpServerTest, SeedsAreStringsOutAndStringsOrNumbersIn) {
    const std::string big =
        submit({{"resolution", "8x8"}, {"seed", "18446744073709551615"}});
    EXPECT_EQ(get_json("/api/renders/" + big)["seed"], "18446744073709551615");
    const std::string exact =
        submit({{"resolution", "8x8"}, {"seed", 9007199254740993u}});
    EXPECT_EQ(get_json("/api/renders/" + exact)["seed"], "9007199254740993");
    const std::string small = submit({{"resolution", "8x8"}, {"seed", 5}});
    EXPECT_EQ(get_json("/api/renders/" + small)["seed"], "5");
    // Named: a range-for over a part of a temporary reads it after it is destroyed.
    const json listed = get_json("/api/renders");
    for (const json& r : listed["renders"]) EXPECT_TRUE(r["seed"].is_string()) << r;
}

TEST_F(HttpServerTest, TheExrDownloadIsTheRendersImageWithItsLayersAndSpec) {
    const std::string id = submit({{"resolution", "12x8"},
                                   {"seed", "18446744073709551615"},
                                   {"strategy", {{"method", "uniform"}, {"spp", 4}}}});
    fake_jobs(*coordinator_, "w1");
    auto res = client_->Get(("/api/renders/" + id + "/image.exr?aovs=1").c_str());
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 200) << res->body;
    EXPECT_EQ(res->get_header_value("Content-Type"), "image/x-exr");
    EXPECT_EQ(res->get_header_value("Content-Disposition"),
              "attachment; filename=\"" + id + ".exr\"");
    EXPECT_EQ(res->body, encode_exr(*coordinator_->image(id, true)));
    const Image image = decode_exr(res->body, "download");
    EXPECT_EQ(image.width, 12u);
    ASSERT_EQ(image.extra.size(), 2u);
    EXPECT_EQ(image.extra[0].name, "sampleCount.Y");
    EXPECT_EQ(image.extra[1].name, "variance.Y");
    EXPECT_EQ(image.attributes.at("aliquot:seed"), "18446744073709551615");
    EXPECT_EQ(image.attributes.at("aliquot:method"), "uniform");
    EXPECT_EQ(image.attributes.at("aliquot:samples"), std::to_string(12 * 8 * 4));

    auto plain = client_->Get(("/api/renders/" + id + "/image.exr").c_str());
    ASSERT_TRUE(plain);
    ASSERT_EQ(plain->status, 200);
    EXPECT_TRUE(decode_exr(plain->body, "download").extra.empty());
}

TEST_F(HttpServerTest, WidthAndHeightMayReplaceResolution) {
    const std::string id =
        submit({{"width", 20},
                {"height", 10},
                {"strategy", {{"method", "optimal"}, {"budget", 4000}}}});
    const json r = get_json("/api/renders/" + id);
    EXPECT_EQ(r["width"], 20);
    EXPECT_EQ(r["method"], "optimal");
    EXPECT_EQ(r["scene"], "cornell-box");
}

TEST_F(HttpServerTest, BadRequestsGetA4xxWithAMessage) {
    const std::string id = submit({{"resolution", "8x8"}, {"strategy", {{"spp", 2}}}});
    struct Case {
        std::string method, path, body;
        int status;
    };
    const std::vector<Case> cases = {
        {"GET", "/api/renders/r-999999", "", 404},
        {"GET", "/api/renders/" + std::string(500, 'x'), "", 404},
        {"POST", "/api/renders/r-999999/cancel", "{}", 404},
        {"POST", "/api/renders/" + id + "/cancel", "", 400},
        {"POST", "/api/renders/" + id + "/cancel", "[]", 400},
        {"POST", "/api/renders/" + id + "/cancel", R"({"now":true})", 400},
        {"GET", "/api/renders/r-999999/rounds", "", 404},
        {"GET", "/api/renders/r-999999/preview.png", "", 404},
        {"GET", "/api/renders/r-999999/image.exr", "", 404},
        {"GET", "/api/renders/" + id + "/image.exr?aovs=yes", "", 400},
        {"GET", "/api/renders/r-999999/maps?kind=spp", "", 404},
        {"GET", "/api/renders/r-999999/buckets", "", 404},
        {"GET", "/api/nothing-here", "", 404},
        {"POST", "/api/renders", "{not json", 400},
        {"POST", "/api/renders", "[1,2]", 400},
        {"POST", "/api/renders", "", 400},
        {"POST", "/api/renders", R"({"resolution":"0x0"})", 400},
        {"POST", "/api/renders", R"({"resolution":"100000x2"})", 400},
        {"POST", "/api/renders", R"({"resolution":"12"})", 400},
        {"POST", "/api/renders", R"({"resolution":"-4x4"})", 400},
        {"POST", "/api/renders", R"({"width":0,"height":5})", 400},
        {"POST", "/api/renders", R"({"width":-3,"height":5})", 400},
        {"POST", "/api/renders", R"({"width":5})", 400},
        {"POST", "/api/renders", R"({"seed":-1})", 400},
        {"POST", "/api/renders", R"({"seed":"seven"})", 400},
        {"POST", "/api/renders", R"({"seed":"-1"})", 400},
        {"POST", "/api/renders", R"({"seed":""})", 400},
        {"POST", "/api/renders", R"({"seed":"18446744073709551616"})", 400},
        {"POST", "/api/renders", R"({"seed":1e19})", 400},
        {"POST", "/api/renders", R"({"seed":2.5})", 400},
        {"POST", "/api/renders", R"({"scene":"../../etc/passwd"})", 400},
        {"POST", "/api/renders", R"({"scene":"no-such-scene"})", 400},
        {"POST", "/api/renders", R"({"colour":"blue"})", 400},
        {"POST", "/api/renders", R"({"strategy":{"method":"magic"}})", 400},
        {"POST", "/api/renders", R"({"strategy":{"method":"optimal","sigma_radius":65}})",
         400},
        {"POST", "/api/renders", R"({"strategy":{"spp":-5}})", 400},
        {"POST", "/api/renders", R"({"strategy":{"spp":1e300}})", 400},
        {"POST", "/api/renders", R"({"strategy":{"budget":18446744073709551615}})", 400},
        {"POST", "/api/renders", R"({"strategy":{"spp":4,"budget":100}})", 400},
        {"POST", "/api/renders", R"({"strategy":{"method":"dammertz","max_variance":0}})",
         400},
        {"POST", "/api/renders", R"({"strategy":{"alpha":"x"}})", 400},
        {"POST", "/api/renders", R"({"strategy":"uniform"})", 400},
        {"POST", "/api/renders", std::string(2 << 20, ' '), 413},
        {"GET", "/api/renders/" + id + "/preview.png?exposure=abc", "", 400},
        {"GET", "/api/renders/" + id + "/preview.png?exposure=1e9", "", 400},
        {"GET", "/api/renders/" + id + "/preview.png?size=0", "", 400},
        {"GET", "/api/renders/" + id + "/maps?kind=colour", "", 400},
        {"GET", "/api/renders/" + id + "/maps?kind=spp&size=nan", "", 400},
        {"GET", "/api/renders/" + id + "/rounds?since=-1", "", 400},
        {"GET", "/api/renders?limit=0", "", 400},
        {"GET", "/api/studies/data/equal-budget/..%2F..%2Fsecret.txt", "", 400},
        {"GET", "/api/studies/data/equal-budget/missing.md", "", 404},
        {"GET", "/api/studies/elsewhere/equal-budget/report.md", "", 404},
    };
    for (const Case& c : cases) {
        auto res = c.method == "GET"
                       ? client_->Get(c.path.c_str())
                       : client_->Post(c.path.c_str(), c.body, "application/json");
        ASSERT_TRUE(res) << c.method << " " << c.path;
        EXPECT_EQ(res->status, c.status) << c.method << " " << c.path.substr(0, 80) << " "
                                         << c.body.substr(0, 80) << ": " << res->body;
        const json body = json::parse(res->body, nullptr, false);
        ASSERT_TRUE(body.is_object()) << c.path.substr(0, 80) << ": " << res->body;
        EXPECT_TRUE(body["error"].is_string() &&
                    !body["error"].get<std::string>().empty())
            << res->body;
    }
    // Nothing bad was created.
    EXPECT_EQ(get_json("/api/renders")["renders"].size(), 1u);
}

TEST_F(HttpServerTest, RoundsPreviewMapsAndBucketsFollowTheRender) {
    const std::string id = submit({{"resolution", "40x24"},
                                   {"strategy",
                                    {{"method", "adaptive"},
                                     {"budget", 40 * 24 * 24},
                                     {"initial_spp", 4},
                                     {"bucket_size", 8}}}});
    EXPECT_EQ(get_json("/api/renders/" + id + "/rounds")["rows"].size(), 0u);
    fake_jobs(*coordinator_, "w1");
    const json info = get_json("/api/renders/" + id);
    ASSERT_EQ(info["state"], "done");

    const json rounds = get_json("/api/renders/" + id + "/rounds");
    EXPECT_EQ(rounds["columns"][2], "samples_total");
    const json& rows = rounds["rows"];
    ASSERT_EQ(rows.size(), info["rounds"].get<size_t>());
    ASSERT_GE(rows.size(), 2u);
    EXPECT_EQ(rounds["count"], rows.size());
    EXPECT_TRUE(rounds["next"].is_null());
    EXPECT_EQ(rows.back()[2], info["samples_done"]);
    EXPECT_GT(rows[1][2], rows[0][2]);
    EXPECT_GT(rows[1][3].get<double>(), 0.0);  // seconds
    EXPECT_GT(rows[1][4].get<double>(), 0.0);  // error estimate
    EXPECT_EQ(get_json("/api/renders/" + id + "/rounds?since=1")["rows"],
              json(rows.begin() + 1, rows.end()));
    const json page = get_json("/api/renders/" + id + "/rounds?limit=1");
    EXPECT_EQ(page["rows"].size(), 1u);
    EXPECT_EQ(page["next"], 1);

    auto png = client_->Get(("/api/renders/" + id + "/preview.png?exposure=1.5").c_str());
    ASSERT_TRUE(png);
    EXPECT_EQ(png->status, 200);
    EXPECT_EQ(png->get_header_value("Content-Type"), "image/png");
    ASSERT_GT(png->body.size(), 24u);
    EXPECT_EQ(png->body.substr(1, 3), "PNG");
    EXPECT_EQ(uint8_t(png->body[19]), 40u);  // IHDR width, big-endian
    EXPECT_EQ(uint8_t(png->body[23]), 24u);
    auto small = client_->Get(("/api/renders/" + id + "/preview.png?size=20").c_str());
    ASSERT_TRUE(small);
    EXPECT_EQ(uint8_t(small->body[19]), 20u);  // 40 / 2
    EXPECT_EQ(uint8_t(small->body[23]), 12u);

    const json spp = get_json("/api/renders/" + id + "/maps?kind=spp");
    EXPECT_EQ(spp["width"], 40);
    EXPECT_EQ(spp["height"], 24);
    EXPECT_EQ(spp["data"].get<std::string>().size(), size_t(40 * 24 + 2) / 3 * 4);
    EXPECT_GE(spp["max"].get<double>(), 4.0);
    const json err = get_json("/api/renders/" + id + "/maps?kind=error&size=10");
    EXPECT_EQ(err["width"], 10);
    EXPECT_EQ(err["height"], 6);
    EXPECT_GT(err["hi"].get<double>(), 0.0);

    const json buckets = get_json("/api/renders/" + id + "/buckets");
    EXPECT_EQ(buckets["buckets"].size(), 5u * 3u);  // 8x8 buckets over 40x24
    EXPECT_EQ(buckets["buckets"][0].size(), 6u);
}

TEST_F(HttpServerTest, CancelStopsARender) {
    // Wide enough for its first round to be several jobs, of which one is merged.
    const std::string id = submit({{"resolution", "64x64"}, {"strategy", {{"spp", 64}}}});
    fake_jobs(*coordinator_, "w1", 1);
    const json r = post_json("/api/renders/" + id + "/cancel", "{}", 200);
    EXPECT_EQ(r["state"], "cancelled");
    EXPECT_EQ(get_json("/api/renders/" + id)["state"], "cancelled");
    EXPECT_EQ(fake_jobs(*coordinator_, "w1"), 0u);
    // Cancelling again is harmless.
    EXPECT_EQ(post_json("/api/renders/" + id + "/cancel", "{}", 200)["state"],
              "cancelled");
}

// Issue 32: renders no worker has taken are queued, with their place in lease order and
// their names; a priority change moves one to the front; the events route serves a
// render's events and refuses what it cannot.
TEST_F(HttpServerTest, QueuedRendersShowTheirPlaceNameAndEvents) {
    const std::string a = submit({{"resolution", "8x8"}, {"name", "first"}});
    const std::string b =
        submit({{"resolution", "8x8"}, {"name", "second \u00e9t\u00e9"}});
    json first = get_json("/api/renders/" + a);
    EXPECT_EQ(first["state"], "queued");
    EXPECT_EQ(first["queue_position"], 1);
    EXPECT_EQ(first["name"], "first");
    EXPECT_EQ(get_json("/api/renders/" + b)["queue_position"], 2);
    auto res = client_->Patch(("/api/renders/" + b).c_str(), R"({"priority": 4})",
                              "application/json");
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 200) << res->body;
    EXPECT_EQ(get_json("/api/renders/" + b)["queue_position"], 1);
    const json listed = get_json("/api/renders");
    ASSERT_EQ(listed["renders"].size(), 2u);
    EXPECT_EQ(listed["renders"][0]["name"], "second \u00e9t\u00e9");
    EXPECT_EQ(listed["renders"][1]["queue_position"], 2);

    fake_jobs(*coordinator_, "w1");
    const json done = get_json("/api/renders/" + a);
    EXPECT_EQ(done["state"], "done");
    EXPECT_EQ(done["queue_position"], 0);
    const json events = get_json("/api/renders/" + a + "/events");
    ASSERT_GE(events["events"].size(), 4u);
    EXPECT_EQ(events["events"][0]["kind"], "submitted");
    EXPECT_EQ(events["events"][0]["fields"]["name"], "first");
    EXPECT_EQ(events["events"][1]["kind"], "started");
    EXPECT_EQ(events["events"].back()["kind"], "finished");
    EXPECT_EQ(events["omitted"], 0);
    const uint64_t next = events["next"];
    EXPECT_EQ(next, events["events"].size());
    EXPECT_TRUE(
        get_json("/api/renders/" + a + "/events?from=" + std::to_string(next))["events"]
            .empty());
    EXPECT_EQ(
        get_json("/api/renders/" + a + "/events?from=1&limit=1")["events"][0]["kind"],
        "started");
    get_json("/api/renders/r-999999/events", 404);
    get_json("/api/renders/" + a + "/events?from=-1", 400);
    get_json("/api/renders/" + a + "/events?limit=0", 400);
    // Names that could forge a log line or a page are refused, and add no render.
    for (const std::string& name :
         {std::string("a\nb"), std::string("\u001b[2J"), std::string(201, 'x')})
        post_json("/api/renders", json{{"name", name}}.dump(), 400);
    post_json("/api/renders", R"({"name": 7})", 400);
    EXPECT_EQ(get_json("/api/renders")["renders"].size(), 2u);
}

// Issue 13: what another site's page can make a browser send is refused before any
// handler, file or body, with a JSON error.
TEST_F(HttpServerTest, CrossSiteRequestsAreRefused) {
    const std::string port = std::to_string(server_->port());
    const std::string body = R"({"resolution":"8x8","strategy":{"spp":2}})";
    const auto expect = [&](const httplib::Result& res, int status,
                            const std::string& what) {
        ASSERT_TRUE(res) << what;
        EXPECT_EQ(res->status, status) << what << ": " << res->body;
        if (status >= 400) {
            const json j = json::parse(res->body, nullptr, false);
            EXPECT_TRUE(j.is_object() && j["error"].is_string())
                << what << ": " << res->body;
        }
    };
    // A "simple" cross-site form post: text/plain, no preflight.
    expect(client_->Post("/api/renders", {{"Origin", "http://evil.example"}}, body,
                         "text/plain"),
           403, "text/plain from another origin");
    expect(client_->Post("/api/renders", body, "text/plain"), 415, "text/plain");
    expect(client_->Post("/api/renders", body, "application/x-www-form-urlencoded"), 415,
           "form");
    expect(client_->Post("/api/renders", {{"Origin", "http://evil.example"}}, body,
                         "application/json"),
           403, "JSON from another origin");
    expect(client_->Post("/api/renders", {{"Origin", "null"}}, body, "application/json"),
           403, "opaque origin");
    expect(client_->Post("/api/renders", {{"Origin", "http://127.0.0.1:1"}}, body,
                         "application/json"),
           403, "another port");
    expect(client_->Put("/api/renders", body, "text/plain"), 415, "PUT");
    expect(client_->Delete("/api/renders/r-000001"), 415, "DELETE without a type");
    EXPECT_EQ(get_json("/api/renders")["renders"].size(), 0u);
    // Cancel: empty body, wrong type, foreign origin.
    const std::string id = submit(json::parse(body));
    expect(client_->Post(("/api/renders/" + id + "/cancel").c_str(), "", "text/plain"),
           415, "cancel as text");
    expect(client_->Post(("/api/renders/" + id + "/cancel").c_str(),
                         {{"Origin", "http://evil.example"}}, "{}", "application/json"),
           403, "cancel from another origin");
    EXPECT_NE(get_json("/api/renders/" + id)["state"], "cancelled");
    // The dashboard's own requests: same origin, JSON, charset allowed.
    expect(client_->Post("/api/renders", {{"Origin", "http://127.0.0.1:" + port}}, body,
                         "application/json; charset=utf-8"),
           201, "same origin");
    expect(
        client_->Post(("/api/renders/" + id + "/cancel").c_str(),
                      {{"Origin", "http://127.0.0.1:" + port}}, "{}", "application/json"),
        200, "same-origin cancel");
    // DNS rebinding: a foreign name in Host gets nothing, files included; /healthz
    // answers probes whatever their Host.
    for (const char* path : {"/api/renders", "/", "/api/workers", "/api/events"})
        expect(client_->Get(path, {{"Host", "evil.example:" + port}}), 403, path);
    expect(client_->Post("/api/renders", {{"Host", "evil.example:" + port}}, body,
                         "application/json"),
           403, "POST with a foreign Host");
    expect(client_->Get("/api/renders", {{"Host", "127.0.0.2:" + port}}), 403,
           "another address");
    expect(client_->Get("/healthz", {{"Host", "10.0.0.7:8080"}}), 200, "probe");
    for (const std::string& host : {"localhost:" + port, "LOCALHOST.:" + port,
                                    "[::1]:" + port, "127.0.0.1:" + port})
        expect(client_->Get("/api/renders", {{"Host", host}}), 200, host);
}

TEST(HttpServerHosts, AllowListAndListenAddressDecideTheHost) {
    using http_api::HostPolicy;
    const HostPolicy loop("127.0.0.1", 8080, {});
    EXPECT_TRUE(loop.allows("127.0.0.1:8080"));
    EXPECT_TRUE(loop.allows("localhost:8080"));
    EXPECT_TRUE(loop.allows("localhost:18080"));  // forwarded ports
    EXPECT_TRUE(loop.allows("localhost"));
    EXPECT_FALSE(loop.allows("10.0.0.1:8080"));
    EXPECT_FALSE(loop.allows("coordinator:8080"));
    EXPECT_FALSE(loop.allows(""));
    EXPECT_FALSE(loop.allows("localhost:8080/x"));
    EXPECT_FALSE(loop.allows("localhost:99999"));
    const HostPolicy any("0.0.0.0", 8080, {"coordinator:8080", "Aliquot-Coordinator"});
    EXPECT_TRUE(any.allows("coordinator:8080"));
    EXPECT_FALSE(any.allows("coordinator:9090"));
    EXPECT_FALSE(any.allows("coordinator"));  // port 80
    EXPECT_TRUE(any.allows("aliquot-coordinator"));
    EXPECT_TRUE(any.allows("aliquot-coordinator:31000"));
    EXPECT_TRUE(any.allows("192.168.1.20:18080"));  // a published port may differ
    EXPECT_TRUE(any.allows("[fe80::1]:8080"));
    EXPECT_FALSE(any.allows("evil.example:8080"));
    EXPECT_FALSE(any.allows("127.0.0.1.evil.example:8080"));
    const HostPolicy named("10.1.2.3", 8080, {});
    EXPECT_TRUE(named.allows("10.1.2.3:8080"));
    EXPECT_FALSE(named.allows("10.1.2.4:8080"));
    EXPECT_FALSE(named.allows("localhost:8080"));
    EXPECT_THROW(HostPolicy("0.0.0.0", 1, {"http://x"}), std::invalid_argument);
    EXPECT_THROW(HostPolicy("0.0.0.0", 1, {""}), std::invalid_argument);
    EXPECT_THROW(HostPolicy("0.0.0.0", 1, {"a b"}), std::invalid_argument);
    EXPECT_TRUE(http_api::is_json_content_type("Application/JSON ; charset=utf-8"));
    EXPECT_FALSE(http_api::is_json_content_type("application/jsonp"));
    EXPECT_FALSE(http_api::is_json_content_type(""));
    EXPECT_TRUE(
        http_api::origin_matches_host("http://Example.org", "example.org:80", false));
    EXPECT_FALSE(
        http_api::origin_matches_host("https://example.org", "example.org", false));
    EXPECT_FALSE(
        http_api::origin_matches_host("http://example.org.evil", "example.org", false));
}

// Under TLS the dashboard's own page is https://HOST: that is the one same-site Origin,
// and the plain-HTTP origin of the same host is another site (a page served by whatever
// answers port 80 there).
TEST(HttpServerHosts, UnderTlsTheSameSiteOriginIsHttps) {
    EXPECT_TRUE(
        http_api::origin_matches_host("https://127.0.0.1:8443", "127.0.0.1:8443", true));
    EXPECT_TRUE(
        http_api::origin_matches_host("HTTPS://Example.org", "example.org:443", true));
    EXPECT_TRUE(
        http_api::origin_matches_host("https://example.org:443", "example.org", true));
    EXPECT_FALSE(
        http_api::origin_matches_host("http://127.0.0.1:8443", "127.0.0.1:8443", true));
    EXPECT_FALSE(
        http_api::origin_matches_host("http://example.org", "example.org:80", true));
    EXPECT_FALSE(
        http_api::origin_matches_host("https://example.org:80", "example.org", true));
    EXPECT_FALSE(
        http_api::origin_matches_host("https://example.org.evil", "example.org", true));
}

// A certificate that cannot be loaded stops the coordinator at start with the files
// named, instead of a server that refuses every handshake.
TEST(HttpServerTls, AMissingOrHalfTlsConfigurationIsRefusedAtStart) {
    Coordinator coordinator{CoordinatorOptions{}};
    HttpOptions half;
    half.tls_cert = "cert.pem";
    EXPECT_THROW(HttpServer(coordinator, "127.0.0.1:0", half), std::invalid_argument);
    HttpOptions missing;
    missing.tls_cert = "/nonexistent/aliquot-cert.pem";
    missing.tls_key = "/nonexistent/aliquot-key.pem";
    try {
        HttpServer server(coordinator, "127.0.0.1:0", missing);
        ADD_FAILURE() << "a missing certificate was accepted";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("aliquot-cert.pem"), std::string::npos)
            << e.what();
    }
}

// Issue 13: a submitted scene that names a mesh file is refused over gRPC without the
// coordinator opening anything (a FIFO would block, /dev/zero never ends), and the error
// carries no content; over HTTP only built-in scene names are accepted at all.
TEST(SubmittedScenes, AMeshFileIsRefusedOverGrpcAndHttpWithoutReadingIt) {
    const fs::path dir = fs::temp_directory_path() /
                         ("aliquot-submitted-scene-" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    const fs::path fifo = dir / "fifo.obj";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    std::ofstream(dir / "secret.obj") << "v 1 the_admin_password 0\n";

    Coordinator coordinator{CoordinatorOptions{}};
    GrpcServer grpc_server(coordinator, "127.0.0.1:0", testing::test_security());
    HttpServer http_server(coordinator, "127.0.0.1:0", options_with_tokens());
    auto stub = v1::ClientService::NewStub(testing::loopback_channel(grpc_server.port()));
    json scene = json::parse(self_contained_scene_json("cornell-box"));
    for (const std::string& file :
         {fifo.string(), std::string("/dev/zero.obj"), (dir / "secret.obj").string(),
          std::string("../../x.obj")}) {
        scene["shapes"][0] = {{"type", "mesh"}, {"material", "white"}, {"file", file}};
        v1::SubmitRequest req;
        req.set_scene_json(scene.dump());
        req.set_scene("attack");
        req.set_width(8);
        req.set_height(8);
        req.set_strategy_json(R"({"spp":1})");
        v1::RenderInfo reply;
        testing::TokenContext ctx(Role::Client);
        ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(5));
        const grpc::Status status = stub->Submit(&ctx, req, &reply);
        EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT)
            << file << ": " << status.error_message();
        EXPECT_EQ(status.error_message(),
                  "attack: /shapes/0/file: mesh files are resolved by the client; a "
                  "submitted scene carries its meshes inline (\"positions\" and "
                  "\"triangles\")");
    }
    httplib::Client client("127.0.0.1", http_server.port());
    client.set_read_timeout(5, 0);
    client.set_bearer_token_auth(testing::kTestTokens.client);
    for (const std::string& name : {fifo.string(), (dir / "secret.obj").string()}) {
        auto res =
            client.Post("/api/renders", json{{"scene", name}}.dump(), "application/json");
        ASSERT_TRUE(res) << name;
        EXPECT_EQ(res->status, 400) << res->body;
        EXPECT_EQ(res->body.find("admin_password"), std::string::npos) << res->body;
    }
    EXPECT_TRUE(coordinator.list(10).empty());
    http_server.shutdown();
    grpc_server.shutdown();
    fs::remove_all(dir);
}

TEST_F(HttpServerTest, WorkersShowStateAndLeases) {
    const std::string alpha = coordinator_->register_worker("alpha", 4).session;
    coordinator_->register_worker("beta", 2);
    submit({{"resolution", "64x64"}, {"strategy", {{"spp", 4}}}});
    ASSERT_TRUE(coordinator_->lease(alpha, std::chrono::milliseconds(0)));
    const json w = get_json("/api/workers");
    ASSERT_EQ(w["workers"].size(), 2u);
    EXPECT_EQ(w["workers"][0]["name"], "alpha");
    EXPECT_EQ(w["workers"][0]["threads"], 4);
    EXPECT_EQ(w["workers"][0]["state"], "busy");
    EXPECT_EQ(w["workers"][0]["leases"].size(), 1u);
    EXPECT_EQ(w["workers"][1]["state"], "idle");
    EXPECT_GT(w["workers"][1]["last_seen_ms"].get<int64_t>(), 0);
}

// Issue 32: the workers page shows where a worker runs, its release and its failed jobs.
TEST_F(HttpServerTest, WorkersShowHostVersionAndFailures) {
    const std::string alpha = coordinator_->register_worker("alpha", 4).session;
    coordinator_->describe_worker("alpha", "render-07", "0.1.0");
    coordinator_->describe_worker("nobody", "x", "y");  // unknown: ignored
    submit({{"resolution", "64x64"}, {"strategy", {{"spp", 4}}}});
    const auto grant = coordinator_->lease(alpha, std::chrono::milliseconds(0));
    ASSERT_TRUE(grant);
    ASSERT_TRUE(coordinator_->fail(alpha, grant->lease_id, "out of memory"));
    const json w = get_json("/api/workers");
    ASSERT_EQ(w["workers"].size(), 1u);
    EXPECT_EQ(w["workers"][0]["host"], "render-07");
    EXPECT_EQ(w["workers"][0]["version"], "0.1.0");
    EXPECT_EQ(w["workers"][0]["failures"], 1);
}

// Issue 32: the renders list's thumbnail, small whatever the render's size.
TEST_F(HttpServerTest, AThumbnailIsASmallPngOfTheRender) {
    const std::string id = submit(
        {{"resolution", "400x240"}, {"strategy", {{"method", "uniform"}, {"spp", 1}}}});
    fake_jobs(*coordinator_, "w1");
    auto png = client_->Get(("/api/renders/" + id + "/thumbnail.png").c_str());
    ASSERT_TRUE(png);
    ASSERT_EQ(png->status, 200);
    EXPECT_EQ(png->get_header_value("Content-Type"), "image/png");
    ASSERT_GT(png->body.size(), 24u);
    EXPECT_EQ(png->body.substr(12, 4), "IHDR");
    auto be32 = [&](size_t at) {
        return uint32_t(uint8_t(png->body[at])) << 24 |
               uint32_t(uint8_t(png->body[at + 1])) << 16 |
               uint32_t(uint8_t(png->body[at + 2])) << 8 |
               uint32_t(uint8_t(png->body[at + 3]));
    };
    EXPECT_LE(be32(16), 96u);
    EXPECT_LE(be32(20), 96u);
    EXPECT_GE(be32(16), 48u);
    auto again = client_->Get(("/api/renders/" + id + "/thumbnail.png").c_str());
    ASSERT_TRUE(again);
    EXPECT_EQ(again->body, png->body);
    get_json("/api/renders/r-999999/thumbnail.png", 404);
}

// A client of `port` with the client token, patient enough for held requests.
std::unique_ptr<httplib::Client> patient_client(int port) {
    auto c = std::make_unique<httplib::Client>("127.0.0.1", port);
    c->set_read_timeout(30, 0);
    c->set_bearer_token_auth(testing::kTestTokens.client);
    return c;
}

// A 64x48 render with some samples, still running (in memory): "/api/renders/ID".
std::string running_render_path(Coordinator& coordinator, int port) {
    auto res = patient_client(port)->Post(
        "/api/renders", R"({"resolution":"64x48","strategy":{"spp":2}})",
        "application/json");
    if (!res || res->status != 201) return "";
    fake_jobs(coordinator, "w1", 3);
    return "/api/renders/" + json::parse(res->body)["id"].get<std::string>();
}

// Review of issue 32: previews and thumbnails were made by any number of requests at
// once, each from a copy of the whole image. Every route that makes or sends an image
// now takes a place among one limit; with every place held (by requests the test hook
// holds, no timing), one more of any of them is 503 with Retry-After.
TEST(HttpServerImages, OneImageRequestPastTheSharedLimitIsRefusedWith503) {
    Coordinator coordinator{CoordinatorOptions{}};
    testing::HeldPlaces held(3);
    HttpOptions options = options_with_tokens();
    options.max_image_requests = 3;
    options.image_admitted = held.hook();
    HttpServer server(coordinator, "127.0.0.1:0", options);
    const auto client = [&] { return patient_client(server.port()); };
    const std::string renders = running_render_path(coordinator, server.port());
    ASSERT_FALSE(renders.empty());

    const std::vector<std::string> holding = {
        renders + "/preview.png", renders + "/thumbnail.png", renders + "/image.exr"};
    std::vector<int> statuses(holding.size(), 0);
    std::vector<std::thread> requests;
    for (size_t i = 0; i < holding.size(); ++i)
        requests.emplace_back([&, i] {
            auto r = client()->Get(holding[i].c_str());
            statuses[i] = r ? r->status : -1;
        });
    ASSERT_TRUE(held.all_held());
    auto refused = client()->Get((renders + "/maps?kind=spp").c_str());
    ASSERT_TRUE(refused);
    EXPECT_EQ(refused->status, 503) << refused->body;
    EXPECT_EQ(refused->get_header_value("Retry-After"), "2");
    EXPECT_NE(refused->body.find("at most 3"), std::string::npos) << refused->body;
    held.release();
    for (std::thread& t : requests) t.join();
    for (size_t i = 0; i < holding.size(); ++i) EXPECT_EQ(statuses[i], 200) << holding[i];
    // The places are given back, the EXR's once its response was sent.
    auto again = client()->Get((renders + "/maps?kind=spp").c_str());
    ASSERT_TRUE(again);
    EXPECT_EQ(again->status, 200) << again->body;
    EXPECT_EQ(held.admitted(), holding.size() + 1);
}

// Review of issue 33 (hostile clients): the cut of a slow reader bounds how long one
// connection holds an image place, not how many a holder of the token opens; one that
// reconnects as fast as it is cut kept all 8. One address now holds at most its share
// (3 of 4 here), and another address is still served.
TEST(HttpServerImages, OneAddressHoldsAtMostItsShareAndAnotherIsStillServed) {
    Coordinator coordinator{CoordinatorOptions{}};
    testing::HeldPlaces held(3);
    HttpOptions options = options_with_tokens();
    options.max_image_requests = 4;
    options.max_image_requests_per_peer = 3;
    options.image_admitted = held.hook();
    HttpServer server(coordinator, "127.0.0.1:0", options);
    const auto client = [&] { return patient_client(server.port()); };
    const std::string renders = running_render_path(coordinator, server.port());
    ASSERT_FALSE(renders.empty());
    const std::string maps = renders + "/maps?kind=spp";

    std::vector<int> statuses(3, 0);
    std::vector<std::thread> holders;
    for (size_t i = 0; i < statuses.size(); ++i)
        holders.emplace_back([&, i] {
            auto r = client()->Get(maps.c_str());
            statuses[i] = r ? r->status : -1;
        });
    ASSERT_TRUE(held.all_held());
    auto refused = client()->Get(maps.c_str());
    ASSERT_TRUE(refused);
    EXPECT_EQ(refused->status, 503) << refused->body;
    EXPECT_EQ(refused->get_header_value("Retry-After"), "2");
    EXPECT_NE(refused->body.find("at most 3 from one address"), std::string::npos)
        << refused->body;
    RawStream other =
        open_stream(server.port(), maps, "Authorization: " + kClientBearer, "127.0.0.2");
    EXPECT_EQ(other.status, 200) << other.head;
    held.release();
    for (std::thread& t : holders) t.join();
    for (int status : statuses) EXPECT_EQ(status, 200);
}

// The same for event streams: one address holds at most its share (2 of 3 here).
TEST(HttpServerStreams, OneAddressHoldsAtMostItsShareAndAnotherIsStillServed) {
    Coordinator coordinator{CoordinatorOptions{}};
    HttpOptions options = options_with_tokens();
    options.max_event_streams = 3;
    options.max_event_streams_per_peer = 2;
    HttpServer server(coordinator, "127.0.0.1:0", options);
    std::vector<RawStream> streams;
    for (int i = 0; i < 2; ++i) {
        streams.push_back(open_stream(server.port()));
        ASSERT_EQ(streams.back().status, 200) << streams.back().head;
    }
    RawStream refused = open_stream(server.port());
    EXPECT_EQ(refused.status, 503) << refused.head;
    EXPECT_NE(body_json(refused).value("error", "").find("at most 2 from one address"),
              std::string::npos)
        << refused.body;
    RawStream other = open_stream(server.port(), "/api/events",
                                  "Authorization: " + kClientBearer, "127.0.0.2");
    EXPECT_EQ(other.status, 200) << other.head;
    EXPECT_TRUE(other.read_until("\"hello\""));
}

// Review of issue 32: an id of 8 KB (about the longest path httplib takes; past it, 414)
// came back whole in the errors of several routes. Each shows 64 bytes of it at most, and
// its length.
TEST_F(HttpServerTest, ALongIdComesBackShortInEveryError) {
    const std::string id(8000, 'x');
    for (const std::string& path :
         {"/api/renders/" + id, "/api/renders/" + id + "/rounds",
          "/api/renders/" + id + "/events", "/api/renders/" + id + "/buckets",
          "/api/renders/" + id + "/thumbnail.png", "/api/renders/" + id + "/image.exr"}) {
        auto res = client_->Get(path.c_str());
        ASSERT_TRUE(res) << path.substr(0, 80);
        EXPECT_EQ(res->status, 404);
        EXPECT_LT(res->body.size(), 200u) << path.substr(path.size() - 20);
        EXPECT_NE(res->body.find("(8000 bytes)"), std::string::npos) << res->body;
    }
    auto deleted =
        client_->Delete(("/api/renders/" + id).c_str(), "{}", "application/json");
    ASSERT_TRUE(deleted);
    EXPECT_EQ(deleted->status, 404);
    EXPECT_LT(deleted->body.size(), 200u);
    auto patched = client_->Patch(("/api/renders/" + id).c_str(), R"({"priority":1})",
                                  "application/json");
    ASSERT_TRUE(patched);
    EXPECT_EQ(patched->status, 404);
    EXPECT_LT(patched->body.size(), 200u);
}

TEST_F(HttpServerTest, EventsAnnounceRendersRoundsAndWorkers) {
    std::mutex mutex;
    std::vector<json> events;
    std::atomic<bool> stop{false};
    std::thread reader([&] {
        httplib::Client c("127.0.0.1", server_->port());
        c.set_read_timeout(30, 0);
        c.set_bearer_token_auth(testing::kTestTokens.client);
        std::string buffer;
        c.Get("/api/events", [&](const char* data, size_t n) {
            buffer.append(data, n);
            size_t end;
            while ((end = buffer.find("\n\n")) != std::string::npos) {
                const std::string block = buffer.substr(0, end);
                buffer.erase(0, end + 2);
                if (block.rfind("data: ", 0) == 0) {
                    EXPECT_LT(block.size(), kMaxResponse);
                    std::lock_guard lock(mutex);
                    events.push_back(json::parse(block.substr(6)));
                }
            }
            return !stop;
        });
    });
    auto count = [&](const std::string& type) {
        std::lock_guard lock(mutex);
        return std::count_if(events.begin(), events.end(),
                             [&](const json& e) { return e["type"] == type; });
    };
    auto wait_for = [&](auto predicate) {
        for (int i = 0; i < 200 && !predicate(); ++i)
            std::this_thread::sleep_for(std::chrono::milliseconds(25));
        return predicate();
    };
    ASSERT_TRUE(wait_for([&] { return count("hello") == 1; }));

    const std::string id = submit({{"resolution", "16x16"}, {"strategy", {{"spp", 8}}}});
    coordinator_->register_worker("w1", 1);
    fake_jobs(*coordinator_, "w1");
    EXPECT_TRUE(wait_for([&] {
        std::lock_guard lock(mutex);
        for (const json& e : events)
            if (e["type"] == "render")
                for (const json& r : e["renders"])
                    if (r["id"] == id && r["state"] == "done") return true;
        return false;
    }));
    // Every round once, in order, whatever the event interval merged.
    EXPECT_TRUE(wait_for([&] {
        std::lock_guard lock(mutex);
        size_t n = 0;
        for (const json& e : events)
            if (e["type"] == "round")
                for (const json& r : e["rounds"])
                    if (r["id"] == id && r["position"] == n) ++n;
        return n == get_json("/api/renders/" + id)["rounds"].get<size_t>();
    }));
    EXPECT_TRUE(wait_for([&] { return count("workers") >= 1; }));
    stop = true;
    coordinator_->register_worker("w2", 1);  // one more event so the reader sees `stop`
    reader.join();
}

TEST_F(HttpServerTest, FiftyRendersAndTenWorkersStayUnder100KB) {
    const std::vector<json> strategies = {
        {{"method", "uniform"}, {"spp", 16}},
        {{"method", "dammertz"}, {"samples_per_iteration", 4}, {"max_spp", 32}},
        {{"method", "adaptive"}, {"budget", 64 * 64 * 16}, {"bucket_size", 8}},
        {{"method", "optimal"}, {"budget", 64 * 64 * 16}},
        {{"method", "optimal-time"}, {"budget", 64 * 64 * 16}},
    };
    std::vector<std::string> ids;
    for (int i = 0; i < 50; ++i)
        ids.push_back(submit(
            {{"resolution", "64x64"}, {"seed", i}, {"strategy", strategies[i % 5]}}));
    for (int w = 0; w < 10; ++w)
        coordinator_->register_worker("worker-" + std::to_string(w), 8);
    // Some renders finished, some part-way, some with a lease outstanding.
    for (int w = 0; w < 10; ++w)
        fake_jobs(*coordinator_, "worker-" + std::to_string(w), 60);
    for (int w = 0; w < 10; ++w)
        coordinator_->lease(
            coordinator_->register_worker("worker-" + std::to_string(w), 8).session,
            std::chrono::milliseconds(0));

    auto size_of = [&](const std::string& path) {
        auto res = client_->Get(path.c_str());
        EXPECT_TRUE(res && res->status == 200) << path;
        return res ? res->body.size() : 0;
    };
    const size_t list = size_of("/api/renders");
    EXPECT_EQ(get_json("/api/renders")["renders"].size(), 50u);
    EXPECT_LT(list, kMaxResponse);
    EXPECT_LT(size_of("/api/workers"), kMaxResponse);
    for (const std::string& id : ids) {
        EXPECT_LT(size_of("/api/renders/" + id), kMaxResponse);
        EXPECT_LT(size_of("/api/renders/" + id + "/rounds"), kMaxResponse);
        EXPECT_LT(size_of("/api/renders/" + id + "/buckets"), kMaxResponse);
        EXPECT_LT(size_of("/api/renders/" + id + "/maps?kind=spp"), kMaxResponse);
        EXPECT_LT(size_of("/api/renders/" + id + "/maps?kind=error"), kMaxResponse);
        EXPECT_LT(size_of("/api/renders/" + id + "/preview.png"), kMaxResponse);
    }
    std::printf(
        "50 renders, 10 workers: /api/renders %zu bytes, /api/workers %zu bytes\n", list,
        size_of("/api/workers"));
}

TEST_F(HttpServerTest, StudiesAreListedAndServedFromTheirDirectoryOnly) {
    const json studies = get_json("/api/studies");
    ASSERT_EQ(studies["studies"].size(), 1u);
    const json s = studies["studies"][0];
    EXPECT_EQ(s["source"], "data");
    EXPECT_EQ(s["name"], "equal-budget");
    EXPECT_EQ(s["title"], "Equal budget");
    EXPECT_EQ(s["report"], "report.md");
    EXPECT_EQ(s["files"], json({"charts/error.png", "report.md"}));
    auto md = client_->Get("/api/studies/data/equal-budget/report.md");
    ASSERT_TRUE(md);
    EXPECT_EQ(md->status, 200);
    EXPECT_EQ(md->body.rfind("# Equal budget", 0), 0u);
    auto png = client_->Get("/api/studies/data/equal-budget/charts/error.png");
    ASSERT_TRUE(png);
    EXPECT_EQ(png->get_header_value("Content-Type"), "image/png");
}

// Found in review: a study name too long for the file system made weakly_canonical fail
// for the root and an absolute rest succeed, and the prefix check then passed any file.
TEST_F(HttpServerTest, AStudyPathCannotReachOutsideItsFolder) {
    const std::string secret = (dir_ / "secret.txt").string();
    for (const std::string& path :
         {"/api/studies/data/" + std::string(300, 'x') + "/" + secret,
          "/api/studies/data/equal-budget/" + secret}) {
        auto res = client_->Get(path);
        ASSERT_TRUE(res) << path;
        EXPECT_TRUE(res->status == 400 || res->status == 404) << res->status;
        EXPECT_EQ(res->body.find("not served"), std::string::npos) << res->body;
    }
}

// Found in review: a URL decoding to bytes that are not UTF-8 was echoed in a JSON error
// whose dump() threw outside any handler's try, and the process ended.
TEST_F(HttpServerTest, APathThatIsNotUtf8GetsA404AndTheServerLivesOn) {
    for (const char* path : {"/%FF", "/api/renders/%FF%FE", "/api/renders/r-1/%C3"}) {
        auto res = client_->Get(path);
        ASSERT_TRUE(res) << path;
        EXPECT_EQ(res->status, 404) << path << " " << res->body;
        EXPECT_NO_THROW(json::parse(res->body)) << res->body;
    }
    auto health = client_->Get("/healthz");
    ASSERT_TRUE(health);
    EXPECT_EQ(health->status, 200);
}

TEST_F(HttpServerTest, ServesTheDashboard) {
    auto res = client_->Get("/");
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 200);
    EXPECT_NE(res->body.find("<title>dash</title>"), std::string::npos);
}

// Issue 12, item 6: every event stream held a server thread, so 32 open streams left
// none for /healthz. Streams over the cap are refused and the rest of the API still
// answers.
TEST_F(HttpServerTest, EventStreamsOverTheCapAreRefusedAndHealthStillAnswers) {
    // All from one address: its share of the places is its cap.
    const size_t cap = HttpOptions{}.max_event_streams_per_peer;
    std::vector<RawStream> streams;
    size_t open = 0, refused = 0;
    for (size_t i = 0; i < 32; ++i) {  // as many as the server has threads
        RawStream s = open_stream(server_->port());
        if (s.status == 200) {
            ++open;
        } else {
            ASSERT_EQ(s.status, 503) << "stream " << i << ": " << s.head;
            EXPECT_NE(s.head.find("Retry-After: "), std::string::npos) << s.head;
            const json error = body_json(s);
            ASSERT_TRUE(error.is_object()) << s.body;
            EXPECT_NE(error.value("error", "").find("too many"), std::string::npos)
                << s.body;
            // The answer says the connection ends here, and a client leaves then.
            EXPECT_NE(s.head.find("Connection: close"), std::string::npos) << s.head;
            s.close();
            ++refused;
        }
        streams.push_back(std::move(s));
    }
    EXPECT_EQ(open, cap);
    EXPECT_EQ(refused, 32 - cap);
    // The open streams are live: each got its hello.
    for (RawStream& s : streams) {
        if (s.status == 200) {
            EXPECT_TRUE(s.read_until("\"hello\""));
        }
    }
    // And the server still answers everything else while they stay open.
    httplib::Client c("127.0.0.1", server_->port());
    c.set_connection_timeout(5, 0);
    c.set_read_timeout(5, 0);
    c.set_bearer_token_auth(testing::kTestTokens.client);
    auto health = c.Get("/healthz");
    ASSERT_TRUE(health) << "/healthz got no answer with " << open << " streams open";
    EXPECT_EQ(health->status, 200);
    auto renders = c.Get("/api/renders");
    ASSERT_TRUE(renders);
    EXPECT_EQ(renders->status, 200);
}

TEST_F(HttpServerTest, AStreamWhoseClientLeftFreesItsSlot) {
    const size_t cap = HttpOptions{}.max_event_streams_per_peer;  // one address's share
    for (int pass = 0; pass < 2; ++pass) {
        std::vector<RawStream> streams;
        // The previous pass's clients have just left: their slots come back within
        // about a quarter of a second, well inside the 15 s between idle comments that
        // used to be the first sign of a departed client.
        for (int attempt = 0; attempt < 50 && streams.size() < cap; ++attempt) {
            RawStream s = open_stream(server_->port());
            if (s.status == 200)
                streams.push_back(std::move(s));
            else
                std::this_thread::sleep_for(std::chrono::milliseconds(100));
        }
        ASSERT_EQ(streams.size(), cap) << "pass " << pass;
        for (RawStream& s : streams) EXPECT_TRUE(s.read_until("\"hello\""));
        EXPECT_EQ(open_stream(server_->port()).status, 503) << "pass " << pass;
        for (RawStream& s : streams) s.close();
    }
    EXPECT_EQ(get_json("/healthz")["ok"], true);
}

// An event stream whose client reads nothing holds its place and thread until the
// sockets' buffers fill, hours of events: every stream ends after event_stream_life
// (the browser opens another), so the place comes back.
TEST(HttpServerStreams, AStreamEndsAfterItsLifeAndItsPlaceComesBack) {
    Coordinator coordinator{CoordinatorOptions{}};
    HttpOptions options = options_with_tokens();
    options.max_event_streams = 1;
    options.event_stream_life = std::chrono::milliseconds(0);
    HttpServer server(coordinator, "127.0.0.1:0", options);
    RawStream first = open_stream(server.port());
    ASSERT_EQ(first.status, 200) << first.head;
    EXPECT_TRUE(first.read_until("\"hello\""));
    // The chunked body's end: the server ended the stream, not the client.
    EXPECT_TRUE(first.read_until("\r\n0\r\n\r\n")) << first.body;
    // The one place is free again (given back as the response ends).
    int status = 0;
    for (int attempt = 0; attempt < 100 && status != 200; ++attempt) {
        status = open_stream(server.port()).status;
        if (status != 200) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    EXPECT_EQ(status, 200);
}

// A coordinator that keeps its record under `dir`/data, its HTTP server, and a client
// holding the client token.
struct RecordedCoordinator {
    static CoordinatorOptions options(const fs::path& dir) {
        CoordinatorOptions co;
        co.data_dir = dir / "data";
        return co;
    }
    explicit RecordedCoordinator(const fs::path& dir,
                                 HttpOptions http = options_with_tokens())
        : coordinator(options(dir)),
          server(coordinator, "127.0.0.1:0", std::move(http)),
          client("127.0.0.1", server.port()) {
        client.set_read_timeout(10, 0);
        client.set_bearer_token_auth(testing::kTestTokens.client);
    }
    // Submits a 16x16 render of 4 spp: its id, empty (and a failure) when refused.
    std::string submit() {
        auto res =
            client.Post("/api/renders", R"({"resolution":"16x16","strategy":{"spp":4}})",
                        "application/json");
        const bool created = res && res->status == 201;
        EXPECT_TRUE(created) << (res ? res->body : "no answer");
        return created ? json::parse(res->body)["id"].get<std::string>() : "";
    }
    // A finished render whose stored EXR is replaced by `bytes` random bytes, which do
    // not compress (the routes send the file as it is): its id (empty on failure) and
    // those bytes.
    std::pair<std::string, std::string> finished_render_storing(size_t bytes,
                                                                uint64_t seed) {
        const std::string id = submit();
        if (id.empty()) return {};
        fake_jobs(coordinator, "w1");
        // The backlog's thread writes the image: a generous deadline, not a timing check.
        for (int i = 0; i < 600 && !coordinator.image_file(id); ++i)
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
        const std::optional<fs::path> file = coordinator.image_file(id);
        EXPECT_TRUE(file);
        if (!file) return {};
        std::string stored(bytes, '\0');
        std::mt19937_64 random(seed);
        for (size_t i = 0; i + 8 <= stored.size(); i += 8) {
            const uint64_t v = random();
            std::memcpy(&stored[i], &v, 8);
        }
        std::ofstream(*file, std::ios::binary | std::ios::trunc) << stored;
        return {id, stored};
    }
    Coordinator coordinator;
    HttpServer server;
    httplib::Client client;
};

// A finished render's EXR is its stored file, sent as it is: not decoded and encoded
// again (with its layers the file itself; without, the copy stored beside it).
TEST(HttpServerStorage, AFinishedRendersExrIsTheStoredFile) {
    const fs::path dir = fs::temp_directory_path() /
                         ("aliquot-http-stored-exr-" + std::to_string(::getpid()));
    fs::remove_all(dir);
    {
        RecordedCoordinator farm(dir);
        Coordinator& coordinator = farm.coordinator;
        httplib::Client& c = farm.client;
        const std::string id = farm.submit();
        ASSERT_FALSE(id.empty());
        coordinator.register_worker("w1", 1);
        fake_jobs(coordinator, "w1");
        // The backlog's thread writes the image, then the session leaves memory: wait
        // for it (a generous deadline, not a timing check).
        for (int i = 0; i < 600 && !coordinator.image_file(id); ++i)
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
        const std::optional<fs::path> file = coordinator.image_file(id);
        ASSERT_TRUE(file);
        const auto bytes_of = [](const fs::path& path) {
            std::ifstream in(path, std::ios::binary);
            return std::string(std::istreambuf_iterator<char>(in), {});
        };
        auto layers = c.Get(("/api/renders/" + id + "/image.exr?aovs=1").c_str());
        ASSERT_TRUE(layers);
        ASSERT_EQ(layers->status, 200) << layers->body;
        EXPECT_EQ(layers->body, bytes_of(*file));
        auto plain = c.Get(("/api/renders/" + id + "/image.exr").c_str());
        ASSERT_TRUE(plain);
        ASSERT_EQ(plain->status, 200) << plain->body;
        EXPECT_EQ(plain->body, bytes_of(file->parent_path() / "image-rgb.exr"));
        EXPECT_TRUE(decode_exr(plain->body, "download").extra.empty());
    }
    fs::remove_all(dir);
}

// Review of issue 32: an EXR download read the whole stored file into memory, twice over
// (a stream's buffer, then its string). It is now sent as it is read: 8 downloads at once
// of a 32 MiB file (what a 2048x2048 render with its layers stores) grow the process by
// less than one file, and every byte arrives as stored.
TEST(HttpServerStorage, ConcurrentExrDownloadsHoldAChunkNotTheFile) {
    const fs::path dir = fs::temp_directory_path() /
                         ("aliquot-http-exr-memory-" + std::to_string(::getpid()));
    fs::remove_all(dir);
    {
        // All 8 from one address: the places in all are what bounds the memory.
        HttpOptions options = options_with_tokens();
        options.max_image_requests_per_peer = options.max_image_requests;
        RecordedCoordinator farm(dir, options);
        const auto [id, stored] = farm.finished_render_storing(32u << 20, 7);
        ASSERT_FALSE(id.empty());

        const testing::PeakMemory peak;
        std::vector<std::thread> downloads;
        std::vector<int> statuses(8, 0);
        std::vector<size_t> matched(8, 0);
        for (size_t d = 0; d < statuses.size(); ++d)
            downloads.emplace_back([&, d] {
                httplib::Client c("127.0.0.1", farm.server.port());
                c.set_read_timeout(30, 0);
                c.set_bearer_token_auth(testing::kTestTokens.client);
                size_t at = 0;
                bool same = true;
                auto res = c.Get(("/api/renders/" + id + "/image.exr?aovs=1").c_str(),
                                 [&](const char* data, size_t n) {
                                     same = same && at + n <= stored.size() &&
                                            std::memcmp(data, &stored[at], n) == 0;
                                     at += n;
                                     return true;
                                 });
                statuses[d] = res ? res->status : -1;
                matched[d] = same ? at : 0;
            });
        for (std::thread& t : downloads) t.join();
        const uint64_t grown_kb = peak.grown_kb();
        for (size_t d = 0; d < statuses.size(); ++d) {
            EXPECT_EQ(statuses[d], 200) << d;
            EXPECT_EQ(matched[d], stored.size()) << d;
        }
        // Each held the file, its copy and the response's: 8 x 96 MiB, or a 503.
        EXPECT_LT(grown_kb, 24u * 1024) << "kB";
    }
    fs::remove_all(dir);
}

// A download read a few bytes at a time, from a socket with a small receive buffer,
// never waiting long enough between reads for one write to time out (curl --limit-rate
// 2k): it reads until the server cuts it or the test stops it.
struct TrickleReader {
    int fd = -1;
    std::atomic<bool> stop{false};
    std::atomic<size_t> got{0};
    std::atomic<bool> cut{false};  // the server closed the connection
    std::thread reader;

    TrickleReader(int port, const std::string& path) {
        fd = ::socket(AF_INET, SOCK_STREAM, 0);
        const int small = 4096;
        ::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
        sockaddr_in addr{};
        addr.sin_family = AF_INET;
        addr.sin_port = htons(uint16_t(port));
        addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) return;
        const std::string request =
            "GET " + path + " HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(port) +
            "\r\nAuthorization: " + kClientBearer + "\r\n\r\n";
        if (::send(fd, request.data(), request.size(), MSG_NOSIGNAL) < 0) return;
        reader = std::thread([this] {
            char buffer[512];
            while (!stop) {
                const ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
                if (n <= 0) {
                    cut = !stop;
                    return;
                }
                got += size_t(n);
                std::this_thread::sleep_for(std::chrono::milliseconds(20));
            }
        });
    }
    ~TrickleReader() {
        stop = true;
        ::shutdown(fd, SHUT_RDWR);  // ends a recv under way
        if (reader.joinable()) reader.join();
        ::close(fd);
    }
};

// Review of issue 33: 8 clients downloading an EXR with curl --limit-rate 2k held every
// image place for about 90 minutes: the write timeout bounds one wait, and a trickle
// keeps each wait short. A reader must now keep a pace (FrontLimits::min_read_rate after
// read_grace): the trickling ones are cut, and the next download gets their place.
TEST(HttpServerStorage, TrickleReadersOfAnExrAreCutAndTheNextDownloadIsServed) {
    const fs::path dir = fs::temp_directory_path() /
                         ("aliquot-http-exr-trickle-" + std::to_string(::getpid()));
    fs::remove_all(dir);
    {
        HttpOptions options = options_with_tokens();
        options.max_image_requests = 2;
        options.front.read_grace = std::chrono::milliseconds(100);
        options.front.min_read_rate = 1 << 20;  // a MiB a second: the trickles keep 25 kB
        // Only the pace may cut them: in production a wait's timeout (5 s) did not, as
        // long as the trickle went on.
        options.front.io_timeout = std::chrono::minutes(5);
        RecordedCoordinator farm(dir, options);
        // 16 MiB, far more than the sockets' buffers take.
        const auto [id, stored] = farm.finished_render_storing(16u << 20, 11);
        ASSERT_FALSE(id.empty());

        const std::string path = "/api/renders/" + id + "/image.exr?aovs=1";
        std::vector<std::unique_ptr<TrickleReader>> trickles;
        for (size_t i = 0; i < options.max_image_requests; ++i)
            trickles.push_back(std::make_unique<TrickleReader>(farm.server.port(), path));
        // Before, each held its place for 16 MiB / 25 kB/s, 11 minutes. A generous
        // deadline against a hang, not a timing check.
        int status = 0;
        std::string body;
        for (int attempt = 0; attempt < 300; ++attempt) {
            const httplib::Result next = farm.client.Get(path.c_str());
            status = next ? next->status : -1;
            if (status != 503) {
                if (next) body = next->body;
                break;
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(200));
        }
        EXPECT_EQ(status, 200) << body.substr(0, 200);
        EXPECT_TRUE(body == stored) << "the download arrived whole and as stored";
        for (const auto& t : trickles) {
            // Its first bytes came (it held a place); its connection was closed by the
            // server long before the whole file could have trickled in.
            for (int i = 0; i < 300 && !t->cut; ++i)
                std::this_thread::sleep_for(std::chrono::milliseconds(100));
            EXPECT_TRUE(t->cut) << t->got.load();
            EXPECT_GT(t->got.load(), 0u);
            EXPECT_LT(t->got.load(), stored.size());
        }
    }
    fs::remove_all(dir);
}

// The coordinator's record cannot be written (here the render's directory was replaced
// by a file, which stops root as well as a user): the API says so, in the list, in a
// render, and in the event stream's greeting.
TEST(HttpServerStorage, StorageWarningIsShownWhileTheRecordCannotBeWritten) {
    const fs::path dir = fs::temp_directory_path() /
                         ("aliquot-http-storage-" + std::to_string(::getpid()));
    fs::remove_all(dir);
    {
        RecordedCoordinator farm(dir);
        Coordinator& coordinator = farm.coordinator;
        HttpServer& server = farm.server;
        httplib::Client& c = farm.client;
        auto list = [&] {
            auto res = c.Get("/api/renders");
            EXPECT_TRUE(res && res->status == 200);
            return res ? json::parse(res->body) : json{};
        };
        EXPECT_EQ(list()["storage_warning"], "");

        const std::string id = farm.submit();
        ASSERT_FALSE(id.empty());
        const fs::path render_dir = dir / "data" / "renders" / id;
        ASSERT_TRUE(fs::is_directory(render_dir));
        fs::remove_all(render_dir);
        std::ofstream(render_dir) << "not a directory";
        coordinator.register_worker("w1", 1);
        fake_jobs(coordinator, "w1");
        ASSERT_EQ(coordinator.info(id)->state, RenderState::Done);
        // The backlog's own thread makes the failing write: wait for it (a generous
        // deadline, not a timing check).
        for (int i = 0; i < 600 && coordinator.storage_warning().empty(); ++i)
            std::this_thread::sleep_for(std::chrono::milliseconds(50));

        const std::string warning = list()["storage_warning"];
        EXPECT_NE(warning.find(id), std::string::npos) << warning;
        auto detail = c.Get(("/api/renders/" + id).c_str());
        ASSERT_TRUE(detail);
        EXPECT_EQ(json::parse(detail->body)["storage_warning"], warning);
        RawStream stream = open_stream(server.port());
        ASSERT_EQ(stream.status, 200);
        EXPECT_TRUE(stream.read_until("\"storage_warning\":\"cannot"));

        // Once the disk takes writes again the warning goes away.
        fs::remove(render_dir);
        fs::create_directory(render_dir);
        // Retries back off from 0.5 s doubling: allow a minute.
        for (int i = 0; i < 1200 && !coordinator.storage_warning().empty(); ++i) {
            coordinator.tick();
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
        }
        EXPECT_EQ(list()["storage_warning"], "");
    }
    fs::remove_all(dir);
}

TEST(PngEncoder, WritesSignatureHeaderAndRejectsBadSizes) {
    const std::string png = encode_png(std::vector<uint8_t>(3 * 5 * 3, 128), 3, 5, 3);
    EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
    EXPECT_EQ(png.substr(12, 4), "IHDR");
    EXPECT_EQ(uint8_t(png[19]), 3u);
    EXPECT_EQ(uint8_t(png[23]), 5u);
    EXPECT_EQ(png.substr(png.size() - 8, 4), "IEND");
    EXPECT_THROW(encode_png(std::vector<uint8_t>(10), 3, 5, 3), std::invalid_argument);
    EXPECT_THROW(encode_png(std::vector<uint8_t>(15), 3, 5, 2), std::invalid_argument);
}

// Issue 12, item 7: a render past the coordinator's memory budget is refused with 429
// and the numbers.
TEST(HttpServerMemory, ASubmissionPastTheMemoryBudgetGets429) {
    CoordinatorOptions options;
    options.memory_limit = 1024;
    Coordinator coordinator(options);
    HttpServer server(coordinator, "127.0.0.1:0", options_with_tokens());
    httplib::Client client("127.0.0.1", server.port());
    client.set_bearer_token_auth(testing::kTestTokens.client);
    auto res =
        client.Post("/api/renders", R"({"scene":"cornell-box","resolution":"64x64"})",
                    "application/json");
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 429) << res->body;
    const json body = json::parse(res->body);
    EXPECT_NE(body.dump().find("--memory-limit"), std::string::npos) << res->body;
    EXPECT_TRUE(coordinator.list(10).empty());
}

// ---- authentication (issue 13): the client token, as a bearer or a session cookie ----

// What a request for `path` carrying `headers` (and no token of the fixture's) gets.
httplib::Result get_with(int port, const std::string& path,
                         const httplib::Headers& headers) {
    httplib::Client c("127.0.0.1", port);
    c.set_read_timeout(10, 0);
    return c.Get(path.c_str(), headers);
}

// The session cookie a sign-in response sets, as a Cookie header sends it back.
std::string cookie_sent_back(const httplib::Response& res) {
    const std::string set = res.get_header_value("Set-Cookie");
    return set.substr(0, set.find(';'));
}

// Signs in with the client token; the cookie to send back ("NAME=ID"), empty on failure.
std::string sign_in(int port) {
    httplib::Client browser("127.0.0.1", port);
    browser.set_read_timeout(10, 0);
    auto res =
        browser.Post("/api/session", json{{"token", testing::kTestTokens.client}}.dump(),
                     "application/json");
    return res && res->status == 200 ? cookie_sent_back(*res) : "";
}

// Routes of every kind: a list, one render, its image and maps, a study's file, the
// session, and a route that does not exist (which must not tell that it does not).
std::vector<std::string> guarded_paths(const std::string& id) {
    return {"/api/renders",
            "/api/renders/" + id,
            "/api/renders/" + id + "/preview.png",
            "/api/renders/" + id + "/thumbnail.png",
            "/api/renders/" + id + "/image.exr",
            "/api/renders/" + id + "/maps?kind=error",
            "/api/renders/" + id + "/rounds",
            "/api/renders/" + id + "/events",
            "/api/workers",
            "/api/methods",
            "/api/studies",
            "/api/studies/data/equal-budget/report.md",
            "/api/studies/data/equal-budget/charts/error.png",
            "/api/session",
            "/api/no-such-route",
            "/metrics"};
}

TEST_F(HttpServerTest, WithoutTheClientTokenEveryApiRouteAnswers401) {
    const std::string id = submit({{"resolution", "8x8"}, {"strategy", {{"spp", 2}}}});
    fake_jobs(*coordinator_, "w1");
    const int port = server_->port();
    const std::vector<httplib::Headers> refused = {
        {},
        {{"Authorization", "Bearer not-the-token-0123456789"}},
        {{"Authorization", "Basic " + http_api::base64(testing::kTestTokens.client)}},
        {{"Cookie",
          http_session::cookie_name(port, false) + "=not-the-token-0123456789"}},
        {{"Cookie", "other=" + testing::kTestTokens.client}},
        // The cookie is never the token, under the old name or the new.
        {{"Cookie", "aliquot_session=" + testing::kTestTokens.client}},
        {{"Cookie",
          http_session::cookie_name(port, false) + "=" + testing::kTestTokens.client}},
    };
    for (const std::string& path : guarded_paths(id)) {
        for (const httplib::Headers& headers : refused) {
            auto res = get_with(port, path, headers);
            ASSERT_TRUE(res) << path;
            EXPECT_EQ(res->status, 401) << path << ": " << res->body;
            EXPECT_EQ(res->get_header_value("WWW-Authenticate"), "Bearer") << path;
            EXPECT_EQ(res->get_header_value("Content-Type"), "application/json") << path;
            const json body = json::parse(res->body, nullptr, false);
            ASSERT_TRUE(body.is_object() && body["error"].is_string()) << res->body;
            EXPECT_NE(body["error"].get<std::string>().find("client token"),
                      std::string::npos);
            EXPECT_EQ(res->body.find(testing::kTestTokens.client), std::string::npos);
            EXPECT_FALSE(res->has_header("Set-Cookie")) << path;
        }
    }
    RawStream events = open_stream(port, "/api/events", "");
    EXPECT_EQ(events.status, 401) << events.head;
    EXPECT_NE(events.head.find("WWW-Authenticate: Bearer"), std::string::npos);
    EXPECT_TRUE(body_json(events)["error"].is_string());
}

TEST_F(HttpServerTest, TheWorkerTokenIsRefusedWith403) {
    const std::string id = submit({{"resolution", "8x8"}, {"strategy", {{"spp", 2}}}});
    fake_jobs(*coordinator_, "w1");
    const httplib::Headers worker = {
        {"Authorization", "Bearer " + testing::kTestTokens.worker}};
    for (const std::string& path : guarded_paths(id)) {
        auto res = get_with(server_->port(), path, worker);
        ASSERT_TRUE(res) << path;
        EXPECT_EQ(res->status, 403) << path << ": " << res->body;
        EXPECT_NE(json::parse(res->body)["error"].get<std::string>().find("worker's"),
                  std::string::npos);
        EXPECT_EQ(res->body.find(testing::kTestTokens.worker), std::string::npos);
    }
    EXPECT_EQ(open_stream(server_->port(), "/api/events",
                          "Authorization: Bearer " + testing::kTestTokens.worker)
                  .status,
              403);
}

TEST_F(HttpServerTest, TheClientTokenOpensEveryRoute) {
    const std::string id = submit({{"resolution", "8x8"}, {"strategy", {{"spp", 2}}}});
    fake_jobs(*coordinator_, "w1");
    const httplib::Headers bearer = {{"Authorization", kClientBearer}};
    for (const std::string& path : guarded_paths(id)) {
        auto res = get_with(server_->port(), path, bearer);
        ASSERT_TRUE(res) << path;
        EXPECT_EQ(res->status, path == "/api/no-such-route" ? 404 : 200)
            << path << ": " << res->body;
    }
    EXPECT_EQ(get_json("/api/session")["signed_in"], true);
    RawStream events = open_stream(server_->port());
    EXPECT_EQ(events.status, 200);
    EXPECT_TRUE(events.read_until("\"hello\""));
}

// Prometheus scrapes with the client token as a bearer; a browser signed in may read it
// with the cookie. Refusals are the API's (above: 401, 403).
TEST_F(HttpServerTest, MetricsAreServedInPrometheusTextFormatWithTheClientToken) {
    submit({{"resolution", "8x8"}, {"strategy", {{"spp", 2}}}});
    fake_jobs(*coordinator_, "w1");
    auto res = client_->Get("/metrics");
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 200) << res->body;
    EXPECT_EQ(res->get_header_value("Content-Type"), FarmMetrics::kContentType);
    EXPECT_NE(res->body.find("aliquot_renders{state=\"done\"} 1"), std::string::npos)
        << res->body;
    EXPECT_NE(res->body.find("aliquot_samples_merged_total 128"), std::string::npos)
        << res->body;  // 8x8 pixels at 2 spp
    const httplib::Headers cookie = {{"Cookie", sign_in(server_->port())}};
    auto with_cookie = get_with(server_->port(), "/metrics", cookie);
    ASSERT_TRUE(with_cookie);
    EXPECT_EQ(with_cookie->status, 200);
}

TEST(HttpServerMetrics, WithoutMetricsTheRouteIsNotFound) {
    Coordinator coordinator{CoordinatorOptions{}};
    HttpServer server(coordinator, "127.0.0.1:0", options_with_tokens());
    const httplib::Headers bearer = {{"Authorization", kClientBearer}};
    auto res = get_with(server.port(), "/metrics", bearer);
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 404);
    EXPECT_EQ(get_with(server.port(), "/metrics", {})->status, 401);
}

// Review of issue 33: a Range header of 2,700 overlapping ranges (8 KB, no token) made
// httplib build a multipart answer of 2,700 copies of a dashboard file in memory (293
// MB for 108 KB; six at once took 1.6 GB). One range is served, several get the whole.
TEST_F(HttpServerTest, SeveralRangesGetTheWholeFileOnceAndOneRangeItsBytes) {
    httplib::Client anonymous("127.0.0.1", server_->port());
    auto whole = anonymous.Get("/index.html");
    ASSERT_TRUE(whole);
    ASSERT_EQ(whole->status, 200);
    std::string ranges = "bytes=0-";
    for (int i = 0; i < 1000; ++i) ranges += ",0-";
    auto many = anonymous.Get("/index.html", {{"Range", ranges}});
    ASSERT_TRUE(many);
    EXPECT_EQ(many->status, 200);
    EXPECT_EQ(many->body, whole->body);
    auto one = anonymous.Get("/index.html", {{"Range", "bytes=2-5"}});
    ASSERT_TRUE(one);
    EXPECT_EQ(one->status, 206);
    EXPECT_EQ(one->body, whole->body.substr(2, 4));
}

TEST_F(HttpServerTest, HealthAndTheDashboardsFilesNeedNoToken) {
    std::ofstream(dir_ / "web" / "app.js") << "console.log(1)";
    httplib::Client anonymous("127.0.0.1", server_->port());
    for (const char* path : {"/healthz", "/", "/index.html", "/app.js"}) {
        auto res = anonymous.Get(path);
        ASSERT_TRUE(res) << path;
        EXPECT_EQ(res->status, 200) << path << ": " << res->body;
    }
}

TEST_F(HttpServerTest, SigningInSetsACookieThatAloneOpensTheApi) {
    httplib::Client browser("127.0.0.1", server_->port());
    browser.set_read_timeout(10, 0);
    const std::string sign_in = json{{"token", testing::kTestTokens.client}}.dump();
    auto res = browser.Post("/api/session", sign_in, "application/json");
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 200) << res->body;
    EXPECT_EQ(json::parse(res->body)["ok"], true);
    const std::string set = res->get_header_value("Set-Cookie");
    const std::string name = http_session::cookie_name(server_->port(), false);
    EXPECT_EQ(set.rfind(name + "=", 0), 0u) << set;
    for (const char* attribute : {"; HttpOnly", "; SameSite=Strict", "; Path=/"})
        EXPECT_NE(set.find(attribute), std::string::npos) << attribute << ": " << set;
    EXPECT_EQ(res->body.find(testing::kTestTokens.client), std::string::npos);

    const httplib::Headers cookie = {{"Cookie", "theme=dark; " + cookie_sent_back(*res)}};
    auto list = browser.Get("/api/renders", cookie);
    ASSERT_TRUE(list);
    EXPECT_EQ(list->status, 200) << list->body;
    auto session = browser.Get("/api/session", cookie);
    ASSERT_TRUE(session);
    EXPECT_EQ(json::parse(session->body)["signed_in"], true);
    auto submitted =
        browser.Post("/api/renders", cookie,
                     R"({"resolution":"8x8","strategy":{"spp":2}})", "application/json");
    ASSERT_TRUE(submitted);
    EXPECT_EQ(submitted->status, 201) << submitted->body;
    RawStream events =
        open_stream(server_->port(), "/api/events", "Cookie: " + cookie_sent_back(*res));
    EXPECT_EQ(events.status, 200);
    EXPECT_TRUE(events.read_until("\"hello\""));

    // Signing out expires the same cookie.
    auto out = browser.Delete("/api/session", cookie, "{}", "application/json");
    ASSERT_TRUE(out);
    EXPECT_EQ(out->status, 200) << out->body;
    const std::string cleared = out->get_header_value("Set-Cookie");
    EXPECT_EQ(cleared.rfind(name + "=;", 0), 0u) << cleared;
    EXPECT_NE(cleared.find("Max-Age=0"), std::string::npos) << cleared;
    EXPECT_NE(cleared.find("SameSite=Strict"), std::string::npos) << cleared;
}

TEST_F(HttpServerTest, AWrongSignInSetsNoCookie) {
    httplib::Client browser("127.0.0.1", server_->port());
    struct Case {
        std::string body;
        int status;
    };
    const std::vector<Case> cases = {
        {json{{"token", "not-the-token-0123456789"}}.dump(), 401},
        {json{{"token", ""}}.dump(), 401},
        {json{{"token", testing::kTestTokens.worker}}.dump(), 403},
        {R"({"token": 12})", 400},
        {R"({})", 400},
        {"not json", 400},
    };
    for (const Case& c : cases) {
        auto res = browser.Post("/api/session", c.body, "application/json");
        ASSERT_TRUE(res) << c.body;
        EXPECT_EQ(res->status, c.status) << c.body << ": " << res->body;
        EXPECT_FALSE(res->has_header("Set-Cookie")) << c.body;
        EXPECT_TRUE(json::parse(res->body)["error"].is_string()) << res->body;
        EXPECT_EQ(res->body.find(testing::kTestTokens.worker), std::string::npos);
    }
    // The cross-site checks come first: another site's page cannot sign a browser in.
    const std::string right = json{{"token", testing::kTestTokens.client}}.dump();
    auto foreign = browser.Post("/api/session", {{"Origin", "http://evil.example"}},
                                right, "application/json");
    ASSERT_TRUE(foreign);
    EXPECT_EQ(foreign->status, 403);
    EXPECT_FALSE(foreign->has_header("Set-Cookie"));
    auto form =
        browser.Post("/api/session", "token=x", "application/x-www-form-urlencoded");
    ASSERT_TRUE(form);
    EXPECT_EQ(form->status, 415);
    EXPECT_FALSE(form->has_header("Set-Cookie"));
}

TEST_F(HttpServerTest, ARefusedRequestChangesNothing) {
    const std::string id = submit({{"resolution", "64x64"}, {"strategy", {{"spp", 64}}}});
    const std::string body = R"({"resolution":"8x8","strategy":{"spp":2}})";
    for (const httplib::Headers& headers :
         {httplib::Headers{},
          httplib::Headers{{"Authorization", "Bearer " + testing::kTestTokens.worker}},
          httplib::Headers{{"Cookie", http_session::cookie_name(server_->port(), false) +
                                          "=" + testing::kTestTokens.worker}}}) {
        httplib::Client c("127.0.0.1", server_->port());
        auto submitted = c.Post("/api/renders", headers, body, "application/json");
        ASSERT_TRUE(submitted);
        EXPECT_TRUE(submitted->status == 401 || submitted->status == 403)
            << submitted->body;
        auto cancelled = c.Post(("/api/renders/" + id + "/cancel").c_str(), headers, "{}",
                                "application/json");
        ASSERT_TRUE(cancelled);
        EXPECT_TRUE(cancelled->status == 401 || cancelled->status == 403)
            << cancelled->body;
    }
    const json list = get_json("/api/renders");
    ASSERT_EQ(list["renders"].size(), 1u);
    EXPECT_EQ(list["renders"][0]["state"],
              "queued");  // as submitted: nothing cancelled it
}

TEST(HttpServerTokens, RefusesToStartWithoutTwoDifferentTokens) {
    Coordinator coordinator{CoordinatorOptions{}};
    const std::string t = testing::kTestTokens.client;
    for (const Tokens& tokens : {Tokens{}, Tokens{t, ""}, Tokens{"", t}, Tokens{t, t}}) {
        HttpOptions options;
        options.tokens = tokens;
        EXPECT_THROW(HttpServer(coordinator, "127.0.0.1:0", options),
                     std::invalid_argument);
    }
}

// A client token that would end or quote a header value, or that the HTTP library would
// percent-decode, is refused at start rather than making sign-in fail later.
TEST(HttpServerTokens, RefusesAClientTokenACookieCannotCarry) {
    Coordinator coordinator{CoordinatorOptions{}};
    for (const char* odd : {"client;token-0123456789", "client,token-0123456789",
                            "client\"token-0123456789", "client\\token-0123456789",
                            "client%41token-0123456789"}) {
        HttpOptions options;
        options.tokens = {odd, testing::kTestTokens.worker};
        EXPECT_THROW(HttpServer(coordinator, "127.0.0.1:0", options),
                     std::invalid_argument)
            << odd;
    }
}

// Issue 30, 3: the cookie was the client token itself, which any server on another port
// of the host received and which then worked as a gRPC bearer token. It is a session id
// now: not the token, no token for either role (what gRPC checks), named with the port,
// and meaningless to a coordinator on another port.
TEST_F(HttpServerTest, TheCookieIsASessionOfThisServerNotTheToken) {
    const std::string cookie = sign_in(server_->port());
    const std::string name = http_session::cookie_name(server_->port(), false);
    ASSERT_EQ(cookie.rfind(name + "=", 0), 0u) << cookie;
    const std::string id = cookie.substr(name.size() + 1);
    EXPECT_EQ(id.size(), 64u);
    EXPECT_EQ(id.find(testing::kTestTokens.client), std::string::npos);
    EXPECT_EQ(check_access(testing::kTestTokens, id, Role::Client),
              Access::Unauthenticated);
    EXPECT_EQ(check_access(testing::kTestTokens, id, Role::Worker),
              Access::Unauthenticated);
    EXPECT_NE(sign_in(server_->port()), cookie);  // each sign-in its own session

    // Another coordinator on another port of this host gets the cookie from the browser
    // and takes it neither under this name nor under its own.
    HttpServer other(*coordinator_, "127.0.0.1:0", options_with_tokens());
    const std::string other_name = http_session::cookie_name(other.port(), false);
    for (const std::string& sent : {cookie, other_name + "=" + id}) {
        auto res = get_with(other.port(), "/api/renders", {{"Cookie", sent}});
        ASSERT_TRUE(res);
        EXPECT_EQ(res->status, 401) << sent;
    }
    auto here = get_with(server_->port(), "/api/renders", {{"Cookie", cookie}});
    ASSERT_TRUE(here);
    EXPECT_EQ(here->status, 200);
}

// Signing out ends the session on the server: a copy of the cookie kept elsewhere opens
// nothing afterwards.
TEST_F(HttpServerTest, SigningOutEndsTheSessionNotJustTheCookie) {
    const std::string cookie = sign_in(server_->port()), other = sign_in(server_->port());
    httplib::Client browser("127.0.0.1", server_->port());
    auto out =
        browser.Delete("/api/session", {{"Cookie", cookie}}, "{}", "application/json");
    ASSERT_TRUE(out);
    EXPECT_EQ(out->status, 200);
    auto kept = get_with(server_->port(), "/api/renders", {{"Cookie", cookie}});
    ASSERT_TRUE(kept);
    EXPECT_EQ(kept->status, 401);
    auto still = get_with(server_->port(), "/api/renders", {{"Cookie", other}});
    ASSERT_TRUE(still);
    EXPECT_EQ(still->status, 200);  // another browser's session is its own
}

// A session past its lifetime is refused like no session at all (the lifetime here is 0,
// so every session is over by its first use).
TEST(HttpServerSessions, AnExpiredSessionIsRefused) {
    Coordinator coordinator{CoordinatorOptions{}};
    HttpOptions options = options_with_tokens();
    options.sessions.lifetime = std::chrono::milliseconds(0);
    HttpServer server(coordinator, "127.0.0.1:0", options);
    const std::string cookie = sign_in(server.port());
    ASSERT_FALSE(cookie.empty());
    auto res = get_with(server.port(), "/api/session", {{"Cookie", cookie}});
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 401);
}

}  // namespace
}  // namespace aliquot
