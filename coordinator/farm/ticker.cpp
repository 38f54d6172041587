#include "ticker.h"

#include <exception>
#include <string>

#include "farm_log.h"

namespace aliquot {

Ticker::Ticker(std::chrono::milliseconds period, std::function<void()> tick) {
    thread_ = std::thread([this, period, tick = std::move(tick)] {
        while (true) {
            {
                std::unique_lock lock(mutex_);
                if (wake_.wait_for(lock, period, [this] { return stopping_; })) return;
            }
            try {
                tick();
            } catch (const std::exception& e) {
                log_farm_error(std::string("tick: ") + e.what());
            }
        }
    });
}

void Ticker::stop() {
    {
        std::lock_guard lock(mutex_);
        stopping_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable() && thread_.get_id() != std::this_thread::get_id())
        thread_.join();
}

}  // namespace aliquot
