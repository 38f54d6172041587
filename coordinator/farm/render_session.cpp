#include "render_session.h"

#include <algorithm>
#include <cmath>
#include <system_error>

#include "error_estimate.h"
#include "error_metric.h"
#include "render_attributes.h"
#include "round_cutter.h"

namespace aliquot {

RenderSession::RenderSession(std::string id, RenderSpec spec, int64_t created_ms)
    : RenderSession(std::move(id), spec, created_ms,
                    make_strategy(spec.strategy, spec.width, spec.height)) {}

RenderSession::RenderSession(std::string id, RenderSpec spec, int64_t created_ms,
                             std::unique_ptr<Strategy> strategy)
    : id_(std::move(id)),
      spec_(std::move(spec)),
      scene_hash_(aliquot::scene_hash(spec_.scene_json)),
      created_ms_(created_ms),
      strategy_(std::move(strategy)),
      merged_(spec_.width, spec_.height),
      aux_(spec_.aux ? AuxSums(spec_.width, spec_.height) : AuxSums()) {
    // A strategy that reads the first hits (`denoised`) has its render trace them,
    // whatever the submitter asked; resumed, the render asks again, so its checkpoint's
    // sums are expected.
    if (strategy_->wants_first_hits() && !spec_.aux) {
        spec_.aux = true;
        aux_ = AuxSums(spec_.width, spec_.height);
    }
    strategy_->watch_first_hits(&aux_);
}

void RenderSession::restore(Accumulator merged, const nlohmann::json& strategy_state,
                            uint32_t rounds_done, double seconds_before,
                            std::vector<uint32_t> planned_round, AuxSums aux) {
    // A checkpoint of another size (damaged, or another render's) would index the
    // buffers out of bounds in every round after it: refused, the render cannot resume.
    if (merged.width() != spec_.width || merged.height() != spec_.height)
        throw std::runtime_error("checkpoint is " + std::to_string(merged.width()) + "x" +
                                 std::to_string(merged.height()) + ", the render " +
                                 std::to_string(spec_.width) + "x" +
                                 std::to_string(spec_.height));
    if (aux.kept() != spec_.aux ||
        (aux.kept() && (aux.width() != spec_.width || aux.height() != spec_.height)))
        throw std::runtime_error(spec_.aux ? "checkpoint has no first-hit sums"
                                           : "checkpoint has first-hit sums the render "
                                             "does not keep");
    merged_ = std::move(merged);
    aux_ = std::move(aux);
    strategy_->restore_state(strategy_state);
    strategy_->restore_planned_round(std::move(planned_round));
    rounds_done_ = rounds_done;
    round_index_ = rounds_done;
    seconds_before_ = seconds_before;
    last_round_.index = rounds_done;
    last_round_.samples_total = merged_.total_samples();
    last_round_.error_estimate = estimate_mean_abs_error(merged_);
}

void RenderSession::start() {
    if (finished()) return;
    started_ = Clock::now();
    state_ = RenderState::Running;
    begin_next_round();
}

Image RenderSession::image(bool aovs) const {
    wait_for_adds();  // no half-added result
    Image image = merged_.image(aovs);
    if (aovs) aux_.add_layers(merged_, image);
    image.attributes =
        render_attributes(spec_, scene_hash_, samples_planned(), merged_.total_samples());
    return image;
}

double RenderSession::seconds() const {
    if (final_seconds_) return *final_seconds_;
    if (!started_ || !leased_any_) return seconds_before_;  // queued: no time of its own
    return seconds_before_ +
           std::chrono::duration<double>(Clock::now() - *started_).count();
}

void RenderSession::plan_next_round(const std::set<std::string>& alive,
                                    const FailurePolicy& policy) {
    std::optional<Round> round;
    std::vector<PixelRect> rects;
    // A strategy may plan a round with no samples; skip such rounds rather than stall.
    while (true) {
        // From here on next_spp_ may point at a vector the strategy has moved from and
        // destroyed: it is never read again (below, only next_data_ is compared).
        round = strategy_->next_round(merged_);
        if (!round) {
            if (next_spp_)
                throw std::logic_error("the round opened ahead was never handed out");
            finish(RenderState::Done);
            return;
        }
        if (next_spp_) break;
        // The jobs' rectangles now, their contents when each is first leased (issue).
        rects = round_tiles(*round, merged_.width(), merged_.height(), 0, min_jobs_);
        if (!rects.empty()) break;
    }
    // The ended round's jobs lend their vectors to the next round's (cut_job).
    spare_.clear();
    for (size_t j = 0; j < current_jobs_; ++j)
        if (jobs_[j].cut) spare_.push_back(std::move(jobs_[j].job));
    if (next_spp_) {
        // The round opened ahead: the strategy hands over the very vector its jobs were
        // cut from (moved, so its buffer is the same). Anything else could trace other
        // samples than the render planned.
        if (round->index != round_index_ + 1 || round->spp.data() != next_data_)
            throw std::logic_error("the round handed out is not the one opened ahead");
        jobs_.erase(jobs_.begin(), jobs_.begin() + std::ptrdiff_t(current_jobs_));
        // Every lease left is the round after's: the round out has merged.
        for (auto& [lease, j] : lease_to_job_) j -= current_jobs_;
        pending_.clear();
        for (size_t j : next_pending_) pending_.push_back(j - current_jobs_);
        next_pending_.clear();
        next_spp_ = nullptr;
        next_data_ = nullptr;
        next_pixels_ = 0;
        opened_ahead_ = true;
    } else {
        opened_ahead_ = false;
        jobs_.clear();
        pending_.clear();
        lease_to_job_.clear();
        for (const PixelRect& rect : rects) {
            pending_.push_back(jobs_.size());
            JobSlot slot;
            slot.job.rect = rect;
            jobs_.push_back(std::move(slot));
        }
    }
    current_jobs_ = jobs_.size();
    merged_jobs_ = 0;
    next_tried_ = false;
    announced_ = false;
    round_index_ = round->index;
    round_samples_ = round->total();
    round_ = std::move(*round);
    // The next round planned while this one is traced: off the lock the caller holds, so
    // results merge and jobs are leased meanwhile.
    if (std::function<void()> work = strategy_->take_work_ahead()) {
        try {
            work_ahead_ = std::async(std::launch::async, work);
        } catch (...) {
            work();  // no thread to be had: done here, as before (complete catches)
        }
    }
    // The results held for this round merge now, after the round before's: each
    // pixel's sums add up in round order.
    using HeldEnd = MergesInFlight::HeldEnd;
    merges_.add_held(
        merged_, aux_, while_adding_held,
        [&](size_t j, HeldEnd how, const std::string& why,
            const MergesInFlight::Credit& credit) noexcept {
            if (how == HeldEnd::Added) {
                ++merged_jobs_;
                if (on_held_merged) on_held_merged(credit);
            } else if (how == HeldEnd::Refused)
                count_refusal(j, why, alive, policy);
            else
                requeue_or_fail(j);  // not the worker's doing: no failure of its
            return state_ == RenderState::Running;
        });
}

void RenderSession::open_next_round() {
    if (next_spp_ || next_tried_ || !work_ahead_.valid() ||
        work_ahead_.wait_for(std::chrono::seconds(0)) != std::future_status::ready)
        return;
    next_tried_ = true;
    try {
        work_ahead_.get();
    } catch (...) {
        return fail_in_catch("plan");
    }
    const std::vector<uint32_t>* spp = strategy_->round_planned_ahead();
    const std::vector<PixelRect> rects =
        spp ? round_tiles(*spp, merged_.width(), merged_.height(), 0, min_jobs_)
            : std::vector<PixelRect>{};
    end_plan_wait(!rects.empty());
    if (rects.empty()) return;
    // All of the round ahead opens or none of it: what can fail (memory) is done before
    // anything changes, so a round ahead short of jobs never skips its pixels' samples.
    std::deque<size_t> ahead;
    for (size_t k = 0; k < rects.size(); ++k) ahead.push_back(jobs_.size() + k);
    jobs_.reserve(jobs_.size() + rects.size());
    merges_.open_round_ahead(rects.size());
    next_spp_ = spp;
    next_data_ = spp->data();
    for (const PixelRect& rect : rects) {
        JobSlot slot;
        slot.job.rect = rect;
        jobs_.push_back(std::move(slot));  // reserved: no allocation
    }
    // Empty until now (no round ahead was open): a swap, which cannot fail.
    if (next_pending_.empty())
        next_pending_.swap(ahead);
    else
        next_pending_.insert(next_pending_.end(), ahead.begin(), ahead.end());
}

void RenderSession::end_plan_wait(bool a_round_came) {
    if (!plan_wait_since_) return;
    // A plan that brought no round (the buffers taken after the pilot, or the budget
    // spent) kept no worker from a job: the round end was coming anyway.
    if (a_round_came)
        plan_wait_seconds_ +=
            std::chrono::duration<double>(Clock::now() - *plan_wait_since_).count();
    plan_wait_since_.reset();
}

std::vector<const SampleJob*> RenderSession::unmerged_jobs() const {
    // A job of the round out not merged is leased or pending: a few, where its jobs can
    // be thousands.
    std::vector<const SampleJob*> out;
    for (const auto& [lease, j] : lease_to_job_)
        if (j < current_jobs_) out.push_back(&jobs_[j].job);
    for (size_t j : pending_) out.push_back(&jobs_[j].job);
    // A result refused off the lock leaves its job unmerged; its end_merge has not put
    // it back in pending_ yet (issue waits for adds in flight before it asks).
    for (size_t j : merges_.refused()) out.push_back(&jobs_[j].job);
    return out;
}

void RenderSession::requeue(size_t j) {
    if (while_requeueing) while_requeueing(j);
    if (j < current_jobs_) {
        pending_.push_front(j);
    } else {
        next_pending_.push_front(j);
        next_pixels_ -= jobs_[j].job.rect.size();
    }
}

std::optional<SampleJob> RenderSession::issue(uint64_t lease_id,
                                              const std::string& worker,
                                              Clock::time_point deadline,
                                              const std::set<std::string>& alive,
                                              const FailurePolicy& policy) {
    if (state_ != RenderState::Running) return std::nullopt;
    if (!open_round_end_plan(alive, policy)) return std::nullopt;
    if (pending_.empty()) open_next_round();
    if (state_ != RenderState::Running || (pending_.empty() && next_pending_.empty())) {
        if (state_ == RenderState::Running && pending_.empty() && plan_coming() &&
            !plan_wait_since_)
            plan_wait_since_ = Clock::now();
        return std::nullopt;
    }
    if (failures_.kept_off(worker, alive, policy)) return std::nullopt;
    // The first pending job this worker may take, the round out's first: one it failed
    // on waits for another.
    const auto may_take = [&](size_t j) {
        return failures_.may_take(jobs_[j].failures, worker, alive, policy);
    };
    std::deque<size_t>* queue = &pending_;
    auto pick = std::find_if(pending_.begin(), pending_.end(), may_take);
    if (pick == pending_.end()) {
        queue = &next_pending_;
        pick = std::find_if(next_pending_.begin(), next_pending_.end(), may_take);
        if (pick == next_pending_.end()) return std::nullopt;
        // What the round after holds is bounded (render_session.h).
        const size_t size = jobs_[*pick].job.rect.size();
        if (next_pixels_ > 0 && next_pixels_ + size > merged_.pixel_count() / 2)
            return std::nullopt;
        next_pixels_ += size;
    }
    const size_t j = *pick;
    queue->erase(pick);
    JobSlot& slot = jobs_[j];
    if (!slot.cut) {
        SampleJob spare;
        if (!spare_.empty()) {
            spare = std::move(spare_.back());
            spare_.pop_back();
        }
        // A job of the round out reads its own pixels' counts, which no add in flight
        // touches (a round's jobs are disjoint); one of the round after counts its
        // pixels' samples to come in the round out too, whose adds must be over.
        if (j >= current_jobs_) wait_for_adds();
        slot.job = j < current_jobs_
                       ? cut_job(slot.job.rect, round_, merged_, std::move(spare))
                       : cut_job_after(slot.job.rect, *next_spp_, merged_,
                                       unmerged_jobs(), std::move(spare));
        slot.job.aux = spec_.aux;
        slot.cut = true;
    }
    slot.worker = worker;
    slot.deadline = deadline;
    lease_to_job_[lease_id] = j;
    if (!leased_any_) started_ = Clock::now();  // time queued is not the render's
    leased_any_ = true;
    return slot.job;
}

void RenderSession::end_rounds(const std::set<std::string>& alive,
                               const FailurePolicy& policy) {
    // Every job of the round out has merged, each counted after its add was over, so no
    // add of the round out is in flight, and the round ahead's results are held: the
    // round's end reads buffers no one writes.
    // A plan begun off the lock (begin_next_round) ends the loop: its round comes later.
    while (state_ == RenderState::Running && !planning_round_end_ &&
           merged_jobs_ == current_jobs_) {
        // Whatever a round's end throws (no memory, a strategy's error, on_round's
        // record, a reference the image cannot be compared with) fails the render with
        // the reason: the round has merged and no job is out, so nothing else would end
        // it, and the merge that ended it is over.
        const char* doing = "plan";
        try {
            finish_work_ahead();
            // From here the round end's own time, which the coordinator counts.
            end_plan_wait(strategy_->round_planned_ahead() != nullptr);
            doing = "end";
            ++rounds_done_;
            RoundSummary summary;
            summary.index = round_index_;
            summary.samples_in_round = round_samples_;
            summary.samples_total = merged_.total_samples();
            summary.seconds = seconds();
            summary.error_estimate = estimate_mean_abs_error(merged_);
            if (spec_.reference) {
                const ErrorMetrics m = compare_images(merged_.image(), *spec_.reference);
                summary.error_vs_reference = m.mean_abs;
                if (std::isfinite(m.mean_bias)) summary.mean_bias = m.mean_bias;
                if (std::isfinite(m.mean_bias_se)) summary.mean_bias_se = m.mean_bias_se;
            }
            last_round_ = summary;
            if (on_round) on_round(*this, summary);
            doing = "plan";
            begin_next_round(alive, policy);
        } catch (...) {
            return fail_in_catch(doing);
        }
    }
}

void RenderSession::finish_work_ahead() {
    if (work_ahead_.valid()) work_ahead_.get();
}

void RenderSession::begin_next_round(const std::set<std::string>& alive,
                                     const FailurePolicy& policy) {
    if (std::function<void()> work = strategy_->take_round_end(merged_)) {
        try {
            work_ahead_ = std::async(std::launch::async, work);
            planning_round_end_ = true;
            // As for a plan made ahead: has_pending, and the tick's announce_next_round
            // once it has ended (issue hands its round out).
            next_tried_ = false;
            announced_ = false;
            return;
        } catch (const std::system_error&) {
            // No thread to be had: next_round plans here, as before.
        }
    }
    plan_next_round(alive, policy);
}

bool RenderSession::open_round_end_plan(const std::set<std::string>& alive,
                                        const FailurePolicy& policy) {
    if (!planning_round_end_) return true;
    if (work_ahead_.wait_for(std::chrono::seconds(0)) != std::future_status::ready) {
        // The workers that ask meanwhile wait on the coordinator (plan_wait_seconds).
        if (!plan_wait_since_) plan_wait_since_ = Clock::now();
        return false;
    }
    planning_round_end_ = false;
    try {
        work_ahead_.get();
        plan_next_round(alive, policy);
    } catch (...) {
        fail_in_catch("plan");
    }
    end_plan_wait(state_ == RenderState::Running);
    return state_ == RenderState::Running;
}

bool RenderSession::renew(uint64_t lease_id, const std::string& worker,
                          Clock::time_point deadline) {
    const auto it = lease_to_job_.find(lease_id);
    if (it == lease_to_job_.end() || jobs_[it->second].worker != worker) return false;
    jobs_[it->second].deadline = deadline;
    return true;
}

bool RenderSession::abandon(uint64_t lease_id, const std::string& worker) {
    const auto it = lease_to_job_.find(lease_id);
    if (it == lease_to_job_.end() || jobs_[it->second].worker != worker) return false;
    requeue(it->second);  // first: when it throws (no memory), the lease still holds it
    lease_to_job_.erase(it);
    return true;
}

std::vector<uint64_t> RenderSession::expire(Clock::time_point now) {
    std::vector<uint64_t> expired;
    // Room first: a job queued again whose lease then stayed would be issued twice.
    expired.reserve(lease_to_job_.size());
    for (auto it = lease_to_job_.begin(); it != lease_to_job_.end();) {
        JobSlot& slot = jobs_[it->second];
        if (slot.deadline <= now) {
            requeue(it->second);
            expired.push_back(it->first);
            it = lease_to_job_.erase(it);
        } else {
            ++it;
        }
    }
    return expired;
}

std::string RenderSession::lease_label(uint64_t lease_id) const {
    const auto it = lease_to_job_.find(lease_id);
    return it == lease_to_job_.end() ? "" : id_ + "/" + std::to_string(it->second);
}

void RenderSession::cancel() {
    if (!finished()) finish(RenderState::Cancelled);
}

void RenderSession::fail(const std::string& message) {
    error_ = message;
    if (!finished()) finish(RenderState::Failed);
}

void RenderSession::finish(RenderState state) {
    // A plan still being made ahead is let finish here, under the render's own lock:
    // whoever drops the session last (the coordinator, under its lock) must not wait. Its
    // plan is no longer needed: the strategy has it give up early where it can
    // (`denoised`'s OIDN passes, minutes at 8192x8192).
    if (work_ahead_.valid()) {
        strategy_->stop_work();
        work_ahead_.wait();
    }
    // Adds in flight end first: what the render's end writes from its buffers no longer
    // changes (a merge that ends after it counts nothing more).
    wait_for_adds();
    final_seconds_ = seconds();
    state_ = state;
    pending_.clear();
    next_pending_.clear();
    next_spp_ = nullptr;
    lease_to_job_.clear();
    merges_.drop_held();
    if (on_finished) on_finished(*this);
}

}  // namespace aliquot
