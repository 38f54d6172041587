// aliquot logs ID [--follow]: a render's events (submitted, started, rounds, its end,
// workers kept off it) as the coordinator's log has them, oldest first.
#include <chrono>
#include <cstdio>
#include <iostream>
#include <memory>
#include <thread>

#include "client.h"
#include "commands.h"
#include "endpoint_options.h"
#include "log_line.h"
#include "render_events.h"

namespace aliquot::cli {

namespace {

struct LogsCommand {
    EndpointOptions coordinator;
    std::string id;
    bool follow = false, json = false;

    // Prints the events numbered from `from` on; the number to ask from next time, and
    // whether the render has ended.
    std::pair<uint64_t, bool> print_from(ClientConnection& c, uint64_t from) const {
        bool ended = false;
        for (;;) {
            v1::GetEventsRequest req;
            req.set_id(id);
            req.set_from(from);
            req.set_limit(1000);
            v1::GetEventsReply reply;
            c.check(c.stub().GetEvents(c.context().get(), req, &reply), "logs " + id);
            for (const v1::RenderEvent& e : reply.events()) {
                if (e.seq() > from && !json)
                    std::printf("... %llu events not kept ...\n",
                                (unsigned long long)(e.seq() - from));
                // As the coordinator's own log line has it: the render first.
                LogFields fields = {log_text("render", id)};
                for (LogField& f : fields_of_json(e.fields_json()))
                    fields.push_back(std::move(f));
                if (json) {
                    std::cout << nlohmann::json{{"seq", e.seq()},
                                                {"at_ms", e.at_ms()},
                                                {"kind", e.kind()},
                                                {"fields",
                                                 nlohmann::json::parse(e.fields_json(),
                                                                       nullptr, false)}}
                                     .dump()
                              << "\n";
                } else {
                    std::cout << format_log_line(LogFormat::Text, e.at_ms(), e.kind(),
                                                 fields)
                              << "\n";
                }
                const auto kind = parse_event_kind(e.kind());
                ended = ended || kind == EventKind::Finished ||
                        kind == EventKind::Failed || kind == EventKind::Cancelled;
                from = e.seq() + 1;
            }
            std::cout.flush();
            if (reply.events_size() < 1000) return {from, ended};
        }
    }

    void run() {
        ClientConnection c(coordinator.resolve(Role::Client));
        auto [from, ended] = print_from(c, 0);
        // Asking once a second costs the coordinator one small read: cheaper than a
        // stream held open.
        while (follow && !ended) {
            std::this_thread::sleep_for(std::chrono::seconds(1));
            std::tie(from, ended) = print_from(c, from);
        }
    }
};

}  // namespace

void register_logs(CLI::App& app) {
    auto c = std::make_shared<LogsCommand>();
    CLI::App* cmd = app.add_subcommand(
        "logs",
        "a render's events: submitted, started, rounds, its end (the first 16 "
        "and last 48 are kept)");
    c->coordinator.add_to(*cmd, Role::Client);
    cmd->add_option("id", c->id, "render id")->required();
    cmd->add_flag("--follow,-f", c->follow, "keep printing events until the render ends");
    cmd->add_flag("--json", c->json, "one JSON object a line, as the HTTP API has them");
    cmd->callback([c] { c->run(); });
}

}  // namespace aliquot::cli
