// `kdtrace info FILE [--drop-invalid]`: loads a mesh and prints what the loader found.
#include <cstdio>
#include <memory>
#include <string>

#include "app/commands.h"
#include "renderer/core/timer.h"
#include "renderer/io/mesh_io.h"

namespace kdt::app {
namespace {

struct InfoArgs {
    std::string file;
    bool drop_invalid = false;
    int threads = 1;
};

void run_info(const InfoArgs& args) {
    MeshLoadOptions options;
    options.drop_invalid = args.drop_invalid;
    options.threads = args.threads;
    MeshLoadInfo info;
    reset_peak_rss();
    const size_t rss_before = current_rss_bytes();
    TriangleMesh mesh = load_mesh(args.file, options, &info);
    const size_t peak = peak_rss_bytes();
    const Bounds3f b = mesh.bounds();
    const double mib = 1.0 / (1024.0 * 1024.0);
    std::printf("file:        %s\n", args.file.c_str());
    std::printf("format:      %s\n", info.format.c_str());
    std::printf("encoding:    %s\n", info.encoding.c_str());
    std::printf("gzip:        %s\n", info.gzip ? "yes" : "no");
    std::printf("data bytes:  %llu\n", (unsigned long long)info.file_bytes);
    std::printf("vertices:    %zu\n", mesh.vertex_count());
    std::printf("faces:       %llu\n", (unsigned long long)info.source_faces);
    if (mesh.triangle_count() == 0)
        std::printf("triangles:   0 (point cloud: no faces)\n");
    else
        std::printf("triangles:   %zu\n", mesh.triangle_count());
    std::printf("degenerate:  %llu faces with repeated indices (kept)\n",
                (unsigned long long)info.degenerate_faces);
    if (args.drop_invalid)
        std::printf("dropped:     %llu faces using non-finite vertices\n",
                    (unsigned long long)info.dropped_faces);
    std::printf("normals:     %s\n", mesh.normals.empty() ? "no" : "yes");
    std::printf("colours:     %s\n", mesh.colors.empty() ? "no" : "yes");
    if (b.empty())
        std::printf("bounds:      empty\n");
    else
        std::printf("bounds:      (%g, %g, %g) - (%g, %g, %g)\n", b.lower.x, b.lower.y, b.lower.z,
                    b.upper.x, b.upper.y, b.upper.z);
    std::printf("mesh memory: %.2f MiB (%zu bytes)\n", mesh.memory_bytes() * mib,
                mesh.memory_bytes());
    std::printf("load time:   %.3f ms\n", info.seconds * 1e3);
    std::printf("peak RSS:    %.2f MiB (%.2f MiB above the RSS before loading)\n", peak * mib,
                (peak > rss_before ? peak - rss_before : 0) * mib);
}

}  // namespace

void add_info_command(CLI::App& parent) {
    auto args = std::make_shared<InfoArgs>();
    CLI::App* cmd =
        parent.add_subcommand("info", "Load a mesh (PLY, PLY.gz, OBJ) and print its statistics");
    cmd->add_option("file", args->file, "Mesh file")->required();
    cmd->add_flag(
        "--drop-invalid", args->drop_invalid,
        "Drop faces that use non-finite vertices instead of failing (and report how many)");
    cmd->add_option("--threads", args->threads,
                    "Threads for ascii PLY parsing (1 = one core, 2 = two, 0 = auto)")
        ->check(CLI::Range(0, 64));
    cmd->callback([args] { run_info(*args); });
}

}  // namespace kdt::app
