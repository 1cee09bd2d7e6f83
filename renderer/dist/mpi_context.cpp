#include "renderer/dist/mpi_context.h"

#include <mpi.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "renderer/core/error.h"
#include "renderer/core/hash.h"
#include "renderer/light/image_environment.h"

namespace kdt::dist {

namespace {

// The tags of the messages outside the work farm (renderer/dist/work_farm.cpp uses 1 and 2).
// A worker tells rank 0 that it finished a check's step, so that a timeout can name the ranks
// that did not (the all-gather itself does not say who is missing).
constexpr int kTagArrived = 7;
constexpr int kTagBroadcast = 8;  // 0 -> worker: MpiContext::broadcast()'s header and text
constexpr int kTagFailed = 9;     // worker -> 0: the line of end_after_failure()
constexpr int kTagLog = 10;       // worker -> 0: its load log (prepare_everywhere())
constexpr int kTagEnded = 11;     // 0 -> worker, no data: the job ends, rank 0 said why
// The longest line end_after_failure() sends, and the longest rank 0 receives.
constexpr size_t kMaxFailureLine = 1024;

// "12 bytes", for messages.
std::string bytes_text(uint64_t n) { return std::to_string(n) + (n == 1 ? " byte" : " bytes"); }

// A length-prefixed message: an 8-byte header holding the text's length, then the text (none
// when `with_text` is false: the receiver fails on the header alone), malformed as `fault`
// says (test only).
constexpr size_t kHeader = sizeof(uint64_t);
std::vector<char> framed_message(const std::string& text, bool with_text, BadBroadcast fault) {
    uint64_t length = text.size();
    size_t sent = with_text ? text.size() : 0;
    if (fault == BadBroadcast::short_text) {
        sent /= 2;
        if (length == 0) length = 1;  // an empty text (a quiet load log) has no half to miss
    }
    if (fault == BadBroadcast::huge_length) length = uint64_t(1) << 60;
    std::vector<char> m(kHeader + sent + (fault == BadBroadcast::long_text ? 8 : 0), '\0');
    std::memcpy(m.data(), &length, kHeader);
    if (sent > 0) std::memcpy(m.data() + kHeader, text.data(), sent);
    if (fault == BadBroadcast::header) m.resize(kHeader - 2);
    return m;
}

// The text of the next framed_message() from `source` with `tag`, trusting nothing in it: a
// message over kHeader + max_text bytes is not received (nor allocated for), and one shorter
// than its header, announcing more than max_text, or followed by a text of another length
// than announced throws Error "<malformed><problem>". Waits as MpiContext::wait() does.
std::string receive_framed(const MpiContext& ctx, int source, int tag, uint64_t max_text,
                           const std::string& malformed) {
    MPI_Status st;
    ctx.poll_until([&] {
        int flag = 0;
        MPI_Iprobe(source, tag, MPI_COMM_WORLD, &flag, &st);
        return flag != 0;
    });
    int count = 0;
    MPI_Get_count(&st, MPI_BYTE, &count);
    if (count < 0 || uint64_t(count) > kHeader + max_text) {
        throw Error(malformed + "a message of " +
                    (count < 0 ? std::string("unknown size") : bytes_text(uint64_t(count))) +
                    ", more than the " + bytes_text(kHeader + max_text) + " a rank accepts");
    }
    std::vector<char> message(static_cast<size_t>(count));
    MPI_Recv(message.data(), count, MPI_BYTE, source, tag, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    if (message.size() < kHeader) {
        throw Error(malformed + bytes_text(message.size()) + ", shorter than its " +
                    std::to_string(kHeader) + "-byte header");
    }
    uint64_t length = 0;
    std::memcpy(&length, message.data(), kHeader);
    if (length > max_text) {
        throw Error(malformed + "its header announces " + bytes_text(length) + ", more than the " +
                    bytes_text(max_text) + " a rank accepts");
    }
    const size_t follow = message.size() - kHeader;
    if (length != follow) {
        throw Error(malformed + "its header announces " + bytes_text(length) + ", but " +
                    bytes_text(follow) + (follow == 1 ? " follows" : " follow") + " it");
    }
    return std::string(message.data() + kHeader, follow);
}

}  // namespace

MpiContext::MpiContext() {
    int provided = 0;
    // Only the main thread calls MPI (OpenMP threads render, the watchdog sets a flag).
    MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
    // Rank 0's host and process id, for rank0_gone().
    struct {
        int32_t pid = 0;
        char host[256] = {};
    } rank0, mine;
    mine.pid = int32_t(getpid());
    gethostname(mine.host, sizeof mine.host - 1);
    if (rank_ == 0) rank0 = mine;
    MPI_Bcast(&rank0, int(sizeof rank0), MPI_BYTE, 0, MPI_COMM_WORLD);
    rank0.host[sizeof rank0.host - 1] = '\0';
    if (rank_ != 0 && mine.host[0] != '\0' && std::strcmp(rank0.host, mine.host) == 0)
        rank0_pid_ = rank0.pid;
}

MpiContext::~MpiContext() {
    stop_watchdog();
    MPI_Finalize();
}

void MpiContext::start_watchdog(double seconds, double grace_seconds) {
    if (!(seconds > 0.0) || watchdog_.joinable()) return;
    timeout_ = seconds;
    // Rank 0 gives its main thread a moment to name the ranks it waits for; a worker waits
    // for rank 0 to end the job, so that rank 0's message comes first.
    const double grace = rank_ == 0 ? std::min(grace_seconds, 1.0) : grace_seconds;
    watchdog_ = std::thread([this, seconds, grace] {
        std::unique_lock<std::mutex> lock(mutex_);
        if (cv_.wait_for(lock, std::chrono::duration<double>(seconds), [this] { return stop_; }))
            return;
        expired_.store(true);
        if (cv_.wait_for(lock, std::chrono::duration<double>(grace), [this] { return stop_; }))
            return;
        if (rank_ == 0) {
            if (!reported_.exchange(true)) {
                std::fprintf(stderr,
                             "kdtrace: error: --timeout %g s reached while rank 0 was busy "
                             "outside the farm's waits; ending every rank\n",
                             seconds);
            }
            std::fflush(stderr);
            std::_Exit(1);
        }
        std::fprintf(stderr,
                     "kdtrace: error: rank %d: --timeout %g s reached and rank 0 did not end the "
                     "job (stopped or stuck); ending this rank\n",
                     rank_, seconds);
        std::fflush(stderr);
        std::_Exit(3);
    });
}

void MpiContext::end_after_timeout(const std::string& message) {
    failed_.store(true);  // mpirun's signals that end the job are no interrupt
    if (rank_ == 0) {
        if (!reported_.exchange(true))
            std::fprintf(stderr, "kdtrace: error: %s\n", message.c_str());
        std::fflush(stderr);
        std::fflush(stdout);
        tell_workers_the_job_ended();
        std::_Exit(1);
    }
    wait_for_the_end();
}

void MpiContext::watch_interrupts(std::function<std::string()> kept) {
    kept_ = std::move(kept);
    interrupt::install(interrupt::Mode::report);
    const double grace = rank_ == 0 ? 0.25 : 2.0;
    std::optional<std::chrono::steady_clock::time_point> since;
    interrupt_watcher_ = std::make_unique<interrupt::Watcher>([this, grace, since]() mutable {
        const auto now = std::chrono::steady_clock::now();
        if (!since) since = now;
        if (std::chrono::duration<double>(now - *since).count() >= grace) die_interrupted();
    });
}

void MpiContext::end_after_interrupt() {
    if (rank_ == 0) die_interrupted();
    // mpirun ends a worker; the watcher, when it does not.
    wait_for_the_end();
}

void MpiContext::end_after_failure(const std::string& line) {
    failed_.store(true);
    const std::string text = line.substr(0, kMaxFailureLine);
    if (rank_ != 0) {
        stop_watchdog();  // the grace below, not --timeout, ends a rank 0 that never answers
        MPI_Request sent = MPI_REQUEST_NULL;
        MPI_Isend(text.data(), int(text.size()), MPI_CHAR, 0, kTagFailed, MPI_COMM_WORLD, &sent);
        // Rank 0 ends the job once it has the line (mpirun then ends this rank). The send's
        // buffer lives until this process ends.
        const auto until =
            std::chrono::steady_clock::now() + std::chrono::duration<double>(failure_grace_);
        while (std::chrono::steady_clock::now() < until) {
            int done = 0;
            if (sent != MPI_REQUEST_NULL) MPI_Test(&sent, &done, MPI_STATUS_IGNORE);
            if (job_ended()) die_interrupted();  // rank 0 printed the line: quiet, status 1
            std::this_thread::sleep_for(std::chrono::milliseconds(10));
        }
    }
    std::fprintf(stderr, "kdtrace: error: %s\n", printable(text).c_str());
    std::fflush(stderr);
    std::fflush(stdout);
    if (rank_ == 0) tell_workers_the_job_ended();
    std::_Exit(1);
}

void MpiContext::tell_workers_the_job_ended() const {
    std::vector<MPI_Request> sent(size_t(std::max(size_ - 1, 0)), MPI_REQUEST_NULL);
    for (int r = 1; r < size_; ++r)
        MPI_Isend(nullptr, 0, MPI_BYTE, r, kTagEnded, MPI_COMM_WORLD, &sent[size_t(r - 1)]);
    // Empty messages go out at once (eager); the bound keeps a dead peer from holding rank 0.
    const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(500);
    int done = 0;
    while (!done && std::chrono::steady_clock::now() < until) {
        MPI_Testall(int(sent.size()), sent.data(), &done, MPI_STATUSES_IGNORE);
        if (!done) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
}

bool MpiContext::job_ended() const {
    if (rank_ == 0) return false;
    int flag = 0;
    MPI_Iprobe(0, kTagEnded, MPI_COMM_WORLD, &flag, MPI_STATUS_IGNORE);
    if (flag) failed_.store(true);
    return flag != 0;
}

bool MpiContext::rank0_gone() const {
    if (rank0_pid_ <= 0) return false;
    // /proc/PID/stat: "PID (COMM) STATE ...", COMM may hold spaces or parentheses.
    char path[64];
    std::snprintf(path, sizeof path, "/proc/%d/stat", rank0_pid_);
    std::FILE* f = std::fopen(path, "r");
    if (!f) return errno == ENOENT;
    char buf[512];
    const size_t n = std::fread(buf, 1, sizeof buf - 1, f);
    std::fclose(f);
    buf[n] = '\0';
    const char* close = std::strrchr(buf, ')');
    // An exited process its parent has not reaped yet is a zombie (Z), or dead (X).
    return close && close[1] == ' ' && (close[2] == 'Z' || close[2] == 'X');
}

void MpiContext::wait_for_the_end() const {
    for (;;) {
        if (job_ended()) die_interrupted();
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
}

void MpiContext::die_interrupted() const {
    if (dying_.exchange(true)) {
        for (;;) std::this_thread::sleep_for(std::chrono::seconds(1));  // the other thread ends it
    }
    // A worker's signal with rank 0 gone is mpirun ending the job (its SIGKILL can come late
    // on a loaded machine): rank 0's line, an interrupt's or a failure's, was the news.
    if (rank_ != 0 && !failed_.load() && rank0_gone()) failed_.store(true);
    if (failed_.load()) {
        // mpirun ending the job after a failure: the failure was the news. The temporary
        // files go as for any signal; the status is the failure's.
        interrupt::die_now([] {
            std::fflush(stderr);
            std::_Exit(1);
        });
    }
    interrupt::die_now([this] {
        if (rank_ == 0) {
            // On a line of its own after the progress bar and the terminal's ^C.
            std::fprintf(stderr, "%skdtrace: interrupted (%s); %s\n",
                         isatty(STDERR_FILENO) ? "\n" : "", interrupt::signal_name(),
                         kept_ ? kept_().c_str() : "nothing was kept");
        } else {
            std::fprintf(stderr, "kdtrace: rank %d: interrupted (%s); ending this rank\n", rank_,
                         interrupt::signal_name());
        }
    });
}

void MpiContext::stop_watchdog() {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        stop_ = true;
    }
    cv_.notify_all();
    if (watchdog_.joinable()) watchdog_.join();
}

std::string MpiContext::broadcast(const std::string& text, int bad_rank, BadBroadcast bad) const {
    if (rank_ == 0) {
        // A text too long for the workers still sends its header: they fail on it and say
        // so, instead of waiting for a message that never comes.
        const bool fits = text.size() <= kMaxBroadcastBytes;
        // Buffers of the sends below: kept if a wait throws (MpiBuffer).
        MpiBuffer<std::vector<std::vector<char>>> messages(static_cast<size_t>(size_));
        MpiBuffer<std::vector<MPI_Request>> requests(static_cast<size_t>(size_), MPI_REQUEST_NULL);
        for (int r = 1; r < size_; ++r) {
            std::vector<char>& m = (*messages)[size_t(r)];
            m = framed_message(text, fits, r == bad_rank ? bad : BadBroadcast::none);
            MPI_Isend(m.data(), int(m.size()), MPI_BYTE, r, kTagBroadcast, MPI_COMM_WORLD,
                      &(*requests)[size_t(r)]);
        }
        for (MPI_Request& request : *requests) wait(request);
        if (!fits) {
            throw Error("the options are " + bytes_text(text.size()) + ", more than the " +
                        bytes_text(kMaxBroadcastBytes) + " a rank accepts");
        }
        return text;
    }
    // Rank 0 never sends more than kMaxBroadcastBytes of text (see above).
    return receive_framed(*this, 0, kTagBroadcast, kMaxBroadcastBytes,
                          "the options from rank 0 are malformed: ");
}

void MpiContext::check_timeout() const {
    // Before the signals mpirun sends once rank 0 has exited: they are no news then.
    if (job_ended()) die_interrupted();
    if (rank_ == 0 && size_ > 1) {
        int flag = 0;
        MPI_Status st;
        MPI_Iprobe(MPI_ANY_SOURCE, kTagFailed, MPI_COMM_WORLD, &flag, &st);
        if (flag) {
            int count = 0;
            MPI_Get_count(&st, MPI_CHAR, &count);
            // The line is the worker's; its length is checked before anything is allocated.
            std::string line = "rank " + std::to_string(st.MPI_SOURCE) + " failed";
            if (count >= 0 && size_t(count) <= kMaxFailureLine) {
                line.assign(size_t(count), '\0');
                MPI_Recv(line.data(), count, MPI_CHAR, st.MPI_SOURCE, kTagFailed, MPI_COMM_WORLD,
                         MPI_STATUS_IGNORE);
            }
            throw FarmRankFailed(line, true);
        }
    }
    if (interrupt_watcher_ && interrupt::requested())
        throw FarmInterrupted(std::string("interrupted (") + interrupt::signal_name() + ")",
                              rank_ == 0);
    if (!expired()) return;
    char buf[64];
    std::snprintf(buf, sizeof buf, "--timeout %g s reached", timeout_);
    std::string m = buf;
    if (rank_ == 0 && pending_) {
        const std::string pending = pending_();
        if (!pending.empty()) m += ": " + pending;
    }
    throw FarmTimeout(m + "; ending every rank", rank_ == 0);
}

void MpiContext::poll_until(const std::function<bool()>& done) const {
    for (int spins = 0;; ++spins) {
        if (done()) return;
        check_timeout();
        // Spin briefly for low latency, then yield the core to the renderers.
        if (spins > 1000) std::this_thread::sleep_for(std::chrono::microseconds(50));
    }
}

void MpiContext::wait(MPI_Request& request) const {
    poll_until([&] {
        int done = 0;
        MPI_Test(&request, &done, MPI_STATUS_IGNORE);
        return done != 0;
    });
}

namespace {

// The texels of an environment map as loaded (0 for a constant colour): what two ranks that
// read "the same" file must agree on, without reading it again.
uint64_t environment_hash(const EnvironmentLight* env) {
    const auto* map = dynamic_cast<const ImageEnvironment*>(env);
    if (!map) return 0;
    const ImageRGB& image = map->image();
    const uint64_t size[2] = {uint64_t(image.width), uint64_t(image.height)};
    return fnv1a(fnv1a(kFnvOffset, size, sizeof size), image.rgb.data(),
                 image.rgb.size() * sizeof(float));
}

}  // namespace

Fingerprint snapshot_fingerprint(const RenderSnapshot& snap, const std::string& options_json) {
    const std::string& scene = snap.scene_name;
    Fingerprint f;
    f.emplace_back("mesh" + (scene.empty() ? std::string() : " of " + scene),
                   snap.scene->mesh ? snap.scene->mesh->content_hash() : 0);
    f.emplace_back("kd-tree", snap.scene->tree ? snap.scene->tree->nodes().size() : 0);
    const std::string& env = snap.environment.file;
    if (!env.empty())
        f.emplace_back("environment map " + env, environment_hash(snap.scene->env.get()));
    f.emplace_back("options", std::hash<std::string>{}(options_json));
    return f;
}

std::string rank_list(const std::vector<int>& ranks, int size) {
    std::string m = ranks.size() == 1 ? "rank " : "ranks ";
    for (size_t i = 0; i < ranks.size(); ++i) m += (i ? ", " : "") + std::to_string(ranks[i]);
    return m + " of " + std::to_string(size);
}

namespace {

// What every rank reports after loading, gathered on all ranks as bytes.
struct LoadStatus {
    int32_t ok = 0;
    int32_t parts = 0;
    uint64_t hash[kMaxFingerprintParts] = {};
    char message[480] = {};
};

// The message for ranks whose part `i` differs; "" when all agree.
std::string mismatch(const std::vector<LoadStatus>& all, size_t i, const std::string& name) {
    std::map<uint64_t, std::vector<int>> groups;
    for (size_t r = 0; r < all.size(); ++r) groups[all[r].hash[i]].push_back(int(r));
    if (groups.size() < 2) return "";
    const int n = int(all.size());
    auto tail = [&](int odd, int other) {
        char hashes[64];
        std::snprintf(hashes, sizeof hashes, "hash %016llx against %016llx",
                      (unsigned long long)all[size_t(odd)].hash[i],
                      (unsigned long long)all[size_t(other)].hash[i]);
        return " (" + std::string(hashes) +
               "): every rank must see the same files (shared filesystem)";
    };
    if (n == 2) return "ranks 0 and 1 of 2 see a different " + name + tail(0, 1);
    const std::vector<int>* major = nullptr;
    bool tie = false;
    for (const auto& [hash, ranks] : groups) {
        if (!major || ranks.size() > major->size()) {
            major = &ranks;
            tie = false;
        } else if (ranks.size() == major->size()) {
            tie = true;
        }
    }
    if (tie) {
        return "the ranks of " + std::to_string(n) + " disagree on the " + name +
               tail(groups.begin()->second[0], std::next(groups.begin())->second[0]);
    }
    std::vector<int> odd;
    for (const auto& [hash, ranks] : groups)
        if (&ranks != major) odd.insert(odd.end(), ranks.begin(), ranks.end());
    std::sort(odd.begin(), odd.end());
    return rank_list(odd, n) + (odd.size() == 1 ? " sees" : " see") + " a different " + name +
           " than the other ranks" + tail(odd[0], (*major)[0]);
}

}  // namespace

void check_every_rank(const MpiContext& ctx, const std::string& what,
                      const std::function<Fingerprint()>& step) {
    // Buffers of the operations below: kept if a wait throws (MpiBuffer).
    MpiBuffer<LoadStatus> mine;
    Fingerprint parts;
    try {
        parts = step();
        if (parts.size() > kMaxFingerprintParts)
            throw std::logic_error("check_every_rank: too many fingerprint parts");
        mine->parts = int32_t(parts.size());
        for (size_t i = 0; i < parts.size(); ++i) mine->hash[i] = parts[i].second;
        mine->ok = 1;
    } catch (const std::exception& e) {
        std::snprintf(mine->message, sizeof mine->message, "%s", e.what());
    }
    MpiBuffer<std::vector<LoadStatus>> all(size_t(ctx.size()));
    MpiBuffer<int32_t> arrived(1);
    MPI_Request sent = MPI_REQUEST_NULL;
    if (ctx.rank() != 0)
        MPI_Isend(&*arrived, 1, MPI_INT32_T, 0, kTagArrived, MPI_COMM_WORLD, &sent);
    struct Pending {
        const MpiContext& ctx;
        ~Pending() { ctx.set_pending({}); }
    } clear{ctx};
    if (ctx.rank() == 0) {
        ctx.set_pending([&ctx, stage = what]() -> std::string {
            std::vector<int> missing;
            for (int r = 1; r < ctx.size(); ++r) {
                int flag = 0;
                MPI_Iprobe(r, kTagArrived, MPI_COMM_WORLD, &flag, MPI_STATUS_IGNORE);
                if (!flag) missing.push_back(r);
            }
            if (missing.empty()) return "";
            return rank_list(missing, ctx.size()) + " had not finished (" + stage + ")";
        });
    }
    // Ranks that finish first wait without spinning, leaving the cores to those still loading.
    MPI_Request request;
    MPI_Iallgather(&*mine, int(sizeof(LoadStatus)), MPI_BYTE, all->data(), int(sizeof(LoadStatus)),
                   MPI_BYTE, MPI_COMM_WORLD, &request);
    ctx.wait(request);
    if (ctx.rank() == 0) {
        for (int r = 1; r < ctx.size(); ++r)
            MPI_Recv(&*arrived, 1, MPI_INT32_T, r, kTagArrived, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    } else {
        ctx.wait(sent);
    }
    // Another rank's message is text only up to its last byte, whatever it sent.
    for (LoadStatus& s : *all) s.message[sizeof s.message - 1] = '\0';
    const std::string of = " of " + std::to_string(ctx.size());
    int failed = 0, first = -1;
    for (int r = 0; r < ctx.size(); ++r) {
        if ((*all)[size_t(r)].ok) continue;
        if (first < 0) first = r;
        ++failed;
    }
    bool same = failed == ctx.size() && ctx.size() > 1;
    for (int r = 1; same && r < ctx.size(); ++r)
        same = std::strcmp((*all)[size_t(r)].message, (*all)[0].message) == 0;
    if (same) {
        throw FarmError("all " + std::to_string(ctx.size()) + " ranks failed to " + what + ": " +
                            (*all)[0].message,
                        ctx.rank() == 0);
    }
    if (failed > 0) {
        std::string m = "rank " + std::to_string(first) + of + " could not " + what + ": " +
                        (*all)[size_t(first)].message;
        if (failed > 1) m += " (and " + std::to_string(failed - 1) + " more ranks failed)";
        throw FarmError(m, ctx.rank() == 0);
    }
    for (size_t i = 0; i < parts.size(); ++i) {
        const std::string m = mismatch(*all, i, parts[i].first);
        if (!m.empty()) throw FarmError(m, ctx.rank() == 0);
    }
}

namespace {

// Rank 0: every rank's lines (joined by '\n', at most kMaxLogBytes each); elsewhere empty.
// Each worker sends rank 0 one framed_message() (malformed as `bad` says on rank `bad_rank`,
// test only), which rank 0 checks as receive_framed() does; then, collectively, a malformed
// one fails every rank with FarmError "rank 0 of N could not read the load logs: the load log
// from rank R is malformed: <problem>" (the lowest such R), so that all stop with one line.
constexpr size_t kMaxLogBytes = 8192;
std::vector<std::string> gather_lines(const MpiContext& ctx, const std::vector<std::string>& lines,
                                      int bad_rank, BadBroadcast bad) {
    std::string mine;
    for (const std::string& line : lines) {
        if (mine.size() + line.size() + 1 > kMaxLogBytes) break;
        mine += line + "\n";
    }
    const bool root = ctx.rank() == 0;
    std::vector<std::string> out;
    std::string problem;
    if (root) {
        out.push_back(std::move(mine));
        for (int r = 1; r < ctx.size(); ++r) {
            try {
                out.push_back(receive_framed(
                    ctx, r, kTagLog, kMaxLogBytes,
                    "the load log from rank " + std::to_string(r) + " is malformed: "));
            } catch (const Error& e) {
                out.emplace_back();
                if (problem.empty()) problem = e.what();
            }
        }
    } else {
        // The buffer of the send below: kept if the wait throws (MpiBuffer).
        MpiBuffer<std::vector<char>> message(
            framed_message(mine, true, ctx.rank() == bad_rank ? bad : BadBroadcast::none));
        MPI_Request sent = MPI_REQUEST_NULL;
        MPI_Isend(message->data(), int(message->size()), MPI_BYTE, 0, kTagLog, MPI_COMM_WORLD,
                  &sent);
        ctx.wait(sent);
    }
    check_every_rank(ctx, "read the load logs", [&]() -> Fingerprint {
        if (!problem.empty()) throw Error(problem);
        return {};
    });
    return out;
}

// A line without a trailing " (...)" (the timings of "kd-tree cache: loaded F (0.012 s)"),
// so that ranks that did the same are not told apart by their times.
std::string without_times(const std::string& line) {
    const size_t open = line.rfind(" (");
    return !line.empty() && line.back() == ')' && open != std::string::npos ? line.substr(0, open)
                                                                            : line;
}

// A load line that reports the usual course, not a problem: which rank wrote the shared
// cache file and which loaded it depends on timing, and is no news.
bool routine(const std::string& line) {
    return line.rfind("kd-tree cache: loaded ", 0) == 0 ||
           line.rfind("kd-tree cache: wrote ", 0) == 0;
}

}  // namespace

Prepared prepare_everywhere(const MpiContext& ctx, const RenderOptions& options,
                            const PrepareLog& log, const InjectedFault& fault) {
    const std::string json = options_to_json(options);
    Prepared prep;
    std::vector<std::string> lines;  // what this rank's load said
    const PrepareLog keep = [&](const std::string& line) {
        lines.push_back(line);
        if (log) log(line);
    };
    check_every_rank(ctx, "load the scene", [&] {
        RenderOptions o = options;
        if (fault.rank == ctx.rank() && fault.what == "load") {
            o.scene.scene_path = "/nonexistent/kdtrace-injected-fault/" +
                                 (o.scene.scene_path.empty() ? "scene.json" : o.scene.scene_path);
        }
        if (fault.rank == ctx.rank() && fault.what == "stall") {
            for (;;) std::this_thread::sleep_for(std::chrono::milliseconds(100));
        }
        prep = prepare_render(o, keep);
        Fingerprint f = snapshot_fingerprint(*prep.snapshot, json);
        if (fault.rank == ctx.rank() && fault.what == "hash") f[1].second ^= 1;  // the tree
        return f;
    });
    // The workers' lines that rank 0 did not say itself (a cache they could not write), once
    // per text with the ranks that said it.
    BadBroadcast bad_log = BadBroadcast::none;
    for (size_t i = 1; i < kBadLogNames.size(); ++i)
        if (fault.what == kBadLogNames[i]) bad_log = BadBroadcast(i);
    const std::vector<std::string> all = gather_lines(ctx, lines, fault.rank, bad_log);
    if (all.empty() || !log) return prep;
    std::vector<std::string> own;
    for (const std::string& line : lines) own.push_back(without_times(line));
    std::vector<std::pair<std::string, std::vector<int>>> said;  // in the order first said
    for (int r = 1; r < ctx.size(); ++r) {
        std::istringstream in(all[size_t(r)]);
        for (std::string line; std::getline(in, line);) {
            const std::string key = without_times(line);
            if (std::find(own.begin(), own.end(), key) != own.end() || routine(line)) continue;
            auto it = std::find_if(said.begin(), said.end(),
                                   [&](const auto& s) { return without_times(s.first) == key; });
            if (it == said.end()) it = said.insert(said.end(), {line, {}});
            if (it->second.empty() || it->second.back() != r) it->second.push_back(r);
        }
    }
    for (const auto& [line, ranks] : said) log(rank_list(ranks, ctx.size()) + ": " + line);
    return prep;
}

}  // namespace kdt::dist
