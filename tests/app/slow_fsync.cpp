// LD_PRELOAD shim for interrupt_test.sh: fsync() first sleeps 300 ms, so that the window in
// which a temporary file exists is long enough, on any machine, to stop the process inside
// it. Depends on POSIX only.
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

extern "C" int fsync(int fd) {
    struct timespec ts {};
    ts.tv_nsec = 300 * 1000000L;
    ::nanosleep(&ts, nullptr);
    return int(::syscall(SYS_fsync, fd));
}
