#include "admission.h"

namespace aliquot {

Admission::Place Admission::take() {
    {
        std::lock_guard lock(mutex_);
        if (taken_ >= places_) return nullptr;
        ++taken_;
    }
    // A non-null pointer to nothing: only its deleter matters.
    return Place(this, [](Admission* admission) {
        std::lock_guard lock(admission->mutex_);
        --admission->taken_;
    });
}

size_t Admission::taken() const {
    std::lock_guard lock(mutex_);
    return taken_;
}

}  // namespace aliquot
