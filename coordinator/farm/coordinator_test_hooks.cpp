// Coordinator's hooks for tests, apart from what the farm runs.
#include "coordinator.h"

namespace aliquot {

std::unique_lock<std::mutex> Coordinator::hold_render_for_test(const std::string& id) {
    const SlotPtr slot = renders_.find(id);
    // The slot outlives the lock: a test holds it only while the render is in memory.
    return slot ? std::unique_lock(slot->mutex) : std::unique_lock<std::mutex>();
}

void Coordinator::set_while_adding_for_test(const std::string& id,
                                            std::function<void(size_t job)> hook) {
    if (const SlotPtr slot = renders_.find(id)) {
        std::lock_guard render(slot->mutex);
        slot->session->while_adding = std::move(hook);
    }
}

void Coordinator::with_session_for_test(const std::string& id,
                                        const std::function<void(RenderSession&)>& f) {
    if (const SlotPtr slot = renders_.find(id)) {
        std::lock_guard render(slot->mutex);
        f(*slot->session);
    }
}

}  // namespace aliquot
