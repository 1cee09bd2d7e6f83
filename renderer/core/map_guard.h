// Reading mapped files safely: a file truncated by another process while it is mapped would
// kill the reader with SIGBUS; under a MapGuard such a read sees zeros instead and the guard
// reports the change as an Error. Depends on core/error.h and POSIX.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace kdt {

/// Guards the mapping [data, data + bytes) of the file `path` for its lifetime. A read of a
/// page the file no longer backs (it was truncated) raises SIGBUS on whichever thread made
/// it; the guard's handler then maps zero pages from there to the end of the region, so the
/// read and every later one return zeros, and records the fault: callers check faulted()
/// (or check()) after their reads and before trusting what they read. Any other SIGBUS goes
/// to the handler that was installed before; the first guard installs the handler and the
/// last one restores the previous one. At most kMaxMapGuards guards live at once (more throw
/// an Error naming the path). Thread-safe; not copyable. The region must stay mapped until
/// the guard is destroyed.
class MapGuard {
public:
    static constexpr int kMaxMapGuards = 64;

    /// `fd` is the mapped file, whose size and modification time check() compares with
    /// today's; -1 to leave that out.
    MapGuard(const void* data, size_t bytes, int fd, std::string path);
    MapGuard(const MapGuard&) = delete;
    MapGuard& operator=(const MapGuard&) = delete;
    ~MapGuard();

    /// True once a read in the region faulted (the file shrank while it was mapped).
    bool faulted() const;
    /// Throws an Error naming the path ("the file changed or was truncated while it was
    /// read") when faulted(), or when the file no longer has the size and modification time
    /// it had when the guard was made.
    void check() const;

private:
    std::string path_;
    int slot_ = -1, fd_ = -1;
    int64_t size_ = -1, mtime_ns_ = -1;
};

/// Tests only: called with the path at the end of every MapGuard constructor, so that a
/// test can truncate the file between mapping and reading. Null (the default) for none.
void set_map_guard_test_hook(void (*hook)(const std::string& path));

}  // namespace kdt
