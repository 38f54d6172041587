#include "render_list.h"

#include <algorithm>

namespace aliquot {

void RenderList::changed() {
    ++version_;
    progress_.notify_all();
    work_ready_.notify_all();
}

SlotPtr RenderList::slot_of(const std::string& id) const {
    const auto it = sessions_.find(id);
    return it == sessions_.end() ? nullptr : it->second;
}

void RenderList::add(std::unique_ptr<RenderSession> session,
                     const std::function<bool(RenderSlot&)>& start) {
    auto slot = std::make_shared<RenderSlot>();
    const std::string id = session->id();
    slot->priority = session->spec().priority;
    slot->session = std::move(session);
    std::lock_guard lock(mutex_);
    slot->number = submissions_++;
    const bool waits = start(*slot);
    order_.push_back(id);
    sessions_[id] = slot;
    if (waits) queue_.add(id, slot->priority, slot->number);  // running at its lease
    changed();
}

bool RenderList::drop_finished(const std::string& id,
                               const std::function<void(RenderSession&)>& release) {
    std::lock_guard lock(mutex_);
    const auto it = sessions_.find(id);
    // Finished sessions change no more, so this reads its state without its lock.
    if (it == sessions_.end() || !it->second->session->finished()) return false;
    release(*it->second->session);
    sessions_.erase(it);
    order_.erase(std::remove(order_.begin(), order_.end(), id), order_.end());
    queue_.leave(id);
    changed();
    return true;
}

SlotPtr RenderList::find(const std::string& id) {
    std::lock_guard lock(mutex_);
    return slot_of(id);
}

RenderList::Place RenderList::place_of(const std::string& id) {
    std::lock_guard lock(mutex_);
    Place place{slot_of(id), 0, queue_.position(id)};
    if (place.slot) place.priority = place.slot->priority;
    return place;
}

std::vector<SlotPtr> RenderList::in_order() {
    std::lock_guard lock(mutex_);
    std::vector<SlotPtr> out;
    out.reserve(order_.size());
    for (const std::string& id : order_) out.push_back(sessions_.at(id));
    return out;
}

std::vector<std::pair<SlotPtr, bool>> RenderList::in_order_with_queued() {
    std::lock_guard lock(mutex_);
    std::vector<std::pair<SlotPtr, bool>> out;
    out.reserve(order_.size());
    for (const std::string& id : order_)
        out.emplace_back(sessions_.at(id), queue_.position(id) > 0);
    return out;
}

std::vector<std::string> RenderList::newest_ids(size_t limit) {
    std::lock_guard lock(mutex_);
    std::vector<std::string> ids;
    for (auto it = order_.rbegin(); it != order_.rend() && ids.size() < limit; ++it)
        ids.push_back(*it);
    return ids;
}

size_t RenderList::size() {
    std::lock_guard lock(mutex_);
    return sessions_.size();
}

std::optional<RenderList::Snapshot> RenderList::by_priority() {
    std::lock_guard lock(mutex_);
    if (stopping_) return std::nullopt;
    Snapshot out{version_, {}};
    out.slots.reserve(order_.size());
    for (const std::string& id : order_) out.slots.push_back(sessions_.at(id));
    std::sort(out.slots.begin(), out.slots.end(), [](const SlotPtr& a, const SlotPtr& b) {
        return LeaseOrder{a->priority, a->number} < LeaseOrder{b->priority, b->number};
    });
    return out;
}

bool RenderList::leased(const std::string& id) {
    std::lock_guard lock(mutex_);
    const bool was_queued = queue_.leave(id);
    changed();
    return was_queued;
}

void RenderList::set_priority(SlotPtr slot, int32_t priority) {
    std::lock_guard lock(mutex_);
    slot->priority = priority;
    queue_.set_priority(slot->session->id(), priority);
    changed();  // waiting workers look again, in the new order
}

void RenderList::forget_leases(LeaseTable& leases, const std::vector<uint64_t>& ended,
                               const std::set<std::string>& finished) const {
    leases.forget_ended(ended, finished,
                        [this](const std::string& r) { return slot_of(r) != nullptr; });
}

void RenderList::cancelled(const std::string& id, LeaseTable& leases) {
    std::lock_guard lock(mutex_);
    forget_leases(leases, {}, {id});
    queue_.leave(id);
    changed();
}

void RenderList::note_change() {
    std::lock_guard lock(mutex_);
    changed();
}

void RenderList::note_ended(LeaseTable& leases, const std::vector<uint64_t>& ended,
                            const std::set<std::string>& finished, bool changed_too) {
    std::lock_guard lock(mutex_);
    forget_leases(leases, ended, finished);
    if (changed_too) changed();
}

bool RenderList::wait_for_work(uint64_t seen,
                               std::chrono::steady_clock::time_point deadline) {
    std::unique_lock lock(mutex_);
    return work_ready_.wait_until(lock, deadline,
                                  [&] { return version_ != seen || stopping_; });
}

uint64_t RenderList::wait_for_change(uint64_t seen, std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex_);
    progress_.wait_for(lock, timeout, [&] { return version_ > seen || stopping_; });
    return version_;
}

bool RenderList::wait_until_gone(const std::string& id,
                                 std::chrono::steady_clock::time_point deadline,
                                 const std::function<bool()>& give_up) {
    std::unique_lock lock(mutex_);
    while (slot_of(id) && !stopping_ && !give_up() &&
           std::chrono::steady_clock::now() < deadline)
        // drop_finished wakes this; what give_up watches may not, hence the period.
        progress_.wait_for(lock, std::chrono::milliseconds(100));
    return slot_of(id) != nullptr;
}

void RenderList::stop() {
    {
        std::lock_guard lock(mutex_);
        stopping_ = true;
    }
    progress_.notify_all();
    work_ready_.notify_all();
}

}  // namespace aliquot
