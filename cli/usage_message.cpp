#include "usage_message.h"

#include <algorithm>

#include "near_miss.h"

namespace aliquot::cli {

namespace {

std::vector<std::string> command_names(const CLI::App& app) {
    std::vector<std::string> names;
    for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; }))
        names.push_back(sub->get_name());
    return names;
}

std::string join(const std::vector<std::string>& words) {
    std::string s;
    for (const std::string& w : words) s += (s.empty() ? "" : ", ") + w;
    return s;
}

// Every spelling of the command's options, "--spp" and "-h" alike.
std::vector<std::string> option_names(const CLI::App& command) {
    std::vector<std::string> names;
    for (const CLI::Option* o : command.get_options()) {
        for (const std::string& l : o->get_lnames()) names.push_back("--" + l);
        for (const std::string& s : o->get_snames()) names.push_back("-" + s);
    }
    return names;
}

}  // namespace

std::string unknown_command(const CLI::App& app, const std::string& word) {
    const std::vector<std::string> names = command_names(app);
    if (std::find(names.begin(), names.end(), word) != names.end()) return "";
    const std::string near = closest(word, names);
    if (!near.empty())
        return "unknown command '" + word + "'; did you mean '" + near + "'?";
    return "unknown command '" + word + "'; the commands are " + join(names) +
           " (aliquot --help says what each does)";
}

std::string parse_error_message(const CLI::App& app, const CLI::ParseError& e) {
    const std::vector<CLI::App*> chosen = app.get_subcommands();
    const CLI::App& command = chosen.empty() ? app : *chosen.front();
    const std::string prefix = chosen.empty() ? "" : command.get_name() + ": ";
    const std::string help =
        chosen.empty() ? "aliquot --help" : "aliquot " + command.get_name() + " --help";
    // CLI11 lists the words it could not place, values and options mixed, in no useful
    // order, and before a command is chosen says only that one is required; an unknown
    // option is what the user can fix.
    for (const std::string& word : command.remaining()) {
        if (word.size() < 2 || word[0] != '-') continue;
        const std::string option = word.substr(0, word.find('='));
        const std::string near = closest(option, option_names(command));
        return prefix + "unknown option " + option +
               (near.empty() ? "" : "; did you mean " + near + "?") + " (" + help +
               " lists the options)";
    }
    if (chosen.empty())
        return "a command is required: " + join(command_names(app)) +
               " (aliquot --help says what each does)";
    if (dynamic_cast<const CLI::ExtrasError*>(&e) && !command.remaining().empty())
        return prefix + "unexpected argument '" + command.remaining().front() + "'";
    return prefix + e.what();
}

}  // namespace aliquot::cli
