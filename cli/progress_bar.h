// ProgressBar: one redrawn line on stderr while a long operation runs; silent when stderr
// is not a terminal, so logs and pipes stay clean.
#pragma once

#include <chrono>
#include <cstdint>
#include <string>

namespace aliquot::cli {

class ProgressBar {
public:
    explicit ProgressBar(std::string label);
    ~ProgressBar();

    // done / total with a free-form note (e.g. "round 3, 1.2 M samples/s").
    void update(uint64_t done, uint64_t total, const std::string& note = "");
    void finish();

private:
    std::string label_;
    bool enabled_;
    bool finished_ = false;
    std::chrono::steady_clock::time_point start_, last_draw_;
};

}  // namespace aliquot::cli
