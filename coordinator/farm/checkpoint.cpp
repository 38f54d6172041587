#include "checkpoint.h"

#include <cstring>
#include <fstream>
#include <string>
#include <type_traits>

#include "bands.h"

namespace aliquot {

namespace {

// Version 2 adds the round planned ahead after the pixels, version 3 the first-hit sums
// after it (a byte, 1 when they follow); the files of 1 and 2 (written before, with
// neither) still load, as renders without them.
constexpr char kMagic[8] = {'A', 'L', 'Q', 'C', 'K', 'P', 'T', '3'};
constexpr char kMagicV2[8] = {'A', 'L', 'Q', 'C', 'K', 'P', 'T', '2'};
constexpr char kMagicV1[8] = {'A', 'L', 'Q', 'C', 'K', 'P', 'T', '1'};
static_assert(std::is_trivially_copyable_v<PixelSums>);
static_assert(std::is_trivially_copyable_v<FirstHitSums>);

template <typename T>
void put(std::ofstream& out, const T& v) {
    out.write(reinterpret_cast<const char*>(&v), sizeof v);
}
template <typename T>
void get(std::ifstream& in, T& v) {
    in.read(reinterpret_cast<char*>(&v), sizeof v);
}

}  // namespace

namespace {

// What a file is written from: a Checkpoint's accumulator or a snapshot's copy, read in
// place.
struct Written {
    uint32_t width = 0, height = 0;
    const PixelSums* sums = nullptr;           // width x height
    const FirstHitSums* first_hits = nullptr;  // width x height, or none
    const nlohmann::json& strategy_state;
    uint32_t rounds_done = 0;
    double seconds = 0;
    const std::vector<uint32_t>& planned_round;
};

void write_checkpoint_file(const std::filesystem::path& tmp, const Written& cp) {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error("cannot write checkpoint " + tmp.string());
    out.write(kMagic, sizeof kMagic);
    put(out, cp.width);
    put(out, cp.height);
    put(out, cp.rounds_done);
    put(out, cp.seconds);
    const std::string state = cp.strategy_state.dump();
    put(out, uint64_t(state.size()));
    out.write(state.data(), std::streamsize(state.size()));
    const size_t n = size_t(cp.width) * cp.height;
    // The pixels as they lie in memory, in one write: put() per pixel spent ~20 ns each
    // (2 M calls at 1920x1080) on the round end's cores. The same bytes.
    if (n > 0)
        out.write(reinterpret_cast<const char*>(cp.sums),
                  std::streamsize(n * sizeof(PixelSums)));
    put(out, uint64_t(cp.planned_round.size()));
    if (!cp.planned_round.empty())
        out.write(reinterpret_cast<const char*>(cp.planned_round.data()),
                  std::streamsize(cp.planned_round.size() * sizeof(uint32_t)));
    put(out, uint8_t(cp.first_hits != nullptr));
    if (cp.first_hits && n > 0)
        out.write(reinterpret_cast<const char*>(cp.first_hits),
                  std::streamsize(n * sizeof(FirstHitSums)));
    out.flush();
    if (!out) throw std::runtime_error("cannot write checkpoint " + tmp.string());
}

void save(const std::filesystem::path& path, const Written& cp) {
    const std::filesystem::path tmp = path.string() + ".tmp";
    try {
        write_checkpoint_file(tmp, cp);
        // A render's buffers are its user's: 0600 whatever the umask (docs/SECURITY.md).
        std::filesystem::permissions(tmp, std::filesystem::perms::owner_read |
                                              std::filesystem::perms::owner_write);
        std::filesystem::rename(tmp, path);
    } catch (...) {
        // A half-written temp file on a full disk holds the space the next try needs.
        std::error_code ignored;
        std::filesystem::remove(tmp, ignored);
        throw;
    }
}

// The first-hit sums to write: a render's that keeps them, of the image's size.
const FirstHitSums* first_hits_of(const AuxSums& aux, uint32_t width, uint32_t height) {
    const bool kept = aux.kept() && aux.width() == width && aux.height() == height &&
                      uint64_t(width) * height > 0;
    return kept ? &aux.at(0) : nullptr;
}

}  // namespace

void CheckpointSnapshot::copy_buffers(const Accumulator& merged, const AuxSums& kept) {
    width = merged.width();
    height = merged.height();
    sums.resize(merged.pixel_count());
    // PixelSums is trivially copyable: a band is one memcpy from the accumulator's
    // contiguous sums.
    for_each_band(sums.size(), kBandPixels, [&](size_t, size_t begin, size_t end) {
        std::memcpy(&sums[begin], &merged.at(begin), (end - begin) * sizeof(PixelSums));
    });
    aux = kept;  // reuses the memory; empty unless kept
}

void save_checkpoint(const std::filesystem::path& path, const CheckpointSnapshot& cp) {
    if (cp.sums.size() != size_t(cp.width) * cp.height)
        throw std::runtime_error("checkpoint snapshot of " + std::to_string(cp.width) +
                                 "x" + std::to_string(cp.height) + " holds " +
                                 std::to_string(cp.sums.size()) + " pixels");
    save(path,
         {cp.width, cp.height, cp.sums.data(), first_hits_of(cp.aux, cp.width, cp.height),
          cp.strategy_state, cp.rounds_done, cp.seconds, cp.planned_round});
}

void save_checkpoint(const std::filesystem::path& path, const Checkpoint& cp) {
    const uint32_t w = cp.merged.width(), h = cp.merged.height();
    save(path, {w, h, cp.merged.pixel_count() > 0 ? &cp.merged.at(0) : nullptr,
                first_hits_of(cp.aux, w, h), cp.strategy_state, cp.rounds_done,
                cp.seconds, cp.planned_round});
}

double expected_checkpoint_seconds(uint64_t pixels, bool first_hits) {
    const double bytes = double(pixels) * double(sizeof(PixelSums) +
                                                 (first_hits ? sizeof(FirstHitSums) : 0));
    return bytes / kFirstCheckpointBytesPerSecond;
}

bool checkpoint_due(double since_last_seconds, double last_cost_seconds) {
    return since_last_seconds >= kCheckpointShare * last_cost_seconds;
}

std::optional<Checkpoint> load_checkpoint(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) return std::nullopt;
    char magic[8];
    in.read(magic, sizeof magic);
    const bool v1 = in && std::memcmp(magic, kMagicV1, sizeof magic) == 0;
    const bool v2 = in && std::memcmp(magic, kMagicV2, sizeof magic) == 0;
    if (!in || (!v1 && !v2 && std::memcmp(magic, kMagic, sizeof magic) != 0))
        throw std::runtime_error("checkpoint " + path.string() + " is not a checkpoint");
    uint32_t width = 0, height = 0;
    Checkpoint cp;
    get(in, width);
    get(in, height);
    get(in, cp.rounds_done);
    get(in, cp.seconds);
    uint64_t state_size = 0;
    get(in, state_size);
    // Nothing is taken for more than the file holds: a damaged size must not ask for
    // gigabytes (a 65536x65536 image's pixels, a state of 1 GB) before the read fails.
    std::error_code error;
    const uint64_t file_size = std::filesystem::file_size(path, error);
    const uint64_t header = sizeof kMagic + 2 * sizeof(uint32_t) + sizeof cp.rounds_done +
                            sizeof cp.seconds + sizeof state_size;
    const uint64_t left = !error && file_size > header ? file_size - header : 0;
    if (!in || state_size > (uint64_t(1) << 30) || width > 65536 || height > 65536 ||
        state_size > left ||
        uint64_t(width) * height * sizeof(PixelSums) > left - state_size)
        throw std::runtime_error("checkpoint " + path.string() + " is damaged");
    std::string state(state_size, '\0');
    in.read(state.data(), std::streamsize(state_size));
    cp.strategy_state = nlohmann::json::parse(state);
    // Restored by merging into a fresh accumulator: 0 + x == x exactly, and the totals
    // are recomputed on the way.
    SampleJobResult all;
    all.rect = {0, 0, width, height};
    all.pixels.resize(size_t(width) * height);
    for (PixelSums& p : all.pixels) get(in, p);
    uint64_t planned = 0;
    if (!v1) get(in, planned);
    if (!in) throw std::runtime_error("checkpoint " + path.string() + " is truncated");
    // A round planned ahead covers the image, or there is none.
    if (planned != 0 && planned != all.pixels.size())
        throw std::runtime_error("checkpoint " + path.string() + " is damaged");
    cp.planned_round.resize(planned);
    in.read(reinterpret_cast<char*>(cp.planned_round.data()),
            std::streamsize(planned * sizeof(uint32_t)));
    if (!in) throw std::runtime_error("checkpoint " + path.string() + " is truncated");
    uint8_t aux = 0;
    if (!v1 && !v2) get(in, aux);
    if (!in || aux > 1)
        throw std::runtime_error("checkpoint " + path.string() + " is damaged");
    if (aux) {
        all.first_hits.resize(all.pixels.size());
        for (FirstHitSums& f : all.first_hits) get(in, f);
        if (!in)
            throw std::runtime_error("checkpoint " + path.string() + " is truncated");
        cp.aux = AuxSums(width, height);
    }
    cp.merged = Accumulator(width, height);
    // Checked as a worker's result is: sums a damaged file made non-finite or larger
    // than their samples allow are refused (MergeError), and the render does not resume.
    merge_with_aux(cp.merged, cp.aux, all);
    return cp;
}

}  // namespace aliquot
