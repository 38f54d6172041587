#include "log_format_option.h"

#include "log_line.h"

namespace aliquot::cli {

void add_log_format_option(CLI::App& command) {
    // Before the option is read: text unless --log-format says otherwise.
    command.preparse_callback([](size_t) { set_log_format(LogFormat::Text); });
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
