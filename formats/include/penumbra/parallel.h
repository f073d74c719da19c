// A parallel loop over indices for the preprocessor, the generators and the
// model upload: plain threads, no pool. Exceptions and threads that cannot be
// started (an address-space limit, a thread limit) end in an error the caller
// sees, never in std::terminate.
#pragma once

#include <cstdint>
#include <functional>

namespace penumbra {

// Runs body(i) for every i in [0, count) on up to `threads` threads (0: the
// hardware's), the caller one of them; items are taken in order from a shared
// counter. tick(done), if set, runs on the calling thread after each item it
// finished, with the number of items finished so far by all threads.
// If body or tick throws, no further items are started, every thread is
// joined and the first exception is rethrown. A thread that cannot be started
// leaves its items to the others (at worst the caller does them all).
void parallelFor(unsigned threads, uint64_t count, const std::function<void(uint64_t)>& body,
                 const std::function<void(uint64_t)>& tick = {});

} // namespace penumbra
