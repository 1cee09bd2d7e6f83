// `kdtrace bench mpi`: runs `mpirun -np N kdtrace render --mpi` (one thread per rank) for
// each rank count and distribution, with and without one throttled rank, and tabulates rank
// 0's per-rank stats: tiles (or frames), busy and idle time, efficiency (busy / (ranks x
// wall)) and speedup against one rank of the same distribution. Runs take turns within each
// repeat; the medians of the repeats are shown. A benchmark: it never fails on a time.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "app/commands.h"
#include "renderer/core/error.h"

namespace kdt::app {
namespace {

struct BenchMpiArgs {
    std::string model;  // empty = the built-in default scene
    std::vector<int> ranks{1, 2, 4};
    std::vector<std::string> distributions{"dynamic", "strips", "interleaved"};
    int width = 320, height = 240, spp = 8, repeat = 3, frames = 0;
    double throttle = 2.0;  // rank 1's slowdown in the throttled runs (1 = none)
    std::string mpiexec = "mpirun";
    std::string work_dir = "bench_mpi";
};

struct Run {
    int ranks = 1;
    std::string distribution;
    bool throttled = false;
    std::vector<double> seconds;  // one per repeat
    nlohmann::json last;          // the stats of the last repeat
};

double median(std::vector<double> v) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    const size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::string self_path() { return std::filesystem::read_symlink("/proc/self/exe").string(); }

nlohmann::json run_once(const BenchMpiArgs& a, const Run& r, int index) {
    const std::string stats = a.work_dir + "/stats_" + std::to_string(index) + ".json";
    std::ostringstream cmd;
    cmd << a.mpiexec << " --oversubscribe --allow-run-as-root -np " << r.ranks << " '"
        << self_path() << "' render";
    if (!a.model.empty()) cmd << " '" << a.model << "'";
    cmd << " --width " << a.width << " --height " << a.height << " --spp " << a.spp
        << " --threads 1 --quiet --mpi --distribution " << r.distribution << " --mpi-stats '"
        << stats << "'";
    if (a.frames > 0) {
        cmd << " --frames " << a.frames << " --turntable -o '" << a.work_dir << "/f_%03d.png'";
    } else {
        cmd << " -o '" << a.work_dir << "/image.png'";
    }
    if (r.throttled) cmd << " --throttle 1:" << a.throttle;
    cmd << " > '" << a.work_dir << "/log.txt' 2>&1";
    std::filesystem::remove(stats);
    if (std::system(cmd.str().c_str()) != 0) {
        throw Error("bench mpi: '" + cmd.str() + "' failed; see " + a.work_dir + "/log.txt");
    }
    std::ifstream in(stats);
    if (!in) throw Error(stats + ": no stats written");
    return nlohmann::json::parse(in);
}

void run(const BenchMpiArgs& a) {
    std::filesystem::create_directories(a.work_dir);
    std::vector<Run> runs;
    for (const std::string& d : a.distributions) {
        for (int n : a.ranks) {
            for (bool throttled : {false, true}) {
                if (throttled && (n < 2 || !(a.throttle > 1.0))) continue;
                runs.push_back({n, d, throttled, {}, {}});
            }
        }
    }
    std::printf(
        "bench mpi: %s, %dx%d, %d spp, %s, one thread per rank, %d repeats (medians); "
        "throttled runs slow rank 1 %gx\n",
        a.model.empty() ? "default scene" : a.model.c_str(), a.width, a.height, a.spp,
        a.frames > 0 ? (std::to_string(a.frames) + "-frame turntable").c_str()
                     : "tiles of one frame",
        a.repeat, a.throttle);
    std::printf("(the machine is shared with other jobs: times are indicative)\n\n");
    for (int rep = 0; rep < a.repeat; ++rep) {
        for (size_t i = 0; i < runs.size(); ++i) {
            runs[i].last = run_once(a, runs[i], int(i));
            runs[i].seconds.push_back(runs[i].last["seconds"].get<double>());
        }
    }
    std::map<std::string, double> one_rank;  // distribution -> median seconds with 1 rank
    for (const Run& r : runs) {
        if (r.ranks == 1 && !r.throttled) one_rank[r.distribution] = median(r.seconds);
    }
    std::printf(
        "| distribution | ranks | throttled | wall s (min-max) | speedup | efficiency | "
        "per rank: items / busy s / idle s / cpu s |\n|---|---|---|---|---|---|---|\n");
    for (const Run& r : runs) {
        const double wall = median(r.seconds);
        double busy = 0.0;
        std::string per;
        for (const auto& k : r.last["per_rank"]) {
            const double b = k["busy_seconds"].get<double>();
            const double w = r.last["seconds"].get<double>();
            busy += b;
            char cell[128];
            std::snprintf(cell, sizeof cell, "%s%d / %.2f / %.2f / %.2f", per.empty() ? "" : "; ",
                          k["items"].get<int>(), b, std::max(0.0, w - b),
                          k["cpu_seconds"].get<double>());
            per += cell;
        }
        const double last_wall = r.last["seconds"].get<double>();
        const auto [lo, hi] = std::minmax_element(r.seconds.begin(), r.seconds.end());
        const double base = one_rank.count(r.distribution) ? one_rank[r.distribution] : 0.0;
        std::printf("| %s | %d | %s | %.3f (%.3f-%.3f) | %.2f | %.2f | %s |\n",
                    r.distribution.c_str(), r.ranks, r.throttled ? "rank 1" : "no", wall, *lo, *hi,
                    base > 0.0 && wall > 0.0 ? base / wall : 0.0,
                    last_wall > 0.0 ? busy / (double(r.ranks) * last_wall) : 0.0, per.c_str());
    }
    std::printf(
        "\nspeedup: 1-rank median wall / this median wall (same distribution); "
        "efficiency: sum of busy / (ranks x wall), last repeat\n");
}

}  // namespace

void add_bench_mpi_command(CLI::App& parent) {
    static BenchMpiArgs args;
    auto* sub = parent.add_subcommand("mpi", "MPI farm: per-rank busy/idle, efficiency, speedup");
    sub->add_option("--model", args.model, "Scene or model (default: the built-in scene)");
    sub->add_option("--ranks", args.ranks, "Rank counts")->delimiter(',')->capture_default_str();
    sub->add_option("--distributions", args.distributions, "dynamic, strips, interleaved")
        ->delimiter(',')
        ->check(CLI::IsMember({"dynamic", "interleaved", "strips"}));
    sub->add_option("--width", args.width)->check(CLI::Range(1, 1 << 14))->capture_default_str();
    sub->add_option("--height", args.height)->check(CLI::Range(1, 1 << 14))->capture_default_str();
    sub->add_option("--spp", args.spp)->check(CLI::Range(1, 1 << 20))->capture_default_str();
    sub->add_option("--repeat", args.repeat)->check(CLI::Range(1, 100))->capture_default_str();
    sub->add_option("--frames", args.frames, "Farm a turntable of this many frames instead")
        ->check(CLI::Range(0, 1 << 16));
    sub->add_option("--throttle", args.throttle, "Slowdown of rank 1 in throttled runs (1 = off)")
        ->check(CLI::Range(1.0, 1000.0))
        ->capture_default_str();
    sub->add_option("--mpiexec", args.mpiexec, "The MPI launcher")->capture_default_str();
    sub->add_option("--work-dir", args.work_dir, "Images, stats and logs")->capture_default_str();
    sub->callback([] { run(args); });
}

}  // namespace kdt::app
