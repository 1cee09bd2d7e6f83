// The MPI process context of a distributed render: init and finalize, rank and size, a
// watchdog that aborts every rank after a timeout, and the collective checks every farm runs
// before any work (every rank loaded the same scene and tree, or all stop with one message).
// Compiled only with MPI (KDT_WITH_MPI). Depends on render.
#pragma once

#include <array>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <mpi.h>

#include "renderer/core/interrupt.h"
#include "renderer/dist/mpi_buffer.h"
#include "renderer/render/prepare.h"

namespace kdt::dist {

/// A failure every rank agreed on (a rank could not load, or ranks disagree). what() is the
/// one message to print; `report` is true on rank 0 only, so that one rank prints it.
class FarmError : public std::runtime_error {
public:
    FarmError(const std::string& message, bool report)
        : std::runtime_error(message), report_(report) {}
    bool report() const { return report_; }

private:
    bool report_;
};

/// The farm's --timeout expired (thrown by MpiContext::check_timeout on every rank). Such a
/// rank must not finalize: an abandoned non-blocking operation may still write into freed
/// buffers, and MPI_Finalize waits for ranks that may never come; end_after_timeout() ends it.
class FarmTimeout : public FarmError {
public:
    using FarmError::FarmError;
};

/// SIGINT or SIGTERM arrived (thrown by MpiContext::check_timeout once
/// MpiContext::watch_interrupts() is on). Such a rank must not finalize either (the other
/// ranks are being ended, and MPI_Finalize waits for them); end_after_interrupt() ends it.
class FarmInterrupted : public FarmError {
public:
    using FarmError::FarmError;
};

/// The largest text MpiContext::broadcast() sends or accepts: rank 0's options are a few
/// kilobytes (file names, not their contents).
inline constexpr uint64_t kMaxBroadcastBytes = uint64_t(1) << 24;

/// Test-only malformed length-prefixed messages, one kind per check of their receiver: a
/// message shorter than its header (header), a text half as long as announced (short; an
/// empty text announced as 1 byte), 8
/// bytes more than announced (long), a header announcing 2^60 bytes (huge). Rank 0's options
/// message to a worker (MpiContext::broadcast(), --mpi-inject RANK:options-*) and a worker's
/// load log to rank 0 (prepare_everywhere(), --mpi-inject RANK:log-*).
enum class BadBroadcast { none, header, short_text, long_text, huge_length };
inline constexpr std::array<const char*, 5> kBadBroadcastNames = {
    "none", "options-header", "options-short", "options-long", "options-huge"};
inline constexpr std::array<const char*, 5> kBadLogNames = {"none", "log-header", "log-short",
                                                            "log-long", "log-huge"};

/// A worker failed alone after the collective checks (MpiContext::end_after_failure() on
/// that worker), thrown by MpiContext::check_timeout() on rank 0: what() is the worker's line,
/// "rank R: <reason>". Rank 0 must not finalize either; end_after_failure() ends it.
class FarmRankFailed : public FarmError {
public:
    using FarmError::FarmError;
};

/// MPI_Init_thread on construction,
/// MPI_Finalize on destruction. One per process. Depends on core/interrupt for signals.
class MpiContext {
public:
    MpiContext();
    ~MpiContext();
    MpiContext(const MpiContext&) = delete;
    MpiContext& operator=(const MpiContext&) = delete;

    int rank() const { return rank_; }
    int size() const { return size_; }

    /// After `seconds` (> 0) without stop_watchdog(), expired() turns true: the farm's waits
    /// poll it and throw FarmTimeout, and end_after_timeout() ends the job: rank 0 prints the
    /// message and exits with status 1 without MPI_Finalize, and mpirun then ends every other
    /// rank (MPI_Abort is not used: Open MPI 4.1.4's mpirun can hang in PMIx_server_finalize
    /// after it). When rank 0's main thread is stuck outside the waits (a blocking call, a
    /// long load), its watchdog does the same 1 s later; a worker still running
    /// `grace_seconds` after expiry (rank 0 stopped or stuck) prints "rank R: --timeout S s
    /// reached ..." and ends with status 3.
    void start_watchdog(double seconds, double grace_seconds = 5.0);
    bool expired() const { return expired_.load(std::memory_order_relaxed); }
    /// Throws FarmRankFailed on rank 0 once a worker reported its failure
    /// (end_after_failure()), FarmInterrupted once a signal arrived under watch_interrupts(),
    /// and FarmTimeout "--timeout S s reached: <pending>; ending every rank" once expired(),
    /// with what set_pending() describes on rank 0; in that order, so that a worker's failure
    /// is the news rather than the signals mpirun then sends. Before all of them a worker that
    /// rank 0 told the job ended (it printed why and exited) ends silently with status 1.
    void check_timeout() const;
    /// Rank 0: what the farm is waiting for, for the timeout message ("rank 2 of 3 had not
    /// answered"); empty = not known. Cleared with an empty function.
    void set_pending(std::function<std::string()> pending) const { pending_ = std::move(pending); }
    /// After a FarmTimeout: rank 0 prints `message` (once) and exits with status 1; a worker
    /// waits to be ended by mpirun (or by its watchdog). Never returns; never finalizes.
    [[noreturn]] void end_after_timeout(const std::string& message);
    double timeout_seconds() const { return timeout_; }
    void stop_watchdog();

    /// Makes SIGINT and SIGTERM end the job with one message. Open MPI's mpirun, given either,
    /// sends every rank SIGCONT, then SIGTERM 1 s later and SIGKILL 1 s after that
    /// (odls_base_sigkill_timeout, Open MPI 4.1.4). From this call on a signal is only
    /// recorded (interrupt::Mode::report): check_timeout() throws FarmInterrupted and
    /// end_after_interrupt() ends the rank. Rank 0 prints "interrupted (SIGTERM); <kept()>"
    /// and dies of the signal, without MPI_Finalize; its watcher thread does so itself when
    /// the main thread has not 0.25 s after the signal (a load, a long pass). A worker waits
    /// silently for mpirun to end it, or for rank 0 to say that the job ended (then it exits
    /// with status 1); one still running 2 s later (the signal was its own) prints "rank R:
    /// interrupted (SIGINT); ending this rank" and dies of it. `kept` is
    /// called on rank 0, on either thread, after the registered temporary files are removed.
    void watch_interrupts(std::function<std::string()> kept);
    /// After a FarmInterrupted, or once interrupt::requested(): ends the rank as
    /// watch_interrupts() says. Never returns; never finalizes.
    [[noreturn]] void end_after_interrupt();

    /// Ends the job after a failure of this rank alone, when the others may be waiting for it
    /// (mid-farm): they never reach MPI_Finalize, so this rank does not call it either, nor
    /// MPI_Abort (see start_watchdog()). Rank 0 prints "kdtrace: error: <line>" (printable())
    /// and exits with status 1; mpirun then ends the workers. A worker sends `line` to rank 0,
    /// which prints it at its next poll (check_timeout() throws FarmRankFailed) and ends the job,
    /// so that the one line on the terminal is the cause, not rank 0's "interrupted
    /// (SIGTERM)" after mpirun ends it for this worker's exit; the worker prints `line`
    /// itself and exits with status 1 only when it is still running failure_grace_seconds()
    /// later (rank 0 stuck); rank 0 tells every worker once it printed the line, and they end
    /// silently. From this call on a signal ends the rank silently with status 1.
    /// Never returns; never finalizes.
    [[noreturn]] void end_after_failure(const std::string& line);
    static constexpr double kFailureGraceSeconds = 10.0;
    /// How long end_after_failure() on a worker waits for rank 0 to end the job (default
    /// kFailureGraceSeconds; the app lets tests shorten it, docs/mpi.md).
    void set_failure_grace_seconds(double seconds) { failure_grace_ = seconds; }
    double failure_grace_seconds() const { return failure_grace_; }
    /// The job ends with a failure every rank knows of (a FarmError, printed by rank 0): from
    /// this call on a signal ends the rank silently with status 1, for it is mpirun ending a
    /// rank that is still finalizing after another one exited with status 1, no interrupt.
    void note_failure() { failed_.store(true); }

    /// Rank 0's `text` on every rank: one message to each worker, an 8-byte header holding
    /// the text's length, then the text. A worker trusts nothing in it: a message shorter than
    /// its header, a header announcing more than kMaxBroadcastBytes, or a text of another
    /// length than announced (shorter or longer) throws Error "the options from rank 0 are
    /// malformed: <problem>" before anything is allocated from the header, and a message over
    /// kMaxBroadcastBytes is not even received. On rank 0 a text over kMaxBroadcastBytes
    /// throws Error after its header went out (so that the workers fail too rather than
    /// wait). Test-only: rank `bad_rank` gets the malformed message `bad` says. Waits as
    /// wait() does.
    std::string broadcast(const std::string& text, int bad_rank = -1,
                          BadBroadcast bad = BadBroadcast::none) const;

    /// Waits for a non-blocking MPI operation without taking a core: a short spin, then
    /// MPI_Test every 50 us with sleeps in between (Open MPI's blocking calls poll at full
    /// speed unless mpi_yield_when_idle, which takes a core from the ranks still rendering
    /// on a machine with as many ranks as cores). Throws what check_timeout() throws.
    void wait(MPI_Request& request) const;
    /// The same polling for any condition (an MPI_Test, an MPI_Iprobe): returns once `done`
    /// returns true; throws what check_timeout() throws.
    void poll_until(const std::function<bool()>& done) const;

private:
    int rank_ = 0, size_ = 1;
    // Rank 0's process id when it runs on this rank's host (else 0): a worker ending after a
    // signal checks whether rank 0 is gone (rank0_gone()).
    int rank0_pid_ = 0;
    std::atomic<bool> expired_{false};
    double timeout_ = 0.0;
    double failure_grace_ = kFailureGraceSeconds;
    std::thread watchdog_;
    std::mutex mutex_;
    std::condition_variable cv_;
    bool stop_ = false;
    mutable std::function<std::string()> pending_;
    std::atomic<bool> reported_{false};  // rank 0 printed the timeout message
    std::function<std::string()> kept_;
    mutable std::atomic<bool> dying_{false};  // a thread is ending the process after a signal
    mutable std::atomic<bool> failed_{
        false};  // the job fails (note_failure()): a signal is no news
    std::unique_ptr<interrupt::Watcher> interrupt_watcher_;  // after kept_: joined first

    /// Ends the process after a signal: silently with status 1 once failed_, else with the
    /// interrupt's message and the signal.
    [[noreturn]] void die_interrupted() const;
    /// Rank 0, ending the job after printing why (end_after_failure(), end_after_timeout()):
    /// tells every worker, so that each ends silently with status 1 at its next poll (or while
    /// it waits to be ended) rather than report the SIGTERM mpirun sends it once rank 0 has
    /// exited: mpirun's SIGKILL, 1 s later, can come after a worker's 2 s of waiting for it on
    /// a loaded machine. Waits at most 0.5 s for the messages to go out.
    void tell_workers_the_job_ended() const;
    /// A worker: whether rank 0 said the job ended (then failed_ is set); false on rank 0.
    bool job_ended() const;
    /// A worker: whether rank 0 runs on this host and has exited (gone or a zombie). Safe on
    /// any thread (no MPI): rank 0 may have ended the job from its watcher thread, which
    /// cannot tell the workers.
    bool rank0_gone() const;
    /// A worker waiting to be ended (by mpirun, its watcher or its watchdog): ends silently
    /// once rank 0 says the job ended.
    [[noreturn]] void wait_for_the_end() const;
};

/// "rank 2 of 3" or "ranks 1, 2 of 3", for messages.
std::string rank_list(const std::vector<int>& ranks, int size);

/// Test-only faults injected on one rank (--mpi-inject RANK:WHAT).
struct InjectedFault {
    int rank = -1;  ///< -1 = none
    /// "load": the scene path cannot be opened; "hash": a different tree; "stall": the load
    /// never ends (until the job is ended); the app handles "write", "stop" and
    /// "interrupt"
    std::string what;
};

/// What ranks must agree on: named parts ("the kd-tree", "the environment map probe.hdr")
/// and their hashes, at most kMaxFingerprintParts; empty = nothing to compare.
using Fingerprint = std::vector<std::pair<std::string, uint64_t>>;
inline constexpr size_t kMaxFingerprintParts = 4;

/// Collective: every rank runs `step`, then all ranks compare outcomes. `what` names the step
/// ("load the scene"). When any rank's step threw, every rank throws FarmError "rank R of N
/// could not <what>: <reason>" (the lowest failing rank, and how many others failed), or "all
/// N ranks failed to <what>: <reason>" when every rank failed with the same reason. The
/// fingerprints `step` returns must agree part by part; for the first part that does not, every
/// rank throws FarmError naming it (rank 0's name) and the odd ranks: with 2 ranks "ranks 0 and 1
/// of 2 see a different <part>", with more the ranks outside the largest group ("rank 0 of 3 sees a
/// different <part> than the other ranks"), or "the ranks of N disagree on <part>" when no group is
/// largest.
void check_every_rank(const MpiContext& ctx, const std::string& what,
                      const std::function<Fingerprint()>& step);

/// Collective: every rank runs prepare_render(options) and then all ranks compare outcomes.
/// When any rank failed, every rank throws FarmError "rank R of N could not load the scene:
/// <reason>" (the lowest failing rank, and how many others failed; "all N ranks failed to
/// load the scene: <reason>" when all failed alike); when ranks loaded a
/// different mesh, tree, environment map or options (snapshot_fingerprint), the message
/// names the part and the odd ranks. No rank renders before every rank has loaded. `log` is
/// called on every rank with its own lines; after a good load rank 0's `log` also gets, once
/// per text, the workers' lines it did not say itself (times left aside), prefixed with the
/// ranks ("rank 1 of 3: kd-tree cache: cannot write to ..."). Rank 0 trusts nothing in a
/// worker's log message (its size and header are checked before anything is allocated from
/// them, as MpiContext::broadcast() checks the options): a malformed one makes every rank
/// throw FarmError "rank 0 of N could not read the load logs: the load log from rank R is
/// malformed: <problem>". Test-only: fault.what "log-header", "log-short", "log-long" or
/// "log-huge" (kBadLogNames) malforms rank fault.rank's log message.
Prepared prepare_everywhere(const MpiContext& ctx, const RenderOptions& options,
                            const PrepareLog& log, const InjectedFault& fault = {});

/// What must agree across ranks: the merged mesh's content, the tree's size, the
/// environment map's texels as loaded (when the environment is a map) and the options.
Fingerprint snapshot_fingerprint(const RenderSnapshot& snapshot, const std::string& options_json);

}  // namespace kdt::dist
