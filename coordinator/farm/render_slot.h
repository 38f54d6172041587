// RenderSlot: a render in memory with its own lock, which guards its session and what
// the archive keeps for it. The Coordinator holds one per render; RenderArchive's writes
// reach it through a weak pointer, so a render that left memory is written no more.
#pragma once

#include <chrono>
#include <memory>
#include <mutex>
#include <vector>

#include "checkpoint.h"
#include "render_session.h"

namespace aliquot {

struct CheckpointTiming {
    std::chrono::steady_clock::time_point ended{};  // of the last checkpoint written
    double cost_seconds = 0;  // what it took: its copy and its write
    bool in_flight = false;   // a copy waits for the writer: no second one meanwhile
};

// The copy of a render's buffers a checkpoint is written from, kept between checkpoints
// so that taking the next copy reuses its memory: a fresh 150 MB copy at 1920x1080 was
// mostly the kernel zeroing new pages.
struct CheckpointCopy {
    CheckpointSnapshot cp;
    bool saved = false;  // written to disk (a retried write does not write it again)
    std::chrono::steady_clock::time_point written{};
    double copy_seconds = 0;   // taking it, under the render's lock
    double write_seconds = 0;  // writing it
};

// A bucket's place and whether it converged: a round's buckets are stored when these
// changed since the last stored layout.
struct BucketShape {
    PixelRect rect;
    bool converged = false;
    bool operator==(const BucketShape&) const = default;
};

struct RenderSlot : std::enable_shared_from_this<RenderSlot> {
    std::mutex mutex;
    std::unique_ptr<RenderSession> session;
    // Its completed rounds (for rounds()): from memory for a live render; a resumed
    // one's earlier rounds are read from the store once.
    std::vector<RoundSummary> round_history;
    std::vector<BucketShape> bucket_shape;  // the last layout stored (record_round)
    CheckpointTiming checkpoint;
    std::shared_ptr<CheckpointCopy> checkpoint_copy;  // the backlog's while in flight
    // Guarded by the coordinator's lock (the render list's), not this slot's: lease()
    // orders renders by it before taking any render's lock.
    int32_t priority = 0;
    uint64_t number = 0;  // submission order: FIFO within a priority
    // Ticks that passed this render over because its lock was busy (tick): after a few,
    // the tick waits for it, so its expired leases are never held back for long.
    int ticks_passed_over = 0;
};

using SlotPtr = std::shared_ptr<RenderSlot>;

}  // namespace aliquot
