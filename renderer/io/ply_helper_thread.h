// A second parsing thread for the ASCII PLY reader. Internal to renderer/io/ply_*; depends
// on the standard library only.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>

namespace kdt::ply {

/// A second parsing thread that takes work when it gets a core: parallel_for(n, fn) runs
/// fn(0), ..., fn(n - 1) on the calling thread and the helper, each taking the next index,
/// and returns once all are done. A helper that wakes late (the machine is shared) finds
/// little or nothing left and holds no one up, unlike a fixed split in halves. Creating one
/// throws std::system_error when no thread can be started.
class Helper {
public:
    Helper();
    Helper(const Helper&) = delete;
    Helper& operator=(const Helper&) = delete;
    ~Helper();

    /// fn must not throw.
    template <typename F>
    void parallel_for(size_t n, F&& fn) {
        Job job;
        job.n = n;
        job.fn = [&fn](size_t k) { fn(k); };
        run(job);
    }

private:
    struct Job {
        size_t n = 0;
        std::function<void(size_t)> fn;
        std::atomic<size_t> next{0};
        int active = 0;  // helpers inside work(); guarded by mutex_
    };

    void run(Job& job);
    static void work(Job& job);
    void loop();

    std::mutex mutex_;
    std::condition_variable wake_, done_;
    Job* job_ = nullptr;
    uint64_t generation_ = 0;
    bool quit_ = false;
    std::thread thread_;  // last: starts once the members above exist
};

}  // namespace kdt::ply
