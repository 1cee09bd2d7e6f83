#include "renderer/dist/work_farm.h"

#include <mpi.h>

#include <csignal>
#include <cstdio>
#include <ctime>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <deque>
#include <exception>
#include <limits>
#include <list>
#include <set>
#include <string>
#include <thread>

#include "renderer/core/error.h"
#include "renderer/core/timer.h"

namespace kdt::dist {

namespace {

constexpr int kTagResult = 1;  // worker -> 0: header, item ids, result bytes
constexpr int kTagWork = 2;    // 0 -> worker: item ids; none = no more work

// A result message starts with this header, then `items` int32 ids, then the result bytes.
// `want` asks for that many more items (0 once the worker was told there are none).
struct ResultHeader {
    int32_t items = 0;
    int32_t want = 0;
};

std::vector<char> pack_result(const std::vector<int>& items, int want,
                              const std::vector<char>& payload) {
    const ResultHeader h{int32_t(items.size()), int32_t(want)};
    std::vector<char> msg(sizeof h + items.size() * sizeof(int32_t) + payload.size());
    std::memcpy(msg.data(), &h, sizeof h);
    if (!items.empty())  // memcpy from an empty vector's null data() is undefined
        std::memcpy(msg.data() + sizeof h, items.data(), items.size() * sizeof(int32_t));
    if (!payload.empty())
        std::memcpy(msg.data() + sizeof h + items.size() * sizeof(int32_t), payload.data(),
                    payload.size());
    return msg;
}

// "1 item", "3 items": for messages.
std::string items_text(int64_t n) { return std::to_string(n) + (n == 1 ? " item" : " items"); }

double process_cpu_seconds() {
    timespec ts{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

// MPI_Probe that gives up when the context's timeout expires (every rank's waits do, so
// all leave the farm together and finalize normally).
void probe(const MpiContext& ctx, int source, int tag, MPI_Status* st) {
    ctx.poll_until([&] {
        int flag = 0;
        MPI_Iprobe(source, tag, MPI_COMM_WORLD, &flag, st);
        return flag != 0;
    });
}

void throttle(const MpiContext& ctx, const FarmParams& p, double seconds) {
    if (ctx.rank() != p.throttle_rank || !(p.throttle_factor > 1.0)) return;
    const auto end = std::chrono::steady_clock::now() +
                     std::chrono::duration<double>(seconds * (p.throttle_factor - 1.0));
    while (std::chrono::steady_clock::now() < end) {
        ctx.check_timeout();
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
}

// Rank 0: the sources of items, the replies to requests, the consumption of results.
class Master {
public:
    Master(const MpiContext& ctx, int items, const FarmParams& params, const ResultSize& size,
           const ConsumeItems& consume, const FarmProgress& progress)
        : ctx_(ctx),
          total_(items),
          params_(params),
          result_size_(size),
          consume_(consume),
          progress_(progress),
          told_done_(size_t(ctx.size()), false),
          given_(size_t(ctx.size())) {
        const auto lists = assign_items(params.distribution, items, params.columns, ctx.size());
        for (const auto& l : lists) sources_.emplace_back(l.begin(), l.end());
    }

    // The next items for `rank` (its own list, or the shared queue when dynamic).
    std::vector<int> take(int rank, int want) {
        std::deque<int>& q =
            params_.distribution == Distribution::dynamic ? sources_[0] : sources_[size_t(rank)];
        std::vector<int> out;
        while (int(out.size()) < want && !q.empty()) {
            out.push_back(q.front());
            q.pop_front();
        }
        return out;
    }

    void done_items(const std::vector<int>& items, const char* bytes, size_t size) {
        consume_(items, bytes, size);
        done_ += int(items.size());
        if (progress_) progress_(done_, total_);
    }

    // Receives one message from `source` (MPI_ANY_SOURCE allowed) and answers it. A message
    // that is not a well-formed result of items given to its sender is an error naming the
    // sender, before any of it is consumed.
    void handle(int source) {
        MPI_Status st;
        probe(ctx_, source, kTagResult, &st);
        Timer serve;
        int size = 0;
        MPI_Get_count(&st, MPI_BYTE, &size);
        const int w = st.MPI_SOURCE;
        buffer_.resize(size_t(std::max(size, 0)));
        MPI_Recv(buffer_.data(), size, MPI_BYTE, w, kTagResult, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        stats.messages += 1;
        stats.bytes += uint64_t(size);
        ResultHeader h;
        const std::vector<int> items = parse_result(w, &h);
        const size_t off = sizeof(ResultHeader) + items.size() * sizeof(int32_t);
        if (!items.empty()) done_items(items, buffer_.data() + off, buffer_.size() - off);
        if (!told_done_[size_t(w)]) {
            const std::vector<int> next = take(w, std::max(h.want, 1));
            send_work(w, next, h.want);
            given_[size_t(w)].insert(next.begin(), next.end());
            stats.messages += 1;
            stats.bytes += next.size() * sizeof(int32_t);
            if (next.empty()) told_done_[size_t(w)] = true;
        }
        stats.serve_seconds += serve.seconds();
    }

    // Also between the passes of rank 0's own items: a signal or a timeout stops it there.
    void poll() {
        ctx_.check_timeout();
        int flag = 1;
        while (flag) {
            MPI_Iprobe(MPI_ANY_SOURCE, kTagResult, MPI_COMM_WORLD, &flag, MPI_STATUS_IGNORE);
            if (flag) handle(MPI_ANY_SOURCE);
        }
    }

    // For a timeout's message: the workers holding items they have not returned.
    std::string pending() const {
        std::vector<int> late;
        for (int w = 1; w < ctx_.size(); ++w)
            if (!given_[size_t(w)].empty()) late.push_back(w);
        if (late.empty()) return "";
        return rank_list(late, ctx_.size()) + " had not returned " +
               (late.size() == 1 ? "its" : "their") + " work";
    }

    void run(const RenderItems& render) {
        Timer wall;
        ctx_.set_pending([this] { return pending(); });
        struct Clear {
            const MpiContext& ctx;
            ~Clear() { ctx.set_pending({}); }
        } clear{ctx_};
        const std::function<void()> poll_fn = [this] { poll(); };
        while (done_ < total_) {
            poll();
            if (done_ >= total_) break;  // the last results came in while polling
            const std::vector<int> own = take(0, params_.batch);
            if (own.empty()) {
                handle(MPI_ANY_SOURCE);  // nothing of our own left: wait for results
                continue;
            }
            Timer t;
            const std::vector<char> bytes = render(own, poll_fn);
            throttle(ctx_, params_, t.seconds());
            stats.busy_seconds += t.seconds();
            stats.items += int32_t(own.size());
            done_items(own, bytes.data(), bytes.size());
        }
        stats.wall_seconds = wall.seconds();
        // Workers whose last request is unanswered (e.g. all items were done before their
        // first request arrived) learn that there is no more work.
        for (int w = 1; w < ctx_.size(); ++w) {
            while (!told_done_[size_t(w)]) handle(w);
        }
    }

    RankStats stats;

private:
    const MpiContext& ctx_;
    int total_, done_ = 0;
    FarmParams params_;
    const ResultSize& result_size_;
    const ConsumeItems& consume_;
    const FarmProgress& progress_;
    std::vector<std::deque<int>> sources_;
    std::vector<bool> told_done_;
    std::vector<std::set<int>> given_;  // per worker: items sent and not returned
    std::vector<char> buffer_;
    bool bad_sent_ = false;  // the test-only malformed work message went out

    // Sends `next` to worker `w`, which asked for `want`; the first non-empty reply to
    // FarmParams::bad_message_rank is malformed as FarmParams::bad_message says.
    void send_work(int w, std::vector<int> next, int want) {
        BadMessage bad = params_.bad_message;
        if (bad_sent_ || w != params_.bad_message_rank || next.empty()) bad = BadMessage::none;
        if (bad == BadMessage::work_item) next[0] = total_;
        if (bad == BadMessage::work_repeat) {
            if (next.size() > 1)
                next.back() = next[0];  // not one more than asked, if it can
            else
                next.push_back(next[0]);
        }
        if (bad == BadMessage::work_count) {
            while (int(next.size()) <= std::max(want, 1)) {
                const std::vector<int> more = take(w, 1);
                next.push_back(more.empty() ? next[0] : more[0]);
            }
        }
        if (bad == BadMessage::work_bytes) {
            std::vector<char> bytes(next.size() * sizeof(int32_t) + 2, 0);
            std::memcpy(bytes.data(), next.data(), next.size() * sizeof(int32_t));
            MPI_Send(bytes.data(), int(bytes.size()), MPI_BYTE, w, kTagWork, MPI_COMM_WORLD);
        } else {
            MPI_Send(next.data(), int(next.size()), MPI_INT, w, kTagWork, MPI_COMM_WORLD);
        }
        bad_sent_ = bad_sent_ || bad != BadMessage::none;
        // Until mpirun ends this rank, after the worker's exit (a signal is handled by the
        // interrupt watcher, not here).
        while (bad != BadMessage::none && params_.stall_after_bad_work)
            std::this_thread::sleep_for(std::chrono::seconds(1));
    }

    std::string bad_result(int w) const {
        return "a result from " + rank_list({w}, ctx_.size()) + " is malformed: ";
    }

    // The header and item ids of the message in buffer_ from worker `w`; marks the items
    // returned. Throws Error when the sizes disagree or an item was not given to `w`.
    std::vector<int> parse_result(int w, ResultHeader* h) {
        const size_t size = buffer_.size();
        if (size < sizeof *h) {
            throw Error(bad_result(w) + std::to_string(size) + " bytes, shorter than its " +
                        std::to_string(sizeof *h) + "-byte header");
        }
        std::memcpy(h, buffer_.data(), sizeof *h);
        if (h->items < 0 || h->want < 0 ||
            uint64_t(h->items) > (size - sizeof *h) / sizeof(int32_t)) {
            throw Error(bad_result(w) + std::to_string(size) + " bytes, but its header announces " +
                        items_text(h->items) + " and asks for " + std::to_string(h->want));
        }
        std::vector<int> items(size_t(h->items));
        if (!items.empty())
            std::memcpy(items.data(), buffer_.data() + sizeof *h, items.size() * sizeof(int32_t));
        for (int i : items) {
            if (given_[size_t(w)].erase(i) == 0) {
                throw Error(bad_result(w) + "item " + std::to_string(i) +
                            " was not given to it or was returned before");
            }
        }
        const size_t bytes = size - sizeof *h - items.size() * sizeof(int32_t);
        const size_t want = items.empty() ? 0 : result_size_(items);
        if (bytes != want) {
            throw Error(bad_result(w) + std::to_string(bytes) + " bytes of results for " +
                        items_text(int64_t(items.size())) + ", not " + std::to_string(want));
        }
        return items;
    }
};

// A worker's sends in flight: requests and results go out without waiting for rank 0 to
// receive them (it may be rendering), and each buffer lives until its send completes. A
// worker that leaves the farm by an exception (a signal, a timeout) never finalizes, and
// until it ends rank 0 may still receive what it sent: Open MPI's shared-memory transport
// copies a large message straight out of this process's memory, so a freed and reused
// buffer would reach rank 0 as a result. The buffers of sends still pending then are never
// freed (MPI_Cancel of a send is deprecated and unreliable).
class Sends {
public:
    explicit Sends(const MpiContext& ctx) : ctx_(ctx) {}
    Sends(const Sends&) = delete;
    Sends& operator=(const Sends&) = delete;
    ~Sends() {
        test();
        if (pending_.empty()) return;
        auto* kept = new std::list<Pending>;  // never deleted, see above
        kept->splice(kept->end(), pending_);
    }

    void send(std::vector<char> msg) {
        pending_.emplace_back(MPI_REQUEST_NULL, std::move(msg));
        Pending& s = pending_.back();
        MPI_Isend(s.second.data(), int(s.second.size()), MPI_BYTE, 0, kTagResult, MPI_COMM_WORLD,
                  &s.first);
        test();
    }

    /// Waits for every send; throws what MpiContext::wait() throws.
    void wait_all() {
        for (Pending& s : pending_) ctx_.wait(s.first);
        pending_.clear();
    }

private:
    using Pending = std::pair<MPI_Request, std::vector<char>>;

    void test() {
        for (auto it = pending_.begin(); it != pending_.end();) {
            int done = 0;
            MPI_Test(&it->first, &done, MPI_STATUS_IGNORE);
            it = done ? pending_.erase(it) : std::next(it);
        }
    }

    const MpiContext& ctx_;
    std::list<Pending> pending_;
};

// Test-only (FarmParams::interrupt_rank): after the worker's sends are gone, allocates
// buffers of their sizes filled with 0xff, which take the place of any buffer that was freed,
// so that a send whose buffer was freed delivers garbage.
struct Scribble {
    bool on = false;
    std::vector<size_t> sizes;
    ~Scribble() {
        if (!on || std::uncaught_exceptions() == 0) return;
        for (size_t n : sizes) new std::vector<char>(n, char(0xff));  // kept until the end
    }
};

// A worker's view of the work messages from rank 0: each answers its oldest unanswered
// request with at most the items it asked for (at least one), each an item of [0, items)
// not given before. Throws Error naming the problem otherwise, before any item is rendered.
class WorkCheck {
public:
    explicit WorkCheck(int items) : given_(size_t(std::max(items, 0)), false) {}

    void asked(int want) { asked_.push_back(std::max(want, 1)); }

    /// The item ids of the work message `st` announces, received; throws before receiving a
    /// malformed one (a receive into too small a buffer would abort the job).
    std::vector<int> receive(const MPI_Status& st) {
        int bytes = 0;
        MPI_Get_count(&st, MPI_BYTE, &bytes);
        if (bytes < 0 || bytes % int(sizeof(int32_t)) != 0) {
            throw Error(bad() + std::to_string(bytes) + " bytes, not a whole number of " +
                        std::to_string(sizeof(int32_t)) + "-byte item ids");
        }
        const int n = bytes / int(sizeof(int32_t));
        if (asked_.empty()) throw Error(bad() + items_text(n) + ", but no request is unanswered");
        const int want = asked_.front();
        asked_.pop_front();
        if (n > want) {
            throw Error(bad() + items_text(n) + ", more than the " + std::to_string(want) +
                        " this rank asked for");
        }
        std::vector<int> items(static_cast<size_t>(n));
        MPI_Recv(items.data(), n, MPI_INT, 0, kTagWork, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        for (int i : items) {
            if (i < 0 || size_t(i) >= given_.size()) {
                throw Error(bad() + "item " + std::to_string(i) + " is outside [0, " +
                            std::to_string(given_.size()) + ")");
            }
            if (given_[size_t(i)])
                throw Error(bad() + "item " + std::to_string(i) + " was given before");
            given_[size_t(i)] = true;
        }
        return items;
    }

private:
    std::vector<bool> given_;
    std::deque<int> asked_;  // the items asked for by requests not yet answered, oldest first

    static std::string bad() { return "a work message from rank 0 is malformed: "; }
};

// Test-only (FarmParams::bad_message): `msg`, a packed result of `items` items, made malformed.
void spoil_result(BadMessage bad, int items, std::vector<char>& msg) {
    const size_t ids = sizeof(ResultHeader) + size_t(items) * sizeof(int32_t);
    if (bad == BadMessage::result_item) {
        const int32_t never = std::numeric_limits<int32_t>::max();  // no farm has that many
        std::memcpy(msg.data() + sizeof(ResultHeader), &never, sizeof never);
    } else if (bad == BadMessage::result_header) {
        msg.resize(sizeof(ResultHeader) - 2);
    } else if (bad == BadMessage::result_ids) {
        const int32_t more = int32_t(msg.size() / sizeof(int32_t));
        std::memcpy(msg.data(), &more, sizeof more);
    } else if (bad == BadMessage::result_short) {
        msg.resize(ids + (msg.size() - ids) / 2);
    }
}

RankStats run_worker(const MpiContext& ctx, int total, const FarmParams& params,
                     const RenderItems& render) {
    RankStats stats;
    stats.rank = ctx.rank();
    Timer wall;
    const int batch = std::max(params.batch, 1);
    Scribble scribble{ctx.rank() == params.interrupt_rank, {}};
    Sends sends(ctx);  // destroyed before `scribble`
    auto send = [&](std::vector<char> msg) {
        stats.messages += 1;
        stats.bytes += msg.size();
        if (scribble.on) scribble.sizes.push_back(msg.size());
        sends.send(std::move(msg));
    };
    WorkCheck check(total);
    const int ahead = batch * std::max(params.batches_in_flight, 1);
    send(pack_result({}, ahead, {}));
    check.asked(ahead);
    bool spoil = ctx.rank() == params.bad_message_rank;  // the first result, when asked to
    std::deque<int> queue;
    bool no_more = false;
    const std::function<void()> no_poll = [] {};
    for (;;) {
        while (!no_more) {
            int flag = 0;
            MPI_Status st;
            if (queue.empty()) {
                probe(ctx, 0, kTagWork, &st);
                flag = 1;
            } else {
                MPI_Iprobe(0, kTagWork, MPI_COMM_WORLD, &flag, &st);
            }
            if (!flag) break;
            const std::vector<int> items = check.receive(st);
            stats.messages += 1;
            stats.bytes += items.size() * sizeof(int32_t);
            if (items.empty()) no_more = true;
            queue.insert(queue.end(), items.begin(), items.end());
        }
        if (queue.empty()) break;
        std::vector<int> mine;
        while (int(mine.size()) < batch && !queue.empty()) {
            mine.push_back(queue.front());
            queue.pop_front();
        }
        // Hangs as a stuck process does, but stays killable: a rank stopped by SIGSTOP
        // made Open MPI 4.1.4's mpirun hang or crash ending the job (docs/mpi.md).
        while (ctx.rank() == params.stop_rank) std::this_thread::sleep_for(std::chrono::seconds(1));
        Timer t;
        const std::vector<char> bytes = render(mine, no_poll);
        throttle(ctx, params, t.seconds());
        stats.busy_seconds += t.seconds();
        stats.items += int32_t(mine.size());
        std::vector<char> msg = pack_result(mine, no_more ? 0 : int(mine.size()), bytes);
        if (spoil) spoil_result(params.bad_message, int(mine.size()), msg);
        spoil = false;
        send(std::move(msg));
        if (!no_more) check.asked(int(mine.size()));
        if (scribble.on) {
            // As a SIGTERM would, while the result is most likely still unreceived.
            std::raise(SIGTERM);
            ctx.check_timeout();
        }
    }
    sends.wait_all();
    stats.wall_seconds = wall.seconds();
    return stats;
}

}  // namespace

std::vector<std::vector<int>> assign_items(Distribution d, int items, int columns, int ranks) {
    std::vector<std::vector<int>> out(size_t(std::max(ranks, 1)));
    const int n = int(out.size());
    if (d == Distribution::dynamic) {
        for (int i = 0; i < items; ++i) out[0].push_back(i);
    } else if (d == Distribution::interleaved) {
        for (int i = 0; i < items; ++i) out[size_t(i % n)].push_back(i);
    } else {
        const int cols = std::max(columns, 1);
        const int rows = (items + cols - 1) / cols;
        for (int r = 0; r < n; ++r) {
            const int row0 = int(int64_t(r) * rows / n), row1 = int(int64_t(r + 1) * rows / n);
            for (int i = row0 * cols; i < std::min(row1 * cols, items); ++i)
                out[size_t(r)].push_back(i);
        }
    }
    return out;
}

std::vector<RankStats> run_farm(const MpiContext& ctx, int items, const FarmParams& params,
                                const RenderItems& render, const ResultSize& size,
                                const ConsumeItems& consume, const FarmProgress& progress) {
    // Every rank starts the clock together. The collectives here wait without spinning
    // (MpiContext::wait): a rank that is done must not take a core from one still rendering.
    MPI_Request request;
    MPI_Ibarrier(MPI_COMM_WORLD, &request);
    ctx.wait(request);
    const double cpu0 = process_cpu_seconds();
    RankStats mine;
    if (ctx.rank() == 0) {
        Master master(ctx, items, params, size, consume, progress);
        master.run(render);
        mine = master.stats;
    } else {
        mine = run_worker(ctx, items, params, render);
    }
    mine.cpu_seconds = process_cpu_seconds() - cpu0;
    // Buffers of the gather: kept if the wait throws (MpiBuffer).
    MpiBuffer<RankStats> sent(mine);
    MpiBuffer<std::vector<RankStats>> all(ctx.rank() == 0 ? size_t(ctx.size()) : 1);
    MPI_Igather(&*sent, int(sizeof(RankStats)), MPI_BYTE, all->data(), int(sizeof(RankStats)),
                MPI_BYTE, 0, MPI_COMM_WORLD, &request);
    ctx.wait(request);
    if (ctx.rank() != 0) (*all)[0] = mine;
    return *all;
}

}  // namespace kdt::dist
