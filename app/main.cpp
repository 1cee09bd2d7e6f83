// kdtrace: command-line entry point. Parses, dispatches, and reports errors in one place.
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <string>
#include <thread>
#include <vector>

#include "app/commands.h"
#include "app/mpi_cli.h"
#include "renderer/core/error.h"

namespace {

size_t edit_distance(const std::string& a, const std::string& b) {
    std::vector<size_t> row(b.size() + 1);
    for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
    for (size_t i = 1; i <= a.size(); ++i) {
        size_t diag = row[0];
        row[0] = i;
        for (size_t j = 1; j <= b.size(); ++j) {
            const size_t up = row[j];
            row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] != b[j - 1])});
            diag = up;
        }
    }
    return row[b.size()];
}

// An argument where `app` expects a subcommand that names none: a message naming the word and
// the closest subcommand, or empty when the word is fine (or an option).
std::string unknown_subcommand(const CLI::App& app, const std::string& word) {
    if (word.empty() || word[0] == '-') return {};
    std::string best;
    size_t best_distance = SIZE_MAX;
    std::string all;
    for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
        const std::string& name = sub->get_name();
        if (name == word) return {};
        all += (all.empty() ? "" : ", ") + name;
        const size_t d = edit_distance(word, name);
        if (d < best_distance) best_distance = d, best = name;
    }
    std::string message = "unknown command '" + kdt::excerpt(word) + "'";
    if (best_distance <= std::max<size_t>(2, word.size() / 3)) {
        message += " (did you mean '" + best + "'?)";
    } else {
        message += " (commands: " + all + ")";
    }
    return message;
}

// A standard descriptor closed by the caller (`>&-`) would be reused by the next open(), and
// stdout's lines would go into that file: each closed one gets /dev/null opened read-only, so
// the descriptor stays taken and writes to it fail (and are reported by finish_stdout()).
void reserve_standard_descriptors() {
    for (int fd = 0; fd <= 2; ++fd) {
        if (::fcntl(fd, F_GETFD) != -1 || errno != EBADF) continue;
        const int got = ::open("/dev/null", O_RDONLY);
        if (got != fd && got >= 0) ::close(got);  // not the lowest free one: leave it be
    }
}

// What a command printed is its product (tables, info): a full disk or a closed stdout must
// not end in status 0. Returns the exit status, 1 when stdout could not be written.
int finish_stdout(int status) {
    const int earlier = errno;  // the failed write's reason, when the error came before
    const bool flushed = std::fflush(stdout) == 0;
    if (flushed && !std::ferror(stdout)) return status;
    const int reason = !flushed ? errno : earlier;
    std::fprintf(stderr, "kdtrace: error: cannot write to standard output: %s\n",
                 reason ? std::strerror(reason) : "write error");
    return status ? status : 1;
}

// A CLI11 parse error in kdtrace's words: one line, lower case, with where to look for the
// options or commands of the (sub)command that was being parsed.
std::string parse_error_message(const CLI::App& app, const CLI::ParseError& e) {
    std::string command = "kdtrace";
    const CLI::App* level = &app;
    for (bool deeper = true; deeper;) {
        deeper = false;
        for (const CLI::App* sub : level->get_subcommands()) {
            command += " " + sub->get_name();
            level = sub;
            deeper = true;
            break;
        }
    }
    std::string m = e.what();
    const size_t colon = m.find(": ");
    if (m == "A subcommand is required") {
        m = "a command is required (`" + command + " --help` lists them)";
    } else if (const size_t at = m.find(" not expected: "); at != std::string::npos) {
        // "The following argument was not expected: --bogus" (an unknown option or an extra
        // argument).
        // CLI11 lists extras last first and counts a "--" among them; the command's own
        // remaining() has them in the order given.
        std::string extras;
        int count = 0;
        for (const std::string& arg : level->remaining()) {
            if (arg == "--") continue;
            extras += (count++ > 0 ? " " : "") + arg;
        }
        if (count == 0) extras = m.substr(at + 15);
        m = std::string("unexpected argument") + (count > 1 ? "s " : " ") + extras + " (`" +
            command + " --help` lists the options)";
    } else if (colon != std::string::npos && m.size() > 8 &&
               m.compare(m.size() - 8, 8, " missing") == 0 &&
               m.find(" required ", colon) != std::string::npos) {
        m = m.substr(0, colon) + " needs a value";  // "--spp: 1 required INT missing"
    } else if (colon != std::string::npos && m.compare(colon, 10, ": must be ") == 0) {
        m.erase(colon, 1);  // in_range()'s check: "--subdivide must be in [0, 4] (got 5)"
    } else if (m.size() > 1 && std::isupper(static_cast<unsigned char>(m[0])) &&
               std::islower(static_cast<unsigned char>(m[1]))) {
        m[0] = char(std::tolower(static_cast<unsigned char>(m[0])));
    }
    for (char& c : m) {
        if (c == '\n') c = ' ';
    }
    return kdt::printable_line(m);
}

int run(int argc, char** argv);
int report_error();

// Under `mpirun ... kdtrace ... --mpi` every rank parses the same command line, so an error in
// it is rank 0's to print: another rank exits with the same status without a word, a second
// later, so that mpirun (which ends the job once a rank exits non-zero) does not end rank 0
// before its message.
int exit_quietly(int status) {
    if (status != 0) std::this_thread::sleep_for(std::chrono::seconds(1));
    return status;
}

}  // namespace

int main(int argc, char** argv) {
    reserve_standard_descriptors();
    const int status = run(argc, argv);
    return finish_stdout(status);
}

namespace {

int run(int argc, char** argv) {
    CLI::App app{"kdtrace: a kd-tree path tracer for big scanned meshes"};
    app.set_version_flag("--version", "kdtrace 0.1.0");
    app.require_subcommand(1);
    // A repeated single-value option takes its last value, as in pbrt and Blender: a script
    // may append an override to a command line. Options that take lists keep every value.
    app.option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
    kdt::app::add_info_command(app);
    kdt::app::add_build_command(app);
    kdt::app::add_render_command(app);
    kdt::app::add_scene_command(app);
    kdt::app::add_view_command(app);
    CLI::App* bench = app.add_subcommand("bench", "Benchmarks: tables in Markdown and CSV");
    bench->require_subcommand(1);
    kdt::app::add_bench_load_command(*bench);
    kdt::app::add_bench_kdtree_command(*bench);
    kdt::app::add_bench_converge_command(*bench);
    kdt::app::add_bench_mpi_command(*bench);
    // CLI11 would take an unknown word for a stray positional and say only that a subcommand
    // is required.
    const bool worker = kdt::app::mpi_worker_before_init(argc, argv);
    const CLI::App* level = &app;
    for (int i = 1; i < argc && level; ++i) {
        if (argv[i][0] == '-') break;
        if (std::string message = unknown_subcommand(*level, argv[i]); !message.empty()) {
            if (worker) return exit_quietly(1);
            std::fprintf(stderr, "kdtrace: error: %s\n", message.c_str());
            return 1;
        }
        const CLI::App* next = nullptr;
        for (const CLI::App* sub : level->get_subcommands([](const CLI::App*) { return true; }))
            if (sub->get_name() == argv[i]) next = sub;
        level = next && !next->get_subcommands([](const CLI::App*) { return true; }).empty()
                    ? next
                    : nullptr;
    }
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        // --help and --version are "errors" with status 0: CLI11 prints them.
        if (e.get_exit_code() == 0) return worker ? 0 : app.exit(e);
        if (worker) return exit_quietly(1);
        std::fprintf(stderr, "kdtrace: error: %s\n", parse_error_message(app, e).c_str());
        return 1;
    } catch (...) {
        if (worker) return exit_quietly(1);
        return report_error();
    }
    return 0;
}

// The message of the exception being handled, printed as kdtrace's one error line; returns 1.
int report_error() {
    try {
        throw;
    } catch (const kdt::Error& e) {
        // printable(): a message may quote bytes from a file through a library (a JSON
        // parser's "last read"); none may reach the terminal raw. Escaped text stays as it is.
        std::fprintf(stderr, "kdtrace: error: %s\n", kdt::printable_line(e.what()).c_str());
        return 1;
    } catch (const std::bad_alloc&) {
        std::fprintf(stderr, "kdtrace: error: out of memory\n");
        return 1;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "kdtrace: error: %s\n", kdt::printable_line(e.what()).c_str());
    }
    return 1;
}

}  // namespace
