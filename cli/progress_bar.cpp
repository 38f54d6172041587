#include "progress_bar.h"

#include <unistd.h>

#include <cstdio>

namespace aliquot::cli {

ProgressBar::ProgressBar(std::string label)
    : label_(std::move(label)),
      enabled_(isatty(STDERR_FILENO)),
      start_(std::chrono::steady_clock::now()) {}

ProgressBar::~ProgressBar() { finish(); }

void ProgressBar::update(uint64_t done, uint64_t total, const std::string& note) {
    if (!enabled_ || finished_) return;
    const auto now = std::chrono::steady_clock::now();
    // Redrawing more than ~10 times a second only costs time.
    if (done < total && now - last_draw_ < std::chrono::milliseconds(100)) return;
    last_draw_ = now;
    const double fraction = total ? double(done) / double(total) : 1.0;
    const int width = 30;
    const int filled = int(fraction * width + 0.5);
    const double seconds = std::chrono::duration<double>(now - start_).count();
    const double eta = fraction > 0 ? seconds * (1.0 - fraction) / fraction : 0.0;
    std::string bar(size_t(filled), '#');
    bar.resize(size_t(width), '.');
    std::fprintf(stderr, "\r%s [%s] %5.1f%%  %6.1fs  eta %6.1fs  %s\x1b[K",
                 label_.c_str(), bar.c_str(), 100.0 * fraction, seconds, eta,
                 note.c_str());
    std::fflush(stderr);
}

void ProgressBar::finish() {
    if (!enabled_ || finished_) return;
    finished_ = true;
    std::fputc('\n', stderr);
}

}  // namespace aliquot::cli
