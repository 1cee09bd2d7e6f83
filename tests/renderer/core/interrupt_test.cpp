#include <fcntl.h>
#include <pthread.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <thread>

#include <gtest/gtest.h>

#include "renderer/core/interrupt.h"
#include "renderer/core/temp_file.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

namespace fs = std::filesystem;

TEST(Interrupt, RegistryHoldsPathsUntilUnregistered) {
    interrupt::reset_for_testing();
    std::vector<int> slots;
    for (int i = 0; i < 5; ++i) {
        const std::string p = "/tmp/kdt-registry-" + std::to_string(i);
        slots.push_back(interrupt::register_temp(p.c_str()));
        EXPECT_GE(slots.back(), 0);
    }
    EXPECT_EQ(interrupt::registered_temp_count(), 5);
    for (int s : slots) interrupt::unregister_temp(s);
    EXPECT_EQ(interrupt::registered_temp_count(), 0);
    // Too long for the handler's table: refused (the owner still removes it itself).
    EXPECT_EQ(interrupt::register_temp(std::string(size_t(interrupt::kMaxTempPath), 'x').c_str()),
              -1);
    interrupt::unregister_temp(-1);  // harmless
    // A full table refuses further paths instead of overwriting one.
    slots.clear();
    for (int i = 0; i < interrupt::kMaxTempFiles; ++i)
        slots.push_back(interrupt::register_temp("p"));
    EXPECT_EQ(interrupt::register_temp("q"), -1);
    for (int s : slots) interrupt::unregister_temp(s);
    EXPECT_EQ(interrupt::registered_temp_count(), 0);
}

TEST(Interrupt, FinishWorkModeRecordsTheSignalAndTheWatcherReacts) {
    for (int sig : {SIGINT, SIGTERM}) {
        interrupt::reset_for_testing();
        interrupt::install(interrupt::Mode::finish_work);
        EXPECT_FALSE(interrupt::requested());
        EXPECT_EQ(interrupt::exit_code(), 0);
        std::atomic<int> calls{0};
        {
            interrupt::Watcher watcher([&calls] { ++calls; }, 1);
            std::this_thread::sleep_for(std::chrono::milliseconds(20));
            EXPECT_EQ(calls.load(), 0);  // nothing before a signal
            ASSERT_EQ(::raise(sig), 0);
            EXPECT_TRUE(interrupt::requested());
            for (int i = 0; i < 2000 && calls.load() < 3; ++i)
                std::this_thread::sleep_for(std::chrono::milliseconds(1));
            EXPECT_GE(calls.load(), 3);  // repeated, not once
        }
        EXPECT_EQ(interrupt::signal_number(), sig);
        EXPECT_STREQ(interrupt::signal_name(), sig == SIGINT ? "SIGINT" : "SIGTERM");
        EXPECT_EQ(interrupt::exit_code(), sig == SIGINT ? 130 : 143);
    }
    interrupt::reset_for_testing();
    interrupt::install(interrupt::Mode::exit_now);
}

// A signal can land between a failing call and its errno check: the handler must leave errno
// as it found it, also when its notice cannot be written (stderr open read-only here, so the
// write fails with EBADF). Sent from another thread while this one waits in join(), so that
// ThreadSanitizer takes it as asynchronous and checks errno too (it skips SIGTERM); it restores
// errno itself and writes its report to the same read-only stderr, so under TSan a regression
// shows only as the exit status 66.
TEST(Interrupt, FinishWorkNoticeKeepsErrno) {
    interrupt::reset_for_testing();
    interrupt::install(interrupt::Mode::finish_work);
    const int saved_stderr = ::dup(STDERR_FILENO);
    const int read_only = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
    ASSERT_GE(saved_stderr, 0);
    ASSERT_GE(read_only, 0);
    ASSERT_EQ(::dup2(read_only, STDERR_FILENO), STDERR_FILENO);
    const pthread_t self = pthread_self();
    errno = ERANGE;
    std::thread([self] { pthread_kill(self, SIGINT); }).join();
    const int err = errno;
    ::dup2(saved_stderr, STDERR_FILENO);
    ::close(saved_stderr);
    ::close(read_only);
    EXPECT_TRUE(interrupt::requested());
    EXPECT_EQ(err, ERANGE) << std::strerror(err);
    interrupt::reset_for_testing();
    interrupt::install(interrupt::Mode::exit_now);
}

// In exit_now mode the first signal, and in finish_work mode the second, removes the
// temporary files and kills the process with the signal.
void die_with_temp_files(const fs::path& dir, interrupt::Mode mode, int sig) {
    interrupt::reset_for_testing();
    interrupt::install(mode);
    TempFile a((dir / "a.png").string());
    TempFile b((dir / "b.kdt").string());
    a.write("data", 4);
    ::raise(sig);
    if (mode == interrupt::Mode::finish_work) ::raise(sig);
    std::fprintf(stderr, "still alive\n");
    std::_Exit(0);
}

TEST(InterruptDeathTest, SignalsRemoveTemporaryFiles) {
    GTEST_FLAG_SET(death_test_style, "threadsafe");
    int n = 0;
    for (interrupt::Mode mode : {interrupt::Mode::exit_now, interrupt::Mode::finish_work}) {
        for (int sig : {SIGINT, SIGTERM}) {
            const fs::path dir = test::temp_dir("interrupt_death_" + std::to_string(n++));
            EXPECT_EXIT(die_with_temp_files(dir, mode, sig), ::testing::KilledBySignal(sig), "");
            EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 0)
                << dir;
        }
    }
}

// Report mode records the first signal without a word; die_now() from another thread then
// removes the temporary files, says its last words and dies of that signal.
void report_then_die_now(const fs::path& dir, int sig) {
    interrupt::reset_for_testing();
    interrupt::install(interrupt::Mode::report);
    TempFile a((dir / "a.png").string());
    a.write("data", 4);
    ::raise(sig);
    if (!interrupt::requested()) std::_Exit(2);
    std::thread([] { interrupt::die_now([] { std::fprintf(stderr, "last words\n"); }); }).join();
    std::_Exit(0);
}

TEST(InterruptDeathTest, ReportModeIsSilentAndDieNowEndsWithTheSignal) {
    GTEST_FLAG_SET(death_test_style, "threadsafe");
    for (int sig : {SIGINT, SIGTERM}) {
        const fs::path dir = test::temp_dir("interrupt_report_" + std::to_string(sig));
        EXPECT_EXIT(report_then_die_now(dir, sig), ::testing::KilledBySignal(sig),
                    "^last words\n$");
        EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 0) << dir;
    }
}

// The kernel hands a process-directed signal to any thread that does not block it: here
// the handler runs on `other` and removes the file that this thread is committing. The
// process must still die of the signal, with no file written and no error reported.
void commit_while_another_thread_dies(const fs::path& dir) {
    interrupt::reset_for_testing();
    interrupt::install(interrupt::Mode::exit_now);
    std::thread other([] {
        for (;;) ::pause();
    });
    other.detach();
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGINT);
    pthread_sigmask(SIG_BLOCK, &set, nullptr);  // after `other` started: only it takes SIGINT
    TempFile tmp((dir / "tree.kdt").string());
    tmp.write("data", 4);
    ::kill(::getpid(), SIGINT);
    while (!interrupt::dying()) std::this_thread::yield();
    tmp.commit();  // blocks until the handler's raise() ends the process
    std::fprintf(stderr, "committed\n");
    std::_Exit(0);
}

TEST(InterruptDeathTest, CommitRacingTheHandlerOnAnotherThreadDiesOfTheSignal) {
    GTEST_FLAG_SET(death_test_style, "threadsafe");
    const fs::path dir = test::temp_dir("interrupt_death_commit");
    EXPECT_EXIT(commit_while_another_thread_dies(dir), ::testing::KilledBySignal(SIGINT), "");
    EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 0) << dir;
}

// While a handler is ending the process (here only marked so: no signal, no handler), a
// commit neither renames its file over the target nor returns or throws. 200 ms is ample for
// an unguarded commit of 4 bytes; a slower machine could only hide a regression.
void commit_while_dying(const fs::path& dir) {
    TempFile tmp((dir / "tree.kdt").string());
    tmp.write("data", 4);
    interrupt::set_dying_for_testing();
    std::atomic<bool> returned{false};
    std::thread committer([&] {
        try {
            tmp.commit();
        } catch (...) {
        }
        returned.store(true);
    });
    committer.detach();
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    const bool written = fs::exists(dir / "tree.kdt");
    std::fprintf(stderr, "written %d, returned %d\n", int(written), int(returned.load()));
    std::_Exit(0);
}

TEST(InterruptDeathTest, CommitWaitsWhileTheProcessIsDying) {
    GTEST_FLAG_SET(death_test_style, "threadsafe");
    const fs::path dir = test::temp_dir("interrupt_death_dying");
    EXPECT_EXIT(commit_while_dying(dir), ::testing::ExitedWithCode(0), "written 0, returned 0");
}

// A signal that comes while another thread is renaming its file over the target (its slot
// claimed) lets the rename finish: the file is complete, and the notice names it instead of
// claiming that nothing was written.
void signal_during_rename(const fs::path& dir) {
    interrupt::reset_for_testing();
    interrupt::install(interrupt::Mode::exit_now);
    interrupt::set_exit_notice("interrupted; nothing written");
    std::thread other([] {
        for (;;) ::pause();
    });
    other.detach();
    interrupt::set_commit_hook_for_testing([] {
        ::kill(::getpid(), SIGINT);  // blocked on this thread: `other` takes it
        while (!interrupt::dying()) std::this_thread::yield();
        std::this_thread::sleep_for(std::chrono::milliseconds(50));  // the handler waits
    });
    TempFile tmp((dir / "tree.kdt").string());
    tmp.write("data", 4);
    tmp.commit();
    for (;;) ::pause();  // the signal unblocked at the end of the commit ends the process
}

TEST(InterruptDeathTest, SignalDuringTheRenameKeepsTheFileAndSaysSo) {
    GTEST_FLAG_SET(death_test_style, "threadsafe");
    const fs::path dir = test::temp_dir("interrupt_death_rename");
    EXPECT_EXIT(signal_during_rename(dir), ::testing::KilledBySignal(SIGINT),
                "^kdtrace: SIGINT: interrupted after writing [^\n]*/tree\\.kdt\n$");
    EXPECT_EQ(test::read_bytes(dir / "tree.kdt"), (std::vector<unsigned char>{'d', 'a', 't', 'a'}));
    EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1) << dir;
}

// The exit notice is the command's until a file is written; set_exit_notice() starts afresh.
void notice_after_commit(const fs::path& dir, bool set_again) {
    interrupt::reset_for_testing();
    interrupt::install(interrupt::Mode::exit_now);
    interrupt::set_exit_notice("interrupted; nothing written");
    write_file_atomically((dir / "a.kdt").string(), "data", 4);
    if (set_again) interrupt::set_exit_notice("interrupted; no image written");
    ::raise(SIGTERM);
    std::_Exit(0);
}

TEST(InterruptDeathTest, NoticeNamesAFileWrittenSinceItWasSet) {
    GTEST_FLAG_SET(death_test_style, "threadsafe");
    const fs::path dir = test::temp_dir("interrupt_death_notice");
    EXPECT_EXIT(notice_after_commit(dir, false), ::testing::KilledBySignal(SIGTERM),
                "^kdtrace: SIGTERM: interrupted after writing [^\n]*/a\\.kdt\n$");
    EXPECT_EXIT(notice_after_commit(dir, true), ::testing::KilledBySignal(SIGTERM),
                "^kdtrace: SIGTERM: interrupted; no image written\n$");
}

}  // namespace
}  // namespace kdt
