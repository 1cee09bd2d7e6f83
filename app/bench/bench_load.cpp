// `kdtrace bench load FILE... [--repeat 5] [--csv out.csv] [--make-binary DIR]`:
// median load time of our PLY reader against Assimp's importer on the same files, the two
// taking turns run by run.
#include <malloc.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "app/bench/bench_options.h"
#include "app/bench/bench_table.h"
#include "app/commands.h"
#include "app/options_cli.h"
#include "renderer/core/error.h"
#include "renderer/core/output_path.h"
#include "renderer/core/temp_file.h"
#include "renderer/core/timer.h"
#include "renderer/io/mesh_io.h"
#include "renderer/io/ply_writer.h"

#ifdef KDT_HAVE_ASSIMP
#include <assimp/cimport.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#endif

namespace kdt::app {
namespace {

struct BenchLoadArgs {
    std::vector<std::string> files;
    int repeat = 5;
    std::string csv;
    std::string make_binary;
    bool no_assimp = false;
    bool warm_heap = false;
    int threads = MeshLoadOptions{}.threads;  // load_mesh's default unless --threads says
};

// CPU seconds of this process (user + system): steadier than wall time on a shared machine,
// and equal to it for our single-threaded loads when the machine is idle.
double cpu_seconds() {
    timespec ts{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

struct Row {
    std::string file, encoding;
    bool gzip = false;
    uint64_t bytes = 0;
    size_t triangles = 0;
    double ours_ms = 0, assimp_ms = 0, ours_cpu_ms = 0, assimp_cpu_ms = 0;
    size_t assimp_triangles = 0;
    double peak_ratio = 0;  // peak RSS delta of our load / mesh bytes
};

#ifdef KDT_HAVE_ASSIMP
// Flags 0: no post-processing, so Assimp does only its PLY import (its loader already
// emits one vertex per face corner); aiProcess_Triangulate etc. would add time that is not
// parsing. Triangles are counted from faces, a polygon of n vertices as n-2.
double assimp_load_ms(const std::string& path, size_t* triangles, double* cpu_ms) {
    Timer t;
    double c0 = cpu_seconds();
    const aiScene* scene = aiImportFile(path.c_str(), 0);
    double ms = t.seconds() * 1e3;
    *cpu_ms = (cpu_seconds() - c0) * 1e3;
    if (!scene)
        throw Error(ErrorLocation{path}, std::string("Assimp failed: ") + aiGetErrorString());
    size_t tris = 0;
    for (unsigned m = 0; m < scene->mNumMeshes; ++m)
        for (unsigned f = 0; f < scene->mMeshes[m]->mNumFaces; ++f) {
            unsigned n = scene->mMeshes[m]->mFaces[f].mNumIndices;
            tris += n >= 3 ? n - 2 : 0;
        }
    aiReleaseImport(scene);
    *triangles = tris;
    return ms;
}
#endif

void run_bench_load(const BenchLoadArgs& args) {
    if (!args.csv.empty()) check_output(args.csv, args.files, "the CSV table");
    std::vector<std::string> files = args.files;
    if (!args.make_binary.empty()) {
        // Every copy's name first, checked before anything is loaded or written: a copy must
        // not replace an input (DIR holding the inputs) nor another copy.
        std::vector<std::string> copies;
        for (const std::string& f : args.files) {
            std::string stem = std::filesystem::path(f).filename().string();
            for (const char* ext : {".gz", ".ply"})
                if (stem.size() > std::strlen(ext) && stem.ends_with(ext))
                    stem.resize(stem.size() - std::strlen(ext));
            for (const char* suffix : {"_le.ply", "_be.ply"})
                copies.push_back(
                    (std::filesystem::path(args.make_binary) / (stem + suffix)).string());
        }
        const bool dir_exists = std::filesystem::is_directory(args.make_binary);
        for (size_t i = 0; i < copies.size(); ++i) {
            for (size_t j = 0; j < i; ++j) {
                if (copies[j] == copies[i])
                    throw Error(ErrorLocation{copies[i]},
                                "cannot write the binary copy of " + args.files[i / 2] +
                                    ": it is also the copy of " + args.files[j / 2] +
                                    " (two inputs with the same name)");
            }
            if (dir_exists) check_output(copies[i], args.files, "the binary copy");
        }
        create_output_directory("--make-binary", args.make_binary);
        for (size_t i = 0; i < args.files.size(); ++i) {
            TriangleMesh mesh = load_mesh(args.files[i]);
            for (PlyEncoding enc :
                 {PlyEncoding::binary_little_endian, PlyEncoding::binary_big_endian}) {
                const std::string& out =
                    copies[2 * i + (enc == PlyEncoding::binary_little_endian ? 0 : 1)];
                write_ply(out, mesh, enc);
                std::printf("wrote %s\n", out.c_str());
                files.push_back(out);
            }
        }
    }

    std::vector<Row> rows;
    for (const std::string& f : files) {
        Row row;
        row.file = f;
        // Ours and Assimp take turns, run by run, so both see the same machine: on a shared
        // machine the load changes within seconds.
        std::vector<double> ours, ours_cpu, peer, peer_cpu;
        bool peer_ok = false;
#ifdef KDT_HAVE_ASSIMP
        peer_ok = !args.no_assimp;
#endif
        for (int r = 0; r < args.repeat; ++r) {
            MeshLoadInfo info;
            // Hand memory freed by earlier loads (Assimp's too) back to the system first, so
            // this load's pages count in the peak instead of reusing a grown heap, and the
            // load pays for its memory as a program loading one model does.
            if (!args.warm_heap) malloc_trim(0);
            reset_peak_rss();
            size_t before = current_rss_bytes();
            Timer t;
            double c0 = cpu_seconds();
            MeshLoadOptions options;
            options.threads = args.threads;
            TriangleMesh mesh = load_mesh(f, options, &info);
            ours.push_back(t.seconds() * 1e3);
            ours_cpu.push_back((cpu_seconds() - c0) * 1e3);
            size_t peak = peak_rss_bytes();
            double ratio = mesh.memory_bytes()
                               ? double(peak > before ? peak - before : 0) / mesh.memory_bytes()
                               : 0;
            row.peak_ratio = r == 0 ? ratio : std::max(row.peak_ratio, ratio);
            row.encoding = info.encoding;
            row.gzip = info.gzip;
            row.bytes = info.file_bytes;
            row.triangles = mesh.triangle_count();
#ifdef KDT_HAVE_ASSIMP
            if (peer_ok) {
                try {
                    double cpu = 0;
                    if (!args.warm_heap) malloc_trim(0);  // as for ours
                    peer.push_back(assimp_load_ms(f, &row.assimp_triangles, &cpu));
                    peer_cpu.push_back(cpu);
                } catch (const Error& e) {
                    // Assimp reads no .ply.gz, for one: the row shows "-" for it.
                    std::printf("note: %s\n", e.what());
                    peer_ok = false;
                    peer.clear();
                    peer_cpu.clear();
                }
            }
#endif
        }
        row.ours_ms = median(ours);
        row.ours_cpu_ms = median(ours_cpu);
        if (peer_ok) {
            row.assimp_ms = median(peer);
            row.assimp_cpu_ms = median(peer_cpu);
        }
        rows.push_back(row);
    }

    std::printf(
        "\nPLY load, median of %d runs (ours: kdt::load_mesh, ascii threads %d; Assimp: "
        "aiImportFile, flags 0).\nwall = elapsed ms; cpu = process CPU ms (user + system, all "
        "threads), "
        "steadier on a busy machine.\n\n",
        args.repeat, args.threads);
    std::printf(
        "| file | encoding | gzip | MB | triangles | ours wall | ours cpu | ours MB/s (cpu) | peak "
        "RSS / mesh "
        "| Assimp wall | Assimp cpu | Assimp tris | speedup wall | speedup cpu |\n");
    std::printf("|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for (const Row& r : rows) {
        double mb = r.bytes / 1e6;
        // A time of 0 (a clock too coarse for the load) gives no rate or speedup: "-".
        std::printf("| %s | %s | %s | %.1f | %zu | %.1f | %.1f | %s | %.2f | ",
                    std::filesystem::path(r.file).filename().c_str(), r.encoding.c_str(),
                    r.gzip ? "yes" : "no", mb, r.triangles, r.ours_ms, r.ours_cpu_ms,
                    fmt("%.0f", quotient(mb, r.ours_cpu_ms * 1e-3)).c_str(), r.peak_ratio);
        if (r.assimp_ms > 0)
            std::printf("%.1f | %.1f | %zu | %s | %s |\n", r.assimp_ms, r.assimp_cpu_ms,
                        r.assimp_triangles, fmt("%.1fx", quotient(r.assimp_ms, r.ours_ms)).c_str(),
                        fmt("%.1fx", quotient(r.assimp_cpu_ms, r.ours_cpu_ms)).c_str());
        else
            std::printf("- | - | - | - | - |\n");
    }
    if (!args.csv.empty()) {
        std::string csv =
            "file,encoding,gzip,bytes,triangles,ours_ms,ours_cpu_ms,assimp_ms,assimp_cpu_ms,"
            "assimp_triangles,peak_rss_over_mesh\n";
        for (const Row& r : rows) {
            char line[512];
            std::snprintf(line, sizeof(line), ",%s,%d,%llu,%zu,%.4f,%.4f,%.4f,%.4f,%zu,%.4f\n",
                          r.encoding.c_str(), int(r.gzip), (unsigned long long)r.bytes, r.triangles,
                          r.ours_ms, r.ours_cpu_ms, r.assimp_ms, r.assimp_cpu_ms,
                          r.assimp_triangles, r.peak_ratio);
            csv += r.file + line;
        }
        write_file_atomically(args.csv, csv.data(), csv.size());
    }
}

}  // namespace

void add_bench_load_command(CLI::App& bench) {
    auto args = std::make_shared<BenchLoadArgs>();
    CLI::App* cmd =
        bench.add_subcommand("load", "PLY load time: ours against Assimp (Markdown table)");
    non_empty_file_name(cmd->add_option("files", args->files, "PLY/OBJ files")->required(),
                        "FILES");
    cmd->add_option("--repeat", args->repeat, "Runs per file and reader (median reported)")
        ->capture_default_str()
        ->check(in_range(1, 1000));
    non_empty_file_name(cmd->add_option("--csv", args->csv, "Also write the table as CSV"),
                        "--csv");
    non_empty_file_name(
        cmd->add_option("--make-binary", args->make_binary,
                        "Write binary little- and big-endian copies of the inputs into DIR with "
                        "our writer and benchmark them too"),
        "--make-binary");
    cmd->add_flag("--no-assimp", args->no_assimp, "Time our reader only");
    cmd->add_flag("--warm-heap", args->warm_heap,
                  "Let each load reuse the heap earlier loads grew (faster, but the peak RSS "
                  "column then undercounts)");
    cmd->add_option("--threads", args->threads,
                    "Threads for our ascii PLY parsing: 1 (the default), 2 or more = two, 0 = two "
                    "when the machine has them")
        ->check(in_range(0, 64));
    cmd->callback([args] { run_bench_load(*args); });
}

}  // namespace kdt::app
