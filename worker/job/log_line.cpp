#include "log_line.h"

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>

namespace aliquot {

namespace {

std::atomic<LogFormat> g_format{LogFormat::None};

// The length of the UTF-8 sequence starting at s[i], or 0 when it is not one.
size_t utf8_length(std::string_view s, size_t i) {
    const auto byte = [&](size_t k) { return static_cast<unsigned char>(s[k]); };
    const unsigned char c = byte(i);
    size_t n = c < 0x80           ? 1
               : (c >> 5) == 0x6  ? 2
               : (c >> 4) == 0xE  ? 3
               : (c >> 3) == 0x1E ? 4
                                  : 0;
    if (n == 0 || i + n > s.size()) return 0;
    for (size_t k = 1; k < n; ++k)
        if ((byte(i + k) & 0xC0) != 0x80) return 0;
    if (n == 2 && c < 0xC2) return 0;  // overlong
    return n;
}

// A JSON string's body: quotes, backslashes and control characters escaped, bytes that
// are not UTF-8 replaced by U+FFFD.
void append_escaped(std::string& out, std::string_view s) {
    for (size_t i = 0; i < s.size();) {
        const unsigned char c = static_cast<unsigned char>(s[i]);
        const size_t n = utf8_length(s, i);
        if (n == 0) {
            out += "\\ufffd";
            ++i;
            continue;
        }
        if (n > 1) {
            out.append(s.substr(i, n));
            i += n;
            continue;
        }
        ++i;
        switch (c) {
            case '"':
                out += "\\\"";
                break;
            case '\\':
                out += "\\\\";
                break;
            case '\n':
                out += "\\n";
                break;
            case '\r':
                out += "\\r";
                break;
            case '\t':
                out += "\\t";
                break;
            default:
                if (c < 0x20 || c == 0x7F) {
                    char hex[8];
                    std::snprintf(hex, sizeof hex, "\\u%04x", c);
                    out += hex;
                } else {
                    out += char(c);
                }
        }
    }
}

bool needs_quotes(std::string_view s) {
    if (s.empty()) return true;
    for (const char ch : s) {
        const unsigned char c = static_cast<unsigned char>(ch);
        if (c <= 0x20 || c == 0x7F || c >= 0x80 || c == '"' || c == '=' || c == '\\')
            return true;
    }
    return false;
}

std::string utc_time(int64_t unix_ms) {
    const std::time_t seconds = std::time_t(unix_ms / 1000);
    std::tm tm{};
    gmtime_r(&seconds, &tm);
    char text[40];
    std::snprintf(text, sizeof text, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ",
                  tm.tm_year + 1900, tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min,
                  tm.tm_sec, int(unix_ms % 1000));
    return text;
}

}  // namespace

bool printable_utf8(std::string_view text) {
    for (size_t i = 0; i < text.size();) {
        const size_t n = utf8_length(text, i);
        if (n == 0) return false;
        const unsigned char c = static_cast<unsigned char>(text[i]);
        if (n == 1 && (c < 0x20 || c == 0x7F)) return false;
        // C1 controls, U+0080..U+009F, are 0xC2 0x80..0x9F.
        if (n == 2 && c == 0xC2 && static_cast<unsigned char>(text[i + 1]) < 0xA0)
            return false;
        i += n;
    }
    return true;
}

std::optional<LogFormat> parse_log_format(std::string_view text) {
    if (text == "text") return LogFormat::Text;
    if (text == "json") return LogFormat::Json;
    return std::nullopt;
}

LogField log_text(std::string key, std::string value) {
    return {std::move(key), std::move(value), false};
}

LogField log_number(std::string key, double value) {
    if (!std::isfinite(value)) return {std::move(key), "null", true};
    char text[32];
    std::snprintf(text, sizeof text, "%.6g", value);
    return {std::move(key), text, true};
}

LogField log_number(std::string key, int64_t value) {
    return {std::move(key), std::to_string(value), true};
}

std::string format_log_line(LogFormat format, int64_t unix_ms, std::string_view event,
                            const LogFields& fields) {
    std::string line;
    if (format == LogFormat::Json) {
        line = "{\"time\":\"" + utc_time(unix_ms) + "\",\"event\":\"";
        append_escaped(line, event);
        line += '"';
        for (const LogField& f : fields) {
            line += ",\"";
            append_escaped(line, f.key);
            line += "\":";
            if (f.number) {
                line += f.value;
            } else {
                line += '"';
                append_escaped(line, f.value);
                line += '"';
            }
        }
        line += '}';
        return line;
    }
    line = utc_time(unix_ms) + ' ';
    append_escaped(line, event);
    for (const LogField& f : fields) {
        line += ' ';
        append_escaped(line, f.key);
        line += '=';
        if (f.number || !needs_quotes(f.value)) {
            append_escaped(line, f.value);
        } else {
            line += '"';
            append_escaped(line, f.value);
            line += '"';
        }
    }
    return line;
}

void set_log_format(LogFormat format) { g_format = format; }

LogFormat log_format() { return g_format; }

namespace {

// One line (with its newline, in one write) to stderr, stamped now.
void write_line(LogFormat format, std::string_view event, const LogFields& fields) {
    const int64_t now = std::chrono::duration_cast<std::chrono::milliseconds>(
                            std::chrono::system_clock::now().time_since_epoch())
                            .count();
    const std::string line = format_log_line(format, now, event, fields) + '\n';
    std::fwrite(line.data(), 1, line.size(), stderr);
}

}  // namespace

void write_log_line(std::string_view event, const LogFields& fields) {
    if (g_format != LogFormat::None) write_line(g_format, event, fields);
}

void write_log_warning(std::string_view event, const LogFields& fields) {
    // The process's format stays None: its other lines stay off (render's own output).
    const LogFormat format = g_format;
    write_line(format == LogFormat::None ? LogFormat::Text : format, event, fields);
}

}  // namespace aliquot
