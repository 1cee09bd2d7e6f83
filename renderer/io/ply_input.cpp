#include "renderer/io/ply_input.h"

#include <sys/mman.h>
#include <unistd.h>
#include <algorithm>

#include "renderer/core/error.h"

namespace kdt::ply {
namespace {

// MADV_POPULATE_READ (Linux 5.14); older kernels reject it and fault pages in as read.
#ifdef MADV_POPULATE_READ
constexpr int kPopulateRead = MADV_POPULATE_READ;
#else
constexpr int kPopulateRead = 22;
#endif

// Mesh data inflate about 2-10:1; the buffer for gzip input is sized for that.
constexpr uint64_t kLikelyInflation = 16;

MapParams g_map_params;

}  // namespace

MapParams set_map_params(const MapParams& params) {
    const MapParams old = g_map_params;
    g_map_params = params;
    g_map_params.window_bytes = std::max<size_t>(params.window_bytes, 1);
    return old;
}

// Plain files of at least MapParams::min_file_bytes are mapped: no copy, no buffer to fault in.
// Small files and gzip/memory input get a buffer, small inputs one of their own size;
// gzip input one for what its compressed size makes likely (it grows when a line needs
// more).
Input::Input(FileReader& reader) : reader_(reader) {
    if (map_file()) return;
    const uint64_t likely =
        reader.size_known() ? reader.size_bound() : reader.file_bytes() * kLikelyInflation;
    buf_.resize(size_t(std::min<uint64_t>(kBlockBytes, std::max<uint64_t>(likely, 4096))) + kPad);
    pos_ = end_ = buf_.data();
}

Input::~Input() {
    guard_.reset();
    if (map_) ::munmap(map_, map_bytes_);
}

bool Input::refill(size_t n) {
    if (map_) return slide(n);
    size_t have = avail();
    if (pos_ != buf_.data()) {
        base_ += uint64_t(pos_ - buf_.data());
        std::memmove(buf_.data(), pos_, have);
        pos_ = buf_.data();
        end_ = pos_ + have;
    }
    if (n > buf_.size() - kPad) {
        std::vector<char> bigger(std::max(n, 2 * (buf_.size() - kPad)) + kPad);
        std::memcpy(bigger.data(), buf_.data(), have);
        buf_.swap(bigger);
        pos_ = buf_.data();
        end_ = pos_ + have;
    }
    while (avail() < n && !eof_) {
        size_t room = buf_.size() - kPad - size_t(end_ - buf_.data());
        size_t got = reader_.read(const_cast<char*>(end_), room);
        if (got == 0) eof_ = true;
        end_ += got;
    }
    return avail() >= n;
}

// Maps the whole file read-only over a reservation one padding page longer, so loads past
// the end read zeros; the parser then sees the file through a window of window_ bytes
// (kBlockBytes but in tests) that slide() moves on. A file truncated by another process while it is
// read would fault; the guard turns the missing pages into zeros and check_unchanged() into an
// Error.
bool Input::map_file() {
    const int fd = reader_.plain_fd();
    const uint64_t size = reader_.file_bytes();
    if (fd < 0 || size == 0 || size < g_map_params.min_file_bytes || size > uint64_t(SIZE_MAX) / 2)
        return false;
    const size_t page = size_t(::sysconf(_SC_PAGESIZE));
    const size_t bytes = (size_t(size) + kPad + 2 * page - 1) / page * page;
    void* base = ::mmap(nullptr, bytes, PROT_READ, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (base == MAP_FAILED) return false;
    if (::mmap(base, size_t(size), PROT_READ, MAP_PRIVATE | MAP_FIXED, fd, 0) == MAP_FAILED) {
        ::munmap(base, bytes);
        return false;
    }
    try {
        guard_ = std::make_unique<MapGuard>(base, bytes, fd, reader_.path());
    } catch (const Error&) {
        ::munmap(base, bytes);  // too many mapped files at once: read this one
        return false;
    }
    ::madvise(base, size_t(size), MADV_SEQUENTIAL);
    map_ = static_cast<char*>(base);
    map_bytes_ = bytes;
    map_end_ = map_ + size;
    page_ = page;
    window_ = g_map_params.window_bytes;
    released_ = map_;
    pos_ = end_ = map_;
    return true;
}

// Moves the window of a mapped file to [pos, pos + max(n, window_)) and unmaps the pages
// before it, so resident memory stays about one window whatever the file size.
bool Input::slide(size_t n) {
    // The pages past a truncation read as zeros: stop at the next window, not at the end.
    if (guard_->faulted()) guard_->check();
    char* done = map_ + size_t(pos_ - map_) / page_ * page_;
    if (size_t(done - released_) >= kReleaseBytes) {
        ::madvise(released_, size_t(done - released_), MADV_DONTNEED);
        released_ = done;
    }
    const char* old_end = end_;
    end_ = pos_ + std::min(size_t(map_end_ - pos_), std::max(n, window_));
    eof_ = end_ == map_end_;
    // Map the window's pages in one call rather than one fault per 16 pages.
    char* from = map_ + size_t(std::max(old_end, pos_) - map_) / page_ * page_;
    if (end_ > from) ::madvise(from, size_t(end_ - from), kPopulateRead);
    return avail() >= n;
}

}  // namespace kdt::ply
