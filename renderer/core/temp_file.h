// Writing a file without ever leaving it half-written: a temporary file beside the target,
// removed on every exit path (signals included, through core/interrupt.h), renamed over the
// target when complete. Depends on core/error.h and core/interrupt.h.
#pragma once

#include <cstddef>
#include <string>

namespace kdt {

/// The file a write to `path` replaces: `path` itself, or for a symlink the file at the end of
/// its chain of links (relative links resolved against their own directory), which need not
/// exist yet (a dangling link). A file is written through a link, as `cp` and the shell's `>`
/// do, so that the link stays. Throws kdt::Error naming `path` for a loop of links.
std::string write_target(const std::string& path);

/// A temporary file "<target>.kdtrace-<pid>-<n>.tmp" in the directory of write_target(target),
/// created exclusively (mode 0666 less the umask) and registered for removal if a signal ends
/// the process. Without commit(), the destructor closes and removes it.
class TempFile {
public:
    /// Throws kdt::Error naming `target` when the file cannot be created.
    explicit TempFile(const std::string& target);
    ~TempFile();
    TempFile(const TempFile&) = delete;
    TempFile& operator=(const TempFile&) = delete;

    const std::string& path() const { return path_; }
    /// Appends bytes; throws kdt::Error naming the target on a write error (a full disk).
    void write(const void* data, size_t size);
    /// Flushes the data to disk, gives the file the mode of an existing regular target (so
    /// overwriting keeps the user's permissions), and renames it over write_target(target). Throws
    /// kdt::Error naming the target on failure (the temporary file is then removed).
    void commit();

private:
    [[noreturn]] void fail(const std::string& message);
    void discard();

    std::string target_;  // as given, for messages
    std::string real_;    // write_target(target_): what the rename replaces
    std::string path_;
    int fd_ = -1;
    int slot_ = -1;
};

/// Writes `size` bytes to `path` through a TempFile.
void write_file_atomically(const std::string& path, const void* data, size_t size);

}  // namespace kdt
