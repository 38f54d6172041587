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

TEST(Checkpoint, DueWhenItsCostIsASmallShareOfTheTimeSinceTheLast) {
    EXPECT_TRUE(checkpoint_due(0.0, 0.0));  // none written yet
    EXPECT_FALSE(checkpoint_due(0.05, 0.01));
    EXPECT_TRUE(checkpoint_due(0.2, 0.01));
    EXPECT_TRUE(checkpoint_due(kCheckpointShare * 0.3, 0.3));
    EXPECT_FALSE(checkpoint_due(kCheckpointShare * 0.3 - 0.01, 0.3));
}

}  // namespace
}  // namespace aliquot
