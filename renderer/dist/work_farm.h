// A master/worker farm of numbered work items (tiles of a frame, or whole frames) over MPI
// ranks. Rank 0 hands out items and also works on them between messages; workers keep
// several items in flight so they never wait for rank 0's reply. Items are given out
// dynamically (from one queue, on request) or by one of the thesis's static distributions
// (section 5.4: strips, or every n-th item to rank n), for comparison.
// Compiled only with MPI. Depends on dist/mpi_context.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <vector>

#include "renderer/dist/mpi_context.h"

namespace kdt::dist {

enum class Distribution { dynamic, interleaved, strips };
inline constexpr std::array<const char*, 3> kDistributionNames = {"dynamic", "interleaved",
                                                                  "strips"};

/// The items each rank renders under a static distribution, in rendering order: `strips`
/// gives rank r the rows [r R / N, (r + 1) R / N) of a grid of `columns` x R items,
/// `interleaved` gives it items r, r + N, r + 2N, ... `dynamic` gives every item to rank 0's
/// list (the shared queue).
std::vector<std::vector<int>> assign_items(Distribution d, int items, int columns, int ranks);

/// Test-only malformed messages (FarmParams::bad_message), one kind per check of the farm's
/// messages. result_*: a worker's first result has an item id it was not given (item), fewer
/// bytes than its header (header), a header announcing more item ids than it holds (ids), or
/// half of its result bytes (short). work_*: rank 0's first reply to a worker has an item id
/// out of range (item), one id twice (repeat), one item more than asked (count), or a size
/// that is not a whole number of ids (bytes).
enum class BadMessage {
    none,
    result_item,
    result_header,
    result_ids,
    result_short,
    work_item,
    work_repeat,
    work_count,
    work_bytes
};
inline constexpr std::array<const char*, 9> kBadMessageNames = {
    "none",      "result-item", "result-header", "result-ids", "result-short",
    "work-item", "work-repeat", "work-count",    "work-bytes"};

struct FarmParams {
    Distribution distribution = Distribution::dynamic;
    int columns = 1;  ///< items per row, for strips
    int batch = 1;    ///< items a rank renders between two messages
    /// Per worker: batches requested ahead, so that it need not wait for rank 0's reply. More
    /// than one hides rank 0's reply time but leaves items queued at a worker at the end.
    int batches_in_flight = 2;
    int throttle_rank = -1;  ///< test-only: this rank sleeps (factor - 1) x its render time
    double throttle_factor = 1.0;
    int stop_rank = -1;  ///< test-only: this rank hangs (sleeps forever) before its first item
    /// Test-only: this worker raises SIGTERM right after sending its first result and leaves
    /// the farm at once (FarmInterrupted), the send most likely still pending; memory it
    /// frees then is overwritten, so that a pending send whose buffer was freed shows.
    int interrupt_rank = -1;
    /// Test-only: the worker that sends (result_*) or receives (work_*) a malformed message.
    int bad_message_rank = -1;
    BadMessage bad_message = BadMessage::none;
    /// Test-only: once the malformed work message (work_*) is sent, rank 0 stops answering for
    /// good, sleeping without polling as a rank 0 stuck in a long call would, so that the
    /// worker's failure line never reaches it (MpiContext::end_after_failure()).
    bool stall_after_bad_work = false;
};

/// What one rank did, gathered on rank 0. idle = wall - busy.
struct RankStats {
    int32_t rank = 0;
    int32_t items = 0;
    double busy_seconds = 0.0;   ///< rendering (and throttle sleeps)
    double wall_seconds = 0.0;   ///< from the farm's start to this rank's last item sent
    double cpu_seconds = 0.0;    ///< CPU time of the process over the farm (all its threads):
                                 ///< below busy_seconds x threads when the machine is shared
    double serve_seconds = 0.0;  ///< rank 0: receiving, consuming and answering results
                                 ///< (part of busy_seconds while it renders)
    uint64_t messages = 0;       ///< sent and received by this rank
    uint64_t bytes = 0;          ///< sent and received by this rank
};

/// Renders items on the calling rank. `poll` (rank 0 only; a no-op elsewhere) may be called
/// between parts of a long item so rank 0 keeps serving workers. Returns the result bytes.
using RenderItems = std::function<std::vector<char>(const std::vector<int>& items,
                                                    const std::function<void()>& poll)>;
/// The size in bytes of the result of `items` (rank 0 checks every worker's against it).
using ResultSize = std::function<size_t(const std::vector<int>& items)>;
/// Rank 0: takes the result bytes of items rendered by any rank (in any order).
using ConsumeItems =
    std::function<void(const std::vector<int>& items, const char* bytes, size_t size)>;
/// Rank 0: items done so far of all, after each consume.
using FarmProgress = std::function<void(int done, int total)>;

/// Collective: every item in [0, items) is rendered exactly once by some rank and consumed on
/// rank 0. Returns every rank's stats on rank 0 (one entry per rank), only the caller's
/// elsewhere. On rank 0, a message that is not the result of items given to its sender, of
/// `size` bytes, throws Error "a result from rank R of N is malformed: ..." before any of it
/// is consumed. On a worker, a work message that is not a whole number of item ids, holds
/// more than the worker asked for, an id outside [0, items) or an id given before, throws
/// Error "a work message from rank 0 is malformed: ..." before any of it is rendered.
std::vector<RankStats> run_farm(const MpiContext& ctx, int items, const FarmParams& params,
                                const RenderItems& render, const ResultSize& size,
                                const ConsumeItems& consume, const FarmProgress& progress = {});

}  // namespace kdt::dist
