#include "log_format_option.h"

#include <grpc/support/log.h>

#include <cstring>

#include "log_line.h"

namespace aliquot::cli {

namespace {

// gRPC core's own lines (a failed TLS handshake, a connection reset) in the process's
// format, instead of its "E1204 12:00:00.000 ..." lines among ours. gRPC calls this only
// for lines at or above GRPC_VERBOSITY (ERROR unless set), from any thread.
void log_grpc_line(gpr_log_func_args* args) {
    const char* severity = args->severity == GPR_LOG_SEVERITY_ERROR  ? "error"
                           : args->severity == GPR_LOG_SEVERITY_INFO ? "info"
                                                                     : "debug";
    const char* file = args->file ? args->file : "";
    // The file's own name: gRPC passes its source path.
    if (const char* slash = std::strrchr(file, '/')) file = slash + 1;
    write_log_warning(
        "grpc", {log_text("severity", severity),
                 log_text("source", std::string(file) + ":" + std::to_string(args->line)),
                 log_text("message", args->message ? args->message : "")});
}

}  // namespace

void add_log_format_option(CLI::App& command) {
    // Before the option is read: text unless --log-format says otherwise; gRPC's lines
    // from then on in the same format.
    command.preparse_callback([](size_t) {
        set_log_format(LogFormat::Text);
        gpr_set_log_function(log_grpc_line);
    });
    command
        .add_option_function<std::string>(
            "--log-format",
            [](const std::string& value) { set_log_format(*parse_log_format(value)); },
            "log lines on stderr: text (for people) or json (one object a line, for a "
            "log collector)")
        ->check(CLI::IsMember({"text", "json"}))
        ->default_str("text");
}

}  // namespace aliquot::cli
