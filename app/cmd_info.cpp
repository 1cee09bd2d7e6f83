// `kdtrace info FILE [--drop-invalid] [--all]`: loads a mesh and prints what the loader
// found, or prints an image's size, format and the render settings stored in it.
#include <algorithm>
#include <cctype>
#include <cstdio>
#include <memory>
#include <string>
#include <string_view>

#include "app/commands.h"
#include "app/options_cli.h"
#include "renderer/core/error.h"
#include "renderer/core/timer.h"
#include "renderer/io/image_io.h"
#include "renderer/io/mesh_io.h"

namespace kdt::app {
namespace {

struct InfoArgs {
    std::string file;
    bool drop_invalid = false;
    bool all = false;
    int threads = 1;
};

bool is_image_file(const std::string& path) {
    std::string lower = path;
    std::transform(lower.begin(), lower.end(), lower.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    for (const char* ext : {".png", ".exr", ".pfm", ".hdr"}) {
        const size_t n = std::char_traits<char>::length(ext);
        if (lower.size() > n && lower.compare(lower.size() - n, n, ext) == 0) return true;
    }
    return false;
}

/// Metadata text as it is safe to print: each line (and each tab-separated part of it)
/// through printable(), so control bytes, C1 controls and invalid UTF-8 come out escaped,
/// while a multi-line value stays readable, each new line indented under the key.
std::string metadata_text(const std::string& value) {
    std::string out;
    size_t begin = 0;
    for (size_t i = 0; i <= value.size(); ++i) {
        if (i < value.size() && value[i] != '\n' && value[i] != '\t') continue;
        out += printable(std::string_view(value).substr(begin, i - begin));
        if (i < value.size()) out += value[i] == '\n' ? "\n             " : "\t";
        begin = i + 1;
    }
    return out;
}

void print_image_info(const InfoArgs& args) {
    const ImageInfo info = read_image_info(args.file);
    // The name as errors show it: one line, nothing that drives the terminal.
    std::printf("file:        %s\n", printable(args.file).c_str());
    std::printf("format:      %s\n", info.format.c_str());
    std::printf("size:        %dx%d\n", info.width, info.height);
    std::printf("encoding:    %s\n", metadata_text(info.encoding).c_str());
    bool rendered = false;
    for (const auto& [key, value] : info.metadata) rendered |= key.rfind("kdtrace:", 0) == 0;
    if (!rendered) std::printf("render:      no kdtrace settings stored\n");
    // The render settings first, in a fixed order; then any other metadata.
    const char* order[] = {"kdtrace:command", "kdtrace:scene",     "kdtrace:spp",
                           "kdtrace:passes",  "kdtrace:seed",      "kdtrace:camera",
                           "kdtrace:params",  "kdtrace:scene_json"};
    // Values kdtrace writes are short but for the scene; a file may hold megabytes in one.
    constexpr size_t kLongValue = 16384;
    auto print = [&](const std::string& key, const std::string& value) {
        if (key == "kdtrace:scene_json" && !args.all) {
            std::printf("%s: %zu bytes of scene JSON (--all prints it)\n", key.c_str(),
                        value.size());
            return;
        }
        if (value.size() > kLongValue && !args.all) {
            std::printf("%s: %zu bytes (--all prints it)\n", metadata_text(key).c_str(),
                        value.size());
            return;
        }
        std::printf("%s: %s\n", metadata_text(key).c_str(), metadata_text(value).c_str());
    };
    for (const char* key : order) {
        for (const auto& [k, v] : info.metadata) {
            if (k == key) print(k, v);
        }
    }
    for (const auto& entry : info.metadata) {
        // Not a structured binding: clang 14 (the TSan and fuzz builds) cannot capture one.
        const std::string& k = entry.first;
        if (std::none_of(std::begin(order), std::end(order), [&](const char* o) { return k == o; }))
            print(k, entry.second);
    }
}

void run_info(const InfoArgs& args) {
    if (is_image_file(args.file)) {
        print_image_info(args);
        return;
    }
    MeshLoadOptions options;
    options.drop_invalid = args.drop_invalid;
    options.threads = args.threads;
    MeshLoadInfo info;
    reset_peak_rss();
    const size_t rss_before = current_rss_bytes();
    TriangleMesh mesh = load_mesh(args.file, options, &info);
    const size_t peak = peak_rss_bytes();
    for (const std::string& w : info.warnings)
        std::fprintf(stderr, "kdtrace: warning: %s\n", w.c_str());
    const Bounds3f b = mesh.bounds();
    const double mib = 1.0 / (1024.0 * 1024.0);
    std::printf("file:        %s\n", printable(args.file).c_str());
    std::printf("format:      %s\n", info.format.c_str());
    std::printf("encoding:    %s\n", printable(info.encoding).c_str());
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
        std::printf("dropped:     %llu faces (non-finite vertices, or fewer than 3 indices)\n",
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
    CLI::App* cmd = parent.add_subcommand(
        "info",
        "Print a mesh's statistics (PLY, PLY.gz, OBJ), or an image's size, format and the render "
        "settings and command stored in it (PNG, EXR, PFM, HDR)");
    non_empty_file_name(cmd->add_option("file", args->file, "Mesh or image file"), "info")
        ->required();
    cmd->add_flag("--all", args->all,
                  "Images: print the stored scene JSON and any value over 16 KiB in full");
    cmd->add_flag("--drop-invalid", args->drop_invalid,
                  "Drop faces that use non-finite vertices or have fewer than 3 indices instead of "
                  "failing (and report how many)");
    cmd->add_option(
           "--threads", args->threads,
           "Threads for ascii PLY parsing: 1 (the default), 2 or more = two, 0 = two when the "
           "machine has them")
        ->check(in_range(0, 1024));
    cmd->callback([args] { run_info(*args); });
}

}  // namespace kdt::app
