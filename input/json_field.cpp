#include "json_field.h"

#include <algorithm>
#include <cmath>
#include <set>

namespace aliquot {

using nlohmann::json;

namespace {

std::string what_of(const std::optional<std::string>& pointer,
                    const std::string& reason) {
    if (!pointer) return reason;
    return (pointer->empty() ? "/" : *pointer) + ": " + reason;
}

std::string in_quotes(std::string_view s) {
    std::string out(1, '"');
    out.append(s).push_back('"');
    return out;
}

std::string without_exception_id(const std::string& what) {
    const size_t end = what.find("] ");
    return end == std::string::npos ? what : what.substr(end + 2);
}

// Follows the parse to know the pointer of the object being read when a key repeats.
class DuplicateKeyCheck {
public:
    bool operator()(int, json::parse_event_t event, json& parsed) {
        switch (event) {
            case json::parse_event_t::object_start:
            case json::parse_event_t::array_start:
                if (frames_.size() == size_t(kMaxJsonDepth))
                    throw JsonError(pointer_to_open(), "nested deeper than " +
                                                           std::to_string(kMaxJsonDepth));
                frames_.emplace_back().array = event == json::parse_event_t::array_start;
                break;
            case json::parse_event_t::key: {
                Frame& f = frames_.back();
                f.key = parsed.get<std::string>();
                if (!f.keys.insert(f.key).second)
                    throw JsonError(pointer(), "duplicate key " + in_quotes(f.key));
                break;
            }
            case json::parse_event_t::object_end:
            case json::parse_event_t::array_end:
                frames_.pop_back();
                [[fallthrough]];
            case json::parse_event_t::value:
                if (!frames_.empty() && frames_.back().array) ++frames_.back().index;
                break;
        }
        return true;
    }

private:
    struct Frame {
        bool array = false;
        size_t index = 0;
        std::string key;
        std::set<std::string> keys;
    };
    // The pointer of the innermost open object.
    std::string pointer() const { return pointer_of(frames_.size() - 1); }
    // The pointer of the value being opened, inside every open frame.
    std::string pointer_to_open() const { return pointer_of(frames_.size()); }
    std::string pointer_of(size_t frames) const {
        std::string out;
        for (size_t i = 0; i < frames; ++i) {
            out += '/';
            out += frames_[i].array ? std::to_string(frames_[i].index)
                                    : json_pointer_token(frames_[i].key);
        }
        return out;
    }

    std::vector<Frame> frames_;
};

// Empties `value` from the leaves up, so that no container is destroyed with anything
// in it: nlohmann's destructor then has nothing to move onto its stack and allocates
// nothing. The recursion is as deep as the document, at most kMaxJsonDepth.
void take_apart(json& value) noexcept {
    if (value.is_array()) {
        json::array_t& array = *value.get_ptr<json::array_t*>();
        while (!array.empty()) {
            take_apart(array.back());
            array.pop_back();
        }
    } else if (value.is_object()) {
        json::object_t& object = *value.get_ptr<json::object_t*>();
        while (!object.empty()) {
            const auto last = std::prev(object.end());
            take_apart(last->second);
            object.erase(last);
        }
    }
}

// Parses `text` into `root`, which the caller owns: on an error it holds what was built
// so far, for the caller to take apart. nlohmann's json::parse builds into a value of its
// own, destroyed inside it when the parse throws; its DOM builder is driven here instead.
// Throws JsonError for text that is not JSON, or std::bad_alloc.
void parse_into(std::string_view text, json& root) {
    try {
        nlohmann::detail::json_sax_dom_callback_parser<json> builder(root,
                                                                     DuplicateKeyCheck());
        json::sax_parse(text.begin(), text.end(), &builder);
    } catch (const json::parse_error& e) {
        // nlohmann's message reads "... parse error at line L, column C: reason".
        const std::string what = e.what();
        if (const size_t at = what.find("at line "); at != std::string::npos)
            throw JsonError(std::nullopt, "invalid JSON " + what.substr(at));
        throw JsonError(std::nullopt, "invalid JSON at byte " + std::to_string(e.byte) +
                                          ": " + without_exception_id(what));
    } catch (const json::exception& e) {  // e.g. a number too large for a double
        throw JsonError(std::nullopt, "invalid JSON: " + without_exception_id(e.what()));
    }
}

}  // namespace

JsonError::JsonError(std::optional<std::string> pointer, std::string reason)
    : std::runtime_error(what_of(pointer, reason)),
      pointer_(std::move(pointer)),
      reason_(std::move(reason)) {}

json parse_json(std::string_view text) {
    json root;
    try {
        parse_into(text, root);
    } catch (...) {
        take_apart(root);
        throw;
    }
    return root;
}

JsonDocument::JsonDocument(std::string_view text) {
    try {
        parse_into(text, root_);
    } catch (...) {
        take_apart(root_);  // what was built before the error
        throw;
    }
}

JsonDocument::~JsonDocument() { take_apart(root_); }

std::string json_pointer_token(std::string_view key) {
    std::string out;
    for (char c : key) {
        if (c == '~')
            out += "~0";
        else if (c == '/')
            out += "~1";
        else
            out += c;
    }
    return out;
}

void JsonField::fail(const std::string& reason) const {
    throw JsonError(pointer_, reason);
}

std::optional<JsonField> JsonField::find(std::string_view key) const {
    if (!value_->is_object()) return std::nullopt;
    const auto it = value_->find(std::string(key));
    if (it == value_->end()) return std::nullopt;
    return JsonField(*it, pointer_ + "/" + json_pointer_token(key));
}

JsonField JsonField::require(std::string_view key) const {
    if (auto field = find(key)) return *field;
    fail("missing key " + in_quotes(key));
}

JsonField JsonField::at(size_t index) const {
    return JsonField((*value_)[index], pointer_ + "/" + std::to_string(index));
}

std::vector<std::pair<std::string, JsonField>> JsonField::members() const {
    std::vector<std::pair<std::string, JsonField>> out;
    for (const auto& [key, v] : value_->items())
        out.emplace_back(key, JsonField(v, pointer_ + "/" + json_pointer_token(key)));
    return out;
}

void JsonField::allow_keys(const std::vector<std::string>& allowed) const {
    for (const auto& [key, field] : members()) {
        if (std::find(allowed.begin(), allowed.end(), key) != allowed.end()) continue;
        std::string list;
        for (const std::string& a : allowed) list += (list.empty() ? "" : ", ") + a;
        field.fail("unknown key (expected " + list + ")");
    }
}

void JsonField::expect_object(const std::string& expected) const {
    if (!value_->is_object()) fail(expected);
}

void JsonField::expect_array(const std::string& expected) const {
    if (!value_->is_array()) fail(expected);
}

std::string JsonField::string(const std::string& expected) const {
    if (!value_->is_string()) fail(expected);
    return value_->get<std::string>();
}

double JsonField::number(const std::string& expected) const {
    if (!value_->is_number() || !std::isfinite(value_->get<double>())) fail(expected);
    return value_->get<double>();
}

uint64_t JsonField::whole(uint64_t min, uint64_t max) const {
    const json& v = *value_;
    bool ok = false;
    uint64_t value = 0;
    if (v.is_number_unsigned()) {
        value = v.get<uint64_t>();
        ok = true;
    } else if (v.is_number_integer()) {
        ok = v.get<int64_t>() >= 0;
        value = ok ? uint64_t(v.get<int64_t>()) : 0;
    } else if (v.is_number_float()) {
        const double d = v.get<double>();
        ok = d >= 0 && d == std::floor(d) && d < 0x1p64;
        value = ok ? uint64_t(d) : 0;
    }
    if (!ok || value < min || value > max)
        fail("expected a whole number " +
             (max == UINT64_MAX
                  ? "of at least " + std::to_string(min)
                  : "from " + std::to_string(min) + " to " + std::to_string(max)));
    return value;
}

}  // namespace aliquot
