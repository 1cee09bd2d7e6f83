#include "renderer/io/ply_reader.h"

#include <algorithm>
#include <cstdio>
#include <new>
#include <string>
#include <vector>

#include "renderer/core/error.h"
#include "renderer/core/huge_pages.h"
#include "renderer/core/timer.h"
#include "renderer/io/ply_line_scan.h"
#include "renderer/io/ply_parser.h"

namespace kdt {
namespace ply {

void PlyParser::non_finite_vertex(const Element& el, uint64_t i, const Vec3f& p) {
    if (!options_.drop_invalid)
        fail_at(el, i,
                "non-finite coordinate (" + std::to_string(p.x) + ", " + std::to_string(p.y) +
                    ", " + std::to_string(p.z) + "); --drop-invalid drops the faces using it");
    // Sized with the positions, which grow with the data; completed after the element.
    if (bad_vertex_.size() <= i)
        bad_vertex_.resize(std::max(size_t(i) + 1, mesh_.positions.size()));
    bad_vertex_[i] = 1;
    ++bad_vertices_;
}

void PlyParser::emit_face(const Element& el, uint64_t i, const int64_t* idx, size_t n) {
    ++source_faces_;
    bool bad = false;
    for (size_t k = 0; k < n; ++k) {
        if (idx[k] < 0 || uint64_t(idx[k]) >= vertex_count_) [[unlikely]]
            fail_at(el, i,
                    "vertex index " + std::to_string(idx[k]) + " out of range (" +
                        std::to_string(vertex_count_) + " vertices)");
        if (!bad_vertex_.empty() && vertices_read_) bad |= bad_vertex_[size_t(idx[k])] != 0;
    }
    if (bad) {
        ++dropped_faces_;
        return;
    }
    bool degenerate = false;
    if (n == 3) {
        degenerate = idx[0] == idx[1] || idx[1] == idx[2] || idx[0] == idx[2];
    } else if (n <= 32) {
        for (size_t a = 0; a < n && !degenerate; ++a)
            for (size_t c = a + 1; c < n; ++c)
                if (idx[a] == idx[c]) {
                    degenerate = true;
                    break;
                }
    } else {
        // Big polygons: sort a copy instead of comparing all pairs (a hostile file could
        // hold a face with millions of corners).
        sorted_.assign(idx, idx + n);
        std::sort(sorted_.begin(), sorted_.end());
        degenerate = std::adjacent_find(sorted_.begin(), sorted_.end()) != sorted_.end();
    }
    degenerate_faces_ += degenerate;
    const size_t first = mesh_.triangles.size();
    for (size_t k = 1; k + 1 < n; ++k)
        mesh_.triangles.emplace_back(uint32_t(idx[0]), uint32_t(idx[k]), uint32_t(idx[k + 1]));
    if (n == 3) return;
    // A polygon: its fan stands unless it is not convex, which needs its corners' positions.
    if (n == 4 && vertices_read_) {
        const Vec3f* p = mesh_.positions.data();
        if (quad_is_convex(p[idx[0]], p[idx[1]], p[idx[2]], p[idx[3]])) return;
    }
    corner_index_.assign(idx, idx + n);
    if (vertices_read_) {
        triangulate_face(first, corner_index_.data(), n);
    } else {
        late_polygons_.push_back({first, late_indices_.size(), n});
        late_indices_.insert(late_indices_.end(), corner_index_.begin(), corner_index_.end());
    }
}

void PlyParser::triangulate_face(size_t first, const uint32_t* idx, size_t n) {
    corner_pos_.resize(n);
    for (size_t k = 0; k < n; ++k) corner_pos_[k] = mesh_.positions[idx[k]];
    Vec3u* t = mesh_.triangles.data() + first;
    triangulate_polygon(corner_pos_, t, polygon_scratch_);
    for (size_t k = 0; k + 2 < n; ++k) t[k] = Vec3u(idx[t[k].x], idx[t[k].y], idx[t[k].z]);
}

// One triangle strip: triangle k of a run is (v_k, v_k+1, v_k+2), with the first two swapped
// for odd k so that all keep one winding; -1 ends a run. Triangles with a repeated vertex
// are how strips are stitched, so they are dropped (they have no area), not kept as faces.
void PlyParser::emit_strip(const Element& el, uint64_t i, const int64_t* idx, size_t n) {
    ++source_faces_;
    int64_t a = -1, b = -1;
    bool odd = false;
    for (size_t k = 0; k < n; ++k) {
        const int64_t c = idx[k];
        // -1 ends a run; so does 2^32 - 1, its bit pattern in an unsigned 32-bit list
        // (never a valid index: at most 2^32 - 1 vertices).
        if (c == -1 || c == int64_t(UINT32_MAX)) {
            a = b = -1;
            odd = false;
            continue;
        }
        if (c < 0 || uint64_t(c) >= vertex_count_) [[unlikely]]
            fail_at(el, i,
                    "vertex index " + std::to_string(c) + " out of range (" +
                        std::to_string(vertex_count_) + " vertices; -1 ends a strip)");
        if (a < 0) {
            a = c;
            continue;
        }
        if (b < 0) {
            b = c;
            continue;
        }
        const int64_t p = odd ? b : a, q = odd ? a : b;
        odd = !odd;
        a = b;
        b = c;
        if (p == q || q == c || p == c) continue;
        if (!bad_vertex_.empty() && vertices_read_ &&
            (bad_vertex_[size_t(p)] || bad_vertex_[size_t(q)] || bad_vertex_[size_t(c)])) {
            ++dropped_faces_;
            continue;
        }
        mesh_.triangles.emplace_back(uint32_t(p), uint32_t(q), uint32_t(c));
    }
}

void PlyParser::finish(TriangleMesh& mesh) {
    for (const LatePolygon& p : late_polygons_) {
        const uint32_t* idx = late_indices_.data() + p.first_index;
        // One using a non-finite vertex is dropped below; its fan needs no better split.
        bool bad = false;
        for (size_t k = 0; k < p.corners && !bad_vertex_.empty(); ++k) bad |= bad_vertex_[idx[k]];
        if (!bad) triangulate_face(p.first_triangle, idx, p.corners);
    }
    if (bad_vertices_ == 0) return;
    // Faces read before the vertices could not see the flags: drop their triangles now.
    std::vector<Vec3u> kept;
    kept.reserve(mesh.triangles.size());
    for (const Vec3u& t : mesh.triangles) {
        if (bad_vertex_[t.x] || bad_vertex_[t.y] || bad_vertex_[t.z]) {
            ++dropped_faces_;
            continue;
        }
        kept.push_back(t);
    }
    mesh.triangles.swap(kept);
    // Remove the non-finite vertices so bounds and builders never see them.
    std::vector<uint32_t> remap(mesh.positions.size());
    uint32_t n = 0;
    for (size_t k = 0; k < mesh.positions.size(); ++k) {
        remap[k] = n;
        if (bad_vertex_[k]) continue;
        mesh.positions[n] = mesh.positions[k];
        if (!mesh.normals.empty()) mesh.normals[n] = mesh.normals[k];
        if (!mesh.colors.empty()) mesh.colors[n] = mesh.colors[k];
        ++n;
    }
    mesh.positions.resize(n);
    if (!mesh.normals.empty()) mesh.normals.resize(n);
    if (!mesh.colors.empty()) mesh.colors.resize(n);
    for (Vec3u& t : mesh.triangles) t = Vec3u(remap[t.x], remap[t.y], remap[t.z]);
}

void PlyParser::grow_vertices(const Element& el, uint64_t n) {
    grow_capacity(mesh_.positions, n, el);
    if (mesh_.positions.size() < n) mesh_.positions.resize(size_t(n));
    if (has_normals_) {
        grow_capacity(mesh_.normals, n, el);
        if (mesh_.normals.size() < n) mesh_.normals.resize(size_t(n));
    }
    if (has_colors_) {
        grow_capacity(mesh_.colors, n, el);
        if (mesh_.colors.size() < n) mesh_.colors.resize(size_t(n));
    }
}

void PlyParser::out_of_memory(const Element& el, uint64_t elements, size_t element_bytes) const {
    ErrorLocation w;
    w.path = reader_.path();
    w.element = el.name;
    throw Error(w, "out of memory growing an array to " + std::to_string(elements) +
                       " elements of " + std::to_string(element_bytes) + " bytes (the header " +
                       "declares " + std::to_string(el.count) + " " + excerpt(el.name) +
                       " elements)");
}

// Input of known size was checked against the counts (check_counts), so its arrays are
// allocated once, with huge pages, before anything touches them: first-touch faults of 4 KiB
// pages would cost more than parsing a binary file. Input of unknown size (gzip) gets arrays
// that grow as its data arrives (grow_capacity), so a header's count costs memory only once
// the data behind it exists.
void PlyParser::allocate_arrays() {
    const Element& v = elements_[size_t(vertex_el_)];
    const uint64_t first =
        reader_.size_known() ? vertex_count_ : std::min<uint64_t>(vertex_count_, kFirstRecords);
    grow_capacity(mesh_.positions, first, v);
    // read_binary_vertices_fixed appends the positions; other layouts write them by index.
    if (ascii_ || v.has_lists) mesh_.positions.resize(size_t(first));
    if (has_normals_ || has_colors_) grow_vertices(v, first);
    if (face_el_ >= 0) {
        const Element& f = elements_[size_t(face_el_)];
        grow_capacity(mesh_.triangles,
                      reader_.size_known() ? face_records_bound_
                                           : std::min<uint64_t>(face_records_bound_, kFirstRecords),
                      f);
    }
}

// Non-blank text after the last ascii element means the header's counts do not match the
// data. Only the first kTrailingLookBytes are looked at: a stream of blank lines after the
// data (gzip makes gigabytes of them from a few kilobytes) is not read to its end.
void PlyParser::check_trailing_text() {
    uint64_t looked = 0, newlines = 0;
    while (looked < kTrailingLookBytes && (in_.avail() > 0 || in_.fill(1))) {
        const size_t n = size_t(std::min<uint64_t>(in_.avail(), kTrailingLookBytes - looked));
        const char* p = in_.pos();
        for (size_t k = 0; k < n; ++k) {
            if (p[k] == '\n') {
                ++newlines;
            } else if (!is_blank(p[k])) {
                in_.advance(k);
                in_.fill(64);
                ErrorLocation w;
                w.path = reader_.path();
                w.line = line_ + 1 + int64_t(newlines);
                throw Error(w, "data after the last element ('" + token_text(in_.pos(), in_.end()) +
                                   "'): the header's element counts do not match the data");
            }
        }
        in_.advance(n);
        looked += n;
    }
}

// Bytes after the last binary element are skipped, as Assimp and other readers do: writers
// may pad or append a footer. But they are also what a header whose counts are too small
// leaves unread, so they get a warning naming the offset and how many follow, unless they are
// one line end or a single blank (a writer ending every file with a newline). Input of
// unknown size (gzip) is looked at for kTrailingLookBytes only, not inflated to its end.
void PlyParser::check_trailing_bytes() {
    const uint64_t at = in_.offset();
    if (!in_.fill(3)) {  // fewer than 3 bytes follow, all of them in the buffer
        const char* p = in_.pos();
        const size_t n = in_.avail();
        if (n == 0 || (n == 1 && is_sep(p[0])) || (n == 2 && p[0] == '\r' && p[1] == '\n')) return;
    }
    uint64_t after = 0;
    bool more = false;
    if (reader_.size_known()) {
        after = reader_.size_bound() > at ? reader_.size_bound() - at : 0;
    } else {
        while (after < kTrailingLookBytes && (in_.avail() > 0 || in_.fill(1))) {
            const size_t n = size_t(std::min<uint64_t>(in_.avail(), kTrailingLookBytes - after));
            in_.advance(n);
            after += n;
        }
        more = in_.avail() > 0 || in_.fill(1);
    }
    if (after == 0) return;
    ErrorLocation w;
    w.path = reader_.path();
    w.offset = int64_t(at);
    warnings_.push_back(Error(w, (more ? "more than " : "") + std::to_string(after) +
                                     (after == 1 ? " byte" : " bytes") +
                                     " after the last element, ignored (padding, or data the "
                                     "header's element counts leave out)")
                            .what());
}

TriangleMesh PlyParser::parse(MeshLoadInfo* info) {
    Timer timer;
    try {
        parse_header();
        plan_elements();
        check_counts();
        read_elements();
        in_.check_unchanged();
    } catch (const Error& e) {
        report(info, timer);
        // Data read from a file that shrank meanwhile: what went wrong is the file.
        in_.check_unchanged();
        // An absurd inflation ratio is the likelier cause of whatever went wrong.
        if (!reader_.gzip() || reader_.over_inflation_limit() ||
            reader_.bytes_read() < kInflationNoteBytes ||
            reader_.inflation_ratio() < double(kAbsurdInflationRatio))
            throw;
        char ratio[32];
        std::snprintf(ratio, sizeof(ratio), "%.0f:1", reader_.inflation_ratio());
        throw Error(e.where(), e.message() + " (the gzip data inflated " + ratio +
                                   " up to here, far more than mesh data does: a gzip bomb?)");
    } catch (const std::bad_alloc&) {
        // Elements name themselves (read_elements); this is the header or the input buffer.
        report(info, timer);
        in_.check_unchanged();
        ErrorLocation w;
        w.path = reader_.path();
        w.element = "header";
        throw Error(w, "out of memory while reading the header");
    } catch (...) {
        report(info, timer);
        in_.check_unchanged();
        throw;
    }
    report(info, timer);
    return std::move(mesh_);
}

void PlyParser::read_elements() {
    allocate_arrays();
    line_ = header_lines_;
    for (Element& el : elements_) {
        try {
            if (ascii_)
                read_ascii_element(el);
            else if (swap_)
                read_binary_element<true>(el);
            else
                read_binary_element<false>(el);
            if (&el == &elements_[size_t(vertex_el_)]) {
                // Arrays grown with the data are now complete; flags cover every vertex.
                grow_vertices(el, vertex_count_);
                if (!bad_vertex_.empty()) bad_vertex_.resize(size_t(vertex_count_), 0);
                vertices_read_ = true;
            }
        } catch (const std::bad_alloc&) {
            ErrorLocation w;
            w.path = reader_.path();
            w.element = el.name;
            throw Error(w, "out of memory while reading the " + std::to_string(el.count) + " " +
                               excerpt(el.name) + " elements the header declares");
        }
    }
    if (ascii_)
        check_trailing_text();
    else
        check_trailing_bytes();
    try {
        finish(mesh_);
    } catch (const std::bad_alloc&) {
        ErrorLocation w;
        w.path = reader_.path();
        throw Error(w, "out of memory while dropping non-finite vertices");
    }
}

void PlyParser::report(MeshLoadInfo* info, const Timer& timer) const {
    if (!info) return;
    info->format = "ply";
    info->encoding = kPlyEncodingNames[size_t(encoding_)];
    info->gzip = reader_.gzip();
    info->file_bytes = in_.offset();
    info->input_bytes_read = reader_.bytes_read();
    info->array_bytes =
        mesh_.positions.capacity() * sizeof(Vec3f) + mesh_.normals.capacity() * sizeof(Vec3f) +
        mesh_.colors.capacity() * sizeof(Vec3f) + mesh_.triangles.capacity() * sizeof(Vec3u);
    info->source_faces = source_faces_;
    info->dropped_faces = dropped_faces_;
    info->degenerate_faces = degenerate_faces_;
    info->warnings = warnings_;
    info->seconds = timer.seconds();
}

}  // namespace ply

TriangleMesh read_ply(FileReader& reader, const MeshLoadOptions& options, MeshLoadInfo* info) {
    // The parser names what ran out where it can; this covers the rest (its input buffer).
    try {
        ply::PlyParser parser(reader, options);
        return parser.parse(info);
    } catch (const std::bad_alloc&) {
        ErrorLocation w;
        w.path = reader.path();
        throw Error(w, "out of memory reading the mesh");
    }
}

TriangleMesh read_ply(const std::string& path, const MeshLoadOptions& options, MeshLoadInfo* info) {
    FileReader reader = FileReader::open(path);
    return read_ply(reader, options, info);
}

TriangleMesh read_ply_memory(const void* data, size_t size, const std::string& name,
                             const MeshLoadOptions& options, MeshLoadInfo* info) {
    FileReader reader = FileReader::from_memory(data, size, name);
    return read_ply(reader, options, info);
}

}  // namespace kdt
