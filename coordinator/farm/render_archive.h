// RenderArchive: the farm's record on disk, and the farm's only includer of the store.
// With a data directory it claims render ids (a directory each), records submissions,
// rounds, checkpoints and ends on its RecordBacklog (off every lock, in order), resumes
// unfinished renders, reads back renders that left memory, deletes them, and writes
// workers' rows. Without one (the embedded render) it keeps nothing and reads nothing.
//
// Its calls on a render in memory take that render's RenderSlot, under the render's lock
// where said; its writes lock the render (through a weak pointer) only for moments.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "image.h"
#include "record_backlog.h"
#include "render_info.h"
#include "render_slot.h"

namespace aliquot {

class RunStore;

class RenderArchive {
public:
    // Creates the directories and opens the store; an empty path keeps nothing.
    explicit RenderArchive(std::filesystem::path data_dir);
    ~RenderArchive();

    bool keeps_records() const { return store_ != nullptr; }
    // For the event log, which writes its rows on the same backlog, in order.
    RunStore* store() { return store_.get(); }
    RecordBacklog& backlog() { return backlog_; }
    // Writes what waits (the coordinator calls it last, before its sessions go).
    void finish_writes() { backlog_.stop_writer(); }

    // ---- Renders coming in ----
    // A fresh render id; with a data directory its directory is the claim.
    std::string claim_render_id();
    // The submission's rows (scene, render, reference file); throws when they cannot be
    // written.
    void record_submission(const std::string& id, const RenderSpec& spec,
                           const std::string& scene_hash, int64_t created_ms,
                           uint64_t samples_planned);
    // Removes the directory of a claimed id whose submission was never recorded.
    void unclaim(const std::string& id);
    struct Resumed {
        std::unique_ptr<RenderSession> session;
        std::string scene_hash;
        bool queued = false;  // no job of it leased before the restart
    };
    // Every unfinished render of the store, from its last checkpoint, handed to `attach`;
    // one that cannot resume is recorded as failed with the reason.
    void resume_unfinished(const std::function<void(Resumed)>& attach);

    // ---- A render in memory (its slot) ----
    void record_running(const std::string& id);
    // Allocates the render's checkpoint copy on the backlog's thread, off every lock.
    void prepare_checkpoint_copy(RenderSlot& slot);
    // The round in the render's history, its row, and a checkpoint when due; under the
    // render's lock (RenderSession::on_round).
    void record_round(RenderSlot& slot, const RoundSummary& round);
    // The render's EXR, state and outcome; then `written(id)`, on the backlog's thread,
    // takes the finished render out of memory. Nothing without a data directory.
    void record_end(RenderSlot& slot, std::function<void(const std::string&)> written);
    void record_priority(const std::string& id, int32_t priority);
    // The rounds of a resumed render before its checkpoint, read once; under its lock.
    void complete_history(RenderSlot& slot);

    // ---- Renders that left memory (finished, or before a restart) ----
    bool knows(const std::string& id);
    std::optional<RenderInfo> stored_info(const std::string& id);
    // The newest renders' ids, newest first (list()).
    std::vector<std::string> recent_ids(size_t limit);
    std::optional<std::vector<RoundSummary>> stored_rounds(const std::string& id);
    std::optional<std::vector<Bucket>> stored_buckets(const std::string& id);
    std::optional<Image> stored_image(const std::string& id, bool aovs);
    std::optional<std::filesystem::path> image_file(const std::string& id);
    std::optional<std::string> stored_scene(const std::string& hash);
    std::map<RenderState, uint64_t> counts_by_state();
    // Deletes a finished render's rows and files for good.
    enum class Deletion { Deleted, Unknown, Unfinished };
    Deletion delete_render(const std::string& id);
    // Ids of renders finished before `before_ms`, at most `limit`.
    std::vector<std::string> finished_before(int64_t before_ms, size_t limit);

    // ---- Workers' rows: statistics, written on the backlog, dropped when they fail ----
    void record_worker(const std::string& name, uint32_t threads, int64_t seen_ms);
    void record_worker_samples(const std::string& name, uint64_t samples,
                               int64_t seen_ms);
    void record_worker_lost(const std::string& name);
    void forget_worker(const std::string& name);
    void forget_workers_silent_since(int64_t before_ms);

    // Retries writes a full disk refused; with `wal_due`, checkpoints the WAL (tick).
    void tick(bool wal_due);
    std::string warning() const { return backlog_.warning(); }
    uint64_t write_failures() const { return backlog_.failures(); }

private:
    std::filesystem::path render_dir(const std::string& id) const;
    uint64_t first_free_render_number() const;
    std::string store_reference(const Image& reference) const;
    void queue_checkpoint(RenderSlot& slot, const RoundSummary& round);
    void queue_worker_write(std::string what, std::function<void()> write);

    std::filesystem::path data_dir_;
    std::unique_ptr<RunStore> store_;
    RecordBacklog backlog_;  // store writes waiting for the disk, in order
    std::mutex ids_mutex_;   // a leaf: claim_render_id
    uint64_t next_render_number_ = 1;
};

}  // namespace aliquot
