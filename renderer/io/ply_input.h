// Block input for the PLY reader: a plain file of 1 MiB or more is mapped and seen through a
// sliding window of kBlockBytes, any other input (small files, gzip, memory) through a reused
// buffer. Internal to renderer/io/ply_*; depends on io/file_reader.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <vector>

#include "renderer/core/map_guard.h"
#include "renderer/io/file_reader.h"
#include "renderer/io/ply_format.h"

namespace kdt::ply {

/// When the PLY reader maps a file, and the window it sees a mapped file through. Tests and
/// fuzzing only, not a user option: they lower both so that small inputs take the mapped
/// path and cross window ends.
struct MapParams {
    uint64_t min_file_bytes = uint64_t(1) << 20;  ///< plain files of this size or more
    size_t window_bytes = kBlockBytes;            ///< at least 1
};

/// Sets the parameters later Inputs use and returns the previous ones. Not thread-safe: to be
/// called while no PLY file is being opened.
MapParams set_map_params(const MapParams& params);

/// A reused buffer refilled from the reader, or a window on the mapped file; never reads past
/// its data.
class Input {
public:
    // kPad bytes after the usable capacity let the parsers load 64 bytes of a line (and 8
    // more for a digit run inside it) near the end of the data without leaving the
    // allocation; bytes at or past end() never count.
    static constexpr size_t kPad = 80;

    // Plain files of at least MapParams::min_file_bytes (1 MiB) are mapped: no copy, no
    // buffer to fault in. Small files and gzip/memory input get a buffer, small inputs one of
    // their own size.
    explicit Input(FileReader& reader);
    Input(const Input&) = delete;
    Input& operator=(const Input&) = delete;
    ~Input();

    const char* pos() const { return pos_; }
    const char* end() const { return end_; }
    bool eof() const { return eof_; }
    size_t avail() const { return size_t(end_ - pos_); }
    /// Bytes the buffer holds without growing.
    size_t capacity() const { return map_ ? window_ : buf_.size() - kPad; }
    void advance(size_t n) { pos_ += n; }
    /// Stream offset of pos().
    uint64_t offset() const {
        return map_ ? uint64_t(pos_ - map_) : base_ + uint64_t(pos_ - buf_.data());
    }

    /// Throws an Error naming the file when a mapped file changed or was truncated while it
    /// was read (the reads then saw zeros); nothing for buffered input, whose reads end
    /// early instead. Callers check this before trusting, or reporting on, what they read.
    void check_unchanged() const {
        if (guard_) guard_->check();
    }

    /// Makes at least n bytes available at pos(); false when the data ends first.
    bool fill(size_t n) {
        if (avail() >= n) return true;
        return refill(n);
    }

    /// Skips n bytes; false when the data ends first.
    bool skip(uint64_t n) {
        while (n > 0) {
            if (pos_ == end_ && !fill(1)) return false;
            size_t k = size_t(std::min<uint64_t>(n, avail()));
            pos_ += k;
            n -= k;
        }
        return true;
    }

    /// The next line [b, e) without its '\n'; false at the end of the data. Throws through
    /// `too_long` when a line exceeds max_bytes. The window grows geometrically while a
    /// line is scanned, so a line of n bytes costs O(n) however long it is.
    template <typename TooLong>
    bool next_line(const char*& b, const char*& e, TooLong&& too_long,
                   size_t max_bytes = kMaxLineBytes) {
        size_t scanned = 0;
        for (;;) {
            const void* nl = std::memchr(pos_ + scanned, '\n', avail() - scanned);
            if (nl) {
                b = pos_;
                e = static_cast<const char*>(nl);
                pos_ = e + 1;
                return true;
            }
            scanned = avail();
            if (eof_) {
                if (scanned == 0) return false;
                b = pos_;
                e = end_;
                pos_ = end_;
                return true;
            }
            if (scanned >= max_bytes) too_long();
            fill(std::min(max_bytes + 1, scanned + std::max(scanned, capacity())));
        }
    }

private:
    bool refill(size_t n);
    bool map_file();
    bool slide(size_t n);

    static constexpr size_t kReleaseBytes = size_t(1) << 20;

    FileReader& reader_;
    std::vector<char> buf_;
    const char* pos_ = nullptr;
    const char* end_ = nullptr;
    uint64_t base_ = 0;
    bool eof_ = false;
    char* map_ = nullptr;  // mapped file, or null for buffered input
    const char* map_end_ = nullptr;
    char* released_ = nullptr;  // pages before it are unmapped again
    size_t map_bytes_ = 0, page_ = 4096, window_ = kBlockBytes;
    std::unique_ptr<MapGuard> guard_;  // set while map_ is
};

}  // namespace kdt::ply
