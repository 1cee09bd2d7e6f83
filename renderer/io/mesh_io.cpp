#include "renderer/io/mesh_io.h"

#include <algorithm>
#include <cctype>

#include "renderer/core/error.h"
#include "renderer/io/file_reader.h"
#include "renderer/io/obj_reader.h"
#include "renderer/io/ply_reader.h"

namespace kdt {
namespace {

bool ends_with_ci(const std::string& s, const std::string& suffix) {
    if (s.size() < suffix.size()) return false;
    return std::equal(suffix.rbegin(), suffix.rend(), s.rbegin(), [](char a, char b) {
        return std::tolower(static_cast<unsigned char>(a)) ==
               std::tolower(static_cast<unsigned char>(b));
    });
}

}  // namespace

MeshFormat detect_mesh_format(const std::string& path) {
    // Content first: a (possibly gzip-compressed) stream starting with "ply" is PLY
    // whatever its name; anything else goes by extension.
    FileReader reader = FileReader::open(path);
    char head[4] = {};
    size_t got = reader.read(head, 4);
    if (got == 4 && head[0] == 'p' && head[1] == 'l' && head[2] == 'y' &&
        (head[3] == '\n' || head[3] == '\r'))
        return MeshFormat::ply;
    if (ends_with_ci(path, ".obj")) return MeshFormat::obj;
    if (ends_with_ci(path, ".ply") || ends_with_ci(path, ".ply.gz")) return MeshFormat::ply;
    return MeshFormat::unknown;
}

TriangleMesh load_mesh(const std::string& path, const MeshLoadOptions& options,
                       MeshLoadInfo* info) {
    switch (detect_mesh_format(path)) {
        case MeshFormat::ply:
            return read_ply(path, options, info);
        case MeshFormat::obj:
            return read_obj(path, options, info);
        default:
            break;
    }
    ErrorLocation w;
    w.path = path;
    throw Error(w, "unknown mesh format (expected a PLY file, .ply.gz or .obj)");
}

}  // namespace kdt
