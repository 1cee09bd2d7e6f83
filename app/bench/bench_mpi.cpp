// `kdtrace bench mpi`: runs `mpirun -np N kdtrace render --mpi` (one thread per rank) for
// each rank count and distribution, with and without one throttled rank, and with --frames a
// turntable farm for each rank count; tabulates rank 0's per-rank stats: tiles or frames,
// busy and idle time, speedup against one rank of the same kind, parallel efficiency
// (speedup / ranks), rank 0's serving time and bytes and messages per frame, and the
// machine's load average. Runs take turns within each repeat; the medians of the repeats are
// shown. A benchmark: it never fails on a time.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "app/bench/bench_options.h"
#include "app/bench/bench_table.h"
#include "app/bench/run_program.h"
#include "app/commands.h"
#include "app/mpi_cli.h"
#include "app/options_cli.h"
#include "renderer/core/error.h"
#include "renderer/core/shell_word.h"

namespace kdt::app {
namespace {

struct BenchMpiArgs {
    std::string model;  // empty = the built-in default scene
    std::vector<int> ranks{1, 2, 4};
    std::vector<std::string> distributions{"dynamic", "strips", "interleaved"};
    int width = 320, height = 240, spp = 8, repeat = 3;
    int frames = 0;  // > 0: turntable rows of this many frames
    int frame_width = 0, frame_height = 0, frame_spp = 0;  // 0 = as the tile rows
    bool tiles = true;                                     // the tile rows
    double throttle = 2.0;  // rank 1's slowdown in the throttled runs (1 = none)
    std::string mpiexec = "mpirun";
    std::string launcher_flags;  // extra flags for mpiexec, e.g. "--mca mpi_yield_when_idle 1"
    std::string work_dir = "bench_mpi";
};

struct Run {
    int ranks = 1;
    std::string distribution;
    bool throttled = false;
    bool frames = false;          // a turntable farm, else the tiles of one frame
    std::vector<double> seconds;  // one per repeat
    std::vector<double> load;     // 1-minute load average before each repeat
    nlohmann::json last;          // the stats of the last repeat
};

double load_average() {
    double one = 0.0;
    std::ifstream("/proc/loadavg") >> one;
    return one;
}

std::string self_path() { return std::filesystem::read_symlink("/proc/self/exe").string(); }

nlohmann::json run_once(const BenchMpiArgs& a, const Run& r, int index) {
    const std::string stats = a.work_dir + "/stats_" + std::to_string(index) + ".json";
    std::vector<std::string> argv = {a.mpiexec, "--oversubscribe", "--allow-run-as-root"};
    // --launcher-flags: words separated by blanks, passed on as they are.
    std::istringstream flags(a.launcher_flags);
    for (std::string word; flags >> word;) argv.push_back(word);
    const int w = r.frames && a.frame_width > 0 ? a.frame_width : a.width;
    const int h = r.frames && a.frame_height > 0 ? a.frame_height : a.height;
    const int spp = r.frames && a.frame_spp > 0 ? a.frame_spp : a.spp;
    argv.insert(argv.end(), {"-np", std::to_string(r.ranks), self_path(), "render"});
    if (!a.model.empty()) argv.push_back(a.model);
    argv.insert(argv.end(), {"--width", std::to_string(w), "--height", std::to_string(h), "--spp",
                             std::to_string(spp), "--threads", "1", "--quiet", "--mpi",
                             "--distribution", r.distribution, "--mpi-stats", stats});
    if (r.frames) {
        argv.insert(argv.end(), {"--frames", std::to_string(a.frames), "--turntable", "-o",
                                 a.work_dir + "/f_%03d.png"});
    } else {
        argv.insert(argv.end(), {"-o", a.work_dir + "/image.png"});
    }
    if (r.throttled) {
        std::ostringstream t;
        t << "1:" << a.throttle;
        argv.insert(argv.end(), {"--throttle", t.str()});
    }
    std::filesystem::remove(stats);
    const std::string log = a.work_dir + "/log.txt";
    if (run_program(argv, log) != 0) {
        std::string cmd;
        for (const std::string& word : argv) cmd += (cmd.empty() ? "" : " ") + shell_word(word);
        throw Error("bench mpi: " + cmd + " failed; see " + log);
    }
    std::ifstream in(stats);
    if (!in) throw Error(stats + ": no stats written");
    return nlohmann::json::parse(in);
}

// CPU seconds of all ranks of the last repeat.
double total_cpu(const Run& r) {
    double cpu = 0.0;
    for (const auto& k : r.last["per_rank"]) cpu += k["cpu_seconds"].get<double>();
    return cpu;
}

std::string row_kind(const BenchMpiArgs& a, const Run& r) {
    return r.frames ? std::to_string(a.frames) + " frames" : "tiles";
}

// Speedups and efficiencies compare with the 1-rank run of the same work and distribution:
// without one (--ranks 2,4) they are "-", and the turntable line gives no ideal time.
void print_table(const BenchMpiArgs& a, const std::vector<Run>& runs) {
    std::map<std::string, double> one_rank;  // kind + distribution -> median s with 1 rank
    std::map<std::string, double> one_cpu;   // the same: CPU seconds, last repeat
    auto baseline = [](const std::map<std::string, double>& m, const std::string& key) {
        const auto it = m.find(key);
        return it != m.end() ? it->second : std::nan("");
    };
    for (const Run& r : runs) {
        if (r.ranks == 1 && !r.throttled) {
            one_rank[row_kind(a, r) + r.distribution] = median(r.seconds);
            one_cpu[row_kind(a, r) + r.distribution] = total_cpu(r);
        }
    }
    std::printf(
        "| work | distribution | ranks | throttled | load | wall s (min-max) | speedup | "
        "speedup / ranks | cpu eff. | rank 0 serve s | per rank: items / busy s / idle s / cpu s "
        "|\n|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (const Run& r : runs) {
        const double wall = median(r.seconds);
        std::string per;
        for (const auto& k : r.last["per_rank"]) {
            const double b = k["busy_seconds"].get<double>();
            char cell[128];
            std::snprintf(cell, sizeof cell, "%s%d / %.2f / %.2f / %.2f", per.empty() ? "" : "; ",
                          k["items"].get<int>(), b,
                          std::max(0.0, r.last["seconds"].get<double>() - b),
                          k["cpu_seconds"].get<double>());
            per += cell;
        }
        const auto [lo, hi] = std::minmax_element(r.seconds.begin(), r.seconds.end());
        const auto [load_lo, load_hi] = std::minmax_element(r.load.begin(), r.load.end());
        const std::string key = row_kind(a, r) + r.distribution;
        const double speedup = quotient(baseline(one_rank, key), wall);
        const double cpu_eff = quotient(baseline(one_cpu, key), total_cpu(r));
        std::printf(
            "| %s | %s | %d | %s | %.1f-%.1f | %.3f (%.3f-%.3f) | %s | %s | %s | %.3f | %s |\n",
            row_kind(a, r).c_str(), r.distribution.c_str(), r.ranks, r.throttled ? "rank 1" : "no",
            *load_lo, *load_hi, wall, *lo, *hi, fmt("%.2f", speedup).c_str(),
            fmt("%.2f", speedup / double(r.ranks)).c_str(), fmt("%.2f", cpu_eff).c_str(),
            r.last["per_rank"][0].value("serve_seconds", 0.0), per.c_str());
    }
    std::printf(
        "\nload: 1-minute load average before each repeat (min-max); speedup: 1-rank median "
        "wall / this median wall (same work and distribution); cpu eff.: the 1-rank run's CPU "
        "seconds / this run's, all ranks (work the farm adds, spinning included, whatever "
        "share of the cores the machine gave); per rank: last repeat\n");
    for (const Run& r : runs) {
        if (!r.frames || r.ranks < 2 || r.throttled) continue;
        const double base = baseline(one_rank, row_kind(a, r) + r.distribution);
        const double wall = median(r.seconds);
        std::string ideal = " (no 1-rank run to compare with)";
        if (std::isfinite(base)) {
            ideal = " against the ideal " + fmt("%.3f", base / double(r.ranks)) + " s (1 rank / " +
                    std::to_string(r.ranks) +
                    "): " + fmt("%.2f", quotient(wall * double(r.ranks), base)) + "x";
        }
        const auto& rank0 = r.last["per_rank"][0];
        const int worker_frames = a.frames - rank0["items"].get<int>();
        std::printf(
            "turntable, %d ranks: %.3f s%s; rank 0 received and sent %llu bytes in %llu messages "
            "for %d frames of the workers (%s bytes, %s messages per frame), serving %.3f s\n",
            r.ranks, wall, ideal.c_str(), (unsigned long long)rank0["bytes"].get<uint64_t>(),
            (unsigned long long)rank0["messages"].get<uint64_t>(), worker_frames,
            fmt("%.0f", quotient(double(rank0["bytes"].get<uint64_t>()), worker_frames)).c_str(),
            fmt("%.1f", quotient(double(rank0["messages"].get<uint64_t>()), worker_frames)).c_str(),
            rank0.value("serve_seconds", 0.0));
    }
}

void run(const BenchMpiArgs& a) {
    refuse_repeated_entries("--ranks", a.ranks);
    refuse_repeated_entries("--distributions", a.distributions);
    if (a.frames == 0) {
        // The turntable's sizes mean nothing without one: say so rather than ignore them.
        for (const auto& [flag, value] :
             {std::pair<const char*, int>{"--frame-width", a.frame_width},
              {"--frame-height", a.frame_height},
              {"--frame-spp", a.frame_spp}}) {
            if (value != 0)
                throw Error(std::string(flag) + " needs --frames N (the turntable it sizes)");
        }
    }
    create_output_directory("--work-dir", a.work_dir);
    std::vector<Run> runs;
    for (const std::string& d : a.distributions) {
        for (int n : a.ranks) {
            for (bool throttled : {false, true}) {
                if (!a.tiles || (throttled && (n < 2 || !(a.throttle > 1.0)))) continue;
                runs.push_back({n, d, throttled, false, {}, {}, {}});
            }
        }
    }
    if (a.frames > 0) {
        for (int n : a.ranks) runs.push_back({n, "dynamic", false, true, {}, {}, {}});
    }
    if (runs.empty()) throw Error("bench mpi: nothing to run (--no-tiles without --frames)");
    std::printf(
        "bench mpi: %s, tiles %dx%d at %d spp%s, one thread per rank, %d repeats (medians); "
        "throttled runs slow rank 1 %gx; launcher: %s %s\n",
        a.model.empty() ? "default scene" : a.model.c_str(), a.width, a.height, a.spp,
        a.frames > 0 ? (", a " + std::to_string(a.frames) + "-frame turntable at " +
                        std::to_string(a.frame_width > 0 ? a.frame_width : a.width) + "x" +
                        std::to_string(a.frame_height > 0 ? a.frame_height : a.height) + ", " +
                        std::to_string(a.frame_spp > 0 ? a.frame_spp : a.spp) + " spp")
                           .c_str()
                     : "",
        a.repeat, a.throttle, a.mpiexec.c_str(), a.launcher_flags.c_str());
    std::printf("(the machine is shared with other jobs: times are indicative)\n\n");
    for (int rep = 0; rep < a.repeat; ++rep) {
        for (size_t i = 0; i < runs.size(); ++i) {
            runs[i].load.push_back(load_average());
            runs[i].last = run_once(a, runs[i], int(i));
            runs[i].seconds.push_back(runs[i].last["seconds"].get<double>());
        }
    }
    print_table(a, runs);
}

}  // namespace

void add_bench_mpi_command(CLI::App& parent) {
    static BenchMpiArgs args;
    auto* sub = parent.add_subcommand("mpi", "MPI farm: per-rank busy/idle, efficiency, speedup");
    non_empty_file_name(
        sub->add_option("--model", args.model, "Scene or model (default: the built-in scene)"),
        "--model", " (omit --model for the built-in scene)");
    // Each count is passed to the launcher as -np (with --oversubscribe): bounded, so that a
    // typo cannot start thousands of processes.
    sub->add_option("--ranks", args.ranks, "Rank counts")
        ->delimiter(',')
        ->check(in_range(1, 4096))
        ->capture_default_str();
    sub->add_option_function<std::vector<std::string>>(
           "--distributions",
           [](const std::vector<std::string>& names) {
               for (const std::string& n : names) check_distribution_name("--distributions", n);
               args.distributions = names;
           },
           "dynamic, strips, interleaved")
        ->delimiter(',');
    sub->add_option("--width", args.width, "Image width of the tile rows")
        ->check(in_range(1, 1 << 14))
        ->capture_default_str();
    sub->add_option("--height", args.height, "Image height of the tile rows")
        ->check(in_range(1, 1 << 14))
        ->capture_default_str();
    sub->add_option("--spp", args.spp, "Samples per pixel of the tile rows")
        ->check(in_range(1, 1 << 20))
        ->capture_default_str();
    sub->add_option("--repeat", args.repeat, "Runs of each configuration (median reported)")
        ->check(in_range(1, 100))
        ->capture_default_str();
    sub->add_option("--frames", args.frames,
                    "Also farm a turntable of this many frames (dynamic, each rank count)")
        ->check(in_range(0, 1 << 16));
    sub->add_option("--frame-width", args.frame_width, "Turntable width (0 = --width)")
        ->check(in_range(0, 1 << 14));
    sub->add_option("--frame-height", args.frame_height, "Turntable height (0 = --height)")
        ->check(in_range(0, 1 << 14));
    sub->add_option("--frame-spp", args.frame_spp, "Turntable spp (0 = --spp)")
        ->check(in_range(0, 1 << 20));
    sub->add_flag_callback(
        "--tiles", [] { args.tiles = true; }, "Run the tile rows (the default)");
    sub->add_flag_callback(
        "--no-tiles", [] { args.tiles = false; }, "Leave out the tile rows (then give --frames)");
    sub->add_option(
        "--launcher-flags", args.launcher_flags,
        "Extra flags for the launcher, words separated by blanks (no shell quoting), e.g. "
        "'--mca mpi_yield_when_idle 1'");
    sub->add_option("--throttle", args.throttle, "Slowdown of rank 1 in throttled runs (1 = off)")
        ->check(in_range(1.0, 1000.0, false))
        ->capture_default_str();
    sub->add_option("--mpiexec", args.mpiexec, "The MPI launcher")->capture_default_str();
    non_empty_file_name(sub->add_option("--work-dir", args.work_dir, "Images, stats and logs")
                            ->capture_default_str(),
                        "--work-dir");
    sub->callback([] { run(args); });
}

}  // namespace kdt::app
