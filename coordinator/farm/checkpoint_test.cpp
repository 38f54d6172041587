#include "checkpoint.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace aliquot {
namespace {

std::filesystem::path temp_file(const char* name) {
    return std::filesystem::temp_directory_path() /
           (std::string("aliquot-") + std::to_string(getpid()) + "-" + name);
}

TEST(Checkpoint, RestoresBuffersBitForBit) {
    Accumulator acc(3, 2);
    SampleJobResult r;
    r.rect = {0, 0, 3, 2};
    r.pixels.resize(6);
    for (size_t i = 0; i < 6; ++i) {
        r.pixels[i].even[0] = 0.1 * double(i) + 1e-17;
        r.pixels[i].odd[2] = 1.0 / 3.0 * double(i);
        r.pixels[i].samples = i + 1;
        r.pixels[i].rays = 5 * i;
    }
    acc.merge(r);
    const auto path = temp_file("cp.bin");
    save_checkpoint(path, {acc, {{"done_spp", 3}}, 4, 1.5, {}});
    const auto cp = load_checkpoint(path);
    ASSERT_TRUE(cp.has_value());
    EXPECT_EQ(cp->rounds_done, 4u);
    EXPECT_EQ(cp->strategy_state["done_spp"], 3);
    EXPECT_EQ(cp->merged.total_samples(), acc.total_samples());
    for (size_t i = 0; i < 6; ++i)
        EXPECT_EQ(std::memcmp(&cp->merged.at(i), &acc.at(i), sizeof(PixelSums)), 0);
    std::filesystem::remove(path);
}

TEST(Checkpoint, ARoundPlannedAheadRoundTripsAndAnOldFileHasNone) {
    Accumulator merged(3, 2);
    const auto path = temp_file("planned.bin");
    save_checkpoint(path, {merged, nlohmann::json::object(), 2, 1.0, {1, 0, 7, 3, 0, 2}});
    EXPECT_EQ(load_checkpoint(path)->planned_round,
              (std::vector<uint32_t>{1, 0, 7, 3, 0, 2}));
    // Version 1 (before the round planned ahead was kept): no count after the pixels,
    // and no first-hit byte after it (version 3's).
    save_checkpoint(path, {merged, nlohmann::json::object(), 2, 1.0, {}});
    std::string bytes;
    {
        std::ifstream in(path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), {});
    }
    ASSERT_EQ(bytes[7], '3');
    bytes[7] = '1';
    bytes.resize(bytes.size() - 1 - sizeof(uint64_t));
    std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
    const auto old = load_checkpoint(path);
    ASSERT_TRUE(old.has_value());
    EXPECT_EQ(old->rounds_done, 2u);
    EXPECT_TRUE(old->planned_round.empty());
    std::filesystem::remove(path);
}

TEST(Checkpoint, ARoundPlannedAheadThatIsNotTheImagesOrIsCutShortIsAnError) {
    Accumulator merged(3, 2);
    const auto path = temp_file("planned-bad.bin");
    save_checkpoint(path, {merged, nlohmann::json::object(), 2, 1.0, {1, 2, 3, 4, 5, 6}});
    std::string bytes;
    {
        std::ifstream in(path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), {});
    }
    // Cut inside the counts, then a count of one pixel too many.
    std::ofstream(path, std::ios::binary | std::ios::trunc)
        << bytes.substr(0, bytes.size() - 2);
    EXPECT_THROW(load_checkpoint(path), std::runtime_error);
    std::string wrong = bytes;
    const size_t count_at = bytes.size() - 1 - 6 * sizeof(uint32_t) - sizeof(uint64_t);
    const uint64_t seven = 7;
    wrong.replace(count_at, sizeof seven, reinterpret_cast<const char*>(&seven),
                  sizeof seven);
    std::ofstream(path, std::ios::binary | std::ios::trunc) << wrong;
    EXPECT_THROW(load_checkpoint(path), std::runtime_error);
    std::filesystem::remove(path);
}

TEST(Checkpoint, MissingIsNoneAndDamagedIsAnError) {
    EXPECT_FALSE(load_checkpoint(temp_file("none.bin")).has_value());
    const auto path = temp_file("bad.bin");
    std::ofstream(path) << "not a checkpoint";
    EXPECT_THROW(load_checkpoint(path), std::runtime_error);
    std::filesystem::remove(path);
}

// Issue 12, reproduction 2: a full disk left checkpoint.bin.tmp behind, holding the space
// the next try needed. /dev/full fails every write with ENOSPC, as a full disk does.
TEST(Checkpoint, AFailedWriteLeavesNoTempFileAndKeepsTheLastCheckpoint) {
    const auto path = temp_file("full.bin");
    const std::filesystem::path tmp = path.string() + ".tmp";
    Accumulator merged(64, 64);
    save_checkpoint(path, {merged, nlohmann::json::object(), 1, 0.5, {}});
    std::filesystem::create_symlink("/dev/full", tmp);
    EXPECT_THROW(save_checkpoint(path, {merged, nlohmann::json::object(), 2, 1.0, {}}),
                 std::runtime_error);
    EXPECT_FALSE(std::filesystem::exists(std::filesystem::symlink_status(tmp)));
    EXPECT_EQ(load_checkpoint(path)->rounds_done, 1u);
    std::filesystem::remove(path);
}

// Issue 33: a round end copies the sums alone (80 bytes a pixel, not the accumulator's
// 112), and the file is the one a Checkpoint of the accumulator gives, byte for byte.
TEST(Checkpoint, ASnapshotOfTheSumsWritesTheAccumulatorsBytes) {
    // More pixels than a band (kBandPixels), so that several bands copy.
    const uint32_t w = 300, h = 230;
    Accumulator acc(w, h);
    SampleJobResult r;
    r.rect = {0, 0, w, h};
    r.pixels.resize(size_t(w) * h);
    for (size_t i = 0; i < r.pixels.size(); ++i) {
        r.pixels[i].even[1] = 1e-3 * double(i % 977) + 1e-17;
        r.pixels[i].odd[0] = 1.0 / 7.0 * double(i % 13);
        r.pixels[i].sum_sq_luminance = 0.5 * double(i % 31);
        r.pixels[i].samples = 2 + i % 5;
        r.pixels[i].rays = 3 * (2 + i % 5);
    }
    acc.merge(r);
    const nlohmann::json state = {{"done_spp", 3}};
    const std::vector<uint32_t> planned(size_t(w) * h, 4);
    const auto from_accumulator = temp_file("acc.bin");
    const auto from_snapshot = temp_file("snap.bin");
    save_checkpoint(from_accumulator, {acc, state, 5, 2.5, planned});
    CheckpointSnapshot snapshot;
    snapshot.copy_buffers(Accumulator(2, 2), AuxSums());  // memory of another size
    snapshot.copy_buffers(acc, AuxSums());
    snapshot.strategy_state = state;
    snapshot.rounds_done = 5;
    snapshot.seconds = 2.5;
    snapshot.planned_round = planned;
    save_checkpoint(from_snapshot, snapshot);
    const auto bytes = [](const std::filesystem::path& path) {
        std::ifstream in(path, std::ios::binary);
        return std::string(std::istreambuf_iterator<char>(in), {});
    };
    EXPECT_EQ(bytes(from_snapshot), bytes(from_accumulator));
    const auto back = load_checkpoint(from_snapshot);
    ASSERT_TRUE(back.has_value());
    EXPECT_EQ(back->merged.total_samples(), acc.total_samples());
    for (size_t i = 0; i < acc.pixel_count(); i += 1009) {
        EXPECT_EQ(back->merged.at(i), acc.at(i)) << i;
        EXPECT_EQ(back->merged.half_difference(i), acc.half_difference(i)) << i;
        EXPECT_EQ(back->merged.luminance_variance(i), acc.luminance_variance(i)) << i;
    }
    // A snapshot whose sums are not its size is refused, not written past.
    snapshot.sums.pop_back();
    EXPECT_THROW(save_checkpoint(from_snapshot, snapshot), std::runtime_error);
    std::filesystem::remove(from_accumulator);
    std::filesystem::remove(from_snapshot);
}

// Issue 33: the first checkpoint was due at a render's first round end (nothing timed
// yet), a whole copy and write of the buffers for a round or two of work.
TEST(Checkpoint, TheFirstIsDueOnceTheRenderRanTheShareOfWhatOneShouldCost) {
    const double full_hd = expected_checkpoint_seconds(1920 * 1080, false);
    EXPECT_DOUBLE_EQ(full_hd, 1920.0 * 1080 * sizeof(PixelSums) / 1e9);  // ~0.17 s
    EXPECT_GT(expected_checkpoint_seconds(1920 * 1080, true), full_hd);
    EXPECT_FALSE(checkpoint_due(0.1, full_hd));  // a first round end
    EXPECT_FALSE(checkpoint_due(kCheckpointShare * full_hd - 0.01, full_hd));
    EXPECT_TRUE(checkpoint_due(kCheckpointShare * full_hd, full_hd));
    // A small render's is due at once, as before.
    EXPECT_TRUE(checkpoint_due(0.01, expected_checkpoint_seconds(16, false)));
}

TEST(Checkpoint, DueWhenItsCostIsASmallShareOfTheTimeSinceTheLast) {
    EXPECT_TRUE(checkpoint_due(0.0, 0.0));  // none written yet
    EXPECT_FALSE(checkpoint_due(0.05, 0.01));
    EXPECT_TRUE(checkpoint_due(0.2, 0.01));
    EXPECT_TRUE(checkpoint_due(kCheckpointShare * 0.3, 0.3));
    EXPECT_FALSE(checkpoint_due(kCheckpointShare * 0.3 - 0.01, 0.3));
}

}  // namespace
}  // namespace aliquot
