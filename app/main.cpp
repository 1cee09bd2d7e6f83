// kdtrace: command-line entry point. Parses, dispatches, and reports errors in one place.
#include <cstdio>
#include <exception>

#include "app/commands.h"
#include "renderer/core/error.h"

int main(int argc, char** argv) {
    CLI::App app{"kdtrace: a kd-tree path tracer for big scanned meshes"};
    app.set_version_flag("--version", "kdtrace 0.1.0");
    app.require_subcommand(1);
    kdt::app::add_info_command(app);
    kdt::app::add_build_command(app);
    kdt::app::add_render_command(app);
    kdt::app::add_scene_command(app);
    CLI::App* bench = app.add_subcommand("bench", "Benchmarks: tables in Markdown and CSV");
    bench->require_subcommand(1);
    kdt::app::add_bench_load_command(*bench);
    kdt::app::add_bench_kdtree_command(*bench);
    kdt::app::add_bench_converge_command(*bench);
    kdt::app::add_bench_mpi_command(*bench);
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e);
    } catch (const kdt::Error& e) {
        std::fprintf(stderr, "kdtrace: error: %s\n", e.what());
        return 1;
    } catch (const std::bad_alloc&) {
        std::fprintf(stderr, "kdtrace: error: out of memory\n");
        return 1;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "kdtrace: error: %s\n", e.what());
        return 1;
    }
    return 0;
}
