// One line on stderr for what the farm cannot do and goes on without (a write that
// failed, a render that cannot resume, a listener gone deaf), in the process's log format
// (log_line.h: `--log-format text|json`), and as text in a process that chose none.
#pragma once

#include <string>
#include <string_view>

#include "log_line.h"

namespace aliquot {

inline void log_farm_error(const std::string& what,
                           std::string_view event = "coordinator_error") {
    write_log_warning(event, {log_text("message", what)});
}

}  // namespace aliquot
