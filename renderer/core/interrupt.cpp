#include "renderer/core/interrupt.h"

#include <pthread.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <mutex>

namespace kdt::interrupt {
namespace {

// A slot is free (0), being written or cleared by its owner (1), holds a path the signal
// handler may remove (2), is being renamed over its target by commit_rename() (3: the handler
// waits for the rename instead of racing it), or was claimed and removed by the handler (4).
struct Slot {
    std::atomic<int> state{0};
    char path[kMaxTempPath];
};
Slot g_slots[kMaxTempFiles];
std::atomic<int> g_signal{0};
std::atomic<int> g_mode{int(Mode::exit_now)};
std::atomic<bool> g_dying{false};
std::atomic<const char*> g_exit_notice{nullptr};
// The first file commit_rename() wrote since the last set_exit_notice(): none (0), being
// recorded (1), or in g_written_path (2). The handler's notice must not say "nothing
// written" once something was.
std::atomic<int> g_written_state{0};
char g_written_path[kMaxTempPath];
std::atomic<void (*)()> g_commit_hook{nullptr};
// Whether stderr was a terminal when the handlers were installed (isatty() is not
// async-signal-safe): a notice then starts on a new line.
std::atomic<bool> g_stderr_tty{false};
static_assert(std::atomic<int>::is_always_lock_free && std::atomic<bool>::is_always_lock_free &&
                  std::atomic<const char*>::is_always_lock_free,
              "the handler needs lock-free atomics");

void write_stderr(const char* s) {
    // write(2) is async-signal-safe; a short or failed write of a notice is harmless.
    const ssize_t ignored = ::write(STDERR_FILENO, s, std::strlen(s));
    (void)ignored;
}

void sleep_ms(long ms) {
    struct timespec ts {};
    ts.tv_nsec = ms * 1000000L;
    ::nanosleep(&ts, nullptr);  // async-signal-safe
}

// Removes the registered temporary files; a file being renamed by commit_rename() on another
// thread is left to finish (one rename, bounded here at 10 s in case that thread is stopped),
// so that the outcome is either the file committed and recorded, or no file. Called once
// g_dying is true: commit_rename() checks it after claiming its slot (both sequentially
// consistent), so a slot is either claimed first and seen here as 3, or not committed.
void settle_registered_temps() {
    for (Slot& s : g_slots) {
        int expected = 2;
        if (s.state.compare_exchange_strong(expected, 4)) {
            ::unlink(s.path);
        } else if (expected == 3) {
            for (int i = 0; i < 10000 && s.state.load() == 3; ++i) sleep_ms(1);
        }
    }
}

// "kdtrace: SIGINT: <text>" on a line of its own. Only async-signal-safe calls.
void write_notice(int sig, const char* text, const char* path = nullptr) {
    if (g_stderr_tty.load()) write_stderr("\n");
    write_stderr(sig == SIGINT ? "kdtrace: SIGINT: " : "kdtrace: SIGTERM: ");
    write_stderr(text);
    if (path) write_stderr(path);
    write_stderr("\n");
}

// Dies of `sig` itself (so a parent shell sees a death by signal, status 128 + sig), after
// removing the temporary files and writing `notice` (unless null), or instead of it, when a
// file was written since it was set, which file. Only async-signal-safe calls.
[[noreturn]] void die(int sig, const char* notice) {
    g_dying.store(true);  // before any removal: a committing thread checks it (commit_rename)
    settle_registered_temps();
    if (notice) {
        if (g_written_state.load() == 2)
            write_notice(sig, "interrupted after writing ", g_written_path);
        else
            write_notice(sig, notice);
    }
    struct sigaction dfl {};
    dfl.sa_handler = SIG_DFL;
    sigemptyset(&dfl.sa_mask);
    ::sigaction(sig, &dfl, nullptr);
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, sig);
    ::raise(sig);  // pending while the handler blocks it; delivered at the unblock
    ::sigprocmask(SIG_UNBLOCK, &set, nullptr);
    ::_exit(128 + sig);  // not reached unless the signal was somehow not fatal
}

void handler(int sig) {
    // The interrupted code may be between a failed call and its errno check, and the notice's
    // write() sets errno when it fails (stderr closed, a closed pipe).
    const int saved_errno = errno;
    int none = 0;
    const bool first = g_signal.compare_exchange_strong(none, sig);
    const int mode = g_mode.load();
    if (first && mode != int(Mode::exit_now)) {
        if (mode == int(Mode::finish_work)) {
            write_notice(sig, sig == SIGINT
                                  ? "finishing the tiles in flight and saving (interrupt again "
                                    "to quit at once)"
                                  : "finishing the tiles in flight and saving (signal again to "
                                    "quit at once)");
        }
        errno = saved_errno;
        return;
    }
    die(sig, first ? g_exit_notice.load() : nullptr);
}

}  // namespace

void install(Mode mode) {
    g_mode.store(int(mode));
    install_handlers();
}

void set_exit_notice(const char* notice) {
    g_written_state.store(0);
    g_exit_notice.store(notice);
}

void install_handlers() {
    static std::once_flag once;
    std::call_once(once, [] {
        g_stderr_tty.store(::isatty(STDERR_FILENO) == 1);
        for (int sig : {SIGINT, SIGTERM}) {
            struct sigaction old {};
            if (::sigaction(sig, nullptr, &old) == 0 && old.sa_handler == SIG_IGN) continue;
            struct sigaction sa {};
            sa.sa_handler = handler;
            sigemptyset(&sa.sa_mask);
            sigaddset(&sa.sa_mask, SIGINT);  // one handler at a time, whichever signal
            sigaddset(&sa.sa_mask, SIGTERM);
            sa.sa_flags = SA_RESTART;
            ::sigaction(sig, &sa, nullptr);
        }
    });
}

bool requested() { return g_signal.load() != 0; }

int signal_number() { return g_signal.load(); }

const char* signal_name() {
    switch (g_signal.load()) {
        case SIGINT:
            return "SIGINT";
        case SIGTERM:
            return "SIGTERM";
        default:
            return "";
    }
}

int exit_code() {
    const int sig = g_signal.load();
    return sig ? 128 + sig : 0;
}

bool dying() { return g_dying.load(); }

void wait_if_dying() {
    // The dying thread's raise() ends every thread, this one included.
    while (g_dying.load()) ::pause();
}

void exit_interrupted() {
    std::fflush(stdout);
    std::fflush(stderr);
    std::exit(exit_code());
}

void die_now(const std::function<void()>& last_words) {
    const int sig = g_signal.load();
    g_dying.store(true);  // before the removal, as in die()
    settle_registered_temps();
    if (last_words) last_words();
    std::fflush(stdout);
    std::fflush(stderr);
    die(sig ? sig : SIGTERM, nullptr);
}

int register_temp(const char* path) {
    const size_t n = std::strlen(path);
    if (n >= size_t(kMaxTempPath)) return -1;
    for (int i = 0; i < kMaxTempFiles; ++i) {
        int expected = 0;
        if (!g_slots[i].state.compare_exchange_strong(expected, 1)) continue;
        std::memcpy(g_slots[i].path, path, n + 1);
        g_slots[i].state.store(2);
        return i;
    }
    return -1;
}

bool commit_rename(int slot, const char* from, const char* to) {
    // With SIGINT and SIGTERM blocked here, the handler never runs on this thread while the
    // slot is claimed (it would wait for itself); one that arrives meanwhile runs at the
    // unblock, and then finds the file recorded as written.
    sigset_t block, old;
    sigemptyset(&block);
    sigaddset(&block, SIGINT);
    sigaddset(&block, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &block, &old);
    Slot* s = slot >= 0 && slot < kMaxTempFiles ? &g_slots[slot] : nullptr;
    bool claimed = false;
    if (s) {
        int expected = 2;
        claimed = s->state.compare_exchange_strong(expected, 3);
    }
    if (g_dying.load()) {
        // The handler removed the file (the claim failed), or will wait for this slot.
        if (claimed) {
            ::unlink(from);
            s->state.store(2);
        }
        pthread_sigmask(SIG_SETMASK, &old, nullptr);
        wait_if_dying();
    }
    if (void (*hook)() = g_commit_hook.load()) hook();
    const bool ok = std::rename(from, to) == 0;
    const int err = errno;
    if (ok) {
        const size_t n = std::strlen(to);
        int none = 0;
        if (n < size_t(kMaxTempPath) && g_written_state.compare_exchange_strong(none, 1)) {
            std::memcpy(g_written_path, to, n + 1);
            g_written_state.store(2);
        }
    }
    if (claimed) s->state.store(2);
    pthread_sigmask(SIG_SETMASK, &old, nullptr);
    errno = err;
    return ok;
}

void unregister_temp(int slot) {
    if (slot >= 0 && slot < kMaxTempFiles) g_slots[slot].state.store(0);
}

int registered_temp_count() {
    int n = 0;
    for (const Slot& s : g_slots) n += s.state.load() == 2;
    return n;
}

Watcher::Watcher(std::function<void()> on_request, int poll_ms)
    : thread_([this, f = std::move(on_request), poll_ms] {
          while (!stop_.load()) {
              if (requested()) f();
              std::this_thread::sleep_for(std::chrono::milliseconds(poll_ms));
          }
      }) {}

Watcher::~Watcher() {
    stop_.store(true);
    thread_.join();
}

void reset_for_testing() { g_signal.store(0); }

void set_dying_for_testing() { g_dying.store(true); }

void set_commit_hook_for_testing(void (*hook)()) { g_commit_hook.store(hook); }

}  // namespace kdt::interrupt
