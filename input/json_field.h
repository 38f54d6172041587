// Reading JSON that users hand us (scenes, studies, strategy parameters): a JsonField is
// a value together with its JSON pointer, so every check can say where it failed.
#pragma once

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

namespace aliquot {

// A mistake in a JSON document. what() reads "/renders/0/resolution: expected ...", or
// the reason alone for text that is not JSON at all (no value to point at). Callers
// prefix it with the document's name.
class JsonError : public std::runtime_error {
public:
    JsonError(std::optional<std::string> pointer, std::string reason);
    // RFC 6901; "" is the root (printed as "/"). Empty for a syntax error.
    const std::optional<std::string>& pointer() const { return pointer_; }
    const std::string& reason() const { return reason_; }

private:
    std::optional<std::string> pointer_;
    std::string reason_;
};

// Parses JSON text, refusing duplicate keys: nlohmann keeps the last one silently, and
// like a misspelt key a duplicate is a mistake the author should hear about. Throws
// JsonError.
nlohmann::json parse_json(std::string_view text);

// How deeply arrays and objects may nest; parse_json refuses deeper text. No document
// of ours comes near it, and it bounds JsonDocument's recursion.
inline constexpr int kMaxJsonDepth = 256;

// A document parsed as parse_json does, whose tree is taken apart without allocating
// when it goes. nlohmann's destructor moves a tree's values onto a heap-allocated stack
// (to bound recursion), and it is noexcept: when memory has run out, that allocation
// aborts the process. A document from the network is held in this instead; out of
// memory while parsing, it throws std::bad_alloc and leaves nothing behind.
class JsonDocument {
public:
    explicit JsonDocument(std::string_view text);  // throws JsonError, std::bad_alloc
    ~JsonDocument();
    JsonDocument(const JsonDocument&) = delete;
    JsonDocument& operator=(const JsonDocument&) = delete;
    const nlohmann::json& root() const { return root_; }

private:
    nlohmann::json root_;
};

// A value inside a parsed document and its pointer. It refers to the document, which
// must outlive it.
class JsonField {
public:
    explicit JsonField(const nlohmann::json& value, std::string pointer = "")
        : value_(&value), pointer_(std::move(pointer)) {}

    const nlohmann::json& value() const { return *value_; }
    const std::string& pointer() const { return pointer_; }
    [[noreturn]] void fail(const std::string& reason) const;

    // Members and elements, each knowing its own pointer.
    std::optional<JsonField> find(std::string_view key) const;
    bool has(std::string_view key) const { return find(key).has_value(); }
    JsonField require(std::string_view key) const;  // fails here: missing key "KEY"
    JsonField at(size_t index) const;
    size_t size() const { return value_->size(); }
    std::vector<std::pair<std::string, JsonField>> members() const;

    // A misspelt key would otherwise be ignored silently and its default used.
    void allow_keys(const std::vector<std::string>& allowed) const;
    void expect_object(const std::string& expected = "expected an object") const;
    void expect_array(const std::string& expected = "expected an array") const;

    // Typed getters: each fails at this field, with `expected` as the reason.
    std::string string(const std::string& expected = "expected a string") const;
    // A finite number.
    double number(const std::string& expected = "expected a number") const;
    // A whole number in [min, max]; 16.0 counts (clients that only have doubles send it),
    // -1 or 2.5 do not (nlohmann would convert them to an unsigned silently).
    uint64_t whole(uint64_t min = 0, uint64_t max = UINT64_MAX) const;

private:
    const nlohmann::json* value_;
    std::string pointer_;
};

// RFC 6901: '~' and '/' inside a key are escaped so the pointer stays unambiguous.
std::string json_pointer_token(std::string_view key);

}  // namespace aliquot
