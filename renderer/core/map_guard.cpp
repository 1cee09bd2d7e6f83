#include "renderer/core/map_guard.h"

#include <signal.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <atomic>
#include <mutex>

#include "renderer/core/error.h"

namespace kdt {
namespace {

// A guarded region [begin, end), end rounded up to whole pages; begin 0 marks a free slot.
// The handler reads the slots without a lock, so they are lock-free atomics.
struct Slot {
    std::atomic<uintptr_t> begin{0}, end{0};
    std::atomic<bool> faulted{false};
};

Slot g_slots[MapGuard::kMaxMapGuards];
std::mutex g_mutex;  // guards g_guards, g_previous and the slots' (de)registration
int g_guards = 0;
struct sigaction g_previous {};
uintptr_t g_page = 4096;
void (*g_test_hook)(const std::string&) = nullptr;

int64_t mtime_ns(const struct stat& st) {
    return int64_t(st.st_mtim.tv_sec) * 1000000000 + int64_t(st.st_mtim.tv_nsec);
}

// Runs on the faulting thread. A fault inside a guarded region is a read past the end of a
// file that shrank: zero pages from the faulting one to the region's end make the read (and
// every later one) succeed, and the slot records the fault. Everything else goes to the
// handler installed before, or kills the process as SIGBUS would have without us.
void on_sigbus(int sig, siginfo_t* info, void* context) {
    const auto addr = reinterpret_cast<uintptr_t>(info->si_addr);
    if (info->si_code > 0) {  // raised by the kernel for a fault, not sent by kill()
        for (Slot& s : g_slots) {
            const uintptr_t begin = s.begin.load(std::memory_order_acquire);
            const uintptr_t end = s.end.load(std::memory_order_acquire);
            if (begin == 0 || addr < begin || addr >= end) continue;
            const uintptr_t from = addr / g_page * g_page;
            void* zeros = ::mmap(reinterpret_cast<void*>(from), end - from, PROT_READ,
                                 MAP_PRIVATE | MAP_ANONYMOUS | MAP_FIXED, -1, 0);
            if (zeros == MAP_FAILED) break;
            s.faulted.store(true, std::memory_order_release);
            return;
        }
    }
    if (g_previous.sa_flags & SA_SIGINFO) {
        g_previous.sa_sigaction(sig, info, context);
        return;
    }
    if (g_previous.sa_handler == SIG_IGN && info->si_code <= 0) return;
    if (g_previous.sa_handler != SIG_DFL && g_previous.sa_handler != SIG_IGN) {
        g_previous.sa_handler(sig);
        return;
    }
    // The default action: a fault repeats on return and now kills; a sent signal is re-sent.
    struct sigaction dfl {};
    dfl.sa_handler = SIG_DFL;
    ::sigemptyset(&dfl.sa_mask);
    ::sigaction(SIGBUS, &dfl, nullptr);
    if (info->si_code <= 0) ::raise(sig);
}

}  // namespace

MapGuard::MapGuard(const void* data, size_t bytes, int fd, std::string path)
    : path_(std::move(path)), fd_(fd) {
    struct stat st {};
    if (fd >= 0 && ::fstat(fd, &st) == 0) {
        size_ = int64_t(st.st_size);
        mtime_ns_ = mtime_ns(st);
    }
    if (data != nullptr && bytes > 0) {
        std::lock_guard<std::mutex> lock(g_mutex);
        for (int i = 0; i < kMaxMapGuards; ++i) {
            if (g_slots[i].begin.load(std::memory_order_relaxed) == 0) {
                slot_ = i;
                break;
            }
        }
        if (slot_ < 0) {
            throw Error(ErrorLocation{path_}, "more than " + std::to_string(kMaxMapGuards) +
                                                  " mapped files open at once");
        }
        if (g_guards++ == 0) {
            g_page = uintptr_t(::sysconf(_SC_PAGESIZE));
            struct sigaction action {};
            action.sa_sigaction = on_sigbus;
            action.sa_flags = SA_SIGINFO | SA_RESTART;
            ::sigemptyset(&action.sa_mask);
            ::sigaction(SIGBUS, &action, &g_previous);
        }
        const auto begin = reinterpret_cast<uintptr_t>(data);
        Slot& s = g_slots[slot_];
        s.faulted.store(false, std::memory_order_relaxed);
        s.end.store((begin + bytes + g_page - 1) / g_page * g_page, std::memory_order_relaxed);
        s.begin.store(begin, std::memory_order_release);
    }
    if (g_test_hook) g_test_hook(path_);
}

MapGuard::~MapGuard() {
    if (slot_ < 0) return;
    std::lock_guard<std::mutex> lock(g_mutex);
    g_slots[slot_].begin.store(0, std::memory_order_release);
    g_slots[slot_].end.store(0, std::memory_order_release);
    if (--g_guards == 0) ::sigaction(SIGBUS, &g_previous, nullptr);
}

bool MapGuard::faulted() const {
    return slot_ >= 0 && g_slots[slot_].faulted.load(std::memory_order_acquire);
}

void MapGuard::check() const {
    bool changed = faulted();
    struct stat st {};
    if (!changed && fd_ >= 0 && size_ >= 0 && ::fstat(fd_, &st) == 0)
        changed = int64_t(st.st_size) != size_ || mtime_ns(st) != mtime_ns_;
    if (changed)
        throw Error(ErrorLocation{path_}, "the file changed or was truncated while it was read");
}

void set_map_guard_test_hook(void (*hook)(const std::string& path)) { g_test_hook = hook; }

}  // namespace kdt
