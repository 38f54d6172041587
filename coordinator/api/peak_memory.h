// For the api room's tests: how far the process's resident memory peaks while a test
// does something, so that a test bounds memory, never time.
#pragma once

#include <cstdint>
#include <fstream>
#include <string>

namespace aliquot::testing {

class PeakMemory {
public:
    // Peaks count from here on (writing 5 to clear_refs resets VmHWM to the current RSS).
    PeakMemory() {
        std::ofstream("/proc/self/clear_refs") << "5";
        start_kb_ = peak_kb();
    }
    // How far the peak has risen above the resident memory at construction, in KiB.
    uint64_t grown_kb() const { return peak_kb() - start_kb_; }

private:
    static uint64_t peak_kb() {
        std::ifstream in("/proc/self/status");
        for (std::string line; std::getline(in, line);)
            if (line.rfind("VmHWM:", 0) == 0) return std::stoull(line.substr(6));
        return 0;
    }
    uint64_t start_kb_ = 0;
};

}  // namespace aliquot::testing
