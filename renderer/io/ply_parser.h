// The PLY parser: reads the header, then each element in file order through the binary
// decoders or the ASCII scanners, and assembles the mesh. Its methods live in ply_header.cpp,
// ply_binary.cpp, ply_ascii.cpp and ply_reader.cpp. Internal to renderer/io/ply_*.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <new>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "renderer/core/error.h"
#include "renderer/core/huge_pages.h"
#include "renderer/core/timer.h"
#include "renderer/geometry/mesh.h"
#include "renderer/geometry/polygon.h"
#include "renderer/io/file_reader.h"
#include "renderer/io/mesh_io.h"
#include "renderer/io/ply_format.h"
#include "renderer/io/ply_helper_thread.h"
#include "renderer/io/ply_input.h"
#include "renderer/io/ply_reader.h"

namespace kdt::ply {

/// One PLY load: parse() reads the header, then every element in file order, and returns the
/// mesh; bad input throws kdt::Error naming the file, element, index and line or offset.
class PlyParser {
public:
    PlyParser(FileReader& reader, const MeshLoadOptions& options)
        : reader_(reader), in_(reader), options_(options) {
        threads_ = options.threads > 0 ? options.threads
                                       : (std::thread::hardware_concurrency() >= 2 ? 2 : 1);
    }

    TriangleMesh parse(MeshLoadInfo* info);

private:
    // Errors
    [[noreturn]] void fail_header(const std::string& message) const {
        ErrorLocation w;
        w.path = reader_.path();
        w.element = "header";
        w.line = line_;
        throw Error(w, message);
    }
    [[noreturn]] void fail_data(const Element& el, uint64_t index, int64_t line, int64_t offset,
                                const std::string& message) const {
        ErrorLocation w;
        w.path = reader_.path();
        w.element = el.name;
        w.index = int64_t(index);
        w.line = line;
        w.offset = offset;
        throw Error(w, message);
    }
    // Location of the record being read: its line for ascii, its first byte for binary.
    [[noreturn]] void fail_at(const Element& el, uint64_t index, const std::string& message) const {
        if (ascii_) fail_data(el, index, line_, -1, message);
        fail_data(el, index, -1, int64_t(record_offset_), message);
    }

    void parse_header();
    void check_version(std::string_view version);
    void plan_elements();
    void check_counts();
    uint64_t min_record_bytes(const Element& el, bool full_faces) const;

    // Binary
    template <bool Swap>
    void read_binary_element(Element& el);
    template <bool Swap>
    void read_binary_vertices_fixed(Element& el);
    template <bool Swap>
    void read_binary_record(Element& el, uint64_t i);
    template <bool Swap>
    void read_binary_faces_fast(Element& el);
    void need(const Element& el, uint64_t i, size_t n) {
        if (!in_.fill(n))
            fail_data(el, i, -1, int64_t(in_.offset()), "unexpected end of data (file truncated?)");
    }

    // ASCII
    void read_ascii_element(Element& el);
    void read_ascii_line(Element& el, uint64_t i, float* v);
    bool fast_ascii_scalars(const Element& el, const char*& p, const char* e, float* v) const;
    bool fast_ascii_triangle(const char*& p, const char* e, int64_t* idx) const;
    bool line_ascii_scalars(const Element& el, const char*& p, const char* e, float* v) const;
    bool line_ascii_triangle(const char*& p, const char* e, int64_t* idx) const;
    struct LinesResult {
        uint64_t lines = 0;
        const char* end = nullptr;
    };
    LinesResult parse_lines(const Element& el, bool faces, bool is_vertex, const char* p,
                            const char* e, uint64_t first, uint64_t max_lines, bool append);
    uint64_t parallel_chunk(const Element& el, uint64_t i, bool faces, bool is_vertex, bool& poor);
    bool next_data_line(const char*& b, const char*& e);

    // Shared
    void store_vertex(const Element& el, uint64_t i, const float* v);
    [[gnu::noinline]] void non_finite_vertex(const Element& el, uint64_t i, const Vec3f& p);
    void emit_face(const Element& el, uint64_t i, const int64_t* idx, size_t n);
    /// A vertex index stored as a float or double: an integer value is taken as it is (out of
    /// range ones then fail as integer indices do); any other value (a fraction, NaN,
    /// infinity) fails naming record i of el and `text`, the value as written.
    int64_t real_index(const Element& el, uint64_t i, double x, const std::string& text) const {
        if (!std::isfinite(x) || x != std::floor(x))
            fail_at(el, i, "vertex index " + text + " is not an integer");
        if (std::fabs(x) >= 0x1p62)  // beyond int64_t, and far out of range
            fail_at(el, i,
                    "vertex index " + text + " out of range (" + std::to_string(vertex_count_) +
                        " vertices)");
        return int64_t(x);
    }
    template <bool Swap>
    int64_t load_index(const Element& el, uint64_t i, const char* p, PlyType t) const;
    void emit_strip(const Element& el, uint64_t i, const int64_t* idx, size_t n);
    /// Replaces the fan of the polygon idx[0 .. n) at mesh_.triangles[first ..] by
    /// triangulate_polygon's triangles; its vertices must have been read.
    void triangulate_face(size_t first, const uint32_t* idx, size_t n);
    // A face lists at least three indices; a strip may hold any number. False for a shorter
    // face that drop_invalid drops (counted in dropped_faces_; the caller still reads its
    // indices, unchecked, and emits nothing); an error without drop_invalid.
    bool check_face_size(const Element& el, uint64_t i, int64_t count) {
        if (count >= 3 || is_strip(el)) return true;
        if (!options_.drop_invalid)
            fail_at(el, i,
                    std::to_string(count) + (count == 1 ? " index" : " indices") +
                        ", a face needs at least 3; --drop-invalid drops such faces");
        ++source_faces_;
        ++dropped_faces_;
        return false;
    }
    bool is_strip(const Element& el) const {
        return strip_el_ >= 0 && &el == &elements_[size_t(strip_el_)];
    }
    void finish(TriangleMesh& mesh);

    // Memory: arrays sized up front for input of known size, grown with the data otherwise.
    void allocate_arrays();
    /// Makes positions (and normals, colours when kept) hold at least n entries, n at most
    /// the vertex count.
    void grow_vertices(const Element& el, uint64_t n);
    /// Gives v capacity for n entries, doubling but not past the element's count unless n
    /// is (polygons make more triangles than faces); out of memory is an Error naming el.
    template <typename T>
    void grow_capacity(std::vector<T>& v, uint64_t n, const Element& el) {
        if (n <= v.capacity()) return;
        const uint64_t doubled = std::max<uint64_t>(n, 2 * uint64_t(v.capacity()));
        const uint64_t cap = n > el.count ? doubled : std::min(doubled, el.count);
        try {
            reserve_huge(v, size_t(cap));
        } catch (const std::bad_alloc&) {
            out_of_memory(el, cap, sizeof(T));
        }
    }
    [[noreturn]] void out_of_memory(const Element& el, uint64_t elements,
                                    size_t element_bytes) const;
    void read_elements();
    void check_trailing_text();
    void check_trailing_bytes();
    void report(MeshLoadInfo* info, const Timer& timer) const;

    FileReader& reader_;
    Input in_;
    MeshLoadOptions options_;
    bool ascii_ = false, swap_ = false;
    PlyEncoding encoding_ = PlyEncoding::ascii;
    int64_t line_ = 0;
    int64_t header_lines_ = 0;
    uint64_t record_offset_ = 0;
    uint64_t data_offset_ = 0;
    std::vector<Element> elements_;
    int vertex_el_ = -1, face_el_ = -1;
    int strip_el_ = -1;  // element "tristrips" (Cyberware-era scans): strips, -1 restarts
    bool has_normals_ = false, has_colors_ = false;
    bool xyz_only_ = false;  // vertex properties: float x, y, z and nothing else
    bool vertices_read_ = false;
    uint64_t vertex_count_ = 0;
    uint64_t face_records_bound_ = 0;  // faces of three indices the input can hold

    TriangleMesh mesh_;
    std::vector<uint8_t> bad_vertex_;  // only allocated once a non-finite vertex is seen
    uint64_t bad_vertices_ = 0;
    uint64_t dropped_faces_ = 0, degenerate_faces_ = 0, source_faces_ = 0;
    std::vector<int64_t> poly_;    // indices of the face being read
    std::vector<int64_t> sorted_;  // scratch for the degenerate test of big polygons
    // Polygons (4+ corners) read before the vertices are fanned, and triangulated in finish().
    struct LatePolygon {
        size_t first_triangle = 0, first_index = 0, corners = 0;
    };
    std::vector<LatePolygon> late_polygons_;
    std::vector<uint32_t> late_indices_;
    std::vector<uint32_t> corner_index_;  // the polygon being triangulated
    std::vector<Vec3f> corner_pos_;
    PolygonScratch polygon_scratch_;
    int threads_ = 1;
    std::unique_ptr<Helper> helper_;  // created by the first two-thread chunk

    std::vector<std::string> warnings_;  // for MeshLoadInfo::warnings
};

inline void PlyParser::store_vertex(const Element& el, uint64_t i, const float* v) {
    if (i >= mesh_.positions.size()) [[unlikely]]
        grow_vertices(el, i + 1);
    Vec3f p(v[kPosX], v[kPosY], v[kPosZ]);
    mesh_.positions[i] = p;
    if (has_normals_) mesh_.normals[i] = Vec3f(v[kNormX], v[kNormY], v[kNormZ]);
    if (has_colors_) mesh_.colors[i] = Vec3f(v[kColR], v[kColG], v[kColB]);
    if (!is_finite(p)) [[unlikely]]
        non_finite_vertex(el, i, p);
}

}  // namespace kdt::ply
