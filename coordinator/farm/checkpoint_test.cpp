#include "checkpoint.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <fstream>

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
    save_checkpoint(path, {acc, {{"done_spp", 3}}, 4, 1.5});
    const auto cp = load_checkpoint(path);
    ASSERT_TRUE(cp.has_value());
    EXPECT_EQ(cp->rounds_done, 4u);
    EXPECT_EQ(cp->strategy_state["done_spp"], 3);
    EXPECT_EQ(cp->merged.total_samples(), acc.total_samples());
    for (size_t i = 0; i < 6; ++i)
        EXPECT_EQ(std::memcmp(&cp->merged.at(i), &acc.at(i), sizeof(PixelSums)), 0);
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
    save_checkpoint(path, {merged, nlohmann::json::object(), 1, 0.5});
    std::filesystem::create_symlink("/dev/full", tmp);
    EXPECT_THROW(save_checkpoint(path, {merged, nlohmann::json::object(), 2, 1.0}),
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
