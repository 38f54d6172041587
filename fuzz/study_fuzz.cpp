// Fuzzes parse_study and the expansion `aliquot study` runs right after it. Its contract:
// a definition and its renders, or a StudyError.
#include <cstddef>
#include <cstdint>
#include <string>

#include "study_definition.h"
#include "study_plan.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string text(reinterpret_cast<const char*>(data), size);
    try {
        const aliquot::StudyDefinition def = aliquot::parse_study(text, "fuzz.json");
        aliquot::expand_study(def, aliquot::study_scale(def, "small"));
    } catch (const aliquot::StudyError&) {
    }
    return 0;
}
