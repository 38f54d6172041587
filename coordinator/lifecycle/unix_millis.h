// The clock a render's life is stamped with: the store's records, the farm's events and
// the dashboard's `now_ms` compare times in this one unit.
#pragma once

#include <cstdint>

namespace aliquot {

// Times in the store are unix milliseconds, always supplied by the caller (records carry
// them, methods that stamp a row take `now_ms`), so the store has no hidden clock and
// tests choose their times. This is the value the coordinator passes.
int64_t unix_millis_now();

}  // namespace aliquot
