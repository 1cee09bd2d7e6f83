// Subcommands of the kdtrace executable. Each add_* registers its flags on the parent
// and sets a callback; the callback throws kdt::Error on bad input, caught in main().
#pragma once

#include <CLI/CLI.hpp>

namespace kdt::app {

void add_info_command(CLI::App& parent);    // cmd_info.cpp
void add_build_command(CLI::App& parent);   // cmd_build.cpp
void add_render_command(CLI::App& parent);  // cmd_render.cpp
void add_scene_command(CLI::App& parent);   // cmd_scene.cpp (export the built-in scene)
void add_view_command(CLI::App& parent);    // cmd_view.cpp (the interactive viewer)

// `kdtrace bench` and its subcommands, one file each.
void add_bench_load_command(CLI::App& bench);      // bench_load.cpp: PLY load vs Assimp
void add_bench_kdtree_command(CLI::App& bench);    // bench_kdtree.cpp: thesis table 6.1, Embree
void add_bench_converge_command(CLI::App& bench);  // bench_converge.cpp: error against time
void add_bench_mpi_command(CLI::App& bench);       // bench_mpi.cpp: MPI farm scaling

}  // namespace kdt::app
