// SIGINT and SIGTERM: a flag that long-running work polls, and removal of temporary files
// on every exit path, signals included. Depends on the standard library and POSIX only.
#pragma once

#include <atomic>
#include <functional>
#include <thread>

namespace kdt::interrupt {

/// What the first SIGINT/SIGTERM does.
enum class Mode {
    /// Removes the registered temporary files and dies of the signal at once (the default:
    /// loading, building, writing).
    exit_now,
    /// Only records the signal (requested() turns true) so that the work in flight can stop
    /// cleanly and save what it has, and says so on stderr (after a line break when stderr is a
    /// terminal, to end the "^C" echo or a progress bar; none on a pipe or file); a second
    /// signal then behaves as exit_now.
    finish_work,
    /// As finish_work, without the notice: the caller says what it keeps (an MPI rank, whose
    /// message rank 0 alone prints).
    report,
};

/// Installs the SIGINT and SIGTERM handlers (install_handlers()) and sets the mode of the
/// first signal.
void install(Mode mode = Mode::exit_now);
/// In exit_now mode, the first signal writes "kdtrace: SIGINT: <notice>" (or SIGTERM) on a
/// line of its own to stderr before the process dies, e.g. "interrupted while loading; nothing
/// written"; nullptr (the default) dies without a word. When a TempFile was committed since
/// this call, the line says "interrupted after writing <its target>" instead. `notice` must
/// stay valid for the process's life (a string literal).
void set_exit_notice(const char* notice);
/// Installs the handlers once, leaving the mode as it is (exit_now unless set). A signal the
/// process inherited as ignored (nohup, a background job) stays ignored. TempFile calls it,
/// so that every temporary file is covered even in a command that never calls install().
void install_handlers();

/// True once a SIGINT or SIGTERM arrived (in finish_work mode; in exit_now mode the process
/// is gone). Async-signal-safe, lock-free.
bool requested();
/// The signal that arrived (SIGINT or SIGTERM), 0 when none.
int signal_number();
/// "SIGINT", "SIGTERM", or "" when none.
const char* signal_name();
/// The shell's exit status for the signal: 130 (SIGINT), 143 (SIGTERM), 0 when none.
int exit_code();
/// True once a signal is ending the process: its handler, on whichever thread the kernel
/// chose, is removing the registered temporary files and then dies of the signal.
/// Async-signal-safe.
bool dying();
/// Returns at once unless dying(); then blocks the calling thread until the process is gone.
/// TempFile calls it before its rename and when the rename fails: a file the handler removes
/// under another thread must end as that signal's death, not as a written file or an error.
void wait_if_dying();
/// Flushes stdout and stderr and exits with exit_code() (static destructors run; the
/// caller has removed or committed its temporary files).
[[noreturn]] void exit_interrupted();
/// From any thread: what exit_now mode's handler does, for a signal that was only recorded.
/// Makes dying() true and removes the registered temporary files (so that a TempFile commit
/// in flight on another thread ends with the process, not as a written file), calls
/// `last_words` (a message), flushes stdout and stderr, and dies of the signal that arrived
/// (SIGTERM when none did).
[[noreturn]] void die_now(const std::function<void()>& last_words = {});

/// Temporary file registry: a fixed table the signal handler can read without locking.
/// Paths longer than kMaxTempPath (or beyond kMaxTempFiles at once) are still removed on
/// normal and exception exits by their owner (TempFile), only not from a signal.
inline constexpr int kMaxTempFiles = 64;
inline constexpr int kMaxTempPath = 4096;
/// Registers `path` for removal if a signal ends the process; returns a slot for
/// unregister_temp(), or -1 when it could not be registered.
int register_temp(const char* path);
/// Renames the registered temporary file `from` (in `slot`, or -1 when it could not be
/// registered) over `to`, as std::rename, without racing a handler that is removing the
/// temporary files: the outcome is either `to` written and recorded, so that the exit notice
/// says "interrupted after writing <to>" instead of its own text, or nothing written and the
/// calling thread blocked until the signal ends the process (as wait_if_dying()). Returns
/// false with errno set when the rename fails. An unregistered file is only checked against
/// dying() before its rename.
bool commit_rename(int slot, const char* from, const char* to);
/// Forgets a slot (the file was renamed or removed); ignores -1.
void unregister_temp(int slot);
/// Paths registered now (for tests).
int registered_temp_count();

/// Calls `on_request` from a thread of its own every `poll_ms` milliseconds once requested()
/// is true, until destroyed: e.g. RenderSession::cancel(), whose flag a new pass clears, so
/// it is repeated until the render loop has seen it. Joins its thread on destruction.
class Watcher {
public:
    explicit Watcher(std::function<void()> on_request, int poll_ms = 10);
    ~Watcher();
    Watcher(const Watcher&) = delete;
    Watcher& operator=(const Watcher&) = delete;

private:
    std::atomic<bool> stop_{false};
    std::thread thread_;
};

/// For tests: forgets a received signal (requested() false again).
void reset_for_testing();
/// For tests: makes dying() true without a signal or a handler (nothing will end the process).
void set_dying_for_testing();
/// For tests: commit_rename() calls `hook` (unless null) just before its rename, with its slot
/// claimed and SIGINT/SIGTERM blocked on its thread.
void set_commit_hook_for_testing(void (*hook)());

}  // namespace kdt::interrupt
