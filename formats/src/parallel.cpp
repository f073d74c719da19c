#include "penumbra/parallel.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace penumbra {

void parallelFor(unsigned threads, uint64_t count, const std::function<void(uint64_t)>& body,
                 const std::function<void(uint64_t)>& tick)
{
    if (threads == 0)
        threads = std::max(1u, std::thread::hardware_concurrency());
    std::atomic<uint64_t> next{0}, done{0};
    std::mutex failureMutex;
    std::exception_ptr failure;
    auto worker = [&](bool caller) noexcept {
        try {
            for (uint64_t i = next++; i < count; i = next++) {
                body(i);
                const uint64_t finished = ++done;
                if (caller && tick)
                    tick(finished);
            }
        } catch (...) {
            next = count; // the others stop after their current item
            const std::lock_guard lock(failureMutex);
            if (!failure)
                failure = std::current_exception();
        }
    };
    const uint64_t extra = count == 0 ? 0 : std::min<uint64_t>(count, threads) - 1;
    std::vector<std::thread> pool;
    try {
        pool.reserve(extra);
        for (uint64_t t = 0; t < extra; ++t)
            pool.emplace_back(worker, false);
    } catch (...) {
        // Out of memory or of threads: those started and the caller share the items.
    }
    worker(true);
    for (std::thread& thread : pool)
        thread.join();
    if (failure)
        std::rethrow_exception(failure);
}

} // namespace penumbra
