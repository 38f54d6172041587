#include "name_option.h"

#include "render_spec.h"

namespace aliquot::cli {

void add_name_option(CLI::App& command, std::string& name, const std::string& shown_by) {
    command
        .add_option("--name", name,
                    "a name for people, shown by " + shown_by + " (at most " +
                        std::to_string(kMaxRenderName) + " bytes, no control characters)")
        ->check([](const std::string& value) { return render_name_error(value); });
}

}  // namespace aliquot::cli
