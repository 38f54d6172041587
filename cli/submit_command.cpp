// aliquot submit: send a render to a coordinator; with --wait follow it to the end.
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>

#include "client.h"
#include "commands.h"
#include "endpoint_options.h"
#include "exr_io.h"
#include "name_option.h"
#include "png_output.h"
#include "progress_bar.h"
#include "render_json.h"
#include "render_options.h"
#include "render_proto.h"
#include "scene_loader.h"
#include "whole_number_option.h"

namespace aliquot::cli {

namespace {

struct SubmitCommand {
    RenderOptions options;
    EndpointOptions coordinator;
    bool wait = false, json = false, aovs = false;
    std::string out;
    int32_t priority = 0;
    std::string name;
    PngOptions png;

    void run() {
        check_render_options(options);
        if (!out.empty()) {
            check_writable(out, "--out");
            wait = true;  // an output file means waiting for the image
        }
        if (png.png && out.empty())
            throw UsageError("--png: needs --out, the EXR it goes beside");
        const std::string png_path = png.path_beside(out);
        v1::SubmitRequest req;
        req.set_scene(options.scene);
        req.set_scene_json(self_contained_scene_json(options.scene));
        req.set_width(options.width);
        req.set_height(options.height);
        req.set_seed(options.seed);
        req.set_priority(priority);
        req.set_name(name);
        req.set_albedo_normal(options.albedo_normal);
        req.set_strategy_json(nlohmann::json(options.strategy).dump());
        if (!options.reference.empty()) {
            std::ifstream in(options.reference, std::ios::binary);
            if (!in) throw CommandError("--reference: cannot open " + options.reference);
            std::stringstream ss;
            ss << in.rdbuf();
            req.set_reference_exr(ss.str());
        }
        ClientConnection c(coordinator.resolve(Role::Client));
        v1::RenderInfo submitted;
        c.check(c.stub().Submit(c.context(60).get(), req, &submitted), "submit");
        RenderInfo info = from_proto(submitted);
        if (!wait) {
            if (json)
                std::cout << render_detail(info).dump() << std::endl;
            else
                std::cout << info.id << std::endl;
            return;
        }
        if (!json) std::cerr << "submitted " << info.id << std::endl;
        ProgressBar bar(info.id);
        info = follow(c, info.id, [&](const RenderInfo& i) {
            bar.update(i.samples_done, i.samples_planned,
                       "round " + std::to_string(i.rounds_done) + ", " +
                           std::to_string(int64_t(i.samples_per_second / 1e3)) +
                           " k samples/s");
        });
        bar.finish();
        if (!out.empty()) fetch_image(c, info.id, out, aovs);
        if (png.png) {
            write_png(read_exr(out), png.exposure, png_path);
            if (!json) std::cerr << "wrote " << png_path << std::endl;
        }
        if (json)
            std::cout << render_detail(info).dump() << std::endl;
        else
            std::cout << describe(info) << std::endl;
        check_done(info);
    }
};

}  // namespace

void register_submit(CLI::App& app) {
    auto c = std::make_shared<SubmitCommand>();
    CLI::App* cmd = app.add_subcommand("submit", "submit a render to a coordinator");
    add_render_options(*cmd, c->options);
    c->coordinator.add_to(*cmd, Role::Client);
    cmd->add_flag("--wait", c->wait,
                  "follow the render with a progress bar until it ends");
    cmd->add_option("--out", c->out, "write the final EXR here (implies --wait)");
    cmd->add_flag("--aovs", c->aovs,
                  "add the layers sampleCount.Y and variance.Y to the EXR");
    cmd->add_flag("--json", c->json, "print JSON");
    c->png.add_to(*cmd);
    cmd->add_option("--priority", c->priority,
                    "leases go to the highest priority first, in submission order within "
                    "one; change it later with `aliquot priority`")
        ->check(signed_whole_number())
        ->capture_default_str();
    add_name_option(*cmd, c->name, "status and the dashboard");
    cmd->callback([c] { c->run(); });
}

}  // namespace aliquot::cli
