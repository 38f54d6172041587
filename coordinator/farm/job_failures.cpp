#include "job_failures.h"

#include <algorithm>

namespace aliquot {
namespace {

// A worker's reason as one bounded line: it ends up in the render's error.
std::string one_line(const std::string& text) {
    constexpr size_t kMax = 500;
    std::string out;
    for (char c : text) {
        if (out.size() >= kMax) {
            out += "...";
            break;
        }
        // ASCII only: a worker's bytes reach proto strings and JSON, which need UTF-8,
        // and a cut at kMax could split a character.
        const auto u = static_cast<unsigned char>(c);
        out += (u < 0x20 || u >= 0x7f) ? (u == '\n' || u == '\r' || u == '\t' ? ' ' : '?')
                                       : c;
    }
    return out.empty() ? "no reason given" : out;
}

bool failed_on(const JobFailures::OfJob& job, const std::string& worker) {
    return std::find(job.failed_on.begin(), job.failed_on.end(), worker) !=
           job.failed_on.end();
}

}  // namespace

std::string JobFailures::count(OfJob& job, const PixelRect& rect,
                               const std::string& worker, const std::string& reason,
                               const std::set<std::string>& alive,
                               const FailurePolicy& policy) {
    ++job.failures;
    if (!failed_on(job, worker)) job.failed_on.push_back(worker);
    ++by_worker_[worker];
    const size_t distinct = job.failed_on.size();
    if (distinct < policy.max_job_failures &&
        (job.failures < policy.max_job_failures || !policy.fail_on_fewer_hosts ||
         another_could_take(job, "", alive, policy)))
        return {};
    // Appended piece by piece: GCC 12 warns (falsely, -Wrestrict) on `"literal" +
    // std::to_string(...)`, which inserts at the front of a temporary.
    std::string why = "job ";
    why += std::to_string(rect.x) + "," + std::to_string(rect.y) + " ";
    why += std::to_string(rect.width) + "x" + std::to_string(rect.height) + " failed";
    if (job.failures != distinct) {
        why += " ";
        why += std::to_string(job.failures) + " times";
    }
    why += " on ";
    why += std::to_string(distinct);
    why += distinct == 1 ? " worker: " : " workers: ";
    why += one_line(reason);
    return why;
}

bool JobFailures::kept_off(const std::string& worker, const std::set<std::string>& alive,
                           const FailurePolicy& policy) const {
    return blocklisted(worker, policy) &&
           std::any_of(alive.begin(), alive.end(), [&](const std::string& other) {
               return other != worker && !blocklisted(other, policy);
           });
}

bool JobFailures::may_take(const OfJob& job, const std::string& worker,
                           const std::set<std::string>& alive,
                           const FailurePolicy& policy) const {
    return !failed_on(job, worker) || !another_could_take(job, worker, alive, policy);
}

uint32_t JobFailures::of(const std::string& worker) const {
    const auto it = by_worker_.find(worker);
    return it == by_worker_.end() ? 0 : it->second;
}

bool JobFailures::blocklisted(const std::string& worker,
                              const FailurePolicy& policy) const {
    const auto it = by_worker_.find(worker);
    return it != by_worker_.end() && it->second >= policy.blocklist_after;
}

bool JobFailures::another_could_take(const OfJob& job, const std::string& worker,
                                     const std::set<std::string>& alive,
                                     const FailurePolicy& policy) const {
    for (const std::string& other : alive)
        if (other != worker && !blocklisted(other, policy) && !failed_on(job, other))
            return true;
    return false;
}

}  // namespace aliquot
