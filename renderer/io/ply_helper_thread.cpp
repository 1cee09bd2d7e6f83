#include "renderer/io/ply_helper_thread.h"

namespace kdt::ply {

Helper::Helper() : thread_([this] { loop(); }) {}

Helper::~Helper() {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        quit_ = true;
    }
    wake_.notify_one();
    thread_.join();
}

void Helper::run(Job& job) {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        job_ = &job;
        ++generation_;
    }
    wake_.notify_one();
    work(job);
    std::unique_lock<std::mutex> lock(mutex_);
    job_ = nullptr;                                     // the helper can no longer join this job...
    done_.wait(lock, [&] { return job.active == 0; });  // ...and has left it
}

void Helper::work(Job& job) {
    for (size_t k; (k = job.next.fetch_add(1, std::memory_order_relaxed)) < job.n;) job.fn(k);
}

void Helper::loop() {
    std::unique_lock<std::mutex> lock(mutex_);
    uint64_t seen = 0;
    for (;;) {
        wake_.wait(lock, [&] { return quit_ || (job_ && generation_ != seen); });
        if (quit_) return;
        seen = generation_;
        Job* job = job_;
        ++job->active;
        lock.unlock();
        work(*job);
        lock.lock();
        if (--job->active == 0) done_.notify_all();
    }
}

}  // namespace kdt::ply
