// Wavefront OBJ reader: positions and faces only, with errors that name the file and
// line.
#include "obj_loader.h"

#include <charconv>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

#include "scene_loader.h"

namespace aliquot {
namespace {

std::vector<std::string_view> split_words(std::string_view line) {
    std::vector<std::string_view> words;
    size_t i = 0;
    while (i < line.size()) {
        while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
        const size_t start = i;
        while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
        if (i > start) words.push_back(line.substr(start, i - start));
    }
    return words;
}

// from_chars is locale-independent (strtod is not) but rejects a leading '+',
// which some exporters write.
template <typename T>
bool parse_whole(std::string_view word, T& out) {
    if (!word.empty() && word[0] == '+') word.remove_prefix(1);
    const char* end = word.data() + word.size();
    auto [ptr, ec] = std::from_chars(word.data(), end, out);
    return ec == std::errc() && ptr == end;
}

// Messages name the line and what was expected, never the text found there: a mesh may
// be any file its path names, and its content must not travel in an error.
class ObjParser {
public:
    explicit ObjParser(const std::string& origin) : origin_(origin) {}

    ObjMesh parse(std::string_view text) {
        size_t pos = 0;
        while (pos <= text.size()) {
            size_t eol = text.find('\n', pos);
            if (eol == std::string_view::npos) eol = text.size();
            ++line_number_;
            parse_line(text.substr(pos, eol - pos));
            pos = eol + 1;
        }
        if (mesh_.triangles.empty()) fail_at_file("no faces (expected \"f\" lines)");
        return std::move(mesh_);
    }

private:
    [[noreturn]] void fail(const std::string& what) const {
        throw SceneError(origin_ + ":" + std::to_string(line_number_) + ": " + what);
    }
    [[noreturn]] void fail_at_file(const std::string& what) const {
        throw SceneError(origin_ + ": " + what);
    }

    void parse_line(std::string_view line) {
        if (const size_t hash = line.find('#'); hash != std::string_view::npos)
            line = line.substr(0, hash);
        if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
        const auto words = split_words(line);
        if (words.empty()) return;
        if (words[0] == "v") parse_vertex(words);
        if (words[0] == "f") parse_face(words);
    }

    void parse_vertex(const std::vector<std::string_view>& words) {
        // An optional w, or per-vertex colours some exporters append, follow x y z.
        if (words.size() < 4) fail("expected \"v x y z\"");
        std::array<double, 3> p{};
        for (int i = 0; i < 3; ++i) {
            if (!parse_whole(words[i + 1], p[i]) || !std::isfinite(p[i]))
                fail("expected a finite number as coordinate " + std::to_string(i + 1) +
                     " of the vertex");
        }
        if (mesh_.positions.size() == std::numeric_limits<uint32_t>::max())
            fail("too many vertices");
        mesh_.positions.push_back(p);
    }

    uint32_t vertex_index(std::string_view word, size_t corner) const {
        // Texture and normal indices ("i/t", "i//n", "i/t/n") are not needed.
        const std::string_view first = word.substr(0, word.find('/'));
        long long index = 0;
        if (!parse_whole(first, index) || index == 0)
            fail("expected a vertex index (non-zero integer) as corner " +
                 std::to_string(corner) + " of the face");
        const long long count = static_cast<long long>(mesh_.positions.size());
        const long long resolved =
            index > 0 ? index - 1 : count + index;  // negative: relative
        if (resolved < 0 || resolved >= count)
            fail("vertex index " + std::to_string(index) + " out of range (" +
                 std::to_string(count) + " vertices defined so far)");
        return static_cast<uint32_t>(resolved);
    }

    void parse_face(const std::vector<std::string_view>& words) {
        if (words.size() < 4) fail("expected a face with at least 3 vertices");
        std::vector<uint32_t> corners;
        for (size_t i = 1; i < words.size(); ++i)
            corners.push_back(vertex_index(words[i], i));
        for (size_t i = 1; i + 1 < corners.size(); ++i)
            mesh_.triangles.push_back({corners[0], corners[i], corners[i + 1]});
    }

    const std::string& origin_;
    int line_number_ = 0;
    ObjMesh mesh_;
};

}  // namespace

ObjMesh parse_obj(std::string_view text, const std::string& origin) {
    return ObjParser(origin).parse(text);
}

ObjMesh load_obj(const std::filesystem::path& file) {
    const std::string origin = file.string();
    std::ifstream in(file, std::ios::binary);
    if (!in || std::filesystem::is_directory(file))
        throw SceneError(origin + ": cannot open file");
    std::ostringstream text;
    text << in.rdbuf();
    return parse_obj(text.str(), origin);
}

}  // namespace aliquot
