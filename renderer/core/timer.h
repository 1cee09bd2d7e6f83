// Wall-clock timing for reports and progress; never used in pass/fail tests.
#pragma once

#include <chrono>

namespace kdt {

class Timer {
public:
    Timer() : start_(std::chrono::steady_clock::now()) {}
    void reset() { start_ = std::chrono::steady_clock::now(); }
    double seconds() const {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    }

private:
    std::chrono::steady_clock::time_point start_;
};

/// Peak resident set size of this process in bytes (VmHWM), 0 when unknown.
size_t peak_rss_bytes();
/// Current resident set size in bytes (VmRSS), 0 when unknown.
size_t current_rss_bytes();
/// Resets the peak RSS counter when the kernel allows it (writes /proc/self/clear_refs).
void reset_peak_rss();

}  // namespace kdt
