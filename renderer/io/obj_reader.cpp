#include "renderer/io/obj_reader.h"

#include <cmath>
#include <unordered_map>

#include <tiny_obj_loader.h>

#include "renderer/core/error.h"
#include "renderer/core/timer.h"
#include "renderer/io/file_reader.h"

namespace kdt {
namespace {

[[noreturn]] void fail(const std::string& path, const std::string& element, int64_t index,
                       const std::string& message) {
    ErrorLocation w;
    w.path = path;
    w.element = element;
    w.index = index;
    throw Error(w, message);
}

std::string first_line(const std::string& s) {
    std::string t = s.substr(0, s.find('\n'));
    return t.empty() ? std::string("unknown error") : t;
}

// Parses the whole OBJ text. `path` names it in errors and info.
TriangleMesh read_obj_text(const std::string& text, const std::string& path,
                           const MeshLoadOptions& options, MeshLoadInfo* info, Timer& timer) {
    const uint64_t file_bytes = text.size();
    tinyobj::ObjReaderConfig config;
    config.triangulate = true;
    config.vertex_color = false;
    tinyobj::ObjReader reader;
    // From a string with an empty material text: ParseFromFile would open every `mtllib`
    // file relative to the OBJ (a device such as /dev/zero there never ends), and the
    // renderer does not use OBJ materials.
    if (!reader.ParseFromString(text, std::string(), config))
        fail(path, "", -1, "OBJ parse error: " + first_line(reader.Error()));

    const tinyobj::attrib_t& attrib = reader.GetAttrib();
    const size_t nv = attrib.vertices.size() / 3;
    const size_t nn = attrib.normals.size() / 3;
    if (nv > size_t(UINT32_MAX)) fail(path, "", -1, "more than 2^32-1 vertices");

    TriangleMesh mesh;
    // Normals are kept only when every face corner names a valid one.
    bool use_normals = options.keep_normals && nn > 0;
    uint64_t faces = 0;
    for (const tinyobj::shape_t& shape : reader.GetShapes()) {
        faces += shape.mesh.num_face_vertices.size();
        for (const tinyobj::index_t& idx : shape.mesh.indices)
            if (idx.normal_index < 0 || size_t(idx.normal_index) >= nn) use_normals = false;
    }

    std::vector<uint8_t> bad(nv, 0);
    uint64_t bad_count = 0;
    for (size_t i = 0; i < nv; ++i) {
        Vec3f p(attrib.vertices[3 * i], attrib.vertices[3 * i + 1], attrib.vertices[3 * i + 2]);
        if (!is_finite(p)) {
            if (!options.drop_invalid)
                fail(path, "vertex", int64_t(i),
                     "non-finite coordinate; --drop-invalid drops the faces using it");
            bad[i] = 1;
            ++bad_count;
        }
    }

    std::unordered_map<uint64_t, uint32_t> split;  // (position, normal) -> vertex, with normals
    std::vector<uint32_t> remap;                   // file position -> vertex, without normals
    if (!use_normals) {
        // Keep the file's vertex order (unused vertices too), minus non-finite ones.
        remap.assign(nv, UINT32_MAX);
        mesh.positions.reserve(nv - bad_count);
        for (size_t v = 0; v < nv; ++v) {
            if (bad[v]) continue;
            remap[v] = uint32_t(mesh.positions.size());
            mesh.positions.emplace_back(attrib.vertices[3 * v], attrib.vertices[3 * v + 1],
                                        attrib.vertices[3 * v + 2]);
        }
    }
    auto vertex_of = [&](const tinyobj::index_t& idx) -> uint32_t {
        if (!use_normals) return remap[size_t(idx.vertex_index)];
        uint64_t key = uint64_t(uint32_t(idx.vertex_index)) << 32 | uint32_t(idx.normal_index);
        auto [it, inserted] = split.try_emplace(key, uint32_t(mesh.positions.size()));
        if (inserted) {
            size_t v = size_t(idx.vertex_index), n = size_t(idx.normal_index);
            mesh.positions.emplace_back(attrib.vertices[3 * v], attrib.vertices[3 * v + 1],
                                        attrib.vertices[3 * v + 2]);
            mesh.normals.emplace_back(attrib.normals[3 * n], attrib.normals[3 * n + 1],
                                      attrib.normals[3 * n + 2]);
        }
        return it->second;
    };

    uint64_t face_index = 0, dropped = 0, degenerate = 0, tris = 0;
    for (const tinyobj::shape_t& shape : reader.GetShapes()) {
        size_t corner = 0;
        for (unsigned char fv : shape.mesh.num_face_vertices) {
            if (fv != 3)
                fail(path, "face", int64_t(face_index),
                     "has " + std::to_string(fv) + " vertices after triangulation");
            if (corner + 3 > shape.mesh.indices.size())
                fail(path, "face", int64_t(face_index), "truncated index list");
            const tinyobj::index_t* c = &shape.mesh.indices[corner];
            bool is_bad = false;
            for (int k = 0; k < 3; ++k) {
                if (c[k].vertex_index < 0 || size_t(c[k].vertex_index) >= nv)
                    fail(path, "face", int64_t(face_index),
                         "vertex index " + std::to_string(int64_t(c[k].vertex_index) + 1) +
                             " (1-based, relative indices resolved) out of range (" +
                             std::to_string(nv) + " vertices)");
                is_bad |= bad[size_t(c[k].vertex_index)] != 0;
            }
            corner += 3;
            ++face_index;
            if (is_bad) {
                ++dropped;
                continue;
            }
            if (c[0].vertex_index == c[1].vertex_index || c[1].vertex_index == c[2].vertex_index ||
                c[0].vertex_index == c[2].vertex_index)
                ++degenerate;
            mesh.triangles.emplace_back(vertex_of(c[0]), vertex_of(c[1]), vertex_of(c[2]));
            ++tris;
        }
    }
    (void)tris;
    if (info) {
        info->format = "obj";
        info->encoding = "text";
        info->gzip = false;
        info->file_bytes = file_bytes;
        info->source_faces = faces;
        info->dropped_faces = dropped;
        info->degenerate_faces = degenerate;
        info->seconds = timer.seconds();
    }
    return mesh;
}

}  // namespace

TriangleMesh read_obj(const std::string& path, const MeshLoadOptions& options, MeshLoadInfo* info) {
    Timer timer;
    // Opening through FileReader gives the same missing-file, directory and device messages
    // as for PLY.
    FileReader reader = FileReader::open(path);
    if (reader.gzip()) fail(path, "", -1, "gzip-compressed OBJ files are not supported");
    std::string text(size_t(reader.file_bytes()), '\0');
    size_t got = 0;
    while (got < text.size()) {
        const size_t n = reader.read(text.data() + got, text.size() - got);
        if (n == 0) break;
        got += n;
    }
    text.resize(got);
    return read_obj_text(text, path, options, info, timer);
}

TriangleMesh read_obj_memory(const void* data, size_t size, const std::string& name,
                             const MeshLoadOptions& options, MeshLoadInfo* info) {
    Timer timer;
    const std::string text(static_cast<const char*>(data), size);
    return read_obj_text(text, name, options, info, timer);
}

}  // namespace kdt
