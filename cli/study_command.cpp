// aliquot study FILE: runs a study definition (studies/*.json) embedded or on a farm,
// then writes its report (report.md, results.csv, charts) with
// tools/report/aliquot_report.py.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <sstream>

#include "child_process.h"
#include "commands.h"
#include "endpoint_options.h"
#include "progress_bar.h"
#include "study_farm.h"
#include "study_runner.h"
#include "whole_number_option.h"

namespace aliquot::cli {

namespace {

namespace fs = std::filesystem;

// The report module: $ALIQUOT_REPORT, else beside the source tree the binary was built in
// (build*/bin/aliquot), the study file's tree (studies/x.json) or the working directory.
fs::path find_report_script(const fs::path& study_file) {
    if (const char* env = std::getenv("ALIQUOT_REPORT")) return env;
    const fs::path rel = fs::path("tools") / "report" / "aliquot_report.py";
    std::vector<fs::path> candidates;
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (!ec) {
        candidates.push_back(exe.parent_path() / ".." / ".." / rel);
        candidates.push_back(exe.parent_path() / ".." / "share" / "aliquot" / "report" /
                             "aliquot_report.py");
    }
    candidates.push_back(fs::absolute(study_file).parent_path() / ".." / rel);
    candidates.push_back(fs::current_path() / rel);
    for (const fs::path& c : candidates)
        if (fs::exists(c)) return fs::weakly_canonical(c);
    throw CommandError(
        "cannot find tools/report/aliquot_report.py (set ALIQUOT_REPORT to its path)");
}

// The file `name` names on PATH, canonical; empty when there is none.
fs::path on_path(const std::string& name) {
    const char* path = std::getenv("PATH");
    std::stringstream dirs(path ? path : "");
    for (std::string dir; std::getline(dirs, dir, ':');) {
        std::error_code ec;
        const fs::path found =
            fs::canonical(fs::path(dir.empty() ? "." : dir) / name, ec);
        if (!ec) return found;
    }
    return {};
}

// The interpreters to try, in order: the repository's .venv when a user made one, python3
// on PATH, then Debian's own python3, where scripts/install-deps.sh installs
// python3-matplotlib and python3-numpy (a python3 from pyenv or conda on PATH does not
// see them).
std::vector<std::string> report_pythons(const fs::path& script) {
    std::vector<std::string> pythons;
    const fs::path venv = script.parent_path() / ".." / ".." / ".venv" / "bin" / "python";
    // Not canonicalised: a venv's python is a symlink, and only its own path selects the
    // venv.
    if (fs::exists(venv))
        pythons.push_back(fs::absolute(venv).lexically_normal().string());
    pythons.push_back("python3");
    std::error_code ec;
    const fs::path debian = fs::canonical("/usr/bin/python3", ec);
    if (!ec && debian != on_path("python3")) pythons.push_back("/usr/bin/python3");
    return pythons;
}

// The report module's exit status when its interpreter lacks matplotlib or numpy.
constexpr int kReportLacksModules = 3;
// Exits 0 when the interpreter can import both, printing nothing either way.
constexpr const char* kHasReportModules =
    "import importlib.util as u, sys; "
    "sys.exit(0 if u.find_spec('numpy') and u.find_spec('matplotlib') else 1)";

struct StudyCommand {
    std::string file;
    std::string scale = "small";
    EndpointOptions coordinator;  // no address: embedded
    std::string out;
    int threads = 0;
    bool no_report = false;

    void run() {
        const StudyDefinition def = parse_study(read_file(), file);
        const StudyScale sc = scale_named(def);
        if (threads < 0) throw UsageError("--threads: must be 0 or more");
        StudyRunOptions options;
        options.study_file = file;
        options.out = out.empty()
                          ? fs::path("out") / ("study-" + def.name + "-" + sc.name)
                          : fs::path(out);
        options.threads = threads;
        if (!coordinator.address.empty())
            options.backend =
                [endpoint = coordinator.resolve(Role::Client)](const fs::path& data) {
                    return make_farm_backend(endpoint, data);
                };
        // Made at the first update, once the references are there, as before the split.
        std::optional<ProgressBar> bar;
        options.progress = [&](uint64_t done, uint64_t total, const std::string& note) {
            if (!bar) bar.emplace("study " + study_id(def, sc));
            bar->update(done, total, note);
        };
        options.done = [&] {
            if (bar) bar->finish();
        };
        const StudyRunSummary s = run_study(def, sc, options);
        std::printf(
            "study %s: %zu renders (%zu rendered now, %zu shared, %zu recorded before) "
            "in %.1f s; data in %s\n",
            study_id(def, sc).c_str(), s.renders, s.rendered, s.reused,
            s.renders - s.rendered - s.reused, s.seconds,
            (options.out / "data").string().c_str());
        std::fflush(stdout);
        if (!no_report) write_report(def, sc, options.out);
    }

private:
    // An unknown --scale is the command line's fault, whichever file it names.
    StudyScale scale_named(const StudyDefinition& def) const {
        try {
            return study_scale(def, scale);
        } catch (const StudyError& e) {
            throw UsageError(e.what());
        }
    }

    std::string read_file() const {
        std::ifstream in(file);
        if (!in) throw CommandError(file + ": cannot open the study file");
        std::stringstream text;
        text << in.rdbuf();
        return text.str();
    }

    void write_report(const StudyDefinition& def, const StudyScale& sc,
                      const fs::path& dir) {
        const fs::path script = find_report_script(file);
        // The first interpreter that has both modules (asked quietly, so that the ones
        // without leave no ImportError on the terminal), else the last, whose report
        // then says what it lacks.
        const std::vector<std::string> pythons = report_pythons(script);
        std::string python = pythons.back();
        for (const std::string& candidate : pythons) {
            if (run_process({candidate, "-c", kHasReportModules}) == 0) {
                python = candidate;
                break;
            }
        }
        const int rc = run_process({python, script.string(), "--db",
                                    (dir / "data" / "aliquot.db").string(), "--study",
                                    study_id(def, sc), "--out", dir.string()});
        if (rc == kReportLacksModules)
            throw CommandError(
                "report not written: no python3 here has matplotlib and numpy (run "
                "scripts/install-deps.sh, which installs Debian's python3-matplotlib and "
                "python3-numpy); the renders are recorded, run the study again to write "
                "the report");
        if (rc != 0)
            throw CommandError("report not written: " + script.string() +
                               " exited with status " + std::to_string(rc));
        std::printf("report: %s\n", (dir / "report.md").string().c_str());
    }
};

}  // namespace

void register_study(CLI::App& app) {
    auto c = std::make_shared<StudyCommand>();
    CLI::App* cmd = app.add_subcommand(
        "study", "run a study (studies/*.json): renders, references, report and charts");
    cmd->add_option("file", c->file, "study definition (.json)")->required();
    cmd->add_option("--scale", c->scale,
                    "small | medium | full (or a scale the file defines)")
        ->capture_default_str();
    c->coordinator.add_to(*cmd, Role::Client);
    // A study runs embedded unless told: ALIQUOT_COORDINATOR, set for the farm's clients,
    // must not move hours of renders onto a farm by surprise.
    cmd->get_option("--coordinator")
        ->description(
            "run the renders on this coordinator, host:port (default: embedded, in this "
            "process; ALIQUOT_COORDINATOR is not read here)");
    cmd->add_option("--out", c->out, "output directory (default out/study-NAME-SCALE)");
    cmd->add_option("--threads", c->threads, "embedded tracing threads (0: all cores)")
        ->check(whole_number());
    cmd->add_flag("--no-report", c->no_report,
                  "record the renders only, write no report");
    cmd->callback([c] { c->run(); });
}

}  // namespace aliquot::cli
