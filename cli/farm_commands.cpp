// aliquot status | watch | fetch | cancel | workers: small clients of a running
// coordinator.
#include <unistd.h>

#include <cstdio>
#include <iostream>
#include <memory>

#include "client.h"
#include "commands.h"
#include "endpoint_options.h"
#include "exr_io.h"
#include "http_api.h"
#include "png_output.h"
#include "progress_bar.h"
#include "render_json.h"
#include "render_options.h"
#include "render_proto.h"
#include "whole_number_option.h"

namespace aliquot::cli {

namespace {

struct FarmOptions {
    EndpointOptions coordinator;
    std::string id;
    std::string out;
    bool json = false, aovs = false;
    PngOptions png;
};

CLI::App* add_common(CLI::App& app, const char* name, const char* help,
                     const std::shared_ptr<FarmOptions>& o) {
    CLI::App* cmd = app.add_subcommand(name, help);
    o->coordinator.add_to(*cmd, Role::Client);
    return cmd;
}

std::string eta(const RenderInfo& i) {
    if (i.samples_done == 0 || i.samples_planned <= i.samples_done) return "-";
    const double left =
        double(i.samples_planned - i.samples_done) / std::max(i.samples_per_second, 1e-9);
    return std::to_string(int64_t(left)) + "s";
}

void register_status(CLI::App& app) {
    auto o = std::make_shared<FarmOptions>();
    CLI::App* cmd = add_common(app, "status", "one render's state, or all renders", o);
    cmd->add_option("id", o->id, "render id (omit for all)");
    cmd->add_flag("--json", o->json, "print JSON");
    cmd->callback([o] {
        ClientConnection c(o->coordinator.resolve(Role::Client));
        std::vector<RenderInfo> renders;
        v1::ListRendersRequest list;
        v1::ListRendersReply reply;
        if (!o->id.empty()) {
            v1::GetRenderRequest req;
            req.set_id(o->id);
            v1::RenderInfo info;
            c.check(c.stub().GetRender(c.context().get(), req, &info), "status " + o->id);
            renders.push_back(from_proto(info));
            list.set_limit(1);  // only for the storage warning below
        }
        c.check(c.stub().ListRenders(c.context().get(), list, &reply), "status");
        if (o->id.empty())
            for (const v1::RenderInfo& r : reply.renders())
                renders.push_back(from_proto(r));
        // On stderr, so that --json output stays one document.
        if (!reply.storage_warning().empty())
            std::cerr << "warning: the coordinator cannot write its record: "
                      << reply.storage_warning() << std::endl;
        if (o->json) {
            // The HTTP API's documents (render_json.h), so a script reads either the same
            // way.
            nlohmann::json all = nlohmann::json::array();
            for (const auto& r : renders) all.push_back(render_detail(r));
            std::cout << (o->id.empty() ? all : all[0]).dump() << std::endl;
        } else {
            for (const auto& r : renders) std::cout << describe(r) << "\n";
        }
    });
}

void register_watch(CLI::App& app) {
    auto o = std::make_shared<FarmOptions>();
    CLI::App* cmd = add_common(app, "watch", "follow a render live until it ends", o);
    cmd->add_option("id", o->id, "render id")->required();
    cmd->callback([o] {
        ClientConnection c(o->coordinator.resolve(Role::Client));
        const bool tty = isatty(STDOUT_FILENO);
        const RenderInfo last = follow(c, o->id, [&](const RenderInfo& i) {
            const std::string line = describe(i) + "  eta " + eta(i);
            if (tty)
                std::printf("\r%s\x1b[K", line.c_str());
            else
                std::printf("%s\n", line.c_str());
            std::fflush(stdout);
        });
        if (tty) std::printf("\n");
        check_done(last);
    });
}

void register_fetch(CLI::App& app) {
    auto o = std::make_shared<FarmOptions>();
    CLI::App* cmd = add_common(app, "fetch", "download a render's current image", o);
    cmd->add_option("id", o->id, "render id")->required();
    cmd->add_option("--out", o->out, "output .exr")->required();
    cmd->add_flag("--aovs", o->aovs, "add the layers sampleCount.Y and variance.Y");
    o->png.add_to(*cmd);
    cmd->callback([o] {
        check_writable(o->out, "--out");
        const std::string png_path = o->png.path_beside(o->out);
        ClientConnection c(o->coordinator.resolve(Role::Client));
        fetch_image(c, o->id, o->out, o->aovs);
        std::cout << "wrote " << o->out << std::endl;
        if (o->png.png) {
            // From the EXR just written: the picture is the file's, whatever the render
            // has merged since.
            write_png(read_exr(o->out), o->png.exposure, png_path);
            std::cout << "wrote " << png_path << std::endl;
        }
    });
}

void register_cancel(CLI::App& app) {
    auto o = std::make_shared<FarmOptions>();
    CLI::App* cmd = add_common(app, "cancel", "stop a render, keeping what it merged", o);
    cmd->add_option("id", o->id, "render id")->required();
    cmd->callback([o] {
        ClientConnection c(o->coordinator.resolve(Role::Client));
        v1::GetRenderRequest req;
        req.set_id(o->id);
        v1::RenderInfo info;
        c.check(c.stub().Cancel(c.context().get(), req, &info), "cancel " + o->id);
        std::cout << describe(from_proto(info)) << std::endl;
    });
}

void register_priority(CLI::App& app) {
    auto o = std::make_shared<FarmOptions>();
    auto priority = std::make_shared<int32_t>(0);
    CLI::App* cmd =
        add_common(app, "priority", "change a queued or running render's priority", o);
    cmd->add_option("id", o->id, "render id")->required();
    cmd->add_option("priority", *priority, "the new priority (higher goes first)")
        ->check(signed_whole_number())
        ->required();
    cmd->callback([o, priority] {
        ClientConnection c(o->coordinator.resolve(Role::Client));
        v1::SetPriorityRequest req;
        req.set_id(o->id);
        req.set_priority(*priority);
        v1::RenderInfo info;
        c.check(c.stub().SetPriority(c.context().get(), req, &info), "priority " + o->id);
        std::cout << describe(from_proto(info)) << std::endl;
    });
}

void register_delete(CLI::App& app) {
    auto o = std::make_shared<FarmOptions>();
    CLI::App* cmd = add_common(
        app, "delete", "delete a finished render: its image, record and rounds", o);
    cmd->add_option("id", o->id, "render id")->required();
    cmd->callback([o] {
        ClientConnection c(o->coordinator.resolve(Role::Client));
        v1::GetRenderRequest req;
        req.set_id(o->id);
        v1::DeleteReply reply;
        c.check(c.stub().Delete(c.context().get(), req, &reply), "delete " + o->id);
        std::cout << "deleted " << o->id << std::endl;
    });
}

void register_workers(CLI::App& app) {
    auto o = std::make_shared<FarmOptions>();
    CLI::App* cmd = add_common(app, "workers", "workers the coordinator knows", o);
    cmd->add_flag("--json", o->json, "print JSON");
    cmd->callback([o] {
        ClientConnection c(o->coordinator.resolve(Role::Client));
        v1::ListWorkersRequest req;
        v1::ListWorkersReply reply;
        c.check(c.stub().ListWorkers(c.context().get(), req, &reply), "workers");
        nlohmann::json all = nlohmann::json::array();
        for (const auto& w : reply.workers()) {
            if (o->json) {
                // The HTTP API's writer, so a script reads either the same way.
                all.push_back(http_api::worker_json(from_proto(w)));
            } else {
                std::printf(
                    "%-24s %-5s %2u threads  %llu samples  %.0f samples/s  %d leases\n",
                    w.name().c_str(), w.state().c_str(), w.threads(),
                    (unsigned long long)w.samples_traced(), w.samples_per_second(),
                    w.leases_size());
            }
        }
        if (o->json) std::cout << all.dump() << std::endl;
    });
}

}  // namespace

void register_farm_clients(CLI::App& app) {
    register_status(app);
    register_watch(app);
    register_fetch(app);
    register_cancel(app);
    register_priority(app);
    register_delete(app);
    register_workers(app);
}

}  // namespace aliquot::cli
