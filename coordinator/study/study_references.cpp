#include "study_references.h"

#include <cctype>
#include <cstdio>

#include "child_process.h"
#include "exr_io.h"
#include "render_spec.h"
#include "scene_loader.h"
#include "sigma_map.h"

namespace aliquot {

namespace fs = std::filesystem;

namespace {

// Runs this binary with `args` and waits; the child's stderr (its progress bar) stays
// ours.
void run_self(const std::vector<std::string>& args, const std::string& what) {
    std::vector<std::string> argv = {fs::read_symlink("/proc/self/exe").string()};
    argv.insert(argv.end(), args.begin(), args.end());
    const int status = run_process(argv);
    if (status == 127) throw StudyError("cannot start " + what);
    if (status != 0) throw StudyError(what + " failed");
}

}  // namespace

std::string safe_file_name(const std::string& s) {
    std::string out;
    for (char c : s)
        out += (std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '.')
                   ? c
                   : '_';
    return out;
}

std::string reference_key(const StudyRender& r) {
    return r.scene + "|" + std::to_string(r.width) + "x" + std::to_string(r.height);
}

std::string resolve_scene(const std::string& scene, const fs::path& study_file) {
    if (builtin_scene_json(scene)) return scene;
    const fs::path p(scene);
    if (p.is_relative() && !fs::exists(p) && fs::exists(study_file.parent_path() / p))
        return (study_file.parent_path() / p).string();
    return scene;
}

StudyReferences prepare_references(const std::vector<StudyRender>& renders,
                                   const fs::path& study_file, const fs::path& dir,
                                   uint64_t spp, int threads) {
    StudyReferences references;
    for (const StudyRender& r : renders) {
        const std::string key = reference_key(r);
        if (references.count(key)) continue;
        const std::string scene = resolve_scene(r.scene, study_file);
        const std::string res = std::to_string(r.width) + "x" + std::to_string(r.height);
        StudyReference ref;
        // Named by the scene's content, not only its name: an edited scene file gets a
        // new reference instead of silently reusing the old one.
        ref.path = dir / (safe_file_name(fs::path(r.scene).stem().string()) + "-" +
                          scene_hash(self_contained_scene_json(scene)).substr(0, 12) +
                          "-" + res + "-" + std::to_string(spp) + "spp.exr");
        if (!fs::exists(ref.path)) {
            std::fprintf(stderr, "study: reference %s %s at %llu spp\n", r.scene.c_str(),
                         res.c_str(), (unsigned long long)spp);
            run_self({"reference", "--scene", scene, "--resolution", res, "--spp",
                      std::to_string(spp), "--threads", std::to_string(threads), "--out",
                      ref.path.string()},
                     "reference for " + r.scene + " " + res);
        }
        ref.image = read_exr(ref.path);
        references[key] = std::move(ref);
    }
    for (const StudyRender& r : renders) {
        StudyReference& ref = references.at(reference_key(r));
        if (r.strategy.method != "oracle" || ref.sigma) continue;
        const std::string scene = resolve_scene(r.scene, study_file);
        const std::string res = std::to_string(r.width) + "x" + std::to_string(r.height);
        fs::path path = ref.path;
        path.replace_extension(".sigma-seed" + std::to_string(kSigmaSeed) + ".exr");
        if (!fs::exists(path)) {
            std::fprintf(stderr, "study: oracle sigma %s %s at %llu spp\n",
                         r.scene.c_str(), res.c_str(), (unsigned long long)spp);
            const fs::path part = path.string() + ".part.exr";
            run_self(
                {"render", "--scene", scene, "--resolution", res, "--spp",
                 std::to_string(spp), "--seed", std::to_string(kSigmaSeed), "--threads",
                 std::to_string(threads), "--aovs", "--out", part.string()},
                "oracle sigma render for " + r.scene + " " + res);
            fs::rename(part, path);
        }
        try {
            ref.sigma = std::make_shared<const std::vector<float>>(
                per_sample_sigma(read_exr(path)));
        } catch (const std::exception& e) {
            throw StudyError("oracle sigma " + path.string() + ": " + e.what());
        }
    }
    return references;
}

}  // namespace aliquot
