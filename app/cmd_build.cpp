// `kdtrace build MODEL`: builds (or reuses from the cache) the kd-tree of a model and prints
// what the build produced; with -o writes the tree to a cache file of the user's choice.
#include <cstdio>
#include <memory>
#include <string>

#include "app/commands.h"
#include "app/options_cli.h"
#include "renderer/accel/kdtree_cache.h"
#include "renderer/core/error.h"
#include "renderer/core/interrupt.h"
#include "renderer/core/output_path.h"
#include "renderer/core/timer.h"
#include "renderer/io/mesh_io.h"
#include "renderer/render/settings.h"
#include "renderer/scene/scene.h"

namespace kdt::app {
namespace {

void print_stats(const KdTree& tree) {
    const KdTreeStats& s = tree.stats();
    const KdTreeParams& p = tree.params();
    std::printf("builder %s: q %.2f, n0 %d, max depth ", kKdBuilderNames[size_t(p.builder)],
                double(p.q), p.n0);
    if (p.max_depth > 0) {
        std::printf("%d", p.max_depth);
    } else {
        std::printf("automatic");
    }
    if (p.builder == KdBuilder::thesis) {
        std::printf("%s%s%s%s\n", p.use_median_split ? "" : ", no median split",
                    p.use_center_split ? "" : ", no center split",
                    p.use_cutoff_split ? "" : ", no cut-off split",
                    p.thesis_all_axes ? ", all axes" : "");
    } else {
        std::printf(", traversal cost %g, intersect cost %g, empty bonus %g\n",
                    double(p.traversal_cost), double(p.intersect_cost), double(p.empty_bonus));
    }
    std::printf(
        "nodes %llu, leaves %llu (%llu empty), depth %u, refs/triangle %.3f, "
        "mean leaf %.2f, max leaf %u\n",
        (unsigned long long)s.nodes, (unsigned long long)s.leaves,
        (unsigned long long)s.empty_leaves, s.max_depth_reached, s.refs_per_triangle,
        s.mean_leaf_size, s.max_leaf_size);
    std::printf("splits: median %llu, center %llu, cut-off %llu, sah %llu\n",
                (unsigned long long)s.median_splits, (unsigned long long)s.center_splits,
                (unsigned long long)s.cutoff_splits, (unsigned long long)s.sah_splits);
    std::printf("size %.1f KB (%.2f bytes/triangle), build %.3f s, peak build memory %.1f MB\n",
                double(s.bytes) / 1024.0, s.bytes_per_triangle, s.build_seconds,
                double(s.peak_build_bytes) / (1024.0 * 1024.0));
}

}  // namespace

void add_build_command(CLI::App& parent) {
    auto* cmd = parent.add_subcommand(
        "build", "Build the kd-tree of a model (reused from the cache when valid) and print it");
    static std::string model, output, cache_dir;
    static KdTreeParams params;
    static int subdivide = 0;
    non_empty_file_name(cmd->add_option("MODEL", model, "Model file (.ply, .ply.gz, .obj)"),
                        "MODEL")
        ->required();
    add_tree_options(*cmd, params);
    cmd->add_option("--subdivide", subdivide, "Split every triangle into 4^K first")
        ->check(in_range(0, 4));
    // The loader's error for a non-finite vertex names this flag: `build` must take it for
    // the tree of the model `render --drop-invalid` renders.
    static bool drop_invalid = false;
    cmd->add_flag("--drop-invalid", drop_invalid,
                  "Drop faces with non-finite vertices (or fewer than 3 indices) instead of "
                  "failing, as render --drop-invalid does");
    static bool quiet = false;
    cmd->add_flag("--quiet", quiet, "No cache messages (warnings are still printed)");
    non_empty_file_name(
        cmd->add_option("-o,--output", output,
                        "Write the tree to this file (always rebuilt) instead of the automatic "
                        "cache"),
        "-o");
    non_empty_file_name(cmd->add_option("--cache-dir", cache_dir,
                                        "Cache directory (default: $KDT_CACHE_DIR/trees, "
                                        "$XDG_CACHE_HOME/kdtrace/trees or ~/.cache/kdtrace/trees)"),
                        "--cache-dir");
    cmd->callback([cmd] {
        interrupt::install();
        interrupt::set_exit_notice("interrupted; no tree written");
        validate(params);
        warn_unused_tree_flags(*cmd, params, false);
        // Fail before a long build, not after it.
        if (!output.empty()) check_output(output, {model}, "the tree");
        MeshLoadInfo info;
        // Through the scene loader's model loading, so that a model without faces gets the
        // warning `render` gives: the tree is valid (one empty leaf) and `render` accepts it.
        SceneLoadOptions load;
        load.drop_invalid = drop_invalid;
        auto mesh = std::make_shared<TriangleMesh>(load_model(model, load, &info));
        std::printf("%s: %zu vertices, %zu triangles, loaded in %.3f s\n", printable(model).c_str(),
                    mesh->vertex_count(), mesh->triangle_count(), info.seconds);
        if (subdivide > 0) {
            Timer t;
            subdivide_model(model, *mesh, subdivide);
            std::printf("subdivided %d times: %zu triangles (%.2f s)\n", subdivide,
                        mesh->triangle_count(), t.seconds());
        }
        // The renderer builds its trees over the mesh in spatial order (compile_snapshot);
        // so does this command, so that `kdtrace render` finds the cached tree.
        apply_order(*mesh, spatial_order(*mesh));
        std::shared_ptr<const TriangleMesh> shared = mesh;
        std::shared_ptr<const KdTree> tree;
        if (!output.empty()) {
            Timer t;
            tree = build_kdtree(shared, params);
            std::printf("built in %.3f s\n", t.seconds());
            // (get_or_build_kdtree() below warns through its log.)
            if (const std::string w = kdtree_leaf_warning(*tree); !w.empty())
                std::fprintf(stderr, "kdtrace: warning: %s\n", w.c_str());
            save_kdtree(output, *tree);
            std::printf("wrote %s\n", printable(output).c_str());
        } else {
            KdCacheReport report;
            const KdCacheLog log = [](const std::string& line) {
                if (!quiet || is_warning(line)) std::fprintf(stderr, "kdtrace: %s\n", line.c_str());
            };
            tree = get_or_build_kdtree(subdivided_model_key(model, subdivide), shared, params,
                                       cache_dir, log, &report);
            std::printf("%s in %.3f s%s%s\n", report.loaded ? "loaded from cache" : "built",
                        report.seconds, report.path.empty() ? "" : ": ",
                        printable(report.path).c_str());
        }
        interrupt::set_exit_notice(nullptr);  // the tree is written (or was loaded)
        print_stats(*tree);
        std::printf("peak RSS %.1f MB\n", double(peak_rss_bytes()) / (1024.0 * 1024.0));
    });
}

}  // namespace kdt::app
