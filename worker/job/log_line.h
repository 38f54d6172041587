// One line of a process's structured log on stderr: text for people (the default) or
// JSON for a log collector, chosen once by `--log-format` (`aliquot coordinator`,
// `aliquot worker`). The coordinator's render and worker events
// (coordinator/farm/render_events.h) and the worker's messages are written through it.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace aliquot {

// None: no lines at all, the default, so that a library or a command that renders in
// this process (render, bench, study) prints only its own output; `aliquot coordinator`
// and `aliquot worker` choose Text unless told json.
enum class LogFormat { None, Text, Json };

// "text" or "json".
std::optional<LogFormat> parse_log_format(std::string_view text);

// A field of a line: a string, or a number written as it is (`number`, already text).
struct LogField {
    std::string key;
    std::string value;
    bool number = false;
};
using LogFields = std::vector<LogField>;

LogField log_text(std::string key, std::string value);
LogField log_number(std::string key, double value);
LogField log_number(std::string key, int64_t value);

// Text:  2026-12-04T12:42:16.123Z round_ended render=r-000001 round=3 name="a b"
// JSON: {"time":"2026-12-04T12:42:16.123Z","event":"round_ended","render":"r-000001",...}
// A value with a space, '"', '=' or any control character is quoted in text; control
// characters and bytes that are not UTF-8 are escaped in both, so a name from the
// network can neither end a line nor forge one.
std::string format_log_line(LogFormat format, int64_t unix_ms, std::string_view event,
                            const LogFields& fields);

// Whether `text` is UTF-8 with no control characters (C0, DEL, C1): what a name people
// give (a render's) may be, so that it prints as it is everywhere.
bool printable_utf8(std::string_view text);

// The process's format; None until a command sets it.
void set_log_format(LogFormat format);
LogFormat log_format();
// Writes one line (with its newline, in one write) to stderr, stamped now.
void write_log_line(std::string_view event, const LogFields& fields);
// A line that must be seen whatever the command (a failure or warning: a write that
// failed, a listener that went deaf, Embree's errors): as write_log_line does, and as
// text where no format was chosen, where it would otherwise be lost.
void write_log_warning(std::string_view event, const LogFields& fields);

}  // namespace aliquot
